"""SQL statements of ``shapedb serve`` (``POST /api/sql``) that can be interrupted.

A statement runs through ``db.sql`` (its sandbox, checksums and limits) in a worker
thread, with an interrupt handle the server keeps, so a statement whose client went away,
or that is still running when the server stops, is interrupted instead of holding a
thread and a core until it ends.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

import pyarrow as pa
from starlette.concurrency import run_in_threadpool

if TYPE_CHECKING:
    from query.database import Database

__all__ = ["ClientGone", "Statement", "Statements"]

log = logging.getLogger(__name__)

#: Seconds between two checks of a running statement for a gone client or a stopping
#: server (an interrupt that lands before DuckDB starts the statement is repeated).
_POLL_SECONDS = 0.2
_SHOWN = 200  # characters of a statement named in an error


class ClientGone(Exception):
    """The client closed its connection before its statement finished."""


def _short(text: str) -> str:
    s = " ".join(text.split())
    return s if len(s) <= _SHOWN else s[: _SHOWN - 3] + "..."


class Statement:
    """One read-only SELECT over a store, run once through ``db.sql`` with a handle the
    server can interrupt it by (:class:`query.sql.InterruptHandle`).

    Parameters
    ----------
    db : shapedb.Database
    text : str
        The statement (``db.sql`` checks that it is exactly one SELECT).
    """

    def __init__(self, db: Database, text: str) -> None:
        from query.sql import InterruptHandle

        self.db = db
        self.text = text
        self.source = _short(text)
        self.interrupted = False
        self._handle = InterruptHandle()

    def run(self) -> pa.Table:
        """Run the statement (blocking; call it in a worker thread) and return its result.

        Raises
        ------
        QueryError
            Not exactly one SELECT, DuckDB refused or failed it, a limit was reached, or
            it was interrupted.
        StoreError
            One of the store's files cannot be read (damaged).
        """
        return self.db.sql(self.text, interrupt=self._handle)

    def interrupt(self) -> None:
        """Stop the statement (now if it runs, or as soon as it would start); thread-safe."""
        self.interrupted = True
        self._handle.interrupt()


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
