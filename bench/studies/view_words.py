"""One-sided scans against each model's simulated scans, by their surface words.

``python -m bench.studies.view_words --sets capod parts`` scans every validation model
from :data:`VIEWS` fixed directions (a Fibonacci lattice on the sphere, the camera at
:data:`VIEW_DISTANCE` bounding radii, :func:`bench.sets.scans.one_sided_scan` without
depth noise) and keeps each view's surface words (:mod:`shapedb.signature.surface_words`).
Each model's own one-sided scan (``bench.quality --queries one-sided``) is then ranked
against the other models by the least chi-square distance over their views, at depth
noises :data:`NOISES` (the bench's scans are 0.003), as it is and after
:func:`flattened` (each point moved onto the plane of its neighbours; against the views as
they are and flattened alike), and fused with the
product's view path (``db.search``, reciprocal ranks, :data:`OFFSETS` x :data:`WEIGHTS`).
Class NN / 1-T, the scan's own model left out. Writes
``bench/results/studies/view_words.json``. Not in the product (docs/studies.md, "One-sided
scans by their silhouette").
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

__all__ = ["view_directions", "flattened", "family_rows", "main"]

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "view_words.json"
#: Simulated views of each model.
VIEWS = 20
#: The simulated camera's distance from the bounding sphere's centre, in radii.
VIEW_DISTANCE = 2.5
#: Depth noises of the scans ranked (``bench.sets.scans.SCAN_NOISE`` is 0.003).
NOISES = (0.0, 0.0015, 0.003, 0.006)
#: Neighbourhood of :func:`flattened`, in units of the scan's bounding radius.
FLAT_RADIUS = 0.06
OFFSETS = (4.0, 16.0)
WEIGHTS = (0.5, 1.0, 2.0)


def view_directions(n: int) -> NDArray[np.float64]:
    """(n, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n)
    azimuth = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack(
        [np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1
    )


def flattened(points: NDArray[np.float64], radius: float = FLAT_RADIUS) -> NDArray[np.float64]:
    """(n, 3) ``points`` each moved onto the least-squares plane of its neighbours within
    ``radius`` x the points' bounding radius (points with fewer than 5 stay)."""
    p = np.asarray(points, np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    reach = float(np.linalg.norm(p - (lo + hi) / 2, axis=1).max())
    out = p.copy()
    for i, near in enumerate(cKDTree(p).query_ball_point(p, radius * reach)):
        if len(near) < 5:
            continue
        q = p[near]
        centre = q.mean(axis=0)
        normal = np.linalg.svd(q - centre, full_matrices=False)[2][2]
        out[i] = p[i] - np.dot(p[i] - centre, normal) * normal
    return out


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
    """One family's scores, every way of ranking its scans."""
    from bench.quality import family_split
    from bench.sets import scans
    from bench.sets.datasets import mesh_arrays, stable_seed
    from bench.support.product_stores import split_store
    from bench.support.scan_queries import query_geometry
    from shapedb.signature.surface_words import WORDS, surface_words, words_distance

    ds = family_split(name, split)
    n, labels = len(ds), np.asarray(ds.labels)
    own = np.eye(n, dtype=bool)
    directions = view_directions(VIEWS)
    views = np.zeros((n, VIEWS, WORDS))
    flat_views = np.zeros((n, VIEWS, WORDS))
    for j, model in enumerate(ds.models):
        v, f = mesh_arrays(model)
        centre, radius = scans.bounding_sphere(v)
        for k, d in enumerate(directions):
            eye = centre + d * VIEW_DISTANCE * radius
            view = scans.one_sided_scan(v, f, seed=k, noise=0.0, eye=eye)
            views[j, k] = surface_words(view)
            flat_views[j, k] = surface_words(flattened(view))
        print(f"  {name} views {j + 1}/{n}", flush=True)

    def by_views(
        words: list[NDArray[np.float32]], stored: NDArray[np.float64] = views
    ) -> NDArray[np.float64]:
        d = np.array([[words_distance(w, stored[j]).min() for j in range(n)] for w in words])
        return np.where(own, np.inf, d)

    out: dict[str, Any] = {"models": n, "views": VIEWS}
    flat_at_scan_noise = None
    for noise in NOISES:
        raw, flat = [], []
        for model in ds.models:
            v, f = mesh_arrays(model)
            seed = stable_seed(model.name, "one-sided")
            points = scans.one_sided_scan(v, f, seed=seed, noise=noise)
            raw.append(surface_words(points))
            flat.append(surface_words(flattened(points)))
        out[f"scans at noise {noise}"] = _scores(by_views(raw), labels)
        d_flat = by_views(flat)
        out[f"scans at noise {noise}, flattened"] = _scores(d_flat, labels)
        out[f"scans at noise {noise}, flattened, against flattened views"] = _scores(
            by_views(flat, flat_views), labels
        )
        if noise == scans.SCAN_NOISE:
            flat_at_scan_noise = d_flat
    db = split_store(ds, {})
    at = {m.name: j for j, m in enumerate(ds.models)}
    view_path = np.full((n, n), np.inf)
    for i, model in enumerate(ds.models):
        for r, hit in enumerate(db.search(query_geometry(model, "one-sided"), k=n)):
            view_path[i, at[hit.name]] = r
    view_path = np.where(own, np.inf, view_path)
    out["the view path (db.search)"] = _scores(view_path, labels)
    if flat_at_scan_noise is not None:
        rv, rw = _ranks(view_path), _ranks(flat_at_scan_noise)
        out["fused with the view path"] = {
            f"offset {o:g}, weight {w:g}": _scores(
                np.where(own, np.inf, -(1 / (o + rv) + w / (o + rw))), labels
            )
            for o in OFFSETS
            for w in WEIGHTS
        }
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
    for name, row in rows.items():
        print(name, json.dumps(row, indent=1))
    write_json(args.out, {"split": args.split, "families": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
