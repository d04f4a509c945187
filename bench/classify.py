"""The paper's Table 1 on real and generated data: graph CNNs on the MDBD contact graph.

Usage (from the repository root)::

    python -m bench.classify --quick      # small sets, few epochs: well under 30 min
    python -m bench.classify              # the full run (about an hour on 2 shared cores)

Learning curves of every classifier ``shapedb train`` chooses among (k-NN, linear,
boosting, graph CNNs) and the held-out check of the chosen one are in
:mod:`bench.classify_curves`.

Evaluation. ``capod`` (15 classes x 12 meshes) uses k-fold cross-validation
stratified by class; inside every fold 15 % of the training models are held out to
choose the epoch (never the test fold). The ``generated`` set (12 classes x 100) uses
one fixed stratified split, 60 % train / 15 % validation / 25 % test, the epoch chosen
on validation; ``--seeds`` repeats the training with other seeds on the same split.
The spread column is the standard deviation over folds (capod) or seeds (generated);
with one seed it is the binomial standard error of the test accuracy.

For each convolution (TAGConv, ARMAConv, SplineConv), with and without random
rotations, the table gives the test accuracy on the meshes' graphs and, for the same
mesh-trained models, on the graphs of point clouds of the same shapes (20 % of the
vertices); the parameter count; the median over folds of the seconds per epoch
(training plus validation pass, single torch thread, on a shared machine: the load
average is recorded); and the peak memory of training (growth of the resident set,
each setting in a fresh process; on a GPU, torch's peak allocation). The baseline, in
the same run and on the same splits, is a 1-nearest-neighbour classifier on the
Eq. 3 kernel, its gallery every non-test model.

Data sets: ``capod`` (../shared/data/capod) and ``generated`` (the machined-part
families of :mod:`shapedb.examples`, one class per kind, seeds varying proportions and
features; ``--classes`` above 12 adds jointed-figure subjects). Decompositions come
from the shared cache of :mod:`bench.common` (``bench/results/cache``, git-ignored).
Results go to ``bench/results/classify.json`` (capod) and
``bench/results/classify_<set>.json`` (other sets), training curves (last fold or
seed) to ``bench/results/classify_<set>_<conv>[_rot].png``.
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
from bench.sets.datasets import Dataset, Model, capod, split_by_model
from shapedb.config.core import Config, MDBDConfig

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
    "best ep",
)
#: Fractions of the fixed split (train, validation, test).
FIXED_SPLIT = (0.6, 0.15, 0.25)
Split = dict[str, Any]
"""``{"train": idx, "val": idx or None, "test": idx, "seed": int}`` (int64 index arrays)."""


# --------------------------------------------------------------------------------------
# Data
# --------------------------------------------------------------------------------------


def generated(per_class: int, classes: int = 12) -> Dataset:
    """``classes`` procedural families from shapedb.examples, ``per_class`` shapes each.

    Every machined-part kind of ``shapedb.examples.PART_KINDS`` is a class (seeds vary
    its dimensions and features); classes beyond those are jointed-figure subjects
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
    ds: Dataset,
    config: MDBDConfig,
    n_balls: int,
    workers: int,
    points: bool | Sequence[int] | NDArray[np.int64] = True,
) -> dict[str, Any]:
    """Mesh and point-cloud graphs of the models (failures dropped).

    Parameters
    ----------
    points : bool or sequence of int
        Decompose the point clouds of every model (True), of none (False), or of
        these model indices only (e.g. a test split); the others' entries are None.

    Returns
    -------
    dict
        ``names``, ``labels``, ``mesh`` (Balls), ``pointcloud`` (Balls or None),
        ``points`` (whether any point cloud is there) and ``kept`` (indices into
        ``ds.models`` of the entries).
    """
    n = len(ds.models)
    if isinstance(points, bool):
        want = np.arange(n) if points else np.zeros(0, dtype=np.int64)
    else:
        want = np.asarray(points, dtype=np.int64)
    mesh = decompose_all(ds.models, "mesh", config, workers=workers)
    pc: list[Any] = [None] * n
    if len(want):
        got = decompose_all([ds.models[i] for i in want], "pointcloud", config, workers=workers)
        for i, b in zip(want.tolist(), got, strict=True):
            pc[i] = b
    need = set(want.tolist())
    ok = lambda b: b is not None and len(b.radii) > 1  # noqa: E731
    keep = [i for i in range(n) if ok(mesh[i]) and (i not in need or ok(pc[i]))]
    if len(keep) < n:
        print(f"  {n - len(keep)} model(s) without their decompositions are left out")
    trunc = lambda b: None if b is None else b.truncate(n_balls)  # noqa: E731 - MDBD prefix
    return {
        "points": bool(len(want)),
        "names": [ds.models[i].name for i in keep],
        "labels": [ds.models[i].label for i in keep],
        "mesh": [trunc(mesh[i]) for i in keep],
        "pointcloud": [trunc(pc[i]) for i in keep],
        "kept": keep,
    }


