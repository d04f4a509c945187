"""One-sided scans by their silhouette and their view words: the view path's fusion.

``python -m bench.studies.view_words --sets capod parts`` builds each family's validation
store (the product's: every record keeps its view words,
:mod:`shapedb.signature.view_words`) and ranks every model's one-sided scan
(``bench.quality --queries one-sided``: depth noise ``bench.sets.scans.SCAN_NOISE``)
against the other models: as the view path did before (silhouettes,
:func:`query.search.view_search.view_distances`, where the geometry calls the scan
one-sided; the whole path where it does not), by the view words alone (the scan's words
:func:`~shapedb.signature.view_words.scan_words` against each shape's views; and the
scan's words not flattened), and routed as the product routes it now: silhouette and
words fused (:func:`query.search.view_search.fused_scores`, a grid of :data:`OFFSETS` x
:data:`WEIGHTS`, the words ranked over the
:data:`~query.search.view_search.WORD_CANDIDATES` nearest) where the geometry calls it
one-sided, the words alone where only its words do
(:func:`query.parts.partial.is_one_sided_cloud`), the whole path otherwise. Class NN /
1-T, the scan's own model left out. It also counts the family's clouds around the whole
surface (20 % of the vertices, even, fall-off) that either test calls one-sided. Writes
``bench/results/studies/view_words.json``; the product's ``WORD_OFFSET`` and
``WORDS_WEIGHT`` are the grid's best NN + 1-T summed over the sets.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["family_rows", "main"]

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "view_words.json"
OFFSETS = (2.0, 4.0, 8.0, 16.0, 32.0)
WEIGHTS = (0.25, 0.5, 1.0, 2.0, 4.0)


def _scores(distance: NDArray[np.float64], labels: NDArray[Any]) -> dict[str, float]:
    from bench.common import retrieval_scores

    s = retrieval_scores(np.where(np.isfinite(distance), -distance, np.nan), labels)
    return {"nn": round(s["nn"], 4), "first_tier": round(s["first_tier"], 4)}


def _ranks(distance: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.empty_like(distance)
    for i, row in enumerate(distance):
        out[i, np.argsort(row, kind="stable")] = np.arange(len(row))
    return out


def family_rows(name: str, split: str) -> dict[str, Any]:
    """One family's scores, every way of ranking its scans, and how its clouds are routed."""
    from bench.quality import family_split
    from bench.support.product_stores import split_store
    from bench.support.scan_queries import query_geometry
    from query.parts.partial import is_one_sided_cloud, words_ratio
    from query.search.scan_words import stored_view_words
    from query.search.view_search import WORD_CANDIDATES, fused_scores, view_distances
    from shapedb.geometry.view import viewing_direction
    from shapedb.signature.scan_view import scan_view_features
    from shapedb.signature.surface_words import surface_words
    from shapedb.signature.view_words import scan_words, view_words_distances

    ds = family_split(name, split)
    n, labels = len(ds), np.asarray(ds.labels)
    own = np.eye(n, dtype=bool)
    db = split_store(ds, {})
    at = {m.name: j for j, m in enumerate(ds.models)}
    ids, rows = stored_view_words(db)
    names = db.sql("SELECT id, name FROM shapes").to_pydict()
    row_of = {at[nm]: i for i, nm in zip(names["id"], names["name"], strict=True)}
    id_at = np.array([row_of[j] for j in range(n)])
    words_at = np.searchsorted(ids, id_at)
    silhouette = np.full((n, n), np.inf)
    by_words = np.full((n, n), np.inf)
    raw_words = np.full((n, n), np.inf)
    whole = np.full((n, n), np.inf)
    seen, ratio, taken = np.zeros(n, bool), np.zeros(n), np.zeros(n, bool)
    for i, model in enumerate(ds.models):
        cloud = query_geometry(model, "one-sided")
        direction = viewing_direction(cloud)
        seen[i] = direction is not None
        if direction is not None:
            features = scan_view_features(cloud.points, direction, db.config.light_field)
            sid, dist = view_distances(db, features) or (np.zeros(0, np.int64), np.zeros(0))
            silhouette[i] = dist[np.searchsorted(sid, id_at)]
        by_words[i] = view_words_distances(scan_words(cloud.points), rows)[words_at]
        raw_words[i] = view_words_distances(surface_words(cloud.points), rows)[words_at]
        for r, hit in enumerate(db.search(cloud, k=n, partial=False)):
            whole[i, at[hit.name]] = r
        found = words_ratio(db, cloud.points)
        ratio[i] = np.inf if found is None else found
        taken[i] = is_one_sided_cloud(db, cloud, direction)
        print(f"  {name} scans {i + 1}/{n}", flush=True)
    silhouette, by_words = np.where(own, np.inf, silhouette), np.where(own, np.inf, by_words)
    whole = np.where(own, np.inf, whole)
    fuse, said = seen & taken, ~seen & taken
    rs, rw, rh = _ranks(silhouette), np.minimum(_ranks(by_words), WORD_CANDIDATES), _ranks(whole)
    before = np.where(seen[:, None], rs, rh)
    out: dict[str, Any] = {
        "models": n,
        "one-sided by their geometry": int(seen.sum()),
        "of those, whole by their words": int((seen & ~taken).sum()),
        "one-sided by their words alone": int(said.sum()),
        "words ratio, geometry one-sided": sorted(np.round(ratio[seen], 3).tolist()),
        "words ratio, the rest": sorted(np.round(ratio[~seen], 3).tolist()),
        "before (silhouettes; the whole path where the geometry misses)": _scores(
            np.where(own, np.inf, before), labels
        ),
        "view words alone, every scan": _scores(by_words, labels),
        "view words alone, the scans not flattened": _scores(
            np.where(own, np.inf, raw_words), labels
        ),
    }
    fused: dict[str, Any] = {}
    for o in OFFSETS:
        for w in WEIGHTS:
            f = -fused_scores(rs, rw, o, w)
            routed = np.where(fuse[:, None], f, np.where(said[:, None], by_words, rh))
            fused[f"offset {o:g}, weight {w:g}"] = _scores(np.where(own, np.inf, routed), labels)
    out["fused (words alone where only they say one-sided)"] = fused
    out["clouds around the whole (20 % vertices, even, fall-off)"] = _routing(db, ds)
    return out


