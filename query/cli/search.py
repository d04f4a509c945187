"""Subcommands that query a store: ``search``, ``sql``, ``show``, ``match``."""

from __future__ import annotations

import argparse
import io
import sys
from typing import TYPE_CHECKING

from query.cli.common import (
    HIT_COLUMNS,
    add_db_argument,
    existing_store,
    hit_row,
    print_json,
    print_rows,
    query_arg,
)
from shapedb.errors import QueryError

if TYPE_CHECKING:
    from query.database import Database

__all__ = [
    "search_arguments",
    "sql_arguments",
    "show_arguments",
    "match_arguments",
    "search",
    "sql",
    "show",
    "match",
    "MATCH_COLUMNS",
    "SEARCH_COLUMNS",
    "readable_names",
]

#: The columns of ``shapedb search`` as a table: a hit's fields and the search that found it.
SEARCH_COLUMNS = (*HIT_COLUMNS, "path")

#: The columns of ``shapedb match`` as a table (``--json`` keeps ``nodes`` as the list).
MATCH_COLUMNS = ("id", "name", "label", "similarity", "centre", "nodes")

MATCH_DESCRIPTION = """\
Find the stored shapes holding a part most like a part of QUERY (the paper's
Algorithm 1). A part is one ball of the query's maximal disjoint ball decomposition
(its centre) with the balls within --hops contacts of it; each stored shape
contributes its best-matching part.

Which part: --node N centres it on ball N of the query; --point X Y Z on the ball
nearest that point; with neither, the whole query model is the part.
Ball numbers: `shapedb show QUERY --balls --db DIR` lists the query's balls
(number, centre, radius, contacts); `shapedb show QUERY --out PNG --db DIR` draws
them."""

MATCH_EPILOG = """\
output columns:
  id, name, label  the stored shape holding the match
  similarity       exp(-lam * distance) of the two parts' vectors, in (0, 1]; 1 is identical
  centre           the ball of that shape at the centre of the matched part
  nodes            how many balls the matched part has (--json: their ball numbers)

--out PNG draws the query (its part highlighted) beside each match (its part highlighted)."""


def search_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``search``."""
    s.add_argument("query", metavar="QUERY", help="a model file, or a stored shape's id or name")
    add_db_argument(s)
    s.add_argument("-k", type=int, default=10, help="number of hits (default 10)")
    s.add_argument("--where", metavar="SQL", help="filter, e.g. \"label = 'Chair'\"")
    s.add_argument("--metric", metavar="JSON", help="a similarity saved by fit-metric")
    path = s.add_mutually_exclusive_group()
    path.add_argument(
        "--partial",
        dest="partial",
        action="store_const",
        const=True,
        help="find the shapes that contain QUERY (a crop, a broken model, a part), by its "
        "surface words and its parts (default: whole shapes; a one-sided scan by its "
        "silhouette)",
    )
    path.add_argument(
        "--whole",
        dest="partial",
        action="store_const",
        const=False,
        help="compare whole shapes, one-sided scans too (default: a one-sided scan by its "
        "silhouette against the stored light fields' views, everything else whole)",
    )
    s.add_argument("--json", action="store_true")


def sql_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``sql``."""
    s.add_argument("statement", metavar="SQL")
    add_db_argument(s)
    s.add_argument("--metric", metavar="JSON", help="weigh mdbd_distance / mdbd_kernel by it")
    fmt = s.add_mutually_exclusive_group()
    fmt.add_argument("--json", action="store_true", help="rows as one JSON list")
    fmt.add_argument("--csv", action="store_true", help="rows as CSV")


def show_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``show``."""
    s.add_argument("model", metavar="MODEL", help="a model file, or a stored id or name (--db)")
    s.add_argument("--out", metavar="PNG", help="picture to write")
    s.add_argument(
        "--balls",
        action="store_true",
        help="list the balls (number, centre, radius): the numbers `match --node` takes",
    )
    add_db_argument(s, required=False)
    s.add_argument("--complement", action="store_true", help="decompose the complement instead")


def match_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``match``, its description and the meaning of its output columns."""
    s.description, s.epilog = MATCH_DESCRIPTION, MATCH_EPILOG
    s.formatter_class = argparse.RawDescriptionHelpFormatter
    s.add_argument("query", metavar="QUERY", help="a model file, or a stored shape's id or name")
    add_db_argument(s)
    where = s.add_mutually_exclusive_group()
    where.add_argument(
        "--node",
        type=int,
        metavar="N",
        help="ball number of the query part's centre (default: the whole model is the part)",
    )
    where.add_argument(
        "--point",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="a point on the model; its nearest ball is the centre (default: none)",
    )
    s.add_argument(
        "--hops",
        type=int,
        default=2,
        metavar="K",
        help="part size: balls within K contacts of the centre (default 2)",
    )
    s.add_argument("-k", type=int, default=10, help="number of matches (default 10)")
    s.add_argument(
        "--where", metavar="SQL", help="restrict the shapes searched (default: all shapes)"
    )
    s.add_argument(
        "--complement",
        action="store_true",
        help="match concave features: parts of the complement (default: off)",
    )
    s.add_argument("--json", action="store_true", help="print JSON (default: a table)")
    s.add_argument(
        "--out", metavar="PNG", help="draw the query and its matches (default: no picture)"
    )


