"""Subcommands that verify and rebuild a store: ``check`` and ``repair`` (docs/store.md)."""

from __future__ import annotations

import argparse

from query.cli.common import add_db_argument, print_json

__all__ = ["check_arguments", "check", "repair"]


def check_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``check`` and ``repair``."""
    add_db_argument(s)
    s.add_argument("--json", action="store_true")


def check(args: argparse.Namespace) -> int:
    """``shapedb check``: exit status 1 naming each damaged or missing segment."""
    from shapedb.store.integrity import check as check_store

    report = check_store(args.db)
    if args.json:
        print_json(report.to_dict())
        return 0 if report.ok else 1
    for file, reason in report.damaged:
        print(f"damaged: {file}: {reason}")
    for file in report.unverified:
        print(f"no checksum recorded: {file} (read in full: intact)")
    for file in report.unlisted:
        print(f"unlisted: {file} (not part of the store)")
    for what, reason in report.conflicts:
        print(f"id conflict: {what}: {reason}")
    verdict = "ok" if report.ok else f"{len(report.damaged)} damaged or missing segment(s)"
    verdict += f", {len(report.conflicts)} id conflict(s)" if report.conflicts else ""
    print(f"{report.path}: {verdict} ({report.checked} verified by checksum)")
    if not report.ok:
        print(f"run `shapedb repair --db {args.db}` to rebuild the store from the intact segments")
    return 0 if report.ok else 1


def repair(args: argparse.Namespace) -> int:
    """``shapedb repair``: exit status 1 when something could not be recovered."""
    from shapedb.store.integrity import repair as repair_store

    report = repair_store(args.db)
    if args.json:
        print_json(report.to_dict())
        return 1 if report.lost else 0
    if not report.changed:
        print(f"{report.path}: intact, nothing to repair ({report.shapes} shapes)")
        return 0
    print(
        f"{report.path}: rebuilt with {report.shapes} shapes from {len(report.recovered)} segment(s)"
    )
    for what, reason in report.lost:
        print(f"  not recovered: {what}: {reason}")
    for note in report.notes:
        print(f"  fixed: {note}")
    if report.moved_to:
        print(f"  previous files moved to {report.moved_to} (delete it once satisfied)")
    return 1 if report.lost else 0
