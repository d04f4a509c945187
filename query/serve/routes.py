"""The routes of ``shapedb serve`` (:mod:`query.serve.server`): the JSON API over one database.

Every route is a plain (synchronous) function, run by FastAPI in its thread pool;
the database's own caches (faiss index, catalogue, DuckDB connection) are shared
between them and follow the store's version. See :mod:`query.serve.server` for the list
of paths, the error statuses and the security rules.
"""

from __future__ import annotations

import json
import logging
import threading
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import pyarrow.compute as pc
from fastapi import FastAPI, File, Form, Query, Request, UploadFile
from fastapi.responses import FileResponse, Response
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException

from query.serve.state import (
    Job,
    Service,
    Uploaded,
    hits_json,
    json_response,
    new_key,
    remove_folder,
    status_of,
    upload_folder,
)
from query.serve.viewer import (
    decomposition_payload,
    record_payload,
    stored_record,
    stored_surface,
    surface_payload,
)
from shapedb.errors import NotFoundError, QueryError, ShapeDBError

__all__ = ["add_routes", "MatchRequest", "SQLRequest"]

log = logging.getLogger(__name__)

_MAX_K = 1000
_MAX_TARGETS = 50
_MAX_JOBS = 64
_UPLOAD = "upload:"

K = Annotated[int, Query(ge=1, le=_MAX_K, description="number of hits")]
Where = Annotated[
    str | None, Query(description="SQL predicate over shapes, e.g. label = 'Chair' (token)")
]


class MatchRequest(BaseModel):
    """Body of ``POST /api/match``: a part of a query model, and where to look for it."""

    query: int | str = Field(description="stored id or name, or 'upload:KEY' (X-Query header)")
    node: int | None = Field(None, ge=0, description="ball number of the query part")
    point: list[float] | None = Field(
        None, min_length=3, max_length=3, description="a point on the query; its nearest ball"
    )
    targets: list[int] | None = Field(
        None,
        max_length=_MAX_TARGETS,
        description="stored ids to match in (the best part of each, in this order); "
        "omitted: search the whole store",
    )
    k: int = Field(10, ge=1, le=100, description="shapes returned by a whole-store search")
    hops: int = Field(2, ge=0, le=8, description="neighbourhood range K")
    where: str | None = Field(None, description="SQL predicate restricting the store (token)")


class SQLRequest(BaseModel):
    """Body of ``POST /api/sql``: one read-only statement."""

    sql: str = Field(description="one statement over the views shapes, balls, edges, failures")
    limit: int = Field(1000, ge=1, le=10_000, description="rows returned at most")


def _scrub(exc: ShapeDBError, folder: Path, names: dict[str, str]) -> HTTPException:
    """The error of an upload, with the private temporary paths replaced by file names."""
    text = str(exc)
    for path, name in names.items():
        text = text.replace(path, name)
    text = text.replace(str(folder) + "/", "").replace(str(folder), "upload")
    return HTTPException(status_of(exc), text)


