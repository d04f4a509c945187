"""The routes of ``shapedb serve`` (:mod:`query.serve.server`): the JSON API over one database.

:data:`ROUTES` is the route table: one :class:`Route` per path and method, whose
handler is a method of :class:`Api` (which holds the service state);
:func:`add_routes` registers them all. Plain (synchronous) handlers are run by FastAPI
in its thread pool; the database's own caches (faiss index, catalogue, DuckDB
connection) are shared between them and follow the store's version. See
:mod:`query.serve.server` for the list of paths, the error statuses and the security
rules.
"""

from __future__ import annotations

import types
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any

import pyarrow.compute as pc
from fastapi import FastAPI, File, Form, Query, Request, UploadFile
from fastapi.responses import FileResponse, Response
from pydantic import BaseModel, Field
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException

from query.serve.jobs import original_name, start_ingest
from query.serve.state import (
    MAX_ID,
    Service,
    Uploaded,
    error_response,
    hits_json,
    json_response,
    new_key,
    remove_folder,
    safe_name,
    status_of,
    upload_folder,
)
from query.serve.statements import ClientGone, Statement
from query.serve.viewer import (
    decomposition_payload,
    record_payload,
    stored_record,
    stored_surface,
    surface_payload,
)
from shapedb.errors import NotFoundError, QueryError, ShapeDBError

__all__ = ["Api", "MatchRequest", "ROUTES", "Route", "SQLRequest", "add_routes"]

_MAX_K = 1000
_MAX_TARGETS = 50
_UPLOAD = "upload:"
_CLIENT_GONE = 499  # no client reads it: the request log's status of an abandoned statement

K = Annotated[int, Query(ge=1, le=_MAX_K, description="number of hits")]
Where = Annotated[
    str | None, Query(description="SQL predicate over shapes, e.g. label = 'Chair' (token)")
]
Coordinate = Annotated[float, Field(allow_inf_nan=False)]


