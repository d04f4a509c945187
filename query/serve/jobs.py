"""Ingest by upload in ``shapedb serve`` (``POST /api/ingest``): background jobs.

The uploaded files are ingested from a private temporary folder; the store records
each under its original file name (``source``), never under its temporary path, and
the job's report and errors name the files as the client sent them.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from query.serve.state import Job, Service, new_key, remove_folder
from shapedb.errors import ShapeDBError

if TYPE_CHECKING:
    from query.database import Database
    from shapedb.store.schema import Failure, ShapeRecord

__all__ = ["original_name", "start_ingest"]

log = logging.getLogger(__name__)

_MAX_JOBS = 64  # finished jobs kept for polling


def original_name(filename: str | None, fallback: str) -> str:
    """The file name a client gave an upload, without any folder (``fallback`` if none)."""
    return Path((filename or "").replace("\\", "/")).name or fallback


class _UploadSources:
    """``db`` as the ingest of uploads sees it: what it commits is recorded under the
    uploads' original file names (``names``: temporary path -> name), not their paths.

    Every other attribute is the database's own.
    """

    def __init__(self, db: Database, names: dict[str, str]) -> None:
        self._db = db
        self._names = names

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._db, attr)

    def name(self, source: str | None) -> str | None:
        return None if source is None else self._names.get(source, Path(source).name)

    def commit(
        self,
        records: Sequence[ShapeRecord] = (),
        *,
        failures: Sequence[Failure] = (),
        delete: Iterable[int] = (),
    ) -> Any:
        return self._db.commit(
            [replace(r, source=self.name(r.source)) for r in records],
            failures=[replace(f, source=self.name(f.source) or f.source) for f in failures],
            delete=delete,
        )


def start_ingest(
    service: Service, folder: Path, paths: list[Path], names: list[str], label: str | None
) -> Job:
    """Start ingesting ``paths`` (uploads in ``folder``, originally ``names``) in a thread.

    The caller holds ``service.ingest_lock``; the job releases it, and deletes
    ``folder``, when it ends.
    """
    job = Job(new_key(), total=len(paths))
    service.jobs[job.id] = job
    finished = [j for j in service.jobs.values() if j.state != "running"]
    for old in finished[: max(0, len(service.jobs) - _MAX_JOBS)]:
        service.jobs.pop(old.id, None)
    worker = threading.Thread(
        target=_run_ingest,
        args=(service, job, folder, dict(zip(map(str, paths), names, strict=True)), label),
        name=f"shapedb-ingest-{job.id}",
        daemon=True,
    )
    worker.start()
    return job


def _run_ingest(
    service: Service, job: Job, folder: Path, names: dict[str, str], label: str | None
) -> None:
    from ingest.pipeline import ingest

    def progress(done: int, total: int) -> None:
        job.done, job.total = done, total

    def scrub(text: str) -> str:
        for path, name in names.items():
            text = text.replace(path, name)
        return text.replace(str(folder) + "/", "")

    db = _UploadSources(service.db, names)
    try:
        report = ingest(
            cast("Database", db),
            list(names),
            names=[Path(n).stem or "upload" for n in names.values()],
            labels={p: label for p in names} if label else None,
            workers=1,
            progress=progress,
        )
        job.report = {
            **json.loads(scrub(json.dumps(report.to_dict()))),
            "ids": [int(i) for i in report.ingested],
        }
        job.done, job.state = job.total, "done"
    except ShapeDBError as exc:
        job.error, job.state = scrub(str(exc)), "failed"
    except Exception:  # noqa: BLE001 - reported on the job, logged in full here
        log.exception("ingest job %s failed", job.id)
        job.error, job.state = "internal error (logged by the server)", "failed"
    finally:
        remove_folder(folder)
        service.ingest_lock.release()
