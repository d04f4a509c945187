"""The state and helpers of ``shapedb serve`` (:mod:`query.serve.server`): errors as JSON,
the per-process caches, uploads and ingest jobs.

:class:`Service` holds the database, the token, the upload limit and small bounded
caches (uploaded queries, shape payloads, surfaces, evaluations), so that the
server's memory stays flat however many requests it answers.
"""

from __future__ import annotations

import hmac
import json
import re
import shutil
import tempfile
import threading
import time
import uuid
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fastapi import Request, UploadFile
from fastapi.responses import Response
from starlette.exceptions import HTTPException

from query.serve.statements import Statements
from shapedb.errors import (
    MissingDependencyError,
    NotFoundError,
    QueryError,
    ShapeDBError,
    StoreError,
    StoreLockedError,
)
from shapedb.results import jsonable

if TYPE_CHECKING:
    from query.database import Database

__all__ = [
    "MAX_ID",
    "Job",
    "LRU",
    "Service",
    "TooLarge",
    "Uploaded",
    "error_response",
    "hits_json",
    "json_response",
    "jsonable",
    "new_key",
    "remove_folder",
    "upload_folder",
    "one_line",
    "safe_name",
    "status_of",
]

#: The largest shape id (ids are int64): larger numbers are refused at the boundary.
MAX_ID = 2**63 - 1
_QUERY_CACHE = 16  # uploaded queries kept for /api/queries and /api/match


class TooLarge(Exception):
    """A request body went over the limit while it was read."""


def status_of(exc: ShapeDBError) -> int:
    """The HTTP status of a shapedb error: 404 unknown, 409 locked, 501 missing extra,
    500 damaged store, 400 any other bad input."""
    if isinstance(exc, NotFoundError):
        return 404
    if isinstance(exc, StoreLockedError):
        return 409
    if isinstance(exc, MissingDependencyError):
        return 501
    if isinstance(exc, StoreError):
        return 500
    return 400


def one_line(text: str) -> str:
    """``text`` with its whitespace runs (newlines included) made single spaces."""
    return " ".join(str(text).split())


def error_response(status: int, message: str, headers: dict[str, str] | None = None) -> Response:
    """``{"error": message, "status": status}`` with that status."""
    body = json.dumps({"error": one_line(message), "status": status})
    return Response(body, status_code=status, media_type="application/json", headers=headers)


def json_response(data: Any, status: int = 200, headers: dict[str, str] | None = None) -> Response:
    """``data`` (see :func:`jsonable`) as a compact JSON response."""
    body = json.dumps(jsonable(data), separators=(",", ":"), allow_nan=False)
    return Response(body, status_code=status, media_type="application/json", headers=headers)


# ------------------------------------------------------------------ state
@dataclass
class Job:
    """One ingest by upload, run in a background thread."""

    id: str
    total: int
    state: str = "running"
    done: int = 0
    report: dict[str, Any] | None = None
    error: str | None = None
    started: float = field(default_factory=time.time)

    def to_dict(self) -> dict[str, Any]:
        return {
            "job": self.id,
            "state": self.state,
            "done": self.done,
            "total": self.total,
            "report": self.report,
            "error": self.error,
        }


