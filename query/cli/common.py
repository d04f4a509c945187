"""What the subcommands of ``shapedb`` share: the ``--db`` argument, opening a store, and output.

Output goes to stdout (tables, JSON); progress bars to stderr, only on a terminal.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from shapedb.results import jsonable

if TYPE_CHECKING:
    from query.database import Database
    from shapedb.results import Hit

__all__ = [
    "Handler",
    "Subparsers",
    "add_db_argument",
    "add_command",
    "open_store",
    "existing_store",
    "query_arg",
    "ProgressBar",
    "hit_row",
    "jsonable",
    "print_json",
    "print_rows",
    "HIT_COLUMNS",
]

#: A subcommand's handler: the parsed arguments in, the exit status out.
Handler = Callable[[argparse.Namespace], int]

#: The columns of a search hit in tables.
HIT_COLUMNS = ("id", "name", "label", "similarity", "distance")


class Subparsers(Protocol):
    """The object ``ArgumentParser.add_subparsers`` returns (what ``register`` receives)."""

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser: ...


def add_command(
    subparsers: Subparsers, name: str, handler: Handler, *, help: str
) -> argparse.ArgumentParser:
    """Add subcommand ``name`` whose parsed arguments go to ``handler``.

    Every subcommand also takes ``-v`` (as the command itself does before it).
    """
    parser = subparsers.add_parser(name, help=help, parents=[_verbose()])
    parser.set_defaults(handler=handler)
    return parser


def _verbose() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=argparse.SUPPRESS,
        help="more log output; tracebacks on errors",
    )
    return parent


def add_db_argument(parser: argparse.ArgumentParser, *, required: bool = True) -> None:
    """Add ``--db DIR``, the store directory."""
    parser.add_argument("--db", required=required, metavar="DIR", help="store directory")


def open_store(path: str, **options: Any) -> Database:
    """The store at ``path``, created with configuration ``options`` when missing."""
    from query.database import connect

    return connect(path, **options)


def existing_store(path: str) -> Database:
    """The store at ``path``; raises :class:`~shapedb.errors.StoreError` when there is none."""
    return open_store(path, create=False)


def positive_int(text: str) -> int:
    """An argparse type: an integer >= 1 (a usage error otherwise)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is invalid: must be >= 1")
    return value


def seconds(text: str) -> float:
    """An argparse type: a finite number of seconds >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not (0.0 <= value < float("inf")):
        raise argparse.ArgumentTypeError(f"{value} is invalid: must be >= 0 seconds")
    return value


def query_arg(text: str) -> str | int:
    """A path when such a file exists, an int id for digits, else a name."""
    if os.path.exists(text):
        return text
    return int(text) if text.strip().isdigit() else text


class ProgressBar:
    """A tqdm progress bar on stderr, fed by the ingest's progress callback ``(done, total)``."""

    def __init__(self, *, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self._bar: Any = None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit="model", file=sys.stderr, dynamic_ncols=True)
        self._bar.update(done - self._bar.n)

    def close(self) -> None:
        """Close the bar (if it was ever shown)."""
        if self._bar is not None:
            self._bar.close()


def hit_row(hit: Hit) -> dict[str, Any]:
    """A search hit as a dict of its fields (:data:`HIT_COLUMNS`)."""
    return hit.to_dict()


def print_json(data: Any) -> None:
    """Print ``data`` as one line of JSON."""
    print(json.dumps(jsonable(data), indent=None))


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    text = "" if v is None else str(v)
    return text if len(text) <= 60 else text[:57] + "..."


def print_rows(rows: list[dict[str, Any]], columns: Sequence[str]) -> None:
    """Print ``rows`` as an aligned text table of ``columns`` (``(no rows)`` when empty)."""
    cells = [[_cell(r.get(c)) for c in columns] for r in rows]
    widths = [max([len(c)] + [len(row[k]) for row in cells]) for k, c in enumerate(columns)]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=True)).rstrip())
    for row in cells:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths, strict=True)).rstrip())
    if not rows:
        print("(no rows)")
