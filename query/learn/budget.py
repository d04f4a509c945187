"""The time budget of a classifier selection, and its progress report.

:class:`Budget` is a deadline on an injectable clock (``time.monotonic`` by
default; tests pass a fake one): how much was spent, how much is left, and whether
work predicted to take ``s`` seconds still fits. :class:`Progress` is one snapshot
of the selection (candidate, fold, epoch, validation score so far, time spent and
left); :class:`ProgressLog` turns a stream of them into log lines, at least one every
``interval`` seconds while work goes on (a background heartbeat covers epochs longer
than the interval) and at most one per ``interval`` otherwise, but for the lines that
close a candidate. :func:`parse_duration` reads the command line's "90s", "5m", "1h".
"""

from __future__ import annotations

import logging
import math
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType

from shapedb.errors import ConfigError

__all__ = [
    "DEFAULT_BUDGET",
    "LOG_INTERVAL",
    "Budget",
    "OutOfBudget",
    "Progress",
    "ProgressLog",
    "parse_duration",
]

log = logging.getLogger(__name__)

#: Seconds ``shapedb train`` spends choosing and fitting when not told otherwise.
DEFAULT_BUDGET = 300.0
#: Longest silence (seconds) of the progress log while training.
LOG_INTERVAL = 10.0

Clock = Callable[[], float]
_UNITS = {"": 1.0, "s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}
_DURATION = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(s|m|min|h)?\s*$")


def parse_duration(text: str) -> float:
    """Seconds of a duration written as "90", "90s", "5m", "1.5h" (a bare number is seconds).

    Raises
    ------
    ConfigError
        Not a positive duration of that form.
    """
    match = _DURATION.match(str(text).lower())
    seconds = float(match.group(1)) * _UNITS[match.group(2) or ""] if match else 0.0
    if seconds <= 0:
        raise ConfigError(f"budget {text!r} is invalid: write a positive duration like 90s, 5m, 1h")
    return seconds


class OutOfBudget(Exception):
    """Raised between epochs to stop work that would end after the deadline."""


class Budget:
    """A deadline ``seconds`` after construction, read on ``clock``.

    Parameters
    ----------
    seconds : float or None
        The budget; None for no limit.
    clock : callable, optional
        Seconds on a monotonic clock (default ``time.monotonic``).
    """

    def __init__(self, seconds: float | None, *, clock: Clock | None = None) -> None:
        if seconds is not None and not seconds > 0:
            raise ConfigError(
                f"budget={seconds!r} is invalid: must be a positive number of seconds"
            )
        self.seconds = seconds
        self.clock: Clock = clock or time.monotonic
        self.start = self.clock()

    def spent(self) -> float:
        """Seconds since the start."""
        return self.clock() - self.start

    def left(self) -> float:
        """Seconds before the deadline (inf without a limit; negative once overrun)."""
        return math.inf if self.seconds is None else self.seconds - self.spent()

    def allows(self, seconds: float) -> bool:
        """Whether work predicted to take ``seconds`` ends before the deadline."""
        return seconds <= self.left()


def _time(spent: float, left: float) -> str:
    """Seconds spent and left, as "95 s spent, 205 s left" (or "..., no limit")."""
    return f"{spent:.0f} s spent, " + (
        "no limit" if math.isinf(left) else f"{max(left, 0.0):.0f} s left"
    )


@dataclass(frozen=True)
class Progress:
    """One snapshot of a selection.

    Attributes
    ----------
    candidate : str
    index, candidates : int
        1-based position of the candidate, and how many there are.
    fold, folds : int
        1-based validation fold (0 for the final fit on all the training shapes).
    epoch, epochs : int
        1-based epoch of a graph CNN (0 for the descriptor models).
    score : float
        Validation accuracy of the candidate over its finished folds (NaN before).
    spent, left : float
        Seconds spent, and left in the budget (inf without a limit).
    done : str
        "" while the candidate runs; when it ends, how ("scored", "skipped", ...).
    """

    candidate: str
    index: int
    candidates: int
    fold: int
    folds: int
    epoch: int
    epochs: int
    score: float
    spent: float
    left: float
    done: str = ""

    def where(self) -> str:
        """The candidate and the step: "tag (6/9) fold 2/5 epoch 13/40"."""
        if self.done:
            step = f"{self.fold}/{self.folds} folds"
        else:
            step = f"fold {self.fold}/{self.folds}" if self.fold else "final fit"
            step += f" epoch {self.epoch}/{self.epochs}" if self.epochs else ""
        return f"{self.candidate} ({self.index}/{self.candidates}) {step}"

    def line(self) -> str:
        """One line: "tag (6/9) fold 2/5 epoch 13/40: validation 0.812; 95 s spent, 205 s left"."""
        score = "n/a" if math.isnan(self.score) else f"{self.score:.3f}"
        state = f" [{self.done}]" if self.done else ""
        return f"{self.where()}: validation {score}{state}; {_time(self.spent, self.left)}"


class ProgressLog:
    """Log :class:`Progress` lines: at least one every ``interval`` s while work goes on.

    Call it with every snapshot; it logs when ``interval`` seconds have passed since
    its last line, and always for a snapshot that ends a candidate. Used as a
    context manager it also runs a heartbeat thread that re-logs the latest
    snapshot (with the time updated) when an epoch outlasts the interval.

    Parameters
    ----------
    interval : float
        Seconds between lines at most (while snapshots arrive or the heartbeat runs).
    clock : callable, optional
        Monotonic seconds (default ``time.monotonic``).
    logger : logging.Logger, optional
    """

    def __init__(
        self,
        interval: float = LOG_INTERVAL,
        *,
        clock: Clock | None = None,
        logger: logging.Logger | None = None,
    ) -> None:
        self.interval = interval
        self.clock: Clock = clock or time.monotonic
        self.logger = logger or log
        self.latest: Progress | None = None
        self.last_line = -math.inf
        self.seen = self.clock()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __call__(self, progress: Progress) -> None:
        with self._lock:
            self.latest, self.seen = progress, self.clock()
            if progress.done or self.seen - self.last_line >= self.interval:
                self._emit(progress)

    def tick(self) -> bool:
        """Re-log the latest snapshot if the log has been silent for ``interval``; whether it did."""
        with self._lock:
            now = self.clock()
            if self.latest is None or now - self.last_line < self.interval:
                return False
            p, late = self.latest, now - self.seen
            spent, left = p.spent + late, p.left - late
            if p.done:  # between candidates (e.g. importing torch, building graph tensors)
                self.last_line = now
                self.logger.info("working after %s [%s]; %s", p.where(), p.done, _time(spent, left))
            else:
                self._emit(Progress(**{**p.__dict__, "spent": spent, "left": left}))
            return True

    def _emit(self, progress: Progress) -> None:
        self.last_line = self.clock()
        self.logger.info("%s", progress.line())

    def __enter__(self) -> ProgressLog:
        def beat() -> None:
            while not self._stop.wait(min(1.0, self.interval / 4)):
                self.tick()

        self._stop.clear()
        self._thread = threading.Thread(target=beat, name="shapedb-progress", daemon=True)
        self._thread.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