def _routing(db: Any, ds: Any) -> dict[str, Any]:
    """How many of the family's whole clouds each test calls one-sided."""
    from bench.support.scan_queries import query_geometry
    from query.parts.partial import is_one_sided_cloud, words_ratio
    from shapedb.geometry.view import viewing_direction

    out: dict[str, Any] = {}
    for kind in ("vertex", "even", "falloff"):
        geometry, taken, ratios = 0, 0, []
        for model in ds.models:
            cloud = query_geometry(model, kind)
            direction = viewing_direction(cloud)
            geometry += direction is not None
            taken += is_one_sided_cloud(db, cloud, direction)
            found = words_ratio(db, cloud.points)
            ratios.append(np.inf if found is None else round(found, 3))
        out[kind] = {
            "clouds": len(ds), "one-sided by the geometry": geometry,
            "taken by the view path": taken, "least words ratios": sorted(ratios)[:8],
        }  # fmt: skip
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.view_words",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--sets", nargs="+", default=["capod", "parts"])
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    from bench.common import write_json

    rows = {name: family_rows(name, args.split) for name in args.sets}
    fused = "fused (words alone where only they say one-sided)"
    grid = next(iter(rows.values()))[fused]
    total = {
        key: round(sum(r[fused][key]["nn"] + r[fused][key]["first_tier"] for r in rows.values()), 4)
        for key in grid
    }
    best = max(total, key=lambda key: total[key])
    for name, row in rows.items():
        print(name, json.dumps(row, indent=1))
    print("best over the sets (NN + 1-T summed):", best, total[best])
    write_json(args.out, {"split": args.split, "families": rows, "best": best, "sums": total})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
