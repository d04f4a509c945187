"""The ``shapedb`` command line: one entry point, one subcommand per task.

::

    shapedb ingest PATH... --db DIR [--labels CSV] [--label-from-folder] [--as pointcloud|smooth_voxels]
                   [--resolution N] [--balls N] [--set KEY=VALUE]... [--workers N]
                   [--scheduler ADDR] [--force] [--lock-timeout S] [--max-bytes N]
                   [--max-faces N] [--json]
    shapedb info --db DIR [--json]
    shapedb delete ID_OR_NAME... --db DIR [--lock-timeout S]
    shapedb check --db DIR [--json]
    shapedb repair --db DIR [--json]
    shapedb search QUERY --db DIR [-k 10] [--where SQL] [--metric JSON] [--json]
    shapedb sql "SELECT ..." --db DIR [--metric JSON] [--json | --csv]
    shapedb show MODEL --out PNG [--db DIR] [--complement]
    shapedb match QUERY --db DIR [--node N | --point X Y Z] [--hops K] [-k 10] [--json] [--out PNG]
    shapedb eval --db DIR [--label label] [--metric JSON] [--json] [--plot pr.png]
    shapedb fit-metric --db DIR [--label label] --out metric.json [--json]
    shapedb train --db DIR [--label label] [--conv tag|arma|spline] [--epochs N] --out model.pt
    shapedb classify MODEL --db DIR --model model.pt [--json]
    shapedb serve --db DIR [--host 127.0.0.1] [--port 8000] [--token TOKEN] [--max-upload-mb 64]
    shapedb demo [--db DIR]

Layout: each module of this package holds one group of subcommands and exposes
``register(subparsers)``, which adds the group's parsers and sets each one's handler
(``set_defaults(handler=...)``); a handler takes the parsed arguments and returns the exit
status. To add a subcommand, add it beside its handler in the module of its group (or a
new module listed in :data:`GROUPS`). The handlers only call the
:class:`~query.database.Database` facade.

Errors: a :class:`~shapedb.errors.ShapeDBError` is printed as one line,
``shapedb: error: ...``, on stderr, with exit status 1; any other exception as one line
naming its type, ``shapedb: internal error: ...``, also with exit status 1; ``-v`` adds the
traceback to either. Usage errors exit with 2 (argparse). ``ingest`` also exits with 1 when
some input failed.
"""

from __future__ import annotations

import argparse
import logging
import sys
import traceback
from collections.abc import Sequence

from query.cli import check, demo, evaluate, learn, search, serve, store
from shapedb.errors import ShapeDBError

__all__ = ["main", "build_parser", "GROUPS"]

#: The modules of subcommands, in the order ``shapedb --help`` lists them.
GROUPS = (store, check, search, evaluate, learn, serve, demo)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``shapedb`` command; each subcommand carries its handler."""
    parser = argparse.ArgumentParser(
        prog="shapedb", description="3-D shape retrieval with maximal disjoint ball decompositions."
    )
    parser.add_argument(
        "-v", "--verbose", action="count", default=0, help="more log output; tracebacks on errors"
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in GROUPS:
        group.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.handler(args))
    except ShapeDBError as exc:
        _report(f"shapedb: error: {_one_line(exc)}", verbose=args.verbose)
        return 1
    except KeyboardInterrupt:
        print("shapedb: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        hint = "" if args.verbose else " (run with -v for the traceback)"
        _report(
            f"shapedb: internal error: {type(exc).__name__}: {_one_line(exc)}{hint}",
            verbose=args.verbose,
        )
        return 1


def _report(line: str, *, verbose: int) -> None:
    if verbose:
        traceback.print_exc(file=sys.stderr)
    print(line, file=sys.stderr)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())
