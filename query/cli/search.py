"""Subcommands that query a store: ``search``, ``sql``, ``show``, ``match``."""

from __future__ import annotations

import argparse
import io
import sys

from query.cli.common import (
    HIT_COLUMNS,
    Subparsers,
    add_command,
    add_db_argument,
    existing_store,
    hit_row,
    print_json,
    print_rows,
    query_arg,
)

__all__ = ["register", "search", "sql", "show", "match"]


def register(subparsers: Subparsers) -> None:
    """Add ``search``, ``sql``, ``show`` and ``match``."""
    s = add_command(subparsers, "search", search, help="the stored shapes most like QUERY")
    s.add_argument("query", metavar="QUERY", help="a model file, or a stored shape's id or name")
    add_db_argument(s)
    s.add_argument("-k", type=int, default=10, help="number of hits (default 10)")
    s.add_argument("--where", metavar="SQL", help="filter, e.g. \"label = 'Chair'\"")
    s.add_argument("--metric", metavar="JSON", help="a similarity saved by fit-metric")
    s.add_argument("--json", action="store_true")

    s = add_command(
        subparsers, "sql", sql, help="run DuckDB SQL over the views shapes, balls, edges"
    )
    s.add_argument("statement", metavar="SQL")
    add_db_argument(s)
    s.add_argument("--metric", metavar="JSON", help="weigh mdbd_distance / mdbd_kernel by it")
    fmt = s.add_mutually_exclusive_group()
    fmt.add_argument("--json", action="store_true")
    fmt.add_argument("--csv", action="store_true")

    s = add_command(subparsers, "show", show, help="draw a model with its MDBD balls into a PNG")
    s.add_argument("model", metavar="MODEL", help="a model file, or a stored id or name (--db)")
    s.add_argument("--out", required=True, metavar="PNG", help="picture to write")
    add_db_argument(s, required=False)
    s.add_argument("--complement", action="store_true", help="decompose the complement instead")

    s = add_command(
        subparsers, "match", match, help="stored parts most like a part of QUERY (Algorithm 1)"
    )
    s.add_argument("query", metavar="QUERY", help="a model file, or a stored shape's id or name")
    add_db_argument(s)
    where = s.add_mutually_exclusive_group()
    where.add_argument("--node", type=int, metavar="N", help="ball number of the query part")
    where.add_argument(
        "--point",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="a point on the model; its nearest ball is the part",
    )
    s.add_argument("--hops", type=int, default=2, metavar="K", help="neighbourhood range")
    s.add_argument("-k", type=int, default=10, help="number of matches (default 10)")
    s.add_argument("--where", metavar="SQL", help="restrict the shapes searched")
    s.add_argument("--complement", action="store_true", help="match concave features")
    s.add_argument("--json", action="store_true")
    s.add_argument("--out", metavar="PNG", help="draw the query and its matches")


def search(args: argparse.Namespace) -> int:
    """``shapedb search``."""
    db = existing_store(args.db)
    hits = db.search(query_arg(args.query), k=args.k, where=args.where, metric=args.metric)
    rows = [hit_row(h) for h in hits]
    if args.json:
        print_json(rows)
        return 0
    print_rows(rows, HIT_COLUMNS)
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
    print_rows(rows, table.column_names)
    return 0


def show(args: argparse.Namespace) -> int:
    """``shapedb show``: a stored shape (with ``--db``) or a model file."""
    if args.db:
        out = existing_store(args.db).show(
            query_arg(args.model), args.out, complement=args.complement
        )
    else:
        from query.render import show as show_model

        out = show_model(None, args.model, args.out, complement=args.complement)
    print(out)
    return 0


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
    rows = [
        {key: m.to_dict()[key] for key in ("id", "name", "label", "similarity", "nodes")}
        for m in matches
    ]
    if args.out:
        db.render_matches(query, matches, args.out, complement=args.complement)
    if args.json:
        print_json(rows)
        return 0
    print_rows(
        [{**r, "nodes": len(r["nodes"])} for r in rows],
        ["id", "name", "label", "similarity", "nodes"],
    )
    if args.out:
        print(f"picture: {args.out}")
    return 0
