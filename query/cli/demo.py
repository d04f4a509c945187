"""``shapedb demo``: ingest the built-in example shapes, then search, score and draw them."""

from __future__ import annotations

import argparse
import shlex
import shutil
import tempfile
from pathlib import Path
from typing import Any

from query.cli.common import (
    HIT_COLUMNS,
    ProgressBar,
    add_db_argument,
    hit_row,
    open_store,
    positive_int,
    print_rows,
)
from query.cli.evaluate import scores_line
from query.cli.store import disk_usage, human_bytes

__all__ = ["demo_arguments", "demo", "DEMO_STORE"]

#: The demo store's configuration: coarser than the default, so the 20 shapes ingest quickly.
DEMO_STORE: dict[str, Any] = {"resolution": 64, "n_balls": 256}


def demo_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``demo``."""
    add_db_argument(s, required=False)
    s.description = (
        "Build a store of the built-in example shapes (in --db, default a new temporary "
        "folder), search and score it, and draw one shape. The last lines say where the "
        "store is and how to remove it; --clean removes it at the end."
    )
    s.add_argument(
        "--workers", type=positive_int, metavar="N", help="worker processes (default: all cores)"
    )
    s.add_argument(
        "--clean",
        action="store_true",
        help="remove the demo store at the end (only a folder the demo created or found empty)",
    )


def demo(args: argparse.Namespace) -> int:
    """``shapedb demo``: a store in ``--db`` (default: a new temporary folder).

    Exit status 1 when no shape could be ingested.
    """
    from shapedb.examples import catalogue

    path = Path(args.db or tempfile.mkdtemp(prefix="shapedb-demo-"))
    fresh = not path.exists() or not any(path.iterdir())
    db = open_store(str(path), **DEMO_STORE)
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
    if rows:
        query = rows[0]
        print(f"\nshapes most like {query['name']!r} (label {query['label']!r}):")
        print_rows([hit_row(h) for h in db.search(int(query["id"]), k=5)], HIT_COLUMNS)
        scores = db.evaluate(label="label").to_dict()
        print(f"\nleave-one-out retrieval over {scores['queries']} shapes: {scores_line(scores)}")
        if not args.clean:
            picture = db.show(int(query["id"]), path / "demo.png")
            print(f"{query['name']} and its balls: {picture}")
            _hints(path)
    _last_lines(path, clean=args.clean, fresh=fresh)
    return 0 if rows else 1


def _hints(path: Path) -> None:
    db = shlex.quote(str(path))
    print(f'\ntry:  shapedb sql "SELECT label, count(*) FROM shapes GROUP BY label" --db {db}')
    print(f"\nbrowse it:  shapedb serve --db {db}    (then open http://127.0.0.1:8000/)")


def _last_lines(path: Path, *, clean: bool, fresh: bool) -> None:
    """Say where the demo store is and how to remove it, or remove it (``clean``)."""
    if clean and fresh:
        shutil.rmtree(path)
        print(f"\nremoved the demo store {path}")
        return
    if clean:
        print(f"\nkept the demo store {path}: it held files before the demo")
        return
    _, size = disk_usage(path)
    print(f"\nthe demo store is {path} ({human_bytes(size)})")
    print(f"remove it with:  rm -r {shlex.quote(str(path))}    (or run `shapedb demo --clean`)")
