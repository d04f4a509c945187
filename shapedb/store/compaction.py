"""Compaction: runs of small segments merged into one, up to a target size.

A store gains one segment per table at every commit, so a store grown by small commits
holds thousands of small files, and every scan opens them all. A compaction rewrites
each run of consecutive segments smaller than the target into one segment of about the
target (:meth:`shapedb.store.store.Store.compact`); segments already that large are
left alone, so compacting again costs nothing and a large store is never read whole.
"""

from __future__ import annotations

from typing import Any

import pyarrow as pa

from shapedb.store.transaction import Transaction

__all__ = ["TARGET_SHAPES", "merge_runs", "merge_small_segments"]

#: Shapes a compacted segment holds at most (about 26 MB of shapes, 300 MB of balls
#: for real packings of ~480 balls): what one run reads into memory while it is merged.
TARGET_SHAPES = 20_000


def merge_runs(segments: list[dict[str, Any]], target_rows: int) -> list[list[int]]:
    """Positions of the runs of ``segments`` (manifest order) to merge, each of at least
    two segments.

    A run is consecutive segments of fewer than ``target_rows`` rows each, cut when it
    reaches ``target_rows`` rows; a segment of ``target_rows`` or more ends a run and is
    never rewritten.

    Parameters
    ----------
    segments : list of dict
        The manifest's entries of one table (each with ``rows``).
    target_rows : int
        Rows of a full segment, >= 1.
    """
    runs: list[list[int]] = []
    run: list[int] = []
    rows = 0
    for k, seg in enumerate(segments):
        n = int(seg.get("rows", 0))
        if n >= target_rows:
            runs.append(run)
            run, rows = [], 0
            continue
        if run and rows + n > target_rows:
            runs.append(run)
            run, rows = [], 0
        run.append(k)
        rows += n
    runs.append(run)
    return [r for r in runs if len(r) >= 2]


def merge_small_segments(txn: Transaction, dim: int, target_shapes: int) -> bool:
    """Stage, in ``txn``, one segment for each run of small segments of the ``shapes``,
    ``balls`` and ``edges`` tables (each table's runs planned on its own rows, ``balls`` and
    ``edges`` scaled by their rows per shape), retiring the merged files; True when any
    run was merged. Reads one run at a time, so memory holds one merged segment."""
    tables = txn.tables
    shapes = max(sum(int(s.get("rows", 0)) for s in tables["shapes"]), 1)
    merged = False
    for table in ("shapes", "balls", "edges"):
        segments = list(tables[table])
        per_shape = sum(int(s.get("rows", 0)) for s in segments) / shapes
        target = max(int(target_shapes * max(per_shape, 1.0)), 1)
        col = "id" if table == "shapes" else "shape_id"
        kept: list[dict[str, Any]] = []
        runs = {run[0]: run for run in merge_runs(segments, target)}
        k = 0
        while k < len(segments):
            run = runs.get(k)
            if run is None:
                kept.append(segments[k])
                k += 1
                continue
            parts = [txn.read_segment(segments[j], table, dim) for j in run]
            files = [segments[j]["file"] for j in run]
            txn.retire(files)
            kept.append(txn.stage(table, pa.concat_tables(parts).sort_by(col), col, replaces=files))
            merged, k = True, run[-1] + 1
        txn.tables[table] = kept
    return merged
