"""``shapedb demo``: ingest the built-in example shapes, then search, score and draw them."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from query.cli.common import (
    HIT_COLUMNS,
    ProgressBar,
    Subparsers,
    add_command,
    add_db_argument,
    hit_row,
    open_store,
    print_rows,
)

__all__ = ["register", "demo"]


def register(subparsers: Subparsers) -> None:
    """Add ``demo``."""
    s = add_command(
        subparsers, "demo", demo, help="ingest the built-in example shapes and search them"
    )
    add_db_argument(s, required=False)
    s.add_argument("--workers", type=int, metavar="N", help="worker processes")


def demo(args: argparse.Namespace) -> int:
    """``shapedb demo``: a store in ``--db`` (default: a new temporary folder)."""
    from shapedb.examples import catalogue

    path = args.db or tempfile.mkdtemp(prefix="shapedb-demo-")
    db = open_store(path, resolution=64, n_balls=256)
    bar = ProgressBar(enabled=True)
    try:
        report = db.ingest(catalogue(), workers=args.workers, progress=bar)
    finally:
        bar.close()
    print(
        f"demo store {path}: ingested {len(report.ingested)}, skipped {len(report.skipped)}, "
        f"failed {len(report.failed)}"
    )
    rows = db.shapes(["id", "name", "label"]).to_pylist()
    if not rows:
        return 1
    query = rows[0]
    print(f"\nshapes most like {query['name']!r} (label {query['label']!r}):")
    hits = db.search(int(query["id"]), k=5)
    print_rows([hit_row(h) for h in hits], HIT_COLUMNS)
    scores = db.evaluate(label="label").to_dict()
    print(
        f"\nleave-one-out retrieval over {scores['queries']} shapes: "
        f"NN {scores['nn']:.3f}  1-T {scores['first_tier']:.3f}  "
        f"2-T {scores['second_tier']:.3f}  DCG {scores['dcg']:.3f}"
    )
    picture = db.show(int(query["id"]), Path(path) / "demo.png")
    print(f"{query['name']} and its balls: {picture}")
    print(f'\ntry:  shapedb sql "SELECT label, count(*) FROM shapes GROUP BY label" --db {path}')
    print(f"\nbrowse it:  shapedb serve --db {path}    (then open http://127.0.0.1:8000/)")
    return 0