def folds_of(labels: Sequence[str], k: int, seed: int = 0) -> list[NDArray[np.int64]]:
    """``k`` disjoint test folds, stratified by class."""
    from query.learn.gnn import stratified_split

    return stratified_split(labels, [1.0 / k] * k, seed=seed)


def kfold_splits(labels: Sequence[str], k: int, seed: int = 0) -> list[Split]:
    """k-fold splits; validation is drawn from each training part by the classifier."""
    n = len(labels)
    return [
        {"train": np.setdiff1d(np.arange(n), t), "val": None, "test": t, "seed": f}
        for f, t in enumerate(folds_of(labels, k, seed))
    ]


def fixed_splits(labels: Sequence[str], seeds: int, seed: int = 0) -> list[Split]:
    """One stratified train / validation / test split, trained with ``seeds`` seeds."""
    from query.learn.gnn import stratified_split

    tr, va, te = stratified_split(labels, FIXED_SPLIT, seed=seed)
    return [{"train": tr, "val": va, "test": te, "seed": s} for s in range(seeds)]


def _remap(splits: list[Split], kept: Sequence[int]) -> list[Split]:
    """Splits over ``ds.models`` indices re-expressed over the kept entries."""
    new = {old: k for k, old in enumerate(kept)}
    out = []
    for s in splits:
        m = {
            key: (
                None
                if s[key] is None
                else np.asarray([new[i] for i in s[key] if i in new], dtype=np.int64)
            )
            for key in ("train", "val", "test")
        }
        out.append({**m, "seed": s["seed"]})
    return out


# --------------------------------------------------------------------------------------
# Baseline: 1-NN on the Eq. 3 kernel
# --------------------------------------------------------------------------------------


