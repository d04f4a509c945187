"""A similarity learned on a labelled store (:mod:`query.learn.metric`), held out.

Usage (from the repository root)::

    python -m bench.metric [--sets capod articulated parts] [--quick]

For each set a :class:`~query.learn.metric.LearnedMetric` is fitted on the *validation*
split exactly as ``db.fit_metric`` fits a store (block weights, regularisation
cross-validated inside the split) and scored on the *test* split against the
unlearned default; then the other way round (fitted on the larger test split, scored
on validation), so that a choice that only one split favours shows. Two store layouts: meshes only, and meshes with their sparse
views (``view_cells = 4``; each mesh's view is one more query during the fit, and a
pair with a cloud side is as far apart as the nearer of the mesh's own feature and
view, as ``CloudConfig.view_cells`` compares them). Rows:
meshes NN / 1-T / DCG, point-cloud queries (20 % of the vertices) against the mesh
database, the even mixture, and the mean log margin ``log(d(nearest same class) /
d(nearest other class))`` of mesh and cloud queries (lower is better). Results go to
bench/results/metric.json. Decompositions come from the bench cache
(:func:`bench.common.decompose_all`), so after ``python -m bench.retrieval --views 4``
this takes a minute.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import (
    decompose_all,
    format_table,
    log_margin,
    mdbd_config,
    retrieval_scores,
    write_json,
)
from bench.retrieval import build_sets
from bench.sets.datasets import Dataset
from bench.support.features import (
    complete,
    kernel_features,
    l1_matrix,
    mixture_mask,
    reconstructions,
)
from query.learn.metric import LearnedMetric, block_layout, fit_metric
from shapedb.config.core import Config, KernelConfig, MDBDConfig

RESULTS = Path(__file__).resolve().parent / "results"
VIEW_CELLS = 4.0


def _features(
    ds: Dataset, split: str, mdbd: MDBDConfig, cfg: KernelConfig, workers: int
) -> dict[str, Any]:
    sub = ds.split(split)
    mesh = decompose_all(sub.models, "mesh", mdbd, workers=workers)
    pc = decompose_all(sub.models, "pointcloud", mdbd, workers=workers)
    view = decompose_all(sub.models, f"view_{VIEW_CELLS:g}", mdbd, workers=workers)
    recon = reconstructions(sub.models, pc, mdbd, workers=workers)
    sub, (mesh, pc, view, recon) = complete(sub, mesh, pc, view, recon)
    return {
        "mesh": kernel_features(mesh, cfg),
        "pc": kernel_features(pc, cfg),
        "recon": kernel_features(recon, cfg),
        "view": kernel_features(view, cfg),
        "labels": sub.labels,
        "mix": mixture_mask([m.name for m in sub.models]),
    }


def _scores(f: dict[str, Any], w: NDArray[np.float64], views: bool) -> dict[str, float]:
    """Test-split measures with per-dimension weights ``w``."""
    m, p, v, lab = f["mesh"] * w, f["pc"] * w, f["view"] * w, f["labels"]
    r, mix = f["recon"] * w, f["mix"]
    d_mm = l1_matrix(m, m)
    # cloud-mesh pairs: the nearest of the store's comparisons (query.search.engine)
    d_pm = np.minimum(l1_matrix(p, m), l1_matrix(r, m))
    x = np.where(mix[:, None], p, m)
    d_xx = l1_matrix(x, x)
    one = mix[:, None] != mix[None, :]
    d_rx = l1_matrix(np.where(mix[:, None], r, m), x)
    d_xx = np.where(one, np.minimum(d_xx, np.minimum(d_rx, d_rx.T)), d_xx)
    if views:  # and the cloud against the mesh's view
        d_pm = np.minimum(d_pm, l1_matrix(p, v))
        d_xy = l1_matrix(x, np.where(mix[:, None], p, v))
        d_xx = np.where(one, np.minimum(d_xx, np.minimum(d_xy, d_xy.T)), d_xx)
    s = retrieval_scores(-d_mm, lab)
    return {
        "nn": s["nn"],
        "first_tier": s["first_tier"],
        "dcg": s["dcg"],
        "pc_to_mesh_nn": retrieval_scores(-d_pm, lab)["nn"],
        "mixture_nn": retrieval_scores(-d_xx, lab)["nn"],
        "margin_mesh": log_margin(d_mm, lab),
        "margin_pc": log_margin(d_pm, lab),
    }


_MEASURES = ("nn", "first_tier", "dcg", "pc_to_mesh_nn", "mixture_nn", "margin_mesh", "margin_pc")
_COLUMNS = (
    "store",
    "similarity",
    "NN",
    "1-T",
    "DCG",
    "cloud->mesh NN",
    "mixture NN",
    "margin mesh",
    "margin cloud",
)
#: (fitted on, scored on): validation to test, then the other way round (the test
#: splits are twice as large) to show that the choice is not one split's accident.
DIRECTIONS = (("validation", "test"), ("test", "validation"))


def _direction(
    fit_on: dict[str, Any], score_on: dict[str, Any], blocks: Any
) -> tuple[dict[str, Any], list[list[Any]]]:
    """Fit both store layouts on one split, score on the other."""
    rows, entry = [], {}
    for layout, views in (("meshes", False), ("meshes + views", True)):
        metric: LearnedMetric = fit_metric(
            fit_on["mesh"], fit_on["labels"], blocks=blocks, views=fit_on["view"] if views else None
        )
        base = _scores(score_on, np.ones(metric.dim), views)
        learned = _scores(score_on, metric.dim_weights(), views)
        entry[layout] = {
            "default": base,
            "learned": learned,
            "reg": metric.reg,
            "weights": dict(zip([b for b, _ in blocks], metric.weights, strict=True)),
            "cv": metric.cv,
        }
        for name, s in (("default", base), (f"learned (reg {metric.reg})", learned)):
            rows.append([layout, name, *(round(s[k], 3) for k in _MEASURES)])
    return entry, rows


def run(sets: Sequence[Dataset], mdbd: MDBDConfig, workers: int) -> dict[str, Any]:
    """Per set, direction and store layout: fit on one split, score on the other."""
    cfg = KernelConfig()
    blocks = block_layout(Config(kernel=cfg))
    out: dict[str, Any] = {}
    for ds in sets:
        feats = {
            split: _features(ds, split, mdbd, cfg, workers) for split in ("validation", "test")
        }
        out[ds.name] = {}
        for fit_split, score_split in DIRECTIONS:
            entry, rows = _direction(feats[fit_split], feats[score_split], blocks)
            print(
                format_table(
                    f"{ds.name}: metric fitted on {fit_split} ({len(feats[fit_split]['labels'])} "
                    f"models), scored on {score_split} ({len(feats[score_split]['labels'])})",
                    _COLUMNS,
                    rows,
                )
            )
            for layout, e in entry.items():
                weights = ", ".join(f"{k} {v:.2f}" for k, v in e["weights"].items())
                print(f"  {layout}: weights {weights}")
            out[ds.name][f"fit {fit_split}, score {score_split}"] = entry
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--quick", action="store_true", help="small subsets")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "metric.json")
    args = ap.parse_args(argv)
    sets = build_sets(args.sets, args.quick)
    result = run(sets, mdbd_config(), args.workers)
    write_json(args.out, {"quick": args.quick, "view_cells": VIEW_CELLS, "datasets": result})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