def search(args: argparse.Namespace) -> int:
    """``shapedb search``."""
    db = existing_store(args.db)
    hits = db.search(
        query_arg(args.query), k=args.k, where=args.where, metric=args.metric,
        partial=args.partial,
    )  # fmt: skip
    rows = [hit_row(h) for h in hits]
    if args.json:
        print_json(rows)
        return 0
    print_rows(rows, SEARCH_COLUMNS)
    return 0


def sql(args: argparse.Namespace) -> int:
    """``shapedb sql``: a text table, JSON rows or CSV."""
    table = existing_store(args.db).sql(args.statement, metric=args.metric)
    if args.csv:
        import pyarrow.csv as pacsv

        buf = io.BytesIO()
        pacsv.write_csv(table, buf)
        sys.stdout.write(buf.getvalue().decode())
        return 0
    rows = table.to_pylist()
    if args.json:
        print_json(rows)
        return 0
    print_rows(rows, table.column_names, headers=readable_names(table.column_names), count=True)
    return 0


def readable_names(columns: list[str]) -> list[str]:
    """Column names for people: DuckDB's ``count_star()`` shown as ``count``.

    A name is kept when its readable form would repeat another column's name.
    """
    readable = [c.removesuffix("_star()") if c.endswith("_star()") else c for c in columns]
    return [
        r if readable.count(r) == 1 and (r == c or r not in columns) else c
        for r, c in zip(readable, columns, strict=True)
    ]


def show(args: argparse.Namespace) -> int:
    """``shapedb show``: a stored shape (with ``--db``) or a model file; ``--balls`` lists
    its balls, ``--out`` draws them.

    Raises
    ------
    QueryError
        When neither ``--out`` nor ``--balls`` is given.
    """
    if not (args.out or args.balls):
        raise QueryError("nothing to show: give --out PNG, --balls, or both", source=args.model)
    db = existing_store(args.db) if args.db else None
    model = query_arg(args.model) if db is not None else args.model
    if args.balls:
        print_balls(db, model, complement=args.complement)
    if args.out:
        if db is not None:
            out = db.show(model, args.out, complement=args.complement)
        else:
            from query.render import show as show_model

            out = show_model(None, model, args.out, complement=args.complement)
        print(out)
    return 0


def print_balls(db: Database | None, model: str | int, *, complement: bool) -> None:
    """Print the balls of ``model``: number, centre, radius, and contacts in the graph
    that part matching uses (the balls ``match --hops 1`` adds around it)."""
    from query.parts.match import resolve
    from shapedb.config.part import PartConfig

    graph = resolve(db, model, complement=complement, part=PartConfig()).graph
    balls = zip(graph.centers.tolist(), graph.radii.tolist(), graph.degrees.tolist(), strict=True)
    rows = [
        {"ball": i, "x": c[0], "y": c[1], "z": c[2], "radius": r, "contacts": n}
        for i, (c, r, n) in enumerate(balls)
    ]
    print_rows(rows, ["ball", "x", "y", "z", "radius", "contacts"], floats=".4f")


def match(args: argparse.Namespace) -> int:
    """``shapedb match``."""
    db = existing_store(args.db)
    query = query_arg(args.query)
    matches = db.match(
        query,
        node=args.node,
        point=args.point,
        hops=args.hops,
        k=args.k,
        where=args.where,
        complement=args.complement,
    )
    if args.out:
        db.render_matches(query, matches, args.out, complement=args.complement)
    if args.json:
        keys = ("id", "name", "label", "similarity", "nodes")
        print_json([{key: m.to_dict()[key] for key in keys} for m in matches])
        return 0
    rows = [{**m.to_dict(), "centre": m.node, "nodes": len(m.nodes)} for m in matches]
    print_rows(rows, MATCH_COLUMNS)
    if args.out:
        print(f"picture: {args.out}")
    return 0
