"""Which segments a compaction merges: runs of small segments, up to a target size.

A store gains one segment per table at every commit, so a store grown by small commits
holds thousands of small files, and every scan opens them all. A compaction rewrites
each run of consecutive segments smaller than the target into one segment of about the
target (:meth:`shapedb.store.store.Store.compact`); segments already that large are
left alone, so compacting again costs nothing and a large store is never read whole.
"""

from __future__ import annotations

from typing import Any

__all__ = ["TARGET_SHAPES", "merge_runs"]

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