class MatchRequest(BaseModel):
    """Body of ``POST /api/match``: a part of a query model, and where to look for it."""

    query: int | str = Field(description="stored id or name, or 'upload:KEY' (X-Query header)")
    node: int | None = Field(None, ge=0, le=MAX_ID, description="ball number of the query part")
    point: list[Coordinate] | None = Field(
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


class Api:
    """The handlers of the routes, over one :class:`~query.serve.state.Service`."""

    def __init__(self, service: Service) -> None:
        self.service = service
        self.db = service.db

    # ------------------------------------------------------------ cached reads
    def record(self, sid: int) -> Any:
        """The stored record ``sid`` without its features, cached per store version."""
        key = ("record", sid, self.db.store.version)
        found = self.service.shapes.get(key)
        if found is None:
            found = stored_record(self.db, sid)
            self.service.shapes.put(key, found)
        return found

    def table(self) -> Any:
        """The columns of ``shapes`` the listing shows, cached per store version."""
        version = self.db.store.version
        cached = self.service.shapes.get(("table", version))
        if cached is None:
            cached = self.db.shapes(["id", "name", "label", "representation", "n_balls"])
            self.service.shapes.put(("table", version), cached)
        return cached

    # ------------------------------------------------------------ store
    def server(self) -> Response:
        """The store's path and version, and the server's limits."""
        import ingest

        return json_response(
            {
                "store": str(self.db.path),
                "version": self.db.store.version,
                "shapes": len(self.db),
                "token_required": self.service.token is not None,
                "max_upload_bytes": self.service.max_upload_bytes,
                "formats": sorted(ingest.SUPPORTED),
            }
        )

    def info(self) -> Response:
        """The store's ``info``: shape count, labels with counts, failures, configuration."""
        return json_response(self.db.info())

    def shapes(
        self,
        offset: Annotated[int, Query(ge=0, le=MAX_ID)] = 0,
        limit: Annotated[int, Query(ge=1, le=1000)] = 50,
        label: Annotated[str | None, Query(description="only this class")] = None,
    ) -> Response:
        """A page of stored shapes (by id), with the total count."""
        t = self.table()
        if label is not None:
            t = t.filter(pc.equal(t.column("label"), label))
        return json_response(
            {
                "total": t.num_rows,
                "offset": offset,
                "limit": limit,
                "shapes": t.slice(min(offset, t.num_rows), limit).to_pylist(),
            }
        )

    def shape(self, id: str) -> Response:
        """One stored shape: its record, balls (centres, radii) and contact edges."""
        return json_response(record_payload(self.record(self.service.resolve_id(id))))

    def surface(self, id: str) -> Response:
        """The mesh or point cloud of a shape's source file, when that file is still there."""
        found = self.record(self.service.resolve_id(id))
        key = (found.id, found.content_hash)
        payload = self.service.surfaces.get(key)
        if payload is None:
            payload = stored_surface(self.db, found)
            self.service.surfaces.put(key, payload)
        return json_response(payload)

    def thumbnail(self, id: str) -> FileResponse:
        """A small picture of the shape's balls, drawn when it was committed (else now, once)."""
        from query.serve.viewer import stored_record
        from query.thumbnails import thumbnail as draw

        path = draw(self.db.path, stored_record(self.db, self.service.resolve_id(id)))
        return FileResponse(path, media_type="image/png", headers={"Cache-Control": "max-age=60"})

    # ------------------------------------------------------------ search
    async def search(
        self,
        request: Request,
        id: Annotated[str, Query(description="stored shape id or name")],
        k: K = 10,
        where: Where = None,
    ) -> Response:
        """The k stored shapes most like a stored one: ``[{id, name, label, similarity}]``."""

        def run() -> Response:
            hits = self.db.search(self.service.resolve_id(id), k=k, where=where)
            return json_response(hits_json(hits))

        if where is not None:
            self.service.require_token(request, "a where filter")
            return await run_in_threadpool(run)  # SQL: may take a while
        # an in-memory index lookup of about a millisecond: run on the event loop, as
        # two thread hops per request cost more than the search on a loaded machine
        return run()

    def search_file(
        self,
        request: Request,
        file: Annotated[UploadFile, File(description="a model file in any format ingest reads")],
        k: K = 10,
        where: Where = None,
    ) -> Response:
        """The k stored shapes most like an uploaded model (decomposed with the store's
        configuration); the response header ``X-Query`` names the query for
        ``/api/queries/{key}`` and ``/api/match``."""
        from shapedb.geometry.pointcloud import PointCloud
        from shapedb.geometry.view import is_sparse
        from shapedb.mdbd.decomposition import decompose

        db = self.db
        self.service.require_token(request, "an upload")
        folder = upload_folder()
        name = original_name(file.filename, "upload")
        try:
            path = self.service.save_upload(file, folder)
            geometry = db.load(path)
            d = decompose(
                geometry, config=db.config.mdbd, tail_balls=db.config.light_field_tail,
                keep_inside=db.config.light_field_inside,
            )  # fmt: skip
            # the decomposition stands for the geometry exactly when the search needs
            # nothing else of it: a dense query in a store without sparse views, and no
            # point cloud (a one-sided scan is searched by its silhouette, any cloud's
            # light fields are drawn from its points)
            exact = (
                not isinstance(geometry, PointCloud)
                and not is_sparse(d.sampling, d.spacing)
                and not db.config.cloud.view_cells
            )
            hits = db.search(d if exact else geometry, k=k, where=where)
        except ShapeDBError as exc:
            raise _scrub(exc, folder, {str(path_in(folder, file)): name}) from exc
        finally:
            remove_folder(folder)
        key = new_key()
        self.service.queries.put(key, Uploaded(name, d, geometry))
        return json_response(hits_json(hits), headers={"X-Query": key})

    def uploaded(self, key: str) -> Response:
        """Balls, contact edges and surface of a recently uploaded query."""
        q = self.service.queries.get(key)
        if q is None:
            raise HTTPException(404, f"{key}: no such uploaded query (they expire)")
        if q.surface is None:
            q.surface = surface_payload(q.geometry)
        return json_response(
            {"name": q.name, **decomposition_payload(q.decomposition), "surface": q.surface}
        )

    def match(self, request: Request, body: MatchRequest) -> Response:
        """Part search (``db.match``): the part of the query around ``node`` (or the ball
        nearest ``point``), matched in each of ``targets`` or in the whole store."""
        if body.where is not None:
            self.service.require_token(request, "a where filter")
        if body.node is None and body.point is None:
            raise QueryError("give the query part as node or point", source="match")
        model = self.match_query(body.query)
        n = len(model.radii)
        if body.node is not None and body.node >= n:
            raise NotFoundError(f"the query has {n} balls", source=f"node {body.node}")
        options: dict[str, Any] = {"node": body.node, "point": body.point, "hops": body.hops}
        if body.targets is not None:
            matches: list[Any] = []
            for target in body.targets:
                other = self.record(self.service.resolve_id(target))
                found = self.db.match(model, other.decomposition, top=1, **options)
                matches.extend(
                    replace(m, id=other.id, name=other.name, label=other.label) for m in found[:1]
                )
        else:
            matches = self.db.match(model, k=body.k, where=body.where, **options)
        out = [m.to_dict() for m in matches]
        return json_response({"query_nodes": out[0]["query_nodes"] if out else [], "matches": out})

    def match_query(self, query: int | str) -> Any:
        """The decomposition of a match's query: a stored shape, or ``upload:KEY``."""
        if isinstance(query, str) and query.startswith(_UPLOAD):
            q = self.service.queries.get(query[len(_UPLOAD) :])
            if q is None:
                raise HTTPException(404, f"{query}: no such uploaded query (they expire)")
            return q.decomposition
        return self.record(self.service.resolve_id(query)).decomposition

    # ------------------------------------------------------------ sql, eval
    async def sql(self, request: Request, body: SQLRequest) -> Response:
        """One read-only statement over the store's views and macros (sandboxed as
        ``db.sql`` is); interrupted when the client goes away or the server stops."""
        self.service.require_token(request, "SQL")
        statement = Statement(self.db, body.sql)
        try:
            result = await self.service.statements.run(statement, request.receive)
        except ClientGone:
            return error_response(_CLIENT_GONE, "the client closed the request")
        except QueryError as exc:
            if statement.interrupted and self.service.statements.stopping:
                raise HTTPException(503, "the server is stopping: statement interrupted") from exc
            raise
        rows = result.slice(0, body.limit).to_pylist()
        return json_response(
            {
                "columns": result.column_names,
                "rows": [[r[c] for c in result.column_names] for r in rows],
                "total": result.num_rows,
                "truncated": result.num_rows > body.limit,
            }
        )

    def evaluate(
        self,
        label: Annotated[str, Query(description="class column or metadata key")] = "label",
    ) -> Response:
        """Leave-one-out retrieval scores by class, and the precision-recall curve."""
        key = (self.db.store.version, label)
        out = self.service.evals.get(key)
        if out is None:
            scores = self.db.evaluate(label=label)
            out = {
                **scores.to_dict(),
                "recall": scores.recall.tolist(),
                "precision": scores.precision.tolist(),
            }
            self.service.evals.put(key, out)
        return json_response(out)

    # ------------------------------------------------------------ ingest
    def ingest_upload(
        self,
        request: Request,
        file: Annotated[list[UploadFile], File(description="model files (repeat the field)")],
        label: Annotated[str | None, Form(description="class label of every file")] = None,
    ) -> Response:
        """Add uploaded model files to the store in the background; poll the job."""
        service = self.service
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
                names.append(original_name(upload.filename, f"upload{i}"))
        except BaseException:
            remove_folder(folder)
            service.ingest_lock.release()
            raise
        job = start_ingest(service, folder, paths, names, label)
        return json_response(job.to_dict(), 202, {"Location": f"/api/ingest/{job.id}"})

    def ingest_job(self, job: str) -> Response:
        """Progress of an ingest by upload: state, done/total, and its report when done."""
        found = self.service.jobs.get(job)
        if found is None:
            raise HTTPException(404, f"{job}: no such ingest job")
        return json_response(found.to_dict())


def path_in(folder: Path, upload: UploadFile) -> Path:
    """Where :meth:`Service.save_upload` writes ``upload`` in ``folder``."""
    return folder / safe_name(upload.filename or "upload")


@dataclass(frozen=True)
class Route:
    """One entry of the route table: ``method path`` answered by ``handler`` (an
    :class:`Api` method), listed under ``tag`` on the OpenAPI page."""

    method: str
    path: str
    handler: Callable[..., Any]
    tag: str
    status: int = 200
    options: Mapping[str, Any] = field(default_factory=dict)


_PNG = {
    "response_class": FileResponse,
    "responses": {200: {"content": {"image/png": {}}}},
}

ROUTES: tuple[Route, ...] = (
    Route("GET", "/api/server", Api.server, "store"),
    Route("GET", "/api/info", Api.info, "store"),
    Route("GET", "/api/shapes", Api.shapes, "store"),
    Route("GET", "/api/shapes/{id}", Api.shape, "store"),
    Route("GET", "/api/shapes/{id}/surface", Api.surface, "store"),
    Route("GET", "/api/shapes/{id}/thumbnail.png", Api.thumbnail, "store", options=_PNG),
    Route("GET", "/api/search", Api.search, "search"),
    Route("POST", "/api/search", Api.search_file, "search"),
    Route("GET", "/api/queries/{key}", Api.uploaded, "search"),
    Route("POST", "/api/match", Api.match, "search"),
    Route("POST", "/api/sql", Api.sql, "sql"),
    Route("GET", "/api/eval", Api.evaluate, "sql"),
    Route("POST", "/api/ingest", Api.ingest_upload, "ingest", status=202),
    Route("GET", "/api/ingest/{job}", Api.ingest_job, "ingest"),
)
"""The API: every path and method the server answers besides the page and /docs."""


def add_routes(app: FastAPI, service: Service) -> None:
    """Register :data:`ROUTES` on ``app``, their handlers bound to one :class:`Api`."""
    api = Api(service)
    for route in ROUTES:
        app.add_api_route(
            route.path,
            types.MethodType(route.handler, api),
            methods=[route.method],
            tags=[route.tag],
            status_code=route.status,
            **route.options,
        )
