"""The ``shapedb`` command line: one entry point, one subcommand per task.

::

    shapedb ingest PATH... --db DIR [--labels CSV] [--label-from-folder] [--as pointcloud|smooth_voxels]
                   [--resolution N] [--balls N] [--set KEY=VALUE]... [--workers N]
                   [--scheduler ADDR] [--force] [--lock-timeout S] [--max-bytes N]
                   [--max-faces N] [--quiet] [--json]
    shapedb info --db DIR [--config] [--json]
    shapedb delete ID_OR_NAME... --db DIR [--lock-timeout S]
    shapedb compact --db DIR [--lock-timeout S] [--json]
    shapedb check --db DIR [--json]
    shapedb repair --db DIR [--json]
    shapedb search QUERY --db DIR [-k 10] [--where SQL] [--metric JSON] [--json]
    shapedb sql "SELECT ..." --db DIR [--metric JSON] [--json | --csv]
    shapedb show MODEL [--out PNG] [--balls] [--db DIR] [--complement]
    shapedb match QUERY --db DIR [--node N | --point X Y Z] [--hops K] [-k 10] [--json] [--out PNG]
    shapedb eval --db DIR [--label label] [--metric JSON] [--json] [--plot pr.png]
    shapedb fit-metric --db DIR [--label label] --out metric.json [--json]
    shapedb train --db DIR [--label label] [--conv tag|arma|spline] [--epochs N] --out model.pt
    shapedb classify MODEL --db DIR --model model.pt [--json]
    shapedb serve --db DIR [--host 127.0.0.1] [--port 8000] [--token TOKEN] [--max-upload-mb 64]
    shapedb demo [--db DIR] [--workers N] [--clean]

Layout: :data:`COMMANDS` is the command table, one :class:`~query.cli.common.Command` per
subcommand (name, one-line help, the function adding its arguments, the handler), in the
order ``shapedb --help`` lists them; :func:`build_parser` builds the parser from it. The
argument functions and handlers live in the module of their group (``store``, ``check``,
``search``, ``evaluate``, ``learn``, ``serve``, ``demo``); a handler takes the parsed
arguments and returns the exit status. To add a subcommand, write its two functions beside
the others of its group and add a row here. The handlers call the
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
import os
import sys
import traceback
from collections.abc import Callable, Sequence

from query.cli import check, demo, evaluate, learn, search, serve, store
from query.cli.common import Arguments, Command, Subparsers, verbose_parent
from shapedb.errors import ShapeDBError

__all__ = ["main", "build_parser", "COMMANDS", "Command"]


class _OneParser:
    """Stands in for ``add_subparsers()`` before a group's ``register(subparsers)``: hands
    it ``parser`` for subcommand ``name`` and a throwaway parser for its other ones."""

    def __init__(self, name: str, parser: argparse.ArgumentParser) -> None:
        self.name, self.parser = name, parser

    def add_parser(self, name: str, **kwargs: object) -> argparse.ArgumentParser:
        return self.parser if name == self.name else argparse.ArgumentParser(add_help=False)


def registered(register: Callable[[Subparsers], None], name: str) -> Arguments:
    """The arguments of subcommand ``name`` as added by a group's ``register(subparsers)``
    (the ``learn`` group still adds its parsers itself)."""

    def arguments(parser: argparse.ArgumentParser) -> None:
        register(_OneParser(name, parser))

    return arguments


#: Every subcommand, in the order ``shapedb --help`` lists them.
COMMANDS: tuple[Command, ...] = (
    Command(
        "ingest", "add model files or folders to a store", store.ingest_arguments, store.ingest
    ),
    Command("info", "shapes, labels, size and build of a store", store.info_arguments, store.info),
    Command("delete", "remove shapes by id or name", store.delete_arguments, store.delete),
    Command(
        "compact",
        "merge runs of small segments (many small commits) into larger ones",
        store.compact_arguments,
        store.compact,
    ),
    Command(
        "check",
        "verify every segment against the size and checksum in the manifest",
        check.check_arguments,
        check.check,
    ),
    Command(
        "repair",
        "rebuild the manifest from the intact segments",
        check.check_arguments,
        check.repair,
    ),
    Command("search", "the stored shapes most like QUERY", search.search_arguments, search.search),
    Command(
        "sql",
        "run DuckDB SQL over the views shapes, balls, edges",
        search.sql_arguments,
        search.sql,
    ),
    Command(
        "show",
        "list a model's MDBD balls, or draw them into a PNG",
        search.show_arguments,
        search.show,
    ),
    Command(
        "match",
        "stored parts most like a part of QUERY (Algorithm 1)",
        search.match_arguments,
        search.match,
    ),
    Command(
        "eval",
        "leave-one-out retrieval scores, overall and by class",
        evaluate.evaluate_arguments,
        evaluate.evaluate,
    ),
    Command(
        "fit-metric",
        "learn block weights of the similarity from the stored labels",
        evaluate.fit_metric_arguments,
        evaluate.fit_metric,
    ),
    Command(
        "train",
        "train the classifier that validates best: k-NN, linear, boosting or a graph CNN "
        "(needs shapedb[learn])",
        registered(learn.register, "train"),
        learn.train,
    ),
    Command(
        "classify",
        "label models with a trained classifier",
        registered(learn.register, "classify"),
        learn.classify,
    ),
    Command(
        "serve",
        "a web page and JSON API over a store (needs shapedb[serve])",
        serve.serve_arguments,
        serve.serve,
    ),
    Command(
        "demo", "ingest the built-in example shapes and search them", demo.demo_arguments, demo.demo
    ),
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``shapedb`` command, built from :data:`COMMANDS`; each
    subcommand's parser carries its handler (``args.handler``)."""
    parser = argparse.ArgumentParser(
        prog="shapedb", description="3-D shape retrieval with maximal disjoint ball decompositions."
    )
    parser.add_argument(
        "-v", "--verbose", action="count", default=0, help="more log output; tracebacks on errors"
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        sub = subparsers.add_parser(
            command.name,
            help=command.help,
            description=command.help,
            parents=[verbose_parent()],
        )
        command.arguments(sub)
        sub.set_defaults(handler=command.handler)
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
    except BrokenPipeError:  # the reader left (e.g. `| head`): stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
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