class LRU:
    """A small thread-safe least-recently-used map."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._data: OrderedDict[Any, Any] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Any) -> Any:
        with self._lock:
            if key not in self._data:
                return None
            self._data.move_to_end(key)
            return self._data[key]

    def put(self, key: Any, value: Any) -> None:
        with self._lock:
            self._data[key] = value
            self._data.move_to_end(key)
            while len(self._data) > self.size:
                self._data.popitem(last=False)


@dataclass
class Uploaded:
    """An uploaded query kept after its search: its decomposition and geometry.

    ``surface`` is the geometry's :func:`query.serve.viewer.surface_payload`, made at the
    first request for it.
    """

    name: str
    decomposition: Any
    geometry: Any
    surface: dict[str, Any] | None = None


class Service:
    """The server's state: the database, its settings and small caches."""

    def __init__(self, db: Database, *, token: str | None, max_upload_bytes: int) -> None:
        self.db = db
        self.token = token
        self.max_upload_bytes = int(max_upload_bytes)
        self.queries = LRU(_QUERY_CACHE)
        self.shapes = LRU(256)
        self.surfaces = LRU(32)
        self.evals = LRU(4)
        self.jobs: dict[str, Job] = {}
        self.ingest_lock = threading.Lock()
        self.statements = Statements()

    # -------------------------------------------------------------- auth
    def authorised(self, request: Request) -> bool:
        if self.token is None:
            return True
        header = request.headers.get("authorization", "")
        scheme, _, given = header.partition(" ")
        return scheme.lower() == "bearer" and hmac.compare_digest(
            given.strip().encode(), self.token.encode()
        )

    def require_token(self, request: Request, what: str) -> None:
        if not self.authorised(request):
            raise HTTPException(401, f"{what} needs the server's token (Authorization: Bearer)")

    # -------------------------------------------------------------- uploads
    def save_upload(self, upload: UploadFile, folder: Path) -> Path:
        """Copy an upload into ``folder`` under a sanitised name, counting its bytes."""
        name = safe_name(upload.filename or "upload")
        path = folder / name
        n = 0
        with open(path, "wb") as out:
            while chunk := upload.file.read(2**20):
                n += len(chunk)
                if n > self.max_upload_bytes:
                    raise TooLarge
                out.write(chunk)
        return path

    def resolve_id(self, id_or_name: str | int) -> int:
        """A stored id from an id or a name, as ``Store.resolve`` reads it: a name first,
        a string of digits that is no shape's name as an id (never a path on the server).
        A number beyond the int64 ids is no shape (404), never an overflow.

        Names are looked up in a map kept per store version, so a request costs no
        table scan. An id that is not stored is left to the caller's lookup to refuse.

        Raises
        ------
        NotFoundError
            No shape has this name (and it is not a number).
        QueryError
            Empty, or a name several shapes share.
        """
        text = str(id_or_name).strip()
        if not text:
            raise QueryError("empty shape id or name", source=repr(id_or_name))
        ids = self.names().get(text)
        if ids is not None:
            if len(ids) > 1:
                raise QueryError(f"name is ambiguous: shapes {ids} have it; use an id", source=text)
            return ids[0]
        if text.isascii() and text.isdigit():
            if int(text) > MAX_ID:
                raise NotFoundError("no shape with this id (ids are below 2**63)", source=text)
            return int(text)
        raise NotFoundError("no shape with this name or id", source=text)

    def names(self) -> dict[str, list[int]]:
        """name -> ids of the shapes of the store's current version."""
        version = self.db.store.version
        cached = self.shapes.get(("names", version))
        if cached is None:
            t = self.db.shapes(["id", "name"])
            cached = {}
            for sid, name in zip(
                t.column("id").to_pylist(), t.column("name").to_pylist(), strict=True
            ):
                cached.setdefault(name, []).append(int(sid))
            self.shapes.put(("names", version), cached)
        return cached  # type: ignore[no-any-return]


def safe_name(filename: str) -> str:
    base = Path(filename.replace("\\", "/")).name
    base = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip(".")
    return (base or "upload")[:120]


def hits_json(hits: Sequence[Any]) -> list[dict[str, Any]]:
    return [
        {"id": int(h.id), "name": h.name, "label": h.label, "similarity": float(h.similarity)}
        for h in hits
    ]


def upload_folder() -> Path:
    """A new private (mode 0700) temporary folder for one request's uploads."""
    return Path(tempfile.mkdtemp(prefix="shapedb-upload-"))


def remove_folder(folder: Path) -> None:
    """Delete an upload folder and everything in it."""
    shutil.rmtree(folder, ignore_errors=True)


def new_key() -> str:
    """A random key naming an uploaded query or an ingest job."""
    return uuid.uuid4().hex[:16]