def knn_baseline(data: dict[str, Any], splits: list[Split]) -> dict[str, Any]:
    """Accuracy of 1-nearest-neighbour on k = exp(-lam d) (Eq. 3), mesh and point cloud.

    The gallery is every non-test model (train and validation: the kernel has nothing
    to select); point-cloud queries are matched against the mesh gallery.
    """
    from shapedb.signature.kernel import features, kernel

    cfg = Config()
    t0 = time.perf_counter()
    feat = lambda b: None if b is None else features(b.decomposition(), cfg)  # noqa: E731
    fm = np.stack([features(b.decomposition(), cfg) for b in data["mesh"]])
    fp = [feat(b) for b in data["pointcloud"]]
    y = np.asarray(data["labels"])
    acc: dict[str, list[float]] = {"mesh": [], "pointcloud": []}
    seen: set[bytes] = set()
    for s in splits:
        test = s["test"]
        if test.tobytes() in seen:  # the same split trained with another seed
            continue
        seen.add(test.tobytes())
        train = np.setdiff1d(np.arange(len(y)), test)
        has = np.asarray([i for i in test if fp[i] is not None], dtype=np.int64)
        queries = [("mesh", test, [fm[i] for i in test])]
        if data["points"] and len(has):
            queries.append(("pointcloud", has, [fp[i] for i in has]))
            if len(has) < len(test):  # point clouds of a subset: the meshes of it too
                queries.append(("mesh_pc_subset", has, [fm[i] for i in has]))
        for name, idx, fq in queries:
            sims = np.stack([kernel(f, fm[train], cfg) for f in fq])
            pred = y[train][sims.argmax(axis=1)]
            acc.setdefault(name, []).append(float(np.mean(pred == y[idx])))
    return {
        "network": "1-NN, Eq. 3 kernel",
        "descriptor": cfg.descriptor.version,
        "rotations": "-",
        "accuracy": acc,
        "n_test": [len(s["test"]) for s in splits],
        "n_points_test": [sum(fp[i] is not None for i in s["test"]) for s in splits],
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
    splits: list[Split],
    conv: str,
    rotate: bool,
    options: dict[str, Any],
    curve: str | None,
) -> dict[str, Any]:
    """Train and test one convolution on every split (runs in a worker process)."""
    import torch

    from query.learn.classify import GraphClassifier
    from query.learn.gnn import import_torch, plot_history

    import_torch()
    torch.set_num_threads(int(options.pop("threads", 0)) or torch.get_num_threads())
    y = list(data["labels"])
    acc: dict[str, list[float]] = {"mesh": [], "pointcloud": []}
    secs, best, summary = [], [], []
    base = _rss_mb()
    cuda = torch.cuda.is_available() and options.get("device") in (None, "cuda")
    t0 = time.perf_counter()
    load = [os.getloadavg()[0]]
    model = None
    pick = lambda idx, xs: [xs[i] for i in idx]  # noqa: E731
    for f, s in enumerate(splits):
        model = GraphClassifier(conv, rotate=rotate, seed=int(s["seed"]), **options)
        val = None if s["val"] is None else (pick(s["val"], data["mesh"]), pick(s["val"], y))
        model.fit(pick(s["train"], data["mesh"]), pick(s["train"], y), validation_data=val)
        test = s["test"]
        acc["mesh"].append(model.score(pick(test, data["mesh"]), pick(test, y)))
        has = [i for i in test if data["pointcloud"][i] is not None]
        if data["points"] and has:
            acc["pointcloud"].append(model.score(pick(has, data["pointcloud"]), pick(has, y)))
            if len(has) < len(test):  # point clouds of a subset: the meshes of it too
                score = model.score(pick(has, data["mesh"]), pick(has, y))
                acc.setdefault("mesh_pc_subset", []).append(score)
        h = model.history_
        secs.append(float(np.median(h["seconds"])))
        best.append(model.best_epoch_ + 1)
        summary.append(
            {
                "best_epoch": model.best_epoch_ + 1,
                "val_accuracy_best": h["val_accuracy"][model.best_epoch_],
                "train_accuracy_last": h["accuracy"][-1],
                "train_loss_last": h["loss"][-1],
                "val_accuracy_last": h["val_accuracy"][-1],
            }
        )
        print(
            f"    {conv:6s} rotate={rotate!s:5s} split {f + 1}/{len(splits)}: "
            f"mesh {acc['mesh'][-1]:.3f}  points {(acc['pointcloud'] or [np.nan])[-1]:.3f}  "
            f"best epoch {best[-1]}  ({secs[-1]:.2f} s/epoch)",
            flush=True,
        )
    load.append(os.getloadavg()[0])
    peak = (
        torch.cuda.max_memory_allocated() / 2**20
        if cuda
        else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - base
    )
    if curve and model is not None:
        plot_history(model.history_, curve, title=f"{conv}, rotate={rotate}, last split")
    return {
        "network": conv,
        "rotations": "yes" if rotate else "no",
        "accuracy": acc,
        "n_test": [len(s["test"]) for s in splits],
        "n_points_test": [
            sum(data["pointcloud"][i] is not None for i in s["test"]) for s in splits
        ],
        "parameters": int(model.n_parameters_) if model else 0,
        "seconds_per_epoch": float(np.median(secs)),
        "seconds_per_epoch_per_split": secs,
        "peak_mb": float(peak),
        "best_epochs": best,
        "splits": summary,
        "history_last_split": model.history_ if model else {},
        "load_average": load,
        "seconds": time.perf_counter() - t0,
    }