def add_routes(app: FastAPI, service: Service) -> None:
    """Register the API routes on ``app``."""
    db = service.db

    def record(sid: int) -> Any:
        key = ("record", sid, db.store.version)
        found = service.shapes.get(key)
        if found is None:
            found = stored_record(db, sid)
            service.shapes.put(key, found)
        return found

    def table() -> Any:
        version = db.store.version
        cached = service.shapes.get(("table", version))
        if cached is None:
            cached = db.shapes(["id", "name", "label", "representation", "n_balls"])
            service.shapes.put(("table", version), cached)
        return cached

    # ---------------------------------------------------------------- store
    @app.get("/api/server", tags=["store"])
    def server() -> Response:
        """The store's path and version, and the server's limits."""
        import ingest

        return json_response(
            {
                "store": str(db.path),
                "version": db.store.version,
                "shapes": len(db),
                "token_required": service.token is not None,
                "max_upload_bytes": service.max_upload_bytes,
                "formats": sorted(ingest.SUPPORTED),
            }
        )

    @app.get("/api/info", tags=["store"])
    def info() -> Response:
        """The store's ``info``: shape count, labels with counts, failures, configuration."""
        return json_response(db.info())

    @app.get("/api/shapes", tags=["store"])
    def shapes(
        offset: Annotated[int, Query(ge=0)] = 0,
        limit: Annotated[int, Query(ge=1, le=1000)] = 50,
        label: Annotated[str | None, Query(description="only this class")] = None,
    ) -> Response:
        """A page of stored shapes (by id), with the total count."""
        t = table()
        if label is not None:
            t = t.filter(pc.equal(t.column("label"), label))
        return json_response(
            {
                "total": t.num_rows,
                "offset": offset,
                "limit": limit,
                "shapes": t.slice(offset, limit).to_pylist(),
            }
        )

    @app.get("/api/shapes/{id}", tags=["store"])
    def shape(id: str) -> Response:
        """One stored shape: its record, balls (centres, radii) and contact edges."""
        return json_response(record_payload(record(service.resolve_id(id))))

    @app.get("/api/shapes/{id}/surface", tags=["store"])
    def surface(id: str) -> Response:
        """The mesh or point cloud of a shape's source file, when that file is still there."""
        found = record(service.resolve_id(id))
        key = (found.id, found.content_hash)
        payload = service.surfaces.get(key)
        if payload is None:
            payload = stored_surface(db, found)
            service.surfaces.put(key, payload)
        return json_response(payload)

    @app.get(
        "/api/shapes/{id}/thumbnail.png",
        tags=["store"],
        response_class=FileResponse,
        responses={200: {"content": {"image/png": {}}}},
    )
    def thumbnail(id: str) -> FileResponse:
        """A small picture of the shape's balls, drawn at the first request and cached."""
        from query.serve.thumbnails import thumbnail as draw

        path = draw(db, service.resolve_id(id))
        return FileResponse(path, media_type="image/png", headers={"Cache-Control": "max-age=60"})

    # ---------------------------------------------------------------- search
    @app.get("/api/search", tags=["search"])
    async def search(
        request: Request,
        id: Annotated[str, Query(description="stored shape id or name")],
        k: K = 10,
        where: Where = None,
    ) -> Response:
        """The k stored shapes most like a stored one: ``[{id, name, label, similarity}]``."""

        def run() -> Response:
            hits = db.search(service.resolve_id(id), k=k, where=where)
            return json_response(hits_json(hits))

        if where is not None:
            service.require_token(request, "a where filter")
            return await run_in_threadpool(run)  # SQL: may take a while
        # an in-memory index lookup of about a millisecond: run on the event loop, as
        # two thread hops per request cost more than the search on a loaded machine
        return run()

    @app.post("/api/search", tags=["search"])
    def search_file(
        request: Request,
        file: Annotated[UploadFile, File(description="a model file in any format ingest reads")],
        k: K = 10,
        where: Where = None,
    ) -> Response:
        """The k stored shapes most like an uploaded model (decomposed with the store's
        configuration); the response header ``X-Query`` names the query for
        ``/api/queries/{key}`` and ``/api/match``."""
        from shapedb.geometry.view import is_sparse
        from shapedb.mdbd.decomposition import decompose

        service.require_token(request, "an upload")
        folder = upload_folder()
        name = file.filename or "upload"
        try:
            path = service.save_upload(file, folder)
            geometry = db.load(path)
            d = decompose(
                geometry, config=db.config.mdbd, tail_balls=db.config.light_field_tail,
                keep_inside=db.config.light_field_inside,
            )  # fmt: skip
            # the decomposition stands for the geometry exactly when the search needs
            # nothing else of it: a dense query in a store without sparse views
            exact = not is_sparse(d.sampling, d.spacing) and not db.config.cloud.view_cells
            hits = db.search(d if exact else geometry, k=k, where=where)
        except ShapeDBError as exc:
            raise _scrub(exc, folder, {str(folder / Path(name).name): name}) from exc
        finally:
            remove_folder(folder)
        key = new_key()
        service.queries.put(key, Uploaded(Path(name).name, d, geometry))
        return json_response(hits_json(hits), headers={"X-Query": key})

    @app.get("/api/queries/{key}", tags=["search"])
    def uploaded(key: str) -> Response:
        """Balls, contact edges and surface of a recently uploaded query."""
        q = service.queries.get(key)
        if q is None:
            raise HTTPException(404, f"{key}: no such uploaded query (they expire)")
        if q.surface is None:
            q.surface = surface_payload(q.geometry)
        return json_response(
            {"name": q.name, **decomposition_payload(q.decomposition), "surface": q.surface}
        )

    @app.post("/api/match", tags=["search"])
    def match(request: Request, body: MatchRequest) -> Response:
        """Part search (``db.match``): the part of the query around ``node`` (or the ball
        nearest ``point``), matched in each of ``targets`` or in the whole store."""
        if body.where is not None:
            service.require_token(request, "a where filter")
        if body.node is None and body.point is None:
            raise QueryError("give the query part as node or point", source="match")
        if isinstance(body.query, str) and body.query.startswith(_UPLOAD):
            q = service.queries.get(body.query[len(_UPLOAD) :])
            if q is None:
                raise HTTPException(404, f"{body.query}: no such uploaded query (they expire)")
            model = q.decomposition
        else:
            model = record(service.resolve_id(body.query)).decomposition
        n = len(model.radii)
        if body.node is not None and body.node >= n:
            raise NotFoundError(f"the query has {n} balls", source=f"node {body.node}")
        options: dict[str, Any] = {"node": body.node, "point": body.point, "hops": body.hops}
        if body.targets is not None:
            matches: list[Any] = []
            for target in body.targets:
                other = record(service.resolve_id(target))
                found = db.match(model, other.decomposition, top=1, **options)
                matches.extend(
                    replace(m, id=other.id, name=other.name, label=other.label) for m in found[:1]
                )
        else:
            matches = db.match(model, k=body.k, where=body.where, **options)
        out = [m.to_dict() for m in matches]
        return json_response({"query_nodes": out[0]["query_nodes"] if out else [], "matches": out})

    # ---------------------------------------------------------------- sql, eval
    @app.post("/api/sql", tags=["sql"])
    def sql(request: Request, body: SQLRequest) -> Response:
        """One read-only statement through ``db.sql`` (sandboxed as the store's SQL is)."""
        service.require_token(request, "SQL")
        result = db.sql(body.sql)
        rows = result.slice(0, body.limit).to_pylist()
        return json_response(
            {
                "columns": result.column_names,
                "rows": [[r[c] for c in result.column_names] for r in rows],
                "total": result.num_rows,
                "truncated": result.num_rows > body.limit,
            }
        )

    @app.get("/api/eval", tags=["sql"])
    def evaluate(
        label: Annotated[str, Query(description="class column or metadata key")] = "label",
    ) -> Response:
        """Leave-one-out retrieval scores by class, and the precision-recall curve."""
        key = (db.store.version, label)
        out = service.evals.get(key)
        if out is None:
            scores = db.evaluate(label=label)
            out = {
                **scores.to_dict(),
                "recall": scores.recall.tolist(),
                "precision": scores.precision.tolist(),
            }
            service.evals.put(key, out)
        return json_response(out)

    # ---------------------------------------------------------------- ingest
    @app.post("/api/ingest", tags=["ingest"], status_code=202)
    def ingest_upload(
        request: Request,
        file: Annotated[list[UploadFile], File(description="model files (repeat the field)")],
        label: Annotated[str | None, Form(description="class label of every file")] = None,
    ) -> Response:
        """Add uploaded model files to the store in the background; poll the job."""
        service.require_token(request, "ingest")
        if not service.ingest_lock.acquire(blocking=False):
            raise HTTPException(409, "an ingest is already running; poll its job")
        folder = upload_folder()
        try:
            paths, names = [], []
            for i, upload in enumerate(file):
                sub = folder / str(i)  # same file names in one upload stay apart
                sub.mkdir()
                paths.append(service.save_upload(upload, sub))
                names.append(Path(upload.filename or f"upload{i}").stem or f"upload{i}")
        except BaseException:
            remove_folder(folder)
            service.ingest_lock.release()
            raise
        job = Job(new_key(), total=len(paths))
        _remember(service, job)
        worker = threading.Thread(
            target=_run_ingest,
            args=(service, job, folder, paths, names, label),
            name=f"shapedb-ingest-{job.id}",
            daemon=True,
        )
        worker.start()
        return json_response(job.to_dict(), 202, {"Location": f"/api/ingest/{job.id}"})

    @app.get("/api/ingest/{job}", tags=["ingest"])
    def ingest_job(job: str) -> Response:
        """Progress of an ingest by upload: state, done/total, and its report when done."""
        found = service.jobs.get(job)
        if found is None:
            raise HTTPException(404, f"{job}: no such ingest job")
        return json_response(found.to_dict())


