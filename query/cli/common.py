"""What the subcommands of ``shapedb`` share: the command table's row type, the ``--db``
argument, opening a store, reading shape ids, and output.

Output goes to stdout (aligned text tables, JSON); progress bars to stderr, only on a terminal.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from shapedb.errors import QueryError
from shapedb.results import jsonable

if TYPE_CHECKING:
    from query.database import Database
    from shapedb.results import Hit

__all__ = [
    "Command",
    "Handler",
    "Subparsers",
    "add_db_argument",
    "add_command",
    "verbose_parent",
    "open_store",
    "existing_store",
    "query_arg",
    "shape_ref",
    "MAX_ID",
    "ProgressBar",
    "hit_row",
    "jsonable",
    "print_json",
    "print_rows",
    "format_table",
    "HIT_COLUMNS",
]

#: A subcommand's handler: the parsed arguments in, the exit status out.
Handler = Callable[[argparse.Namespace], int]

#: Adds a subcommand's arguments to its parser (and may set its description and epilog).
Arguments = Callable[[argparse.ArgumentParser], None]

#: The largest shape id: ids are stored as int64.
MAX_ID = 2**63 - 1

#: The columns of a search hit in tables.
HIT_COLUMNS = ("id", "name", "label", "similarity", "distance")


@dataclass(frozen=True)
class Command:
    """One row of the command table (:data:`query.cli.COMMANDS`).

    Attributes
    ----------
    name : str
        The subcommand, e.g. ``"ingest"``.
    help : str
        One line for ``shapedb --help`` (also the start of ``shapedb NAME --help``).
    arguments : callable
        ``arguments(parser)`` adds the subcommand's arguments.
    handler : callable
        ``handler(args) -> int``: runs the subcommand, returns the exit status.
    """

    name: str
    help: str
    arguments: Arguments
    handler: Handler


class Subparsers(Protocol):
    """The object ``ArgumentParser.add_subparsers`` returns (what a group's ``register``
    receives, for groups that still add their parsers themselves)."""

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser: ...


def add_command(
    subparsers: Subparsers, name: str, handler: Handler, *, help: str
) -> argparse.ArgumentParser:
    """Add subcommand ``name`` whose parsed arguments go to ``handler``.

    Every subcommand also takes ``-v`` (as the command itself does before it).
    """
    parser = subparsers.add_parser(name, help=help, parents=[verbose_parent()])
    parser.set_defaults(handler=handler)
    return parser


def verbose_parent() -> argparse.ArgumentParser:
    """A parent parser holding ``-v``, so that it also works after the subcommand."""
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


def shape_ref(text: str) -> str | int:
    """A stored shape's int id for digits, else its name.

    Raises
    ------
    QueryError
        For digits beyond the largest id (:data:`MAX_ID`).
    """
    if not text.strip().isdigit():
        return text
    value = int(text)
    if value > MAX_ID:
        raise QueryError(f"shape id out of range: ids run from 1 to {MAX_ID}", source=text.strip())
    return value


def query_arg(text: str) -> str | int:
    """A path when such a file exists, else :func:`shape_ref` (an int id for digits, a name)."""
    if os.path.exists(text):
        return text
    return shape_ref(text)


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


def _cell(v: Any, floats: str = ".6g") -> str:
    if isinstance(v, float):
        text = format(v, floats)
        return text[1:] if text.startswith("-") and not text.strip("-0.") else text  # no -0.00
    text = "" if v is None else str(v)
    return text if len(text) <= 60 else text[:57] + "..."


def format_table(
    rows: Sequence[dict[str, Any]],
    columns: Sequence[str],
    *,
    headers: Sequence[str] | None = None,
    floats: str = ".6g",
) -> list[str]:
    """The lines of an aligned text table: a header, then one line per row.

    Numbers are right-aligned, everything else left-aligned; floats are formatted with
    the format spec ``floats`` (default 6 significant digits) and long cells are cut to
    60 characters. ``headers`` (default ``columns``) are the names shown.
    """
    names = list(columns if headers is None else headers)
    cells = [[_cell(r.get(c), floats) for c in columns] for r in rows]
    widths = [max([len(n)] + [len(row[k]) for row in cells]) for k, n in enumerate(names)]
    numeric = [
        bool(rows) and all(_is_number(r.get(c)) or r.get(c) is None for r in rows) for c in columns
    ]

    def line(values: Sequence[str]) -> str:
        parts = [
            v.rjust(w) if right else v.ljust(w)
            for v, w, right in zip(values, widths, numeric, strict=True)
        ]
        return "  ".join(parts).rstrip()

    return [line(names)] + [line(row) for row in cells]


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def print_rows(
    rows: list[dict[str, Any]],
    columns: Sequence[str],
    *,
    headers: Sequence[str] | None = None,
    floats: str = ".6g",
    count: bool = False,
) -> None:
    """Print ``rows`` as an aligned text table of ``columns`` (:func:`format_table`, which
    takes ``headers`` and ``floats``).

    ``(no rows)`` follows an empty table; with ``count``, ``(N rows)`` follows any table.
    """
    for line in format_table(rows, columns, headers=headers, floats=floats):
        print(line)
    if count:
        print(f"({len(rows)} row{'' if len(rows) == 1 else 's'})")
    elif not rows:
        print("(no rows)")
