"""Choose one descriptor combination for all sets together, on validation only.

Usage (from the repository root)::

    python -m bench.studies.select_descriptors [--quick] [--no-refine] [--geodesic] [--subjects 15 --poses 20]

Every subset of up to five blocks of :mod:`bench.studies.descriptors` (and a double weight on
``inertia``) is scored on the validation split of each set with
``(NN + 1-T + DCG) / 3 + 0.25 * NN(point-cloud queries -> mesh database)``; the
subset with the best mean over the sets wins. It is then reported on the test splits
next to the paper's kernel with its published weights and with flat weights
(la = lb = 1, n_r = 32, t = 20, w = 0.7, the best of the kernel study), and next to
the winner plus that flat-weight kernel. Results go to
bench/results/studies/descriptor_selection.json.

``--geodesic`` instead re-weighs the library's own blocks (:mod:`shapedb.signature.descriptor`,
version 3 layout): version 2's blocks and weights fixed, the two inner-distance
blocks ``geodesic`` and ``geodesic_mean`` at every weight pair of {0, 1, 2, 4}, the
same objective on the validation splits; the grid and the test-split figures of the
best go to bench/results/studies/descriptor_geodesic.json. That is how version 3 was chosen.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import decompose_all, format_table, log_margin, retrieval_scores, write_json
from bench.retrieval import build_sets
from bench.sets.datasets import Dataset
from bench.studies import descriptors as desc
from shapedb.config.core import MDBDConfig

POOL = ("radius", "d2c", "d2c_mean", "d1c", "inertia", "degree", "wwl", "walk")
RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


def _paper_flat(b: Any) -> np.ndarray:
    return desc.paper_features(b, n_r=32, t=20, w=0.7, la=1.0, lb=1.0)


def _blocks(ds: Dataset, split: str, mdbd: MDBDConfig, workers: int) -> tuple[Any, Any, Any]:
    sub = ds.split(split)
    m = decompose_all(sub.models, "mesh", mdbd, workers=workers)
    p = decompose_all(sub.models, "pointcloud", mdbd, workers=workers)
    keep = [i for i in range(len(sub)) if m[i] is not None and p[i] is not None]
    names = (*POOL, "paper", "paper_flat")
    return (
        desc.describe([m[i] for i in keep], names),  # type: ignore[misc]
        desc.describe([p[i] for i in keep], names),  # type: ignore[misc]
        np.asarray([sub.models[i].label for i in keep]),
    )


def _score(data: Any, weights: dict[str, float], scales: dict[str, float]) -> dict[str, float]:
    bm, bp, lab = data
    s = retrieval_scores(-desc.combined_distance(bm, bm, weights, scales), lab)
    x = retrieval_scores(-desc.combined_distance(bp, bm, weights, scales), lab)
    return {**s, "pc_to_mesh_nn": x["nn"]}


def select(sets: Sequence[Dataset], mdbd: MDBDConfig, workers: int) -> dict[str, Any]:
    """Validation-only choice of a block combination; test-split report."""
    desc.BLOCKS.setdefault("paper_flat", _paper_flat)
    val = {ds.name: _blocks(ds, "validation", mdbd, workers) for ds in sets}
    scales = {n: desc.block_scales(v[0]) for n, v in val.items()}
    trials = []
    for k in range(1, 6):
        for combo in itertools.combinations(POOL, k):
            for wi in (1.0, 2.0) if "inertia" in combo else (1.0,):
                w = {b: (wi if b == "inertia" else 1.0) for b in combo}
                objs = []
                for n, v in val.items():
                    s = _score(v, w, scales[n])
                    objs.append(
                        (s["nn"] + s["first_tier"] + s["dcg"]) / 3 + 0.25 * s["pc_to_mesh_nn"]
                    )
                trials.append((float(np.mean(objs)), w, objs))
    trials.sort(key=lambda t: -t[0])
    best = trials[0][1]
    methods = {
        "paper kernel (published weights)": {"paper": 1.0},
        "paper kernel, flat weights": {"paper_flat": 1.0},
        "chosen": best,
        "chosen + 2 x paper flat": {**best, "paper_flat": 2.0},
    }
    test_res: dict[str, Any] = {}
    for ds in sets:
        data = _blocks(ds, "test", mdbd, workers)
        rows = []
        for name, w in methods.items():
            s = _score(data, w, scales[ds.name])
            test_res.setdefault(ds.name, {})[name] = s
            rows.append(
                [name, s["nn"], s["first_tier"], s["second_tier"], s["dcg"], s["pc_to_mesh_nn"]]
            )
        print()
        print(
            format_table(
                f"{ds.name} test split ({len(data[2])} models); chosen: {'+'.join(best)}",
                ("descriptor", "NN", "1-T", "2-T", "DCG", "pc->mesh NN"),
                rows,
            )
        )
    return {
        "top_validation": [{"mean": t[0], "weights": t[1], "per_set": t[2]} for t in trials[:10]],
        "chosen": best,
        "test": test_res,
    }


def _library_blocks(
    ds: Dataset, split: str, mdbd: MDBDConfig, workers: int, version: int = 3
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], np.ndarray]:
    """Per-block vectors of the library's descriptor ``version``, each divided by its
    typical distance (unit weight, before the overall calibration)."""
    from shapedb.signature.descriptor import LAYOUTS, describe

    sub = ds.split(split)
    m = decompose_all(sub.models, "mesh", mdbd, workers=workers)
    p = decompose_all(sub.models, "pointcloud", mdbd, workers=workers)
    keep = [i for i in range(len(sub)) if m[i] is not None and p[i] is not None]

    def blocks(balls: list[Any]) -> dict[str, np.ndarray]:
        layout = LAYOUTS[version]
        calibration = np.log(10.0) / sum(b[3] for b in layout)
        f = np.stack([describe(b.decomposition().graph, version) for b in balls])
        out, at = {}, 0
        for name, size, _, weight in layout:
            out[name] = f[:, at : at + size] / (weight * calibration)
            at += size
        return out

    labels = np.asarray([sub.models[i].label for i in keep])
    return blocks([m[i] for i in keep]), blocks([p[i] for i in keep]), labels


def _weighted_score(data: Any, weights: dict[str, float]) -> dict[str, float]:
    bm, bp, lab = data

    def dist(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> np.ndarray:
        return sum(w * desc.l1_matrix(a[k], b[k]) for k, w in weights.items() if w)

    dmm, dpm = dist(bm, bm), dist(bp, bm)
    s = retrieval_scores(-dmm, lab)
    return {
        **s,
        "pc_to_mesh_nn": retrieval_scores(-dpm, lab)["nn"],
        "mesh_margin": log_margin(dmm, lab),
        "pc_margin": log_margin(dpm, lab),
    }


def select_geodesic(sets: Sequence[Dataset], mdbd: MDBDConfig, workers: int) -> dict[str, Any]:
    """Weights of the two inner-distance blocks on top of version 2, on validation."""
    from shapedb.signature.descriptor import LAYOUTS

    base = {name: weight for name, _, _, weight in LAYOUTS[2]}
    val = {ds.name: _library_blocks(ds, "validation", mdbd, workers) for ds in sets}
    grid = []
    for a, b in itertools.product((0.0, 1.0, 2.0, 4.0), repeat=2):
        w = {**base, "geodesic": a, "geodesic_mean": b}
        per_set = []
        for v in val.values():
            s = _weighted_score(v, w)
            per_set.append((s["nn"] + s["first_tier"] + s["dcg"]) / 3 + 0.25 * s["pc_to_mesh_nn"])
        grid.append({"geodesic": a, "geodesic_mean": b, "mean": float(np.mean(per_set)),
                     "per_set": per_set})  # fmt: skip
    grid.sort(key=lambda g: -g["mean"])
    print(
        format_table(
            "validation objective, version 2 + inner-distance blocks",
            ("geodesic", "geodesic_mean", "objective", *[ds.name for ds in sets]),
            [[g["geodesic"], g["geodesic_mean"], g["mean"], *g["per_set"]] for g in grid],
        )
    )
    best = {**base, "geodesic": grid[0]["geodesic"], "geodesic_mean": grid[0]["geodesic_mean"]}
    test: dict[str, Any] = {}
    for ds in sets:
        data = _library_blocks(ds, "test", mdbd, workers)
        rows = []
        for label, w in (("version 2", {**base}), ("best on validation", best)):
            s = _weighted_score(data, w)
            test.setdefault(ds.name, {})[label] = s
            rows.append([label, s["nn"], s["first_tier"], s["dcg"], s["pc_to_mesh_nn"]])
        print()
        print(
            format_table(
                f"{ds.name} test split", ("weights", "NN", "1-T", "DCG", "pc->mesh NN"), rows
            )
        )
    return {"grid": grid, "chosen": best, "test": test}


def select_sorted(sets: Sequence[Dataset], mdbd: MDBDConfig, workers: int) -> dict[str, Any]:
    """Version 4: version 3 with the Eq. 1 block's walk averages sorted; its weight.

    Walk averages are sorted within groups of balls of near-equal radius
    (``shapedb.signature.descriptor.WALK_TIE``: each within that fraction of the previous one's
    radius; 1 sorts them all), tried at 0.02, 0.05, 0.1 and 1. The ``paper_sorted``
    block's typical distance is measured for each as every block's was (geometric
    mean over the validation sets of its median pairwise distance); its weight is
    chosen from {4, 6, 8} by the objective on the validation splits, the other
    weights are version 3's. Version 3 itself is scored alongside, and every setting
    also reports the mean log margin of mesh and cloud queries
    (``log(d(nearest same class) / d(nearest other class))``, lower is better).
    """
    import shapedb.signature.descriptor as sd

    val3 = {ds.name: _library_blocks(ds, "validation", mdbd, workers, 3) for ds in sets}
    base = {name: weight for name, _, _, weight in sd.LAYOUTS[3]}
    settings: list[tuple[str, Any, dict[str, float]]] = [("version 3", val3, base)]
    typicals = {}
    saved = sd.WALK_TIE
    try:
        for tie in (0.02, 0.05, 0.1, 1.0):
            sd.WALK_TIE = tie
            val4 = {ds.name: _library_blocks(ds, "validation", mdbd, workers, 4) for ds in sets}
            medians = []
            for bm, _, _ in val4.values():
                x = bm["paper_sorted"] * sd.PAPER_SORTED_TYPICAL
                medians.append(np.median(desc.l1_matrix(x, x)[np.triu_indices(len(x), 1)]))
            typical = float(np.exp(np.mean(np.log(medians))))
            typicals[tie] = typical
            for bm, bp, _ in val4.values():
                for b in (bm, bp):
                    b["paper_sorted"] = b["paper_sorted"] * sd.PAPER_SORTED_TYPICAL / typical
            for weight in (4.0, 6.0, 8.0):
                w = {("paper_sorted" if k == "paper" else k): (weight if k == "paper" else v)
                     for k, v in base.items()}  # fmt: skip
                settings.append((f"tie {tie:g}, weight {weight:g}", val4, w))
    finally:
        sd.WALK_TIE = saved
    grid = []
    for label, data, w in settings:
        per_set, margins = [], []
        for v in data.values():
            s = _weighted_score(v, w)
            per_set.append((s["nn"] + s["first_tier"] + s["dcg"]) / 3 + 0.25 * s["pc_to_mesh_nn"])
            margins += [s["mesh_margin"], s["pc_margin"]]
        grid.append({"setting": label, "mean": float(np.mean(per_set)),
                     "per_set": per_set, "margins": margins})  # fmt: skip
    print(f"paper_sorted typical distance (validation) by tie: {typicals}")
    print(
        format_table(
            "validation objective and log margins (mesh, cloud per set), version 3 vs 4",
            (
                "setting",
                "objective",
                *[ds.name for ds in sets],
                *[f"{ds.name} {q}" for ds in sets for q in ("mesh", "cloud")],
            ),  # fmt: skip
            [[g["setting"], g["mean"], *g["per_set"], *g["margins"]] for g in grid],
        )
    )
    return {"typical": {str(k): v for k, v in typicals.items()}, "grid": grid}


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.select_descriptors")
    ap.add_argument("--datasets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-refine", action="store_true")
    ap.add_argument("--subjects", type=int, default=15)
    ap.add_argument("--poses", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--geodesic", action="store_true", help="weigh the inner-distance blocks")
    ap.add_argument("--sorted-walks", action="store_true", help="version 4's sorted Eq. 1 block")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    default = "descriptor_geodesic.json" if args.geodesic else "descriptor_selection.json"
    if args.sorted_walks:
        default = "descriptor_sorted.json"
    out = args.out or RESULTS / default
    mdbd = MDBDConfig()
    if args.quick:
        mdbd = dataclasses.replace(mdbd, resolution=64, n_balls=256)
    if args.no_refine:
        mdbd = dataclasses.replace(mdbd, refine=False)
    sets = build_sets(args.datasets, args.quick, args.subjects, args.poses)
    run = select_geodesic if args.geodesic else select
    if args.sorted_walks:
        run = select_sorted
    write_json(out, run(sets, mdbd, args.workers))
    print(f"\nwritten {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
