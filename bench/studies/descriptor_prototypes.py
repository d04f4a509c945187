"""Descriptor prototypes and stability, beside the paper's kernel and D2.

Usage (from the repository root; the data sets of :mod:`bench.retrieval`)::

    python -m bench.studies.descriptor_prototypes --descriptors     # run_descriptors
    python -m bench.studies.descriptor_prototypes --refine-shift    # run_refine_shift

``run_descriptors``
    Every block of :mod:`bench.studies.descriptors` alone and in combinations, on the
    validation split (mesh vs mesh retrieval and point-cloud queries against the mesh
    database); a greedy forward selection of blocks on validation; then the chosen
    combinations, the paper's kernel and D2 on the test split.
(The stability probes that began here are the product bench :mod:`bench.stability`.)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import Balls, decompose_all, format_table, retrieval_scores
from bench.sets.datasets import Dataset, mesh_arrays
from bench.studies import descriptors as desc
from bench.support.baselines import D2Config, d2_descriptor, l1_similarity
from shapedb.config.core import KernelConfig, MDBDConfig

__all__ = ["CANDIDATES", "main", "run_descriptors", "run_refine_shift"]

#: Hand-made combinations (equal weights after scaling each block by its median distance).
CANDIDATES: dict[str, tuple[str, ...]] = {
    "geom": ("d2c", "radius", "inertia"),
    "geom+d1": ("d2c", "d1c", "radius", "inertia"),
    "geom+graph": ("d2c", "radius", "inertia", "degree", "spectrum"),
    "geom+wwl": ("d2c", "radius", "inertia", "wwl"),
    "geom+wwl+walk": ("d2c", "radius", "inertia", "wwl", "walk"),
    "all": ("d2c", "d2c_mean", "d1c", "radius", "inertia", "degree", "spectrum", "wwl", "walk"),
    # Chosen on the validation splits of all three sets together (best mean objective).
    "chosen": ("radius", "d2c", "d2c_mean", "inertia", "walk"),
}


def _eval(
    q: Mapping[str, NDArray[np.float64]],
    db: Mapping[str, NDArray[np.float64]],
    names: Sequence[str],
    scales: Mapping[str, float],
    labels: NDArray[Any],
) -> dict[str, float]:
    d = desc.combined_distance(q, db, dict.fromkeys(names, 1.0), scales)
    return retrieval_scores(-d, labels)


def _objective(s: Mapping[str, float]) -> float:
    return (s["nn"] + s["first_tier"] + s["dcg"]) / 3


def _both(ds: Dataset, mdbd: MDBDConfig, workers: int) -> tuple[Dataset, list[Balls], list[Balls]]:
    mesh = decompose_all(ds.models, "mesh", mdbd, workers=workers)
    pc = decompose_all(ds.models, "pointcloud", mdbd, workers=workers)
    keep = [i for i in range(len(ds)) if mesh[i] is not None and pc[i] is not None]
    sub = Dataset(ds.name, tuple(ds.models[i] for i in keep))
    return sub, [mesh[i] for i in keep], [pc[i] for i in keep]  # type: ignore[misc]


def run_descriptors(ds: Dataset, mdbd: MDBDConfig, *, workers: int = 2) -> dict[str, Any]:
    """Blocks and combinations on validation; chosen ones, paper kernel and D2 on test."""
    val, vm, vp = _both(ds.split("validation"), mdbd, workers)
    labels = val.labels
    bm, bp = desc.describe(vm), desc.describe(vp)
    scales = desc.block_scales(bm)
    ms_per_model = {}
    for name in desc.BLOCKS:
        t0 = time.perf_counter()
        for b in vm[:20]:
            desc.block(name, b)
        ms_per_model[name] = (time.perf_counter() - t0) / min(len(vm), 20) * 1e3
    rows: list[list[Any]] = []
    results: dict[str, dict[str, float]] = {}

    def record(name: str, names: Sequence[str]) -> None:
        s = _eval(bm, bm, names, scales, labels)
        x = _eval(bp, bm, names, scales, labels)
        results[name] = {**s, "pc_to_mesh_nn": x["nn"]}
        rows.append([name, s["nn"], s["first_tier"], s["dcg"], x["nn"], x["dcg"]])

    for b in desc.BLOCKS:
        record(b, (b,))
    for name, names in CANDIDATES.items():
        record(name, names)
    # Greedy forward selection on validation (mesh retrieval + pc->mesh NN).
    chosen: list[str] = []
    best = -1.0
    pool = [b for b in desc.BLOCKS if b != "paper"]
    while pool and len(chosen) < 6:
        trial = {}
        for b in pool:
            s = _eval(bm, bm, chosen + [b], scales, labels)
            x = _eval(bp, bm, chosen + [b], scales, labels)
            trial[b] = _objective(s) + 0.5 * x["nn"]
        b, v = max(trial.items(), key=lambda kv: kv[1])
        if v <= best + 1e-4:
            break
        best = v
        chosen.append(b)
        pool.remove(b)
    greedy = "greedy:" + "+".join(chosen)
    record(greedy, chosen)
    print()
    print(
        format_table(
            f"descriptor prototypes, {ds.name} validation split ({len(val)} models)",
            ("descriptor", "NN", "1-T", "DCG", "pc->mesh NN", "pc->mesh DCG"),
            rows,
        )
    )

    # Test split: the candidates and the greedy choice, the paper kernel, D2.
    test, tm, tp = _both(ds.split("test"), mdbd, workers)
    tl = test.labels
    qm, qp = desc.describe(tm), desc.describe(tp)
    test_rows: list[list[Any]] = []
    test_res: dict[str, dict[str, float]] = {}
    combos = {**CANDIDATES, greedy: tuple(chosen), "paper kernel (Eq. 2)": ("paper",)}
    for name, names in combos.items():
        s = _eval(qm, qm, names, scales, tl)
        x = _eval(qp, qm, names, scales, tl)
        p = _eval(qp, qp, names, scales, tl)
        test_res[name] = {**s, "pc_to_mesh_nn": x["nn"], "pc_to_pc_nn": p["nn"]}
        test_rows.append([name, s["nn"], s["first_tier"], s["dcg"], x["nn"], p["nn"]])
    dd = np.stack([d2_descriptor(*mesh_arrays(m), D2Config(n_pairs=2**18)) for m in test.models])
    s = retrieval_scores(l1_similarity(dd), tl)
    test_res["D2"] = s
    test_rows.append(["D2 (meshes)", s["nn"], s["first_tier"], s["dcg"], None, None])
    print()
    print(
        format_table(
            f"descriptors on the {ds.name} test split ({len(test)} models; block scales from validation)",
            ("descriptor", "NN", "1-T", "DCG", "pc->mesh NN", "pc->pc NN"),
            test_rows,
        )
    )
    return {
        "validation": results,
        "greedy": chosen,
        "scales": scales,
        "ms_per_model": ms_per_model,
        "test": test_res,
    }


def run_refine_shift(
    ds: Dataset, mdbd: MDBDConfig, kcfg: KernelConfig, *, workers: int = 2, n: int = 24
) -> dict[str, Any]:
    """Sub-cell shift with and without off-grid refinement, on ``n`` test models.

    For each setting: the paper kernel between a model and its copy shifted by
    (0.37, 0.21, 0.43) cells (mean), against the mean kernel between different
    models of the same class; and how often the shifted copy ranks its original first
    among the ``n`` originals, for the paper kernel and the prototype combinations.
    """
    import dataclasses

    test = ds.split("test")
    step = max(1, len(test) // n)
    sub = Dataset(ds.name, test.models[::step][:n])
    methods = {
        "paper kernel": ("paper",),
        **{k: CANDIDATES[k] for k in ("geom", "chosen", "all")},
    }
    out: dict[str, Any] = {}
    rows = []
    for refine in (False, True):
        cfg = dataclasses.replace(mdbd, refine=refine)
        orig = decompose_all(sub.models, "mesh", cfg, workers=workers)
        shift = decompose_all(sub.models, "mesh_shift", cfg, workers=workers)
        keep = [i for i in range(len(sub)) if orig[i] is not None and shift[i] is not None]
        o = desc.describe([orig[i] for i in keep])  # type: ignore[misc]
        s = desc.describe([shift[i] for i in keep])  # type: ignore[misc]
        lab = np.asarray([sub.models[i].label for i in keep])
        k_os = np.exp(-kcfg.lam * desc.l1_matrix(s["paper"], o["paper"]))
        same = (lab[:, None] == lab[None, :]) & ~np.eye(len(lab), dtype=bool)
        res: dict[str, float] = {
            "k_model_vs_shifted": float(np.diag(k_os).mean()),
            "k_same_class": float(k_os[same].mean()) if same.any() else float("nan"),
        }
        scales = desc.block_scales(o)
        for name, names in methods.items():
            d = desc.combined_distance(s, o, dict.fromkeys(names, 1.0), scales)
            res[name] = float(np.mean(np.argmin(d, axis=1) == np.arange(len(keep))))
        out["refine" if refine else "no_refine"] = {"models": len(keep), **res}
        rows.append(["refine" if refine else "no refine", len(keep), *res.values()])
    print()
    print(
        format_table(
            f"sub-cell shift, {ds.name}: k(model, shifted) and copy-ranks-original-first",
            ("setting", "models", "k(m,shift)", "k same class", *methods),
            rows,
        )
    )
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    from pathlib import Path

    from bench.common import mdbd_config
    from bench.retrieval import build_sets

    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.descriptor_prototypes", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--datasets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--quick", action="store_true", help="small subsets and a coarse grid")
    ap.add_argument("--descriptors", action="store_true", help="every block, alone and combined")
    ap.add_argument("--refine-shift", action="store_true", help="sub-cell shift, refined or not")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--out",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "results" / "studies" / "prototypes.json",
    )
    args = ap.parse_args(argv)
    base = MDBDConfig(resolution=64, n_balls=256) if args.quick else MDBDConfig()
    mdbd = mdbd_config(base)
    report: dict[str, Any] = {}
    for ds in build_sets(args.datasets, args.quick):
        entry: dict[str, Any] = {}
        if args.descriptors:
            entry["descriptors"] = run_descriptors(ds, mdbd, workers=args.workers)
        if args.refine_shift:
            entry["refine_shift"] = run_refine_shift(ds, mdbd, KernelConfig(), workers=args.workers)
        report[ds.name] = entry
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1) + "\n")
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
