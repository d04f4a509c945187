"""SQL statements of ``shapedb serve`` (``POST /api/sql``) that can be interrupted.

A statement runs on its own sandboxed DuckDB connection (:func:`query.sql.connect`) in
a worker thread; the server keeps a reference to that connection, so a statement whose
client went away, or that is still running when the server stops, is interrupted
(``DuckDBPyConnection.interrupt``) instead of holding a thread and a core until it ends.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

import pyarrow as pa
from starlette.concurrency import run_in_threadpool

from shapedb.errors import QueryError

if TYPE_CHECKING:
    from query.database import Database

__all__ = ["ClientGone", "Statement", "Statements"]

log = logging.getLogger(__name__)

#: Seconds between two checks of a running statement for a gone client or a stopping
#: server (an interrupt that lands before DuckDB starts the statement is repeated).
_POLL_SECONDS = 0.2
_SHOWN = 200  # characters of a statement named in an error
_VIEWS = ("shapes", "balls", "edges", "failures")


class ClientGone(Exception):
    """The client closed its connection before its statement finished."""


def _short(text: str) -> str:
    s = " ".join(text.split())
    return s if len(s) <= _SHOWN else s[: _SHOWN - 3] + "..."


class Statement:
    """One read-only SELECT over a store, run once on its own DuckDB connection.

    Parameters
    ----------
    db : shapedb.Database
    text : str
        The statement; :meth:`run` checks that it is exactly one SELECT (DuckDB's parser).
    """

    def __init__(self, db: Database, text: str) -> None:
        self.db = db
        self.text = text
        self.source = _short(text)
        self.interrupted = False
        self._con: Any = None
        self._lock = threading.Lock()

    def check(self) -> None:
        """QueryError unless the statement is exactly one SELECT (DuckDB's parser)."""
        import duckdb

        if not self.text.strip():
            raise QueryError("empty SQL statement", source=repr(self.text))
        try:
            parsed = duckdb.extract_statements(self.text)
        except duckdb.Error as exc:
            raise QueryError(
                f"{type(exc).__name__}: {_short(str(exc))}", source=self.source
            ) from exc
        if len(parsed) != 1:
            raise QueryError(
                f"exactly one statement is allowed, got {len(parsed)}", source=self.source
            )
        if parsed[0].type != duckdb.StatementType.SELECT:
            raise QueryError(
                f"only read-only SELECT statements are allowed, not {parsed[0].type.name}",
                source=self.source,
            )

    def run(self) -> pa.Table:
        """Run the statement (blocking; call it in a worker thread) and return its result.

        Raises
        ------
        QueryError
            Not exactly one SELECT, DuckDB refused or failed it, or it was interrupted.
        StoreError
            One of the store's files cannot be read (damaged); as ``db.sql`` says it.
        """
        import duckdb

        from query.sql import connect

        self.check()
        con = connect(self.db)
        try:
            with self._lock:
                if self.interrupted:
                    raise QueryError("the statement was interrupted", source=self.source)
                self._con = con
            rel = con.sql(self.text)
            return pa.table({}) if rel is None else rel.to_arrow_table()
        except duckdb.InterruptException as exc:
            raise QueryError("the statement was interrupted", source=self.source) from exc
        except duckdb.Error as exc:
            text = " ".join(str(exc).split())
            if any(path in text for path in self._store_files()):
                self.db.sql(self.text)  # raises the store's own error, naming the segment
            raise QueryError(f"{type(exc).__name__}: {text[:300]}", source=self.source) from exc
        finally:
            with self._lock:
                self._con = None
            con.close()

    def _store_files(self) -> list[str]:
        store = self.db.store
        return [p for table in _VIEWS for p in store.files(table)]

    def interrupt(self) -> None:
        """Stop the statement (now if it runs, or as soon as it would start); thread-safe."""
        with self._lock:
            self.interrupted = True
            con = self._con
        if con is not None:
            con.interrupt()


class Statements:
    """The statements running in a server, to interrupt them when it stops."""

    def __init__(self) -> None:
        self.stopping = False
        self._running: set[Statement] = set()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        with self._lock:
            return len(self._running)

    def stop(self) -> None:
        """Interrupt every running statement, and every one started from now on."""
        self.stopping = True
        with self._lock:
            running = list(self._running)
        for statement in running:
            statement.interrupt()

    async def run(self, statement: Statement, receive: Callable[[], Awaitable[Any]]) -> pa.Table:
        """Run ``statement`` in a worker thread until it ends, its client goes or the
        server stops.

        Parameters
        ----------
        statement : Statement
        receive : callable
            The request's ASGI ``receive``, its body already read: it returns
            ``http.disconnect`` when the client goes.

        Raises
        ------
        ClientGone
            The client went away; the statement was interrupted.
        QueryError
            The statement failed, or was interrupted because the server stops.
        """
        with self._lock:
            self._running.add(statement)
        if self.stopping:
            statement.interrupt()
        work = asyncio.ensure_future(run_in_threadpool(statement.run))
        work.add_done_callback(lambda _: self._discard(statement))  # when its thread ends
        gone = asyncio.ensure_future(_disconnect(receive))
        try:
            while not work.done():
                waiting = {work} if gone.done() else {work, gone}
                await asyncio.wait(
                    waiting, timeout=_POLL_SECONDS, return_when=asyncio.FIRST_COMPLETED
                )
                if gone.done() or self.stopping:
                    statement.interrupt()
            if gone.done() and statement.interrupted:
                log.info("client gone: interrupted %s", statement.source)
                raise ClientGone(statement.source)
            return work.result()
        finally:
            if not work.done():  # cancelled: the server is going down
                statement.interrupt()
            gone.cancel()

    def _discard(self, statement: Statement) -> None:
        with self._lock:
            self._running.discard(statement)


async def _disconnect(receive: Callable[[], Awaitable[Any]]) -> None:
    """Return when ``receive`` says the client disconnected."""
    while (await receive())["type"] != "http.disconnect":
        pass
