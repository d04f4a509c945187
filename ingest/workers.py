"""Where ingest's work runs: a process pool on this machine, a Dask cluster, or inline.

The pool's workers fork from a forkserver that imported and warmed everything once
(``ingest._warmup``), and exit when the ingesting process dies (even by SIGKILL).
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing
import os
import sys
from collections.abc import Callable, Iterable
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from shapedb.errors import MissingDependencyError, ShapeDBError
from shapedb.store.schema import Failure, ShapeRecord

__all__ = ["executor", "wait_any", "result"]

log = logging.getLogger(__name__)


class _Serial:
    """A stand-in executor that runs each task in the calling process."""

    def submit(self, fn: Callable[..., Any], *args: Any) -> cf.Future[Any]:
        fut: cf.Future[Any] = cf.Future()
        try:
            fut.set_result(fn(*args))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            fut.set_exception(exc)
        return fut

    def shutdown(self) -> None:
        pass


def executor(workers: int, scheduler: Any) -> tuple[Any, Callable[[], None], str]:
    """(submit-able executor, close function, description)."""
    if scheduler is not None:
        try:
            from distributed import Client
        except ImportError as exc:
            raise MissingDependencyError(
                f"ingesting on the Dask cluster {scheduler!r} needs the optional dependency "
                "dask[distributed]: install it with  pip install 'shapedb[distributed]'"
            ) from exc
        if isinstance(scheduler, Client):
            return scheduler, lambda: None, f"dask {scheduler.scheduler.address}"
        client = Client(scheduler)
        return client, client.close, f"dask {scheduler}"
    if workers <= 1:
        return _Serial(), lambda: None, "serial"
    # forkserver, not fork: the caller may run threads (progress bars, Dask). Workers
    # fork from a server that imported and warmed everything once (ingest._warmup).
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["__main__", "ingest.pipeline", "ingest._warmup"])
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_watch_parent)
    return pool, lambda: pool.shutdown(wait=True, cancel_futures=True), f"{workers} processes"


def _watch_parent() -> None:
    """Worker initializer: exit when the ingesting process dies (even by SIGKILL)."""
    import threading

    parent = multiprocessing.parent_process()
    if parent is None:  # pragma: no cover
        return

    def watch() -> None:
        parent.join()
        os._exit(70)

    threading.Thread(target=watch, name="shapedb-parent-watch", daemon=True).start()


def wait_any(futures: Iterable[Any], dask: bool) -> set[Any]:
    if dask:
        from distributed import wait

        return set(wait(list(futures), return_when="FIRST_COMPLETED").done)
    done, _ = cf.wait(list(futures), return_when=cf.FIRST_COMPLETED)
    return done


def _script_hint() -> str:
    """A hint for the commonest cause when ingest runs from a user's script: the workers start
    by importing that script, which must not ingest again at import time."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if not path or Path(path).name in ("shapedb", "__main__.py", "pytest"):
        return ""
    return (
        f" (if {Path(path).name} calls ingest at its top level, put that under "
        "`if __name__ == '__main__':`: each worker process imports the script)"
    )


def result(fut: Any, item: Any) -> ShapeRecord | Failure:
    try:
        return fut.result()  # type: ignore[no-any-return]
    except BrokenProcessPool as exc:
        raise ShapeDBError(
            f"a worker process died while ingesting {item.source}; "
            f"the batches committed so far are kept: re-run to continue{_script_hint()}"
        ) from exc
    except Exception as exc:  # an unexpected error inside the worker
        log.warning("ingesting %s failed unexpectedly", item.source, exc_info=True)
        return Failure.from_exception(item.source, exc)
