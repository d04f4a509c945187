"""The paper's Table 1 on real and generated data: graph CNNs on the MDBD contact graph.

Usage (from the repository root)::

    python -m bench.classify --quick      # small graphs, few epochs: well under 30 min
    python -m bench.classify              # the full run (hours on 2 CPU cores)

For each data set, k-fold cross-validation stratified by class; inside every fold 15 %
of the training models are held out to choose the epoch (never the test fold). For
each convolution (TAGConv, ARMAConv, SplineConv), with and without random rotations,
the table gives the test accuracy (mean and standard deviation over the folds) on the
meshes' graphs and, for the same mesh-trained models, on the graphs of point clouds
of the same shapes (20 % of the vertices); the parameter count; the seconds per epoch;
and the peak memory of training (growth of the resident set, each setting in a fresh
process; on a GPU, torch's peak allocation). The baseline, in the same run and on the
same folds, is a 1-nearest-neighbour classifier on the Eq. 3 kernel.

Data sets: ``capod`` (../shared/data/capod, 15 classes x 12 meshes) and ``generated``
(families of machined parts and jointed figures from :mod:`shapedb.examples`, each
class a family with varied proportions). Decompositions come from the shared cache of
:mod:`bench.common` (``bench/results/cache``, git-ignored). Results go to
``bench/results/classify.json`` and a training curve per convolution to
``bench/results/classify_<set>_<conv>.png``.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import decompose_all, format_table, write_json
from bench.datasets import Dataset, Model, capod, split_by_model
from shapedb.config import KernelConfig, MDBDConfig

RESULTS = Path(__file__).resolve().parent / "results"
COLUMNS = (
    "network",
    "rotations",
    "acc mesh",
    "+-",
    "acc points",
    "+-",
    "params (M)",
    "s/epoch",
    "peak MB",
)


# --------------------------------------------------------------------------------------
# Data
# --------------------------------------------------------------------------------------


def generated(per_class: int, classes: int = 10) -> Dataset:
    """``classes`` procedural families from shapedb.examples, ``per_class`` shapes each.

    Every machined-part kind of ``shapedb.examples.PART_KINDS`` is a class (seeds vary
    its dimensions and features); the remaining classes are jointed-figure subjects
    (each with its own limb proportions) in ``per_class`` poses.
    """
    from shapedb import examples

    kinds = tuple(examples.PART_KINDS)[:classes]
    models = [Model(f"{k}_{i:03d}", k, f"part:{k}:{i}") for k in kinds for i in range(per_class)]
    for s in range(classes - len(kinds)):
        label = f"figure{s:02d}"
        models += [Model(f"{label}_{p:03d}", label, f"figure:{s}:{p}") for p in range(per_class)]
    return Dataset("generated", split_by_model(models))


def graphs_of(
    ds: Dataset, config: MDBDConfig, n_balls: int, workers: int, points: bool = True
) -> dict[str, Any]:
    """Mesh and point-cloud graphs of every model decomposed in both (failures dropped).

    Without ``points`` the point-cloud entries are the mesh graphs (not evaluated).
    """
    mesh = decompose_all(ds.models, "mesh", config, workers=workers)
    pc = decompose_all(ds.models, "pointcloud", config, workers=workers) if points else mesh
    keep = [
        i
        for i, (a, b) in enumerate(zip(mesh, pc, strict=True))
        if a is not None and b is not None and len(a.radii) > 1 and len(b.radii) > 1
    ]
    if len(keep) < len(ds.models):
        print(f"  {len(ds.models) - len(keep)} model(s) without both decompositions are left out")
    trunc = lambda b: b.truncate(n_balls)  # noqa: E731 - the greedy MDBD prefix
    return {
        "points": points,
        "names": [ds.models[i].name for i in keep],
        "labels": [ds.models[i].label for i in keep],
        "mesh": [trunc(mesh[i]) for i in keep],
        "pointcloud": [trunc(pc[i]) for i in keep],
    }


def folds_of(labels: Sequence[str], k: int, seed: int = 0) -> list[NDArray[np.int64]]:
    """``k`` disjoint test folds, stratified by class."""
    from query.gnn import stratified_split

    return stratified_split(labels, [1.0 / k] * k, seed=seed)


# --------------------------------------------------------------------------------------
# Baseline: 1-NN on the Eq. 3 kernel
# --------------------------------------------------------------------------------------


def knn_baseline(data: dict[str, Any], folds: list[NDArray[np.int64]]) -> dict[str, Any]:
    """Accuracy of 1-nearest-neighbour on k = exp(-lam d) (Eq. 3), mesh and point cloud."""
    from shapedb.kernel import features, kernel

    cfg = KernelConfig()
    t0 = time.perf_counter()
    fm = np.stack([features(b.decomposition(), cfg) for b in data["mesh"]])
    fp = np.stack([features(b.decomposition(), cfg) for b in data["pointcloud"]])
    y = np.asarray(data["labels"])
    acc: dict[str, list[float]] = {"mesh": [], "pointcloud": []}
    for test in folds:
        train = np.setdiff1d(np.arange(len(y)), test)
        for name, f in (("mesh", fm), ("pointcloud", fp)) if data["points"] else (("mesh", fm),):
            sims = np.stack([kernel(f[i], fm[train], cfg) for i in test])
            pred = y[train][sims.argmax(axis=1)]
            acc[name].append(float(np.mean(pred == y[test])))
    return {
        "network": "1-NN, Eq. 3 kernel",
        "rotations": "-",
        "accuracy": acc,
        "parameters": 0,
        "seconds_per_epoch": None,
        "peak_mb": None,
        "seconds": time.perf_counter() - t0,
    }


# --------------------------------------------------------------------------------------
# Graph CNNs, one setting per fresh process (for a clean memory peak)
# --------------------------------------------------------------------------------------


def _rss_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return float(line.split()[1]) / 1024
    return float("nan")


def run_setting(
    data: dict[str, Any],
    folds: list[NDArray[np.int64]],
    conv: str,
    rotate: bool,
    options: dict[str, Any],
    curve: str | None,
) -> dict[str, Any]:
    """Train and test one convolution on every fold (runs in a worker process)."""
    import torch

    from query.classify import GraphClassifier
    from query.gnn import import_torch, plot_history

    import_torch()
    torch.set_num_threads(int(options.pop("threads", 0)) or torch.get_num_threads())
    y = list(data["labels"])
    acc: dict[str, list[float]] = {"mesh": [], "pointcloud": []}
    secs, best = [], []
    base = _rss_mb()
    cuda = torch.cuda.is_available() and options.get("device") in (None, "cuda")
    t0 = time.perf_counter()
    model = None
    for f, test in enumerate(folds):
        train = np.setdiff1d(np.arange(len(y)), test)
        model = GraphClassifier(conv, rotate=rotate, seed=f, **options)
        model.fit([data["mesh"][i] for i in train], [y[i] for i in train])
        for name in ("mesh", "pointcloud") if data["points"] else ("mesh",):
            acc[name].append(model.score([data[name][i] for i in test], [y[i] for i in test]))
        secs.append(float(np.mean(model.history_["seconds"])))
        best.append(model.best_epoch_ + 1)
        print(
            f"    {conv:6s} rotate={rotate!s:5s} fold {f + 1}/{len(folds)}: "
            f"mesh {acc['mesh'][-1]:.3f}  points {(acc['pointcloud'] or [np.nan])[-1]:.3f}  "
            f"({secs[-1]:.2f} s/epoch)",
            flush=True,
        )
    peak = (
        torch.cuda.max_memory_allocated() / 2**20
        if cuda
        else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - base
    )
    if curve and model is not None:
        plot_history(model.history_, curve, title=f"{conv}, rotate={rotate}, last fold")
    return {
        "network": conv,
        "rotations": "yes" if rotate else "no",
        "accuracy": acc,
        "parameters": int(model.n_parameters_) if model else 0,
        "seconds_per_epoch": float(np.mean(secs)),
        "peak_mb": float(peak),
        "best_epochs": best,
        "seconds": time.perf_counter() - t0,
    }


def run_set(name: str, data: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
    """Every setting on one data set; prints and returns its table."""
    folds = folds_of(data["labels"], args.folds)
    print(
        f"  {len(data['labels'])} models, {len(set(data['labels']))} classes, "
        f"{args.folds} folds, up to {args.balls} balls per graph",
        flush=True,
    )
    rows = [knn_baseline(data, folds)]
    options = {"epochs": args.epochs, "batch_size": args.batch_size, "threads": args.threads}
    for conv in args.convs:
        for rotate in (True, False):
            curve = str(RESULTS / f"classify_{name}_{conv}.png") if rotate else None
            ctx = get_context("spawn")
            with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
                rows.append(
                    pool.submit(
                        run_setting, data, folds, conv, rotate, dict(options), curve
                    ).result()
                )
    table = []
    for r in rows:
        m, p = np.asarray(r["accuracy"]["mesh"]), np.asarray(r["accuracy"]["pointcloud"])
        table.append(
            [
                r["network"],
                r["rotations"],
                100 * m.mean(),
                100 * m.std(),
                100 * p.mean() if len(p) else None,
                100 * p.std() if len(p) else None,
                r["parameters"] / 1e6,
                r["seconds_per_epoch"],
                r["peak_mb"],
            ]
        )
    print(
        format_table(
            f"Table 1 on {name}: accuracy % over {args.folds} folds (models trained on meshes)",
            COLUMNS,
            table,
        ),
        flush=True,
    )
    return {
        "models": len(data["labels"]),
        "classes": len(set(data["labels"])),
        "folds": args.folds,
        "rows": rows,
    }


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="small graphs and few epochs")
    p.add_argument("--sets", nargs="+", default=["capod", "generated"])
    p.add_argument("--convs", nargs="+", default=["tag", "arma", "spline"])
    p.add_argument("--folds", type=int, default=None)
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--balls", type=int, default=None, help="graph size n (largest balls)")
    p.add_argument(
        "--per-class",
        type=int,
        default=None,
        help="shapes per class (generated: 40 quick, 100 full; capod: all 12)",
    )
    p.add_argument("--batch-size", type=int, default=16)
    p.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch threads (0: torch's default; 1 avoids contention on 2 cores)",
    )
    p.add_argument(
        "--generated-points",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="also test the generated set on point clouds (default: not with --quick)",
    )
    p.add_argument("--workers", type=int, default=2, help="decomposition processes")
    p.add_argument("--out", type=Path, default=RESULTS / "classify.json")
    args = p.parse_args(argv)
    q = args.quick
    args.folds = args.folds or (3 if q else 4)
    args.epochs = args.epochs or (25 if q else 100)
    args.balls = args.balls or (128 if q else 512)
    per_class = args.per_class or (40 if q else 100)
    # capod as bench.retrieval decomposes it (shared cache), without off-grid refinement;
    # the generated set at a coarser grid so that 1000+ shapes decompose in minutes.
    configs = {
        "capod": MDBDConfig(refine=False),
        "generated": MDBDConfig(resolution=64, n_balls=256, refine=False),
    }
    if args.generated_points is None:
        args.generated_points = not q
    out: dict[str, Any] = {
        "settings": {k: v for k, v in vars(args).items() if k != "out"},
        "sets": {},
    }
    out["settings"]["cpu_count"] = os.cpu_count()
    for name in args.sets:
        t0 = time.perf_counter()
        print(f"== {name}", flush=True)
        if name == "capod":
            ds = capod().head(per_class=args.per_class) if args.per_class else capod()
        else:
            ds = generated(per_class)
        points = name == "capod" or args.generated_points
        data = graphs_of(ds, configs[name], args.balls, args.workers, points)
        res = run_set(name, data, args)
        res["point_clouds_tested"] = points
        res["config"] = configs[name].__dict__
        res["seconds"] = time.perf_counter() - t0
        out["sets"][name] = res
        write_json(args.out, out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
