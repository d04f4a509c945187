"""Halves ranked by their surface words at a ladder of scales, fused with their parts.

``python -m bench.studies.part_words`` takes every validation model's cropped half
(:func:`bench.sets.scans.cropped_mesh`) of CAPOD, parts and enclosures, asks the partial
path for all its candidates once (:func:`query.parts.partial.partial_candidates`: every
stored shape's parts score and least words distance), reads the half's words at each
reach of :data:`query.parts.part_words.PART_REACHES` alone, and scores (class NN / 1-T,
the half's own model left out):

- the words at each single reach, and at the least distance over the ladder (the
  product's);
- the parts alone;
- the two fused (:func:`query.parts.partial.fused_similarity`) over a grid of offsets and
  parts weights; the product's is the best sum of NN and 1-T over the three families.

Writes ``bench/results/studies/part_words.json``.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["main"]

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "part_words.json"
OFFSETS = (2.0, 4.0, 8.0, 16.0)
WEIGHTS = (0.0, 0.25, 0.5, 1.0)


def _scores(similarity: NDArray[np.float64], labels: NDArray[Any]) -> dict[str, float]:
    from bench.common import retrieval_scores

    s = retrieval_scores(similarity, labels)
    return {"nn": round(s["nn"], 4), "first_tier": round(s["first_tier"], 4)}


def family_rows(name: str, split: str) -> dict[str, Any]:
    """One family's scores, every way of ranking its halves."""
    from bench.quality import family_split
    from bench.support.product_stores import split_store
    from bench.support.scan_queries import query_geometry
    from query.parts.part_words import PART_REACHES, part_words, stored_words
    from query.parts.partial import fused_similarity, partial_candidates
    from shapedb.signature.surface_words import words_distance

    ds = family_split(name, split)
    db = split_store(ds, {})
    table = db.sql("select id, name from shapes")
    column_of = dict(
        zip(table.column("id").to_pylist(), table.column("name").to_pylist(), strict=True)
    )
    names = [m.name for m in ds.models]
    at = {n: j for j, n in enumerate(names)}
    labels = np.asarray(ds.labels)
    ids, rows = stored_words(db)
    n = len(names)
    reach = np.full((len(PART_REACHES), n, n), np.nan)
    parts, words = np.full((n, n), np.nan), np.full((n, n), np.nan)
    for i, model in enumerate(ds.models):
        half = query_geometry(model, "cropped")
        found = partial_candidates(db, half, k=len(db))
        cols = np.array([at[column_of[int(s)]] for s in found.ids])
        parts[i, cols], words[i, cols] = found.parts, found.words
        ladder = part_words(half, 0.0)
        wcols = np.array([at[column_of[int(s)]] for s in ids])
        for r in range(len(PART_REACHES)):
            reach[r, i, wcols] = words_distance(ladder[r], rows)
        print(f"  {name} {i + 1}/{n}", flush=True)
    own = np.eye(n, dtype=bool)
    out: dict[str, Any] = {"models": n}
    for r, value in enumerate(PART_REACHES):
        out[f"words at reach {value}"] = _scores(np.where(own, np.nan, -reach[r]), labels)
    out["words, least over the ladder"] = _scores(np.where(own, np.nan, -words), labels)
    out["parts"] = _scores(np.where(own, np.nan, parts), labels)
    grid = {}
    for o in OFFSETS:
        for v in WEIGHTS:
            fused = np.full((n, n), np.nan)
            for i in range(n):
                keep = ~own[i]
                fused[i, keep] = fused_similarity(
                    parts[i, keep], words[i, keep], offset=o, weight=v
                )
            grid[f"offset {o:g}, weight {v:g}"] = _scores(fused, labels)
    out["fused"] = grid
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.part_words",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--sets", nargs="+", default=["capod", "parts", "enclosures"])
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    from bench.common import write_json

    rows = {name: family_rows(name, args.split) for name in args.sets}
    keys = list(next(iter(rows.values()))["fused"])
    total = {
        k: sum(r["fused"][k]["nn"] + r["fused"][k]["first_tier"] for r in rows.values())
        for k in keys
    }
    best = max(keys, key=lambda k: total[k])
    for name, row in rows.items():
        print(name, json.dumps({k: v for k, v in row.items() if k != "fused"}))
        print(f"  fused, best overall ({best}):", row["fused"][best])
    write_json(args.out, {"split": args.split, "best fused": best, "families": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
