"""Issue 6: choose one descriptor combination for all sets together, on validation only.

Usage (from the repository root)::

    python -m bench.select_descriptors [--quick] [--no-refine] [--subjects 10 --poses 10]

Every subset of up to five blocks of :mod:`bench.descriptors` (and a double weight on
``inertia``) is scored on the validation split of each set with
``(NN + 1-T + DCG) / 3 + 0.25 * NN(point-cloud queries -> mesh database)``; the
subset with the best mean over the sets wins. It is then reported on the test splits
next to the paper's kernel with its published weights and with flat weights
(la = lb = 1, n_r = 32, t = 20, w = 0.7, the best of the kernel study), and next to
the winner plus that flat-weight kernel. Results go to
bench/results/descriptor_selection.json.
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

from bench import descriptors as desc
from bench.common import decompose_all, format_table, retrieval_scores, write_json
from bench.datasets import Dataset
from bench.issue6 import _scales
from bench.retrieval import build_sets
from shapedb.config import MDBDConfig

POOL = ("radius", "d2c", "d2c_mean", "d1c", "inertia", "degree", "wwl", "walk")
RESULTS = Path(__file__).resolve().parent / "results"


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
    scales = {n: _scales(v[0]) for n, v in val.items()}
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


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.select_descriptors")
    ap.add_argument("--datasets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-refine", action="store_true")
    ap.add_argument("--subjects", type=int, default=10)
    ap.add_argument("--poses", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "descriptor_selection.json")
    args = ap.parse_args(argv)
    mdbd = MDBDConfig()
    if args.quick:
        mdbd = dataclasses.replace(mdbd, resolution=64, n_balls=256)
    if args.no_refine:
        mdbd = dataclasses.replace(mdbd, refine=False)
    sets = build_sets(args.datasets, args.quick, args.subjects, args.poses)
    write_json(args.out, select(sets, mdbd, args.workers))
    print(f"\nwritten {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
