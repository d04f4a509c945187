"""Subcommands that fill and inspect a store: ``ingest``, ``info``, ``delete``."""

from __future__ import annotations

import argparse
import os
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from query.cli.common import (
    ProgressBar,
    add_db_argument,
    existing_store,
    format_table,
    open_store,
    positive_int,
    print_json,
    seconds,
    shape_ref,
)

__all__ = [
    "ingest_arguments",
    "info_arguments",
    "delete_arguments",
    "ingest",
    "info",
    "delete",
    "print_config",
    "disk_usage",
    "human_bytes",
    "build_line",
]


def ingest_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``ingest``."""
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
        help="any configuration option of a new store, e.g. --set tie_cells=0 (repeatable; "
        "`shapedb info --config` lists them)",
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
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    s.add_argument("--json", action="store_true", help="print the report as JSON")


def info_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``info``."""
    add_db_argument(s)
    s.add_argument(
        "--config",
        action="store_true",
        help="print every configuration option, one per line, grouped by section",
    )
    s.add_argument("--json", action="store_true", help="print the summary (or --config) as JSON")


def delete_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``delete``."""
    s.add_argument("targets", nargs="+", metavar="ID_OR_NAME")
    add_db_argument(s)
    _lock_timeout(s)


def compact_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``compact``."""
    add_db_argument(s)
    _lock_timeout(s)
    s.add_argument("--json", action="store_true")


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
    bar = ProgressBar(enabled=not (args.json or args.quiet))
    try:
        report = db.ingest(
            args.paths,
            labels=args.labels,
            label_from_folder=args.label_from_folder,
            as_=args.as_,
            workers=args.workers,
            scheduler=args.scheduler,
            force=args.force,
            progress=False if args.quiet else bar,
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
    """``shapedb info``: a short summary; ``--config`` every configuration option."""
    db = existing_store(args.db)
    if args.config:
        if args.json:
            print_json(db.config.to_dict())
        else:
            print_config(db.config.options())
        return 0
    summary = db.info()
    if args.json:
        print_json(summary)
        return 0
    labels = summary["labels"]
    print(f"store:    {os.path.abspath(args.db)}")
    print(f"shapes:   {summary['shapes']}")
    print(f"labels:   {len(labels)}" + ("" if labels else " (no labelled shapes)"))
    rows = [{"label": name, "shapes": count} for name, count in labels.items()]
    for line in format_table(rows, ["label", "shapes"], headers=["", ""])[1:] if rows else []:
        print(f"  {line}")
    files, size = disk_usage(db.path)
    print(f"size:     {human_bytes(size)} in {files} files")
    print(f"build:    {build_line(db.path)}")
    print(f"failures: {len(summary['failures'])}")
    for f in summary["failures"]:
        print(f"  {f['path']}: {f['error']}")
    print(f"config:   `shapedb info --config --db {args.db}` lists every option")
    return 0


def print_config(options: dict[str, Any]) -> None:
    """Print ``options`` (``Config.options()``) one per line, grouped by section.

    Each line is ``name = value``, with the name ``--set`` and ``connect`` take.
    """
    from shapedb.config.core import OPTIONS

    sections: dict[str, list[str]] = {}
    for name in options:
        sections.setdefault(OPTIONS[name][0], []).append(name)
    width = max(len(name) for name in options)
    for k, (section, names) in enumerate(sections.items()):
        print(("\n" if k else "") + f"[{section}]")
        for name in names:
            print(f"  {name.ljust(width)} = {options[name]}")


def disk_usage(path: Path) -> tuple[int, int]:
    """(files, bytes) under ``path``, recursively."""
    files = [p for p in path.rglob("*") if p.is_file()]
    return len(files), sum(p.stat().st_size for p in files)


def human_bytes(n: int) -> str:
    """``n`` bytes as B, KB, MB, GB or TB (powers of 1024), e.g. ``"1.2 MB"``."""
    size = float(n)
    for unit in ("B", "KB", "MB", "GB"):
        if size < 1024:
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    return f"{size:.1f} TB"


def build_line(path: Path) -> str:
    """The store's format and schema versions, creation and last-change times (UTC)."""
    from shapedb.store.manifest import read_manifest

    manifest = read_manifest(path)

    def when(key: str) -> str:
        stamp = manifest.get(key)
        if not isinstance(stamp, (int, float)):
            return "unknown"
        return datetime.fromtimestamp(stamp, tz=timezone.utc).strftime("%Y-%m-%d %H:%M UTC")

    return (
        f"format {manifest['format_version']}, schema {manifest.get('schema_version', '?')}, "
        f"version {manifest['version']}, created {when('created_at')}, "
        f"updated {when('updated_at')}"
    )


def compact(args: argparse.Namespace) -> int:
    """``shapedb compact``: merge runs of small segments (``Store.compact``)."""
    db = open_store(args.db, create=False, lock_timeout=args.lock_timeout)
    tables = ("shapes", "balls", "edges")
    before = {t: len(db.store.files(t)) for t in tables}
    result = db.store.compact()
    after = {t: len(db.store.files(t)) for t in tables}
    if args.json:
        print_json({"version": result.version, "before": before, "after": after})
        return 0
    counts = ", ".join(f"{t} {before[t]} -> {after[t]}" for t in tables)
    print(f"segments: {counts} (store version {result.version})")
    return 0


def delete(args: argparse.Namespace) -> int:
    """``shapedb delete``."""
    for target in args.targets:
        shape_ref(target)  # the range check; the store reads a name of digits as a name first
    n = open_store(args.db, create=False, lock_timeout=args.lock_timeout).delete(args.targets)
    print(f"deleted {n} shape(s)")
    return 0
