"""Per-file progress of an ingest, for a person waiting on it.

On a terminal, a tqdm bar on stderr (count, rate, time left); elsewhere (a log file, a
job scheduler, a pipe), one log line every :data:`LOG_SECONDS` with the count, the
rate and the time left, written by a heartbeat thread so that it keeps coming while a
slow file is being built. ``progress=False`` silences both; a callable receives
``(done, total)`` after each file instead.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable
from typing import IO, Any

__all__ = ["Progress", "LOG_SECONDS", "ProgressOption"]

log = logging.getLogger(__name__)

#: Seconds between progress log lines off a terminal: at least one line every ~10 s
#: reassures a person waiting, and more than one every ~2 s floods a log file.
LOG_SECONDS = 5.0

ProgressOption = bool | Callable[[int, int], None]
"""What ``ingest(progress=...)`` takes: True (bar or log lines), False, or a callback."""


class Progress:
    """Report ``done`` of ``total`` files as an ingest runs; use as a context manager.

    Parameters
    ----------
    total : int
        Files (and in-memory shapes) in the run.
    done : int
        Already resolved before any is built (unchanged or unreadable inputs); the
        rate counts only the files built after.
    progress : bool or callable
        True: a bar when ``stream`` is a terminal, else log lines; False: nothing;
        a callable: ``progress(done, total)`` at the start and after each file.
    stream : file, optional
        Where the bar goes; default ``sys.stderr``.
    seconds : float, optional
        Seconds between log lines; default :data:`LOG_SECONDS`.
    """

    def __init__(
        self,
        total: int,
        *,
        done: int = 0,
        progress: ProgressOption = True,
        stream: IO[str] | None = None,
        seconds: float | None = None,
    ) -> None:
        self.total, self.done, self._start_done = total, done, done
        self._t0 = time.monotonic()
        self._callback = progress if callable(progress) else None
        self._bar: Any = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        stream = sys.stderr if stream is None else stream
        if self._callback is not None:
            self._callback(done, total)
        elif progress and _isatty(stream):
            from tqdm import tqdm

            self._bar = tqdm(
                total=total, initial=done, unit="file", file=stream, dynamic_ncols=True
            )
        elif progress and done < total:
            self._thread = threading.Thread(
                target=self._heartbeat,
                args=(LOG_SECONDS if seconds is None else seconds,),
                name="shapedb-ingest-progress",
            )
            self._thread.daemon = True
            self._thread.start()

    def update(self, done: int) -> None:
        """``done`` files of the total are resolved."""
        self.done = done
        if self._callback is not None:
            self._callback(done, self.total)
        elif self._bar is not None:
            self._bar.update(done - self._bar.n)

    def line(self) -> str:
        """``"ingest: 12 / 40 files, 0.8 files/s, about 35 s left"``."""
        built = self.done - self._start_done
        elapsed = max(time.monotonic() - self._t0, 1e-9)
        rate = built / elapsed
        left = self.total - self.done
        if left <= 0:
            eta = "done"
        elif built == 0:
            eta = "time left unknown yet"
        else:
            eta = f"about {_duration(left / rate)} left"
        return f"ingest: {self.done} / {self.total} files, {rate:.2f} files/s, {eta}"

    def _heartbeat(self, seconds: float) -> None:
        while not self._stop.wait(seconds):
            log.info("%s", self.line())

    def close(self) -> None:
        """Stop the bar or the log lines."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._bar is not None:
            self._bar.close()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _isatty(stream: IO[str]) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # closed or not a real stream
        return False


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