def _remember(service: Service, job: Job) -> None:
    service.jobs[job.id] = job
    finished = [j for j in service.jobs.values() if j.state != "running"]
    for old in finished[: max(0, len(service.jobs) - _MAX_JOBS)]:
        service.jobs.pop(old.id, None)


def _run_ingest(
    service: Service,
    job: Job,
    folder: Path,
    paths: list[Path],
    names: list[str],
    label: str | None,
) -> None:
    def progress(done: int, total: int) -> None:
        job.done, job.total = done, total

    try:
        report = service.db.ingest(
            [str(p) for p in paths],
            names=names,
            labels={str(p): label for p in paths} if label else None,
            workers=1,
            progress=progress,
        )
        text = json.dumps(report.to_dict()).replace(str(folder) + "/", "")
        job.report = {**json.loads(text), "ids": [int(i) for i in report.ingested]}
        job.done, job.state = job.total, "done"
    except ShapeDBError as exc:
        job.error, job.state = str(exc).replace(str(folder) + "/", ""), "failed"
    except Exception:  # noqa: BLE001 - reported on the job, logged in full here
        log.exception("ingest job %s failed", job.id)
        job.error, job.state = "internal error (logged by the server)", "failed"
    finally:
        remove_folder(folder)
        service.ingest_lock.release()