def _spread(acc: NDArray[np.float64], n_test: Sequence[int]) -> float:
    """Std over folds / seeds; for a single result the binomial standard error."""
    if len(acc) > 1:
        return float(acc.std())
    if len(acc) == 1 and n_test:
        return float(np.sqrt(acc[0] * (1 - acc[0]) / n_test[0]))
    return float("nan")


def table_rows(rows: Sequence[dict[str, Any]]) -> list[list[Any]]:
    """The printed table's rows (accuracies in %)."""
    table = []
    for r in rows:
        m, p = np.asarray(r["accuracy"]["mesh"]), np.asarray(r["accuracy"]["pointcloud"])
        n = r.get("n_test", [])
        table.append(
            [
                r["network"],
                r["rotations"],
                100 * m.mean(),
                100 * _spread(m, n),
                100 * p.mean() if len(p) else None,
                100 * _spread(p, r.get("n_points_test", n)) if len(p) else None,
                r["parameters"] / 1e6,
                r["seconds_per_epoch"],
                r["peak_mb"],
                float(np.median(r["best_epochs"])) if r.get("best_epochs") else None,
            ]
        )
    return table


def run_set(
    name: str, data: dict[str, Any], splits: list[Split], args: argparse.Namespace
) -> dict[str, Any]:
    """Every setting on one data set; prints and returns its table."""
    how = (
        f"{args.folds} folds"
        if splits[0]["val"] is None
        else f"fixed split {len(splits[0]['train'])}/{len(splits[0]['val'])}/"
        f"{len(splits[0]['test'])}, {len(splits)} seed(s)"
    )
    print(
        f"  {len(data['labels'])} models, {len(set(data['labels']))} classes, {how}, "
        f"up to {args.balls} balls per graph, {args.epochs} epochs",
        flush=True,
    )
    rows = [knn_baseline(data, splits)]
    options = {"epochs": args.epochs, "batch_size": args.batch_size, "threads": args.threads}
    jobs = []
    ctx = get_context("spawn")
    # max_tasks_per_child=1: every setting in a fresh process, for a clean memory peak.
    with ProcessPoolExecutor(max_workers=args.jobs, mp_context=ctx, max_tasks_per_child=1) as pool:
        for conv in args.convs:
            for rotate in (False, True):
                curve = str(RESULTS / f"classify_{name}_{conv}{'_rot' if rotate else ''}.png")
                jobs.append(
                    pool.submit(run_setting, data, splits, conv, rotate, dict(options), curve)
                )
        rows += [j.result() for j in jobs]
    print(
        format_table(
            f"Table 1 on {name}: test accuracy % ({how}; models trained on meshes)",
            COLUMNS,
            table_rows(rows),
        ),
        flush=True,
    )
    return {
        "models": len(data["labels"]),
        "classes": len(set(data["labels"])),
        "evaluation": how,
        "folds": args.folds if splits[0]["val"] is None else None,
        "rows": rows,
    }


def refresh_baseline(name: str, data: dict[str, Any], splits: list[Split], directory: Path) -> None:
    """Replace the 1-NN row of ``name``'s stored result by one on today's descriptor.

    The networks do not use the descriptor, so their rows stay; the replaced row is
    kept, labelled with the descriptor version it was computed with (rows that
    predate the label were computed with version 2).
    """
    import json

    path = out_path(name, directory)
    stored = json.loads(path.read_text())
    res = stored["sets"][name]
    row = knn_baseline(data, splits)
    rows = []
    for r in res["rows"]:
        if r["network"] == row["network"]:
            r["network"] = f"{r['network']} (descriptor {r.get('descriptor', 2)})"
        rows.append(r)
    res["rows"] = [row, *rows]
    print(format_table(f"Table 1 on {name}: test accuracy %", COLUMNS, table_rows(res["rows"])))
    write_json(path, stored)
    print(f"wrote {path}", flush=True)


