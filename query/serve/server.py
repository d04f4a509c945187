"""``shapedb serve``: one warm process with a JSON API and a web page (FastAPI + uvicorn).

The store's indexes are opened once and stay in memory; every request reads the
store's manifest version first (:func:`query.search.index.open_index` does), so versions
committed by another process (an ingest running beside the server) are picked up
without a restart.

API (all JSON; the OpenAPI page is ``/docs``; the table is :data:`query.serve.routes.ROUTES`)::

    GET  /api/info                         the store's db.info()
    GET  /api/search?id=ID_OR_NAME&k=10[&where=SQL]     -> [{id, name, label, similarity}]
    POST /api/search?k=10[&where=SQL]      multipart field "file": a model file
    GET  /api/queries/{key}                balls, edges and surface of an uploaded query
    GET  /api/shapes?offset=&limit=&label= a page of shapes and the total
    GET  /api/shapes/{id}                  record, balls and edges
    GET  /api/shapes/{id}/surface          mesh or cloud of its source file, when still there
    GET  /api/shapes/{id}/thumbnail.png    cached under <store>/thumbnails/
    POST /api/match                        part search, as db.match
    POST /api/sql                          one SELECT, sandboxed as db.sql is (interruptible)
    GET  /api/eval?label=label             db.evaluate: scores, per class, PR curve
    POST /api/ingest                       multipart "file" (repeatable) [+ "label"] -> job
    GET  /api/ingest/{job}                 its progress and report
    GET  /api/server                       store version, limits, whether a token is needed

Errors are ``{"error": "<one line>", "status": N}`` with 400 (bad input, naming the
reason), 401 (no or wrong token where one is needed), 403 (a cross-origin write),
404 (unknown shape, or an id beyond int64), 409 (an ingest already running or the
store locked), 413 (body too large), 500 (a damaged store, or an unexpected error:
logged, never shown) or 503 (an SQL statement interrupted as the server stops).

A statement of ``/api/sql`` is interrupted when its client disconnects, and when the
server stops (Ctrl-C ends the server within seconds). Every request is logged, one
line ``METHOD PATH STATUS MS ms`` at INFO on the logger ``query.serve``, which
:func:`serve` shows (status 499: a statement whose client went away; 0: no answer
was started).

Safe by default: :func:`serve` binds 127.0.0.1 and refuses any other host without a
token; with a token, uploads, ingest and SQL (``/api/sql`` and ``where``) need
``Authorization: Bearer TOKEN``. Requests with a body larger than
``max_upload_bytes`` are refused; uploads are written to a private temporary folder
(mode 0700) and deleted after use. No CORS headers are sent, writes carrying a
foreign ``Origin`` (``null`` included) are refused, and a loopback server only answers to loopback host
names (against DNS rebinding).
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from shapedb.errors import ConfigError, MissingDependencyError, ShapeDBError

try:
    from fastapi import FastAPI, Request
    from fastapi.exceptions import RequestValidationError
    from fastapi.openapi.docs import get_swagger_ui_html
    from fastapi.responses import HTMLResponse, Response
    from fastapi.staticfiles import StaticFiles
    from starlette.exceptions import HTTPException
except ImportError as _exc:  # pragma: no cover - exercised without the extra only
    raise MissingDependencyError(
        f"shapedb serve needs FastAPI ({_exc}); install it with  pip install 'shapedb[serve]'"
    ) from _exc

from query.serve.state import Service, TooLarge, error_response, status_of

if TYPE_CHECKING:
    from query.database import Database

__all__ = ["create_app", "serve", "DEFAULT_MAX_UPLOAD_BYTES", "is_loopback"]

log = logging.getLogger(__name__)
#: One line per request: method, path, status, milliseconds (INFO; ``serve`` shows it).
requests_log = logging.getLogger("query.serve")

WEB = Path(__file__).parent / "web"
DEFAULT_MAX_UPLOAD_BYTES = 64 * 2**20
_MULTIPART_SLACK = 64 * 2**10  # headers and boundaries around the uploaded bytes
_LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1", "[::1]")
_GRACE_SECONDS = 3  # at shutdown, requests still running after this are cancelled


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an address) only accepts connections from this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


# ------------------------------------------------------------------ middleware
class _Guard:
    """Pure ASGI middleware: body size limit, host check and cross-origin writes refused.

    Every response carries ``Server-Timing: app;dur=MS``, the milliseconds from the
    request's arrival to its response headers (the server's own share of a request).
    """

    def __init__(self, app: Any, *, limit: int, hosts: Sequence[str] | None) -> None:
        self.app = app
        self.limit = limit
        self.hosts = None if hosts is None else {h.lower() for h in hosts}

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        t0 = time.perf_counter()
        status = 0  # no response started (yet)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        seen = 0

        async def limited() -> Any:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.limit + _MULTIPART_SLACK:
                    raise TooLarge
            return message

        async def tracked(message: Any) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
                took = f"app;dur={1e3 * (time.perf_counter() - t0):.3f}".encode()
                message = {
                    **message,
                    "headers": [*message.get("headers", []), (b"server-timing", took)],
                }
            await send(message)

        try:
            refusal = self._refusal(scope, headers, headers.get("host", ""))
            if refusal is not None:
                await refusal(scope, receive, tracked)
                return
            try:
                await self.app(scope, limited, tracked)
            except TooLarge:
                if status:  # the response had started
                    raise
                await _too_large(self.limit)(scope, receive, tracked)
        except Exception:
            status = status or 500  # answered by the error handler outside this middleware
            raise
        finally:
            took = 1e3 * (time.perf_counter() - t0)
            # status 0: the client went away, or an error escaped, before any response
            requests_log.info("%s %s %d %.1f ms", scope["method"], scope["path"], status, took)

    def _refusal(self, scope: Any, headers: dict[str, str], host: str) -> Any:
        if self.hosts is not None:
            name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
            if name.lower() not in self.hosts:
                return error_response(400, f"unexpected Host header {host!r}: this server is local")
        length = headers.get("content-length", "")
        if length.isdigit() and int(length) > self.limit + _MULTIPART_SLACK:
            return _too_large(self.limit)
        if scope["method"] not in ("GET", "HEAD", "OPTIONS"):
            origin = headers.get("origin")
            # "null" (a sandboxed frame, a file:// page, a redirect) is no origin of ours
            if headers.get("sec-fetch-site") == "cross-site" or (
                origin is not None and (origin == "null" or origin.split("://", 1)[-1] != host)
            ):
                return error_response(
                    403, "cross-origin request refused: use the page this server serves"
                )
        return None


def _too_large(limit: int) -> Response:
    return error_response(413, f"request body too large: the limit is {limit} bytes")


# ------------------------------------------------------------------ the app
def create_app(
    db: Database,
    *,
    token: str | None = None,
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES,
    allowed_hosts: Sequence[str] | None = None,
) -> FastAPI:
    """The FastAPI application serving ``db``.

    Parameters
    ----------
    db : shapedb.Database
        The store; kept open for the application's life.
    token : str, optional
        Bearer token required for uploads, ingest and SQL; None: no token needed.
    max_upload_bytes : int
        Largest accepted upload, bytes (requests with larger bodies get 413).
    allowed_hosts : sequence of str, optional
        Host names the server answers to (checked against the ``Host`` header, port
        ignored); None: any.

    Returns
    -------
    fastapi.FastAPI
    """
    from query.serve.routes import add_routes

    if token is not None and not token.strip():
        raise ConfigError("the token is empty", source="--token")
    if max_upload_bytes < 1:
        raise ConfigError("must be positive", source=f"max_upload_bytes={max_upload_bytes}")
    service = Service(db, token=token, max_upload_bytes=max_upload_bytes)
    app = FastAPI(
        title="shapedb",
        summary="3-D shape retrieval with maximal disjoint ball decompositions",
        version="1",
        docs_url=None,  # served below from the vendored Swagger UI, not from a CDN
        redoc_url=None,
    )
    app.state.service = service
    _add_error_handlers(app)
    add_routes(app, service)
    app.mount("/static", StaticFiles(directory=WEB), name="static")

    @app.get("/", include_in_schema=False)
    def page() -> HTMLResponse:
        return HTMLResponse((WEB / "index.html").read_text(encoding="utf-8"))

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url="/openapi.json",
            title="shapedb API",
            swagger_js_url="/static/vendor/swagger-ui/swagger-ui-bundle.js",
            swagger_css_url="/static/vendor/swagger-ui/swagger-ui.css",
            swagger_favicon_url="data:,",
        )

    app.add_middleware(_Guard, limit=service.max_upload_bytes, hosts=allowed_hosts)
    return app


def _add_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(ShapeDBError)
    async def shapedb_error(request: Request, exc: ShapeDBError) -> Response:
        status = status_of(exc)
        if status >= 500:
            log.error("%s %s: %s", request.method, request.url.path, exc)
        return error_response(status, str(exc))

    @app.exception_handler(RequestValidationError)
    async def invalid(request: Request, exc: RequestValidationError) -> Response:
        parts = []
        for e in exc.errors():
            loc = ".".join(str(x) for x in e.get("loc", ()) if x not in ("query", "body", "path"))
            parts.append(f"{loc or 'request'}: {e.get('msg', 'invalid')}")
        return error_response(400, "; ".join(parts) or "invalid request")

    @app.exception_handler(HTTPException)
    async def http_error(request: Request, exc: HTTPException) -> Response:
        if isinstance(exc.__cause__, TooLarge):
            return _too_large(app.state.service.max_upload_bytes)
        headers = {"WWW-Authenticate": "Bearer"} if exc.status_code == 401 else None
        return error_response(exc.status_code, str(exc.detail), headers)

    @app.exception_handler(TooLarge)
    async def too_large(request: Request, exc: TooLarge) -> Response:
        return _too_large(app.state.service.max_upload_bytes)

    @app.exception_handler(Exception)
    async def unexpected(request: Request, exc: Exception) -> Response:
        log.error("%s %s failed", request.method, request.url.path, exc_info=exc)
        return error_response(500, "internal error (logged by the server)")


# ------------------------------------------------------------------ running
def serve(
    db: Database,
    *,
    host: str = "127.0.0.1",
    port: int = 8000,
    token: str | None = None,
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES,
    log_level: str = "warning",
    on_ready: Callable[[str], None] | None = None,
) -> None:
    """Serve ``db`` over HTTP until interrupted (the ``serve`` extension entry point).

    Parameters
    ----------
    db : shapedb.Database
    host : str
        Address to bind; anything but a loopback address needs ``token``.
    port : int
        TCP port (0: any free port).
    token : str, optional
        Bearer token for uploads, ingest and SQL.
    max_upload_bytes : int
        Largest accepted upload, bytes.
    log_level : str
        uvicorn's log level.
    on_ready : callable, optional
        Called with the page's URL once the indexes are loaded, before serving.

    Raises
    ------
    ConfigError
        A non-loopback host without a token, or a bad port.
    MissingDependencyError
        uvicorn is not installed.
    """
    from shapedb.errors import require

    if not is_loopback(host) and not token:
        raise ConfigError(
            "serving beyond this machine needs a token: add --token SECRET "
            "(clients send Authorization: Bearer SECRET for uploads and SQL)",
            source=f"--host {host}",
        )
    if not 0 <= int(port) < 65536:
        raise ConfigError("must be in 0..65535", source=f"--port {port}")
    uvicorn = require("uvicorn", extra="serve", feature="shapedb serve")
    hosts = list(_LOOPBACK_NAMES) if is_loopback(host) else None
    app = create_app(db, token=token, max_upload_bytes=max_upload_bytes, allowed_hosts=hosts)
    warm(db)
    if requests_log.level == logging.NOTSET:  # the request log shows unless set otherwise
        requests_log.setLevel(logging.INFO)
    config = uvicorn.Config(
        app,
        host=host,
        port=int(port),
        log_level=log_level,
        access_log=False,  # the request log (requests_log) says more: the milliseconds
        lifespan="off",
        timeout_graceful_shutdown=_GRACE_SECONDS,
    )
    server = _stopping_server(uvicorn, app.state.service)(config)
    sock = _bind(host, int(port))  # bound here: the real port is known, errors come first
    if on_ready is not None:
        shown = f"[{host}]" if ":" in host else host
        on_ready(f"http://{shown}:{sock.getsockname()[1]}/")
    try:
        server.run(sockets=[sock])
    finally:
        app.state.service.statements.stop()
        sock.close()


def _stopping_server(uvicorn: Any, service: Service) -> Any:
    """uvicorn's ``Server`` that interrupts the running SQL statements as it stops, so
    that Ctrl-C ends the server within seconds even with a long statement running."""

    class Server(uvicorn.Server):  # type: ignore[misc,name-defined]
        async def shutdown(self, sockets: Any = None) -> None:
            service.statements.stop()
            await super().shutdown(sockets)

    return Server


def _bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: a free one).

    Raises
    ------
    ConfigError
        The address cannot be bound (in use, or not this machine's).
    """
    family = socket.AF_INET6 if ":" in host.strip("[]") else socket.AF_INET
    sock = socket.socket(
        family, socket.SOCK_STREAM, socket.IPPROTO_TCP
    )  # asyncio then sets TCP_NODELAY
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host.strip("[]"), port))
    except OSError as exc:
        sock.close()
        raise ConfigError(
            f"cannot listen there: {exc.strerror or exc}", source=f"{host}:{port}"
        ) from exc
    sock.listen(2048)
    sock.set_inheritable(True)
    return sock


def warm(db: Database) -> None:
    """Load the store's feature index (and build it if missing) before the first request."""
    from query.search.index import open_index

    if len(db):
        open_index(db)
        if db.config.cloud.view_cells:
            open_index(db, view=True)
