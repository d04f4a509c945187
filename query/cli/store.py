"""Subcommands that fill and inspect a store: ``ingest``, ``info``, ``delete``."""

from __future__ import annotations

import argparse
import os

from query.cli.common import (
    ProgressBar,
    Subparsers,
    add_command,
    add_db_argument,
    existing_store,
    open_store,
    positive_int,
    print_json,
    seconds,
)

__all__ = ["register", "ingest", "info", "delete"]


def register(subparsers: Subparsers) -> None:
    """Add ``ingest``, ``info`` and ``delete``."""
    s = add_command(subparsers, "ingest", ingest, help="add model files or folders to a store")
    s.add_argument("paths", nargs="+", metavar="PATH", help="files or folders")
    add_db_argument(s)
    s.add_argument("--labels", metavar="CSV", help="CSV with path,label[,extra columns]")
    s.add_argument("--label-from-folder", action="store_true", help="label = parent folder")
    s.add_argument(
        "--as",
        dest="as_",
        choices=["mesh", "pointcloud", "smooth_voxels"],
        help="force representation (smooth_voxels: occupancy grids as smooth solids)",
    )
    s.add_argument("--resolution", type=int, metavar="N", help="grid cells (new store)")
    s.add_argument("--balls", type=int, metavar="N", help="max balls per shape (new store)")
    s.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="any configuration option of a new store, e.g. --set tie_cells=0 (repeatable)",
    )
    s.add_argument(
        "--workers", type=positive_int, metavar="N", help="worker processes (default: all cores)"
    )
    s.add_argument("--scheduler", metavar="ADDR", help="Dask scheduler address, e.g. tcp://h:8786")
    s.add_argument(
        "--batch-size", type=positive_int, default=32, metavar="N", help="shapes per commit"
    )
    s.add_argument("--force", action="store_true", help="rebuild shapes already stored")
    _lock_timeout(s)
    s.add_argument(
        "--max-bytes", type=positive_int, metavar="N", help="refuse files larger than N bytes"
    )
    s.add_argument(
        "--max-faces", type=positive_int, metavar="N", help="refuse meshes of more than N faces"
    )
    s.add_argument("--json", action="store_true", help="print the report as JSON")

    s = add_command(
        subparsers, "info", info, help="counts, labels, failures and configuration of a store"
    )
    add_db_argument(s)
    s.add_argument("--json", action="store_true")

    s = add_command(subparsers, "delete", delete, help="remove shapes by id or name")
    s.add_argument("targets", nargs="+", metavar="ID_OR_NAME")
    add_db_argument(s)
    _lock_timeout(s)


def _lock_timeout(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--lock-timeout",
        type=seconds,
        default=10.0,
        metavar="S",
        help="seconds to wait for another writer to finish (default 10)",
    )


def ingest(args: argparse.Namespace) -> int:
    """``shapedb ingest``: exit status 1 when some input failed."""
    from shapedb.config.core import parse_options

    options = parse_options(args.settings)
    if args.resolution is not None:
        options["resolution"] = args.resolution
    if args.balls is not None:
        options["n_balls"] = args.balls
    db = open_store(args.db, lock_timeout=args.lock_timeout, **options)
    bar = ProgressBar(enabled=not args.json)
    try:
        report = db.ingest(
            args.paths,
            labels=args.labels,
            label_from_folder=args.label_from_folder,
            as_=args.as_,
            workers=args.workers,
            scheduler=args.scheduler,
            force=args.force,
            progress=bar,
            batch_size=args.batch_size,
            max_bytes=args.max_bytes,
            max_faces=args.max_faces,
        )
    finally:
        bar.close()
    if args.json:
        print_json(report.to_dict())
    else:
        print(
            f"ingested {len(report.ingested)}, skipped {len(report.skipped)}, "
            f"failed {len(report.failed)} ({report.seconds:.1f} s)"
        )
        for path, error in report.failed:
            print(f"  failed: {path}: {error}")
        for path, note in report.notes:
            print(f"  note: {path}: {note}")
    return 1 if report.failed else 0


def info(args: argparse.Namespace) -> int:
    """``shapedb info``."""
    db = existing_store(args.db)
    summary = db.info()
    if args.json:
        print_json(summary)
        return 0
    print(f"store:    {os.path.abspath(args.db)}")
    print(f"shapes:   {summary['shapes']}")
    labels = summary["labels"]
    print(f"labels:   {len(labels)}" + (":" if labels else ""))
    for name, count in labels.items():
        print(f"  {count:6d}  {name}")
    options = db.config.options()
    print("config:   " + ", ".join(f"{k}={v}" for k, v in options.items()))
    print(f"failures: {len(summary['failures'])}")
    for f in summary["failures"]:
        print(f"  {f['path']}: {f['error']}")
    return 0


def delete(args: argparse.Namespace) -> int:
    """``shapedb delete``."""
    n = open_store(args.db, create=False, lock_timeout=args.lock_timeout).delete(args.targets)
    print(f"deleted {n} shape(s)")
    return 0