def out_path(name: str, directory: Path = RESULTS) -> Path:
    """``classify.json`` for capod, ``classify_<name>.json`` for the others."""
    return directory / ("classify.json" if name == "capod" else f"classify_{name}.json")


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="small sets and few epochs")
    p.add_argument("--sets", nargs="+", default=["capod", "generated"])
    p.add_argument("--convs", nargs="+", default=["tag", "arma", "spline"])
    p.add_argument("--folds", type=int, default=None, help="capod folds (3 quick, 5 full)")
    p.add_argument("--epochs", type=int, default=None, help="25 quick, 60 full")
    p.add_argument("--balls", type=int, default=128, help="graph size n (largest balls)")
    p.add_argument(
        "--per-class",
        type=int,
        default=None,
        help="shapes per class (generated: 40 quick, 100 full; capod: all 12)",
    )
    p.add_argument("--classes", type=int, default=12, help="generated classes")
    p.add_argument(
        "--generated-eval",
        choices=("fixed", "kfold"),
        default="fixed",
        help="generated set: fixed 60/15/25 split or k-fold",
    )
    p.add_argument("--seeds", type=int, default=1, help="trainings on the fixed split")
    p.add_argument(
        "--points-per-class",
        type=int,
        default=None,
        help="generated, fixed split: point clouds of this many test shapes per class only",
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
    p.add_argument("--jobs", type=int, default=1, help="settings trained in parallel")
    p.add_argument("--out-dir", type=Path, default=RESULTS)
    p.add_argument(
        "--baseline-only",
        action="store_true",
        help="recompute only the 1-NN row of an existing result (after a descriptor change)",
    )
    args = p.parse_args(argv)
    q = args.quick
    args.folds = args.folds or (3 if q else 5)
    args.epochs = args.epochs or (25 if q else 60)
    per_class = args.per_class or (40 if q else 100)
    # capod as bench.retrieval decomposes it (shared cache), without off-grid refinement;
    # the generated set at a coarser grid, only the balls the graphs use, so that its
    # 1000+ shapes decompose in minutes.
    configs = {
        "capod": MDBDConfig(refine=False),
        "generated": MDBDConfig(resolution=64, n_balls=128, refine=False),
    }
    if args.generated_points is None:
        args.generated_points = not q
    for name in args.sets:
        t0 = time.perf_counter()
        out: dict[str, Any] = {
            "settings": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
            "sets": {},
        }
        out["settings"]["cpu_count"] = os.cpu_count()
        out["settings"]["load_average_start"] = os.getloadavg()
        print(f"== {name}", flush=True)
        if name == "capod":
            ds = capod().head(per_class=args.per_class) if args.per_class else capod()
        else:
            ds = generated(per_class, args.classes)
        labels = [m.label for m in ds.models]
        if name == "capod" or args.generated_eval == "kfold":
            splits = kfold_splits(labels, args.folds)
        else:
            splits = fixed_splits(labels, args.seeds)
        points: bool | NDArray[np.int64] = True
        if name != "capod":
            # point clouds of the test models only (all of them under k-fold)
            points = np.unique(np.concatenate([s["test"] for s in splits]))
            if args.points_per_class and args.generated_eval == "fixed":
                lab = np.asarray(labels)
                points = np.concatenate(
                    [points[lab[points] == c][: args.points_per_class] for c in sorted(set(labels))]
                )
            points = points if args.generated_points else False
        data = graphs_of(ds, configs[name], args.balls, args.workers, points)
        if args.baseline_only:
            refresh_baseline(name, data, _remap(splits, data["kept"]), args.out_dir)
            continue
        res = run_set(name, data, _remap(splits, data["kept"]), args)
        res["point_clouds_tested"] = data["points"]
        res["config"] = configs[name].__dict__
        res["seconds"] = time.perf_counter() - t0
        out["settings"]["load_average_end"] = os.getloadavg()
        out["sets"][name] = res
        path = out_path(name, args.out_dir)
        write_json(path, out)
        print(f"wrote {path} ({res['seconds']:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
