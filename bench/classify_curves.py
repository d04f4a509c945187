"""Learning curves of every classifier, and the one chosen on validation, on held-out data.

Usage (from the repository root)::

    python -m bench.classify_curves                       # heldout + capod
    python -m bench.classify_curves --sets heldout --per-class 14 --epochs 40

For each training size (models per class) every candidate of
:mod:`query.learn.selection` (1/3/5-NN on the store's descriptor, logistic regression,
gradient boosting, the graph CNNs TAG / ARMA / Spline, and TAG reading the
descriptor too) is (a) scored on validation data drawn from the training part only,
with the protocol ``shapedb train`` uses (``select_classifier``: 5-fold
cross-validation when a class has fewer than 20 training models), and (b) fitted on
the whole training part and tested on the held-out test part, on the meshes and, for
the same mesh-trained models, on point clouds of the test shapes. The "chosen" row is
the candidate with the best validation accuracy (ties to the simplest), i.e. what
``shapedb train`` would have saved; its test accuracy is the one reported for it.
The baseline of the same run is the 1-NN row. Every row also gives the seconds to
train (validation of the candidate and its final fit; for "chosen", every
candidate's validation and the chosen one's fit, i.e. what ``shapedb train`` pays),
and the learning curve sets test accuracy against that time: the accuracy gained over
1-NN per extra minute of training.

Sets (decompositions from the shared bench cache, as in :mod:`bench.classify`):

- ``heldout``: 20 classes x 20 models, the 12 machined-part kinds and 8 jointed-figure
  subjects of :func:`bench.classify.generated` (64 cells, 128 balls), split per class
  14 to train, 6 to test; training sizes 5, 10, 14 per class (nested subsets).
- ``capod``: 15 classes x 12 meshes, 3 stratified folds (8 train, 4 test per class);
  training sizes 5, 8 per class; the figures are means over the folds.
- ``heldout50``: the same 20 classes with 56 models per class (the first 20 of each are
  ``heldout``'s models); the test part is ``heldout``'s 6 per class, the training part the
  other 50 per class (``heldout``'s 14 and 36 more); training sizes 20, 50 per class.
- ``large``: 12 part / figure classes of :func:`bench.classify.generated` with 20 test
  and up to 100 training models per class (sizes 20, 50, 100): costly, off by default.

Results go to ``bench/results/classify_curves_<set>.json``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.classify import generated, graphs_of
from bench.common import format_table, write_json
from bench.sets.datasets import CAPOD_ROOT, capod
from query.learn.budget import DEFAULT_BUDGET
from query.learn.selection import CANDIDATES, make_candidate, select_classifier
from query.learn.training_data import stratified_folds, stratified_split
from shapedb.config.core import Config, MDBDConfig

RESULTS = Path(__file__).resolve().parent / "results"
CONFIGS = {
    "heldout": MDBDConfig(resolution=64, n_balls=128, refine=False),
    "heldout50": MDBDConfig(resolution=64, n_balls=128, refine=False),
    "large": MDBDConfig(resolution=64, n_balls=128, refine=False),
    "capod": MDBDConfig(refine=False),
}
SIZES = {"heldout": (5, 10, 14), "heldout50": (20, 50), "capod": (5, 8), "large": (20, 50, 100)}


def heldout50() -> tuple[Any, NDArray[np.int64], NDArray[np.int64]]:
    """The ``heldout50`` set and its (train, test) indices.

    Returns
    -------
    dataset : the 20 classes of :func:`bench.classify.generated` at 56 models per class
    train : (1000,) int64, the 50 per class outside the test part
    test : (120,) int64, the same models as the ``heldout`` set's 6 test models per class
    """
    ds = generated(56, 20)
    small = [m.label for m in generated(20, 20).models]
    _, te20 = stratified_split(small, (14 / 20, 6 / 20), seed=0)
    # model j of class c is index c * 20 + j there and c * 56 + j here
    te = np.sort(np.asarray([(i // 20) * 56 + i % 20 for i in te20], dtype=np.int64))
    return ds, np.setdiff1d(np.arange(len(ds.models)), te), te


def load_set(
    name: str, workers: int, points: bool, capod_root: Path = CAPOD_ROOT
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Graphs, descriptors and (train, test) splits of a set.

    Returns
    -------
    data : dict
        ``labels``, ``mesh`` / ``pointcloud`` (Balls or None), ``x_mesh`` (n, d) and
        ``x_points`` (n, d; NaN rows where there is no point cloud).
    splits : list of {"train": idx, "test": idx}
    """
    if name == "heldout":
        ds = generated(20, 20)
        labels = [m.label for m in ds.models]
        tr, te = stratified_split(labels, (14 / 20, 6 / 20), seed=0)
        splits, want = [{"train": tr, "test": te}], te
    elif name == "heldout50":
        ds, tr, te = heldout50()
        splits, want = [{"train": tr, "test": te}], te
    elif name == "large":
        ds = generated(120, 12)
        labels = [m.label for m in ds.models]
        tr, te = stratified_split(labels, (100 / 120, 20 / 120), seed=0)
        splits, want = [{"train": tr, "test": te}], te
    else:
        ds = capod(capod_root)
        labels = [m.label for m in ds.models]
        n = np.arange(len(labels))
        splits = [{"train": np.setdiff1d(n, t), "test": t} for t in stratified_folds(labels, 3)]
        want = n
    data = graphs_of(ds, CONFIGS[name], 128, workers, want if points else False)
    new = {old: k for k, old in enumerate(data["kept"])}
    splits = [
        {k: np.asarray([new[i] for i in s[k] if i in new], dtype=np.int64) for k in s}
        for s in splits
    ]
    from shapedb.signature.kernel import features

    cfg = Config()
    data["x_mesh"] = np.stack([features(b.decomposition(), cfg) for b in data["mesh"]])
    data["x_points"] = np.stack(
        [
            features(b.decomposition(), cfg) if b is not None else np.full(cfg.dim, np.nan)
            for b in data["pointcloud"]
        ]
    )
    return data, splits


def subset(labels: Sequence[str], idx: NDArray[np.int64], per_class: int) -> NDArray[np.int64]:
    """The first ``per_class`` of each class in a seeded shuffle of ``idx`` (nested in size)."""
    order = np.random.default_rng(1).permutation(idx)
    count: dict[str, int] = {}
    keep = []
    for i in order:
        c = labels[i]
        if count.get(c, 0) < per_class:
            count[c] = count.get(c, 0) + 1
            keep.append(int(i))
    return np.sort(np.asarray(keep, dtype=np.int64))


def run_candidate(
    name: str, data: dict[str, Any], train: NDArray[np.int64], test: NDArray[np.int64],
    options: dict[str, Any],
) -> dict[str, Any]:  # fmt: skip
    """Validation score (training part only) and test accuracy of one candidate."""
    import torch

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    y = np.asarray(data["labels"])
    mesh = data["mesh"]
    pick = lambda idx, xs: [xs[i] for i in idx]  # noqa: E731
    sel, _ = select_classifier(
        pick(train, mesh), data["x_mesh"][train], y[train].tolist(),
        candidates=[name], graph_options=options, refit=False,
    )  # fmt: skip
    val = sel.score_of(name)
    model = make_candidate(name, seed=0, graph_options=options)
    graph = hasattr(model, "conv")
    t_fit = time.perf_counter()
    if graph:
        model.fit(pick(train, mesh), y[train].tolist(), descriptors=data["x_mesh"][train])
    else:
        model.fit(data["x_mesh"][train], y[train].tolist())
    fit_seconds = time.perf_counter() - t_fit

    def accuracy(graphs: list[Any], x: NDArray[np.float64], truth: NDArray[Any]) -> float:
        if not len(x):
            return float("nan")
        if graph:
            pred = model.predict(graphs, descriptors=x)
        else:
            pred = model.predict(x)
        return float(np.mean(np.asarray(pred) == truth))

    has = np.asarray([i for i in test if data["pointcloud"][i] is not None], dtype=np.int64)
    return {
        "candidate": name,
        "validation_correct": val.correct,
        "validation_total": val.total,
        "validation_accuracy": val.accuracy,
        "protocol": f"{sel.protocol} ({sel.folds})",
        "test_mesh": accuracy(pick(test, mesh), data["x_mesh"][test], y[test]),
        "test_points": accuracy(pick(has, data["pointcloud"]), data["x_points"][has], y[has]),
        "n_test": len(test),
        "n_points_test": len(has),
        "validation_seconds": val.seconds,
        "fit_seconds": fit_seconds,
        "train_seconds": val.seconds + fit_seconds,
        "seconds": time.perf_counter() - t0,
    }


def budget_row(
    data: dict[str, Any], train: NDArray[np.int64], test: NDArray[np.int64],
    options: dict[str, Any], budget: float,
) -> dict[str, Any]:  # fmt: skip
    """What ``shapedb train --budget`` saves on this split: the product's own selection
    within ``budget`` seconds (cheapest candidates first), refitted, and its test accuracy."""
    import torch

    torch.set_num_threads(1)
    y = np.asarray(data["labels"])
    mesh = data["mesh"]
    t0 = time.perf_counter()
    sel, model = select_classifier(
        [mesh[i] for i in train], data["x_mesh"][train], y[train].tolist(),
        graph_options=options, budget=budget,
    )  # fmt: skip
    seconds = time.perf_counter() - t0
    if hasattr(model, "conv"):
        pred = model.predict([mesh[i] for i in test], descriptors=data["x_mesh"][test])
    else:
        pred = model.predict(data["x_mesh"][test])
    return {
        "candidate": f"budget {budget:.0f} s",
        "name": sel.chosen,
        "test_mesh": float(np.mean(np.asarray(pred) == y[test])),
        "train_seconds": seconds,
        "statuses": {s.name: s.status for s in sel.scores},
    }


def chosen_row(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The candidate with the best validation accuracy, ties to the simplest.

    Its training time is what ``shapedb train`` pays: every candidate's validation
    and the chosen one's final fit.
    """
    ranked = sorted(results, key=lambda r: CANDIDATES.index(r["candidate"]))
    best = max(ranked, key=lambda r: r["validation_correct"])
    selection = sum(r.get("validation_seconds", 0.0) for r in results)
    train = selection + best.get("fit_seconds", 0.0)
    return {**best, "candidate": "chosen", "name": best["candidate"], "train_seconds": train}


#: Columns of :func:`time_curve`.
TIME_CURVE = ("classifier", "per class", "test mesh", "train s", "vs 1-NN", "per extra min")


def time_curve(points: dict[int, list[dict[str, Any]]]) -> list[list[Any]]:
    """Test accuracy against training time: what extra minutes buy over 1-NN.

    Parameters
    ----------
    points : {models per class: rows of :func:`size_rows`}
        Each row with "candidate", "test_mesh" and "train_seconds" (validation of
        the candidate plus its final fit, seconds).

    Returns
    -------
    list of [classifier, per class, test accuracy, training seconds, accuracy gain
    over 1-NN, gain per extra minute over 1-NN (NaN when not slower, or without a
    1-NN row)], by size, then by training time.
    """
    out = []
    for n, rows in points.items():
        base = next((r for r in rows if r["candidate"] == "1-nn"), None)
        for r in sorted(rows, key=lambda r: r["train_seconds"]):
            gain = extra = float("nan")
            if base is not None:
                gain = r["test_mesh"] - base["test_mesh"]
                extra = r["train_seconds"] - base["train_seconds"]
            per_minute = gain / (extra / 60) if extra > 0 else float("nan")
            out.append([r["candidate"], n, r["test_mesh"], r["train_seconds"], gain, per_minute])
    return out


MEANS = ("validation_accuracy", "test_mesh", "test_points", "train_seconds", "seconds")


def size_rows(per_fold: list[list[dict[str, Any]]]) -> list[dict[str, Any]]:
    """One row per candidate and the chosen one, means over the splits of one size."""
    folds = [[*rs, chosen_row(rs)] for rs in per_fold]
    names = [r["candidate"] for r in folds[0][:-1]] + ["chosen"]
    rows = []
    for k, label in enumerate(names):
        rs = [fr[k] for fr in folds]
        rows.append(
            {
                "candidate": label,
                "chosen": [r["name"] for r in rs] if label == "chosen" else None,
                **{key: float(np.nanmean([r[key] for r in rs])) for key in MEANS},
                "folds": rs,
            }
        )
    return rows


def _run_jobs(
    args: argparse.Namespace, data: dict[str, Any], splits: list[dict[str, Any]], sizes: list[int]
) -> dict[tuple[int, int, str], dict[str, Any]]:
    """Every (size, split, candidate), in parallel processes; prints each as it ends."""
    labels = list(data["labels"])
    options = {"epochs": args.epochs, "batch_size": 16}
    jobs: dict[tuple[int, int, str], Any] = {}
    with ProcessPoolExecutor(max_workers=args.jobs, mp_context=get_context("spawn")) as pool:
        for n in sizes:
            for f, s in enumerate(splits):
                train = subset(labels, s["train"], n)
                for c in args.candidates:
                    jobs[(n, f, c)] = pool.submit(run_candidate, c, data, train, s["test"], options)
        results = {}
        for (n, f, c), j in jobs.items():  # submission order: the smaller sizes first
            r = results[(n, f, c)] = j.result()
            print(
                f"  {n}/class split {f} {c}: validation {r['validation_accuracy']:.3f}, "
                f"test mesh {r['test_mesh']:.3f}, points {r['test_points']:.3f} "
                f"({r['train_seconds']:.0f} s to train)",
                flush=True,
            )
    return results


def _budget_rows(
    args: argparse.Namespace,
    data: dict[str, Any],
    splits: list[dict[str, Any]],
    n: int,
    rows: list[dict[str, Any]],
) -> list[dict[str, Any]]:
    """The budgeted selection on every split at ``n`` a class, beside the full choice."""
    if not args.budget:
        return []
    labels = list(data["labels"])
    options = {"epochs": args.epochs, "batch_size": 16}
    got = [
        budget_row(data, subset(labels, s["train"], n), s["test"], options, args.budget)
        for s in splits
    ]
    full = next(r for r in rows if r["chosen"] is not None)
    test = float(np.mean([r["test_mesh"] for r in got]))
    table = [
        ["full choice: " + "/".join(full["chosen"]), full["test_mesh"], full["train_seconds"]],
        [f"within {args.budget:.0f} s: " + "/".join(sorted({r["name"] for r in got})), test,
         float(np.median([r["train_seconds"] for r in got]))],
    ]  # fmt: skip
    title = f"{n} a class: shapedb train within its budget against the full choice"
    print(format_table(title, ("selection", "test mesh", "train s"), table), flush=True)
    return got


def run_set(name: str, args: argparse.Namespace) -> dict[str, Any]:
    t0 = time.perf_counter()
    data, splits = load_set(name, args.workers, args.points, args.capod_root)
    labels = list(data["labels"])
    sizes = [s for s in (args.per_class or SIZES[name])]
    print(
        f"== {name}: {len(labels)} models, {len(set(labels))} classes, {len(splits)} split(s), "
        f"sizes {sizes}, graph CNNs {args.epochs} epochs",
        flush=True,
    )
    results = _run_jobs(args, data, splits, sizes)
    points: dict[int, Any] = {}
    for n in sizes:
        rows = points[n] = size_rows(
            [[results[(n, f, c)] for c in args.candidates] for f in range(len(splits))]
        )
        title = f"{name}, {n} training models per class: accuracy (validation on the training "
        title += "part; test on held-out meshes and point clouds) and seconds to train"
        columns = ("classifier", "validation", "test mesh", "test points", "train s")
        table = [
            [
                r["candidate"] if r["chosen"] is None else f"chosen: {'/'.join(r['chosen'])}",
                *(r[k] for k in ("validation_accuracy", "test_mesh", "test_points")),
                r["train_seconds"],
            ]
            for r in rows
        ]
        print(format_table(title, columns, table), flush=True)
    curve = time_curve(points)
    title = f"{name}: learning curve, test accuracy on meshes against training time"
    print(format_table(title, TIME_CURVE, curve))
    budgets = _budget_rows(args, data, splits, max(sizes), points[max(sizes)])
    return {
        "models": len(labels),
        "classes": len(set(labels)),
        "splits": len(splits),
        "sizes": sizes,
        "config": CONFIGS[name].__dict__,
        "epochs": args.epochs,
        "points": {str(n): rows for n, rows in points.items()},
        "time_curve": [dict(zip(TIME_CURVE, row, strict=True)) for row in curve],
        "budget": budgets,
        "seconds": time.perf_counter() - t0,
    }


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sets", nargs="+", default=["heldout", "capod"])
    p.add_argument("--per-class", type=int, nargs="+", help="training sizes (default per set)")
    p.add_argument("--candidates", nargs="+", default=list(CANDIDATES))
    p.add_argument("--epochs", type=int, default=40, help="graph-CNN epochs")
    p.add_argument("--points", action=argparse.BooleanOptionalAction, default=True)
    p.add_argument("--workers", type=int, default=2, help="decomposition processes")
    p.add_argument("--jobs", type=int, default=2, help="candidates trained in parallel")
    p.add_argument("--capod-root", type=Path, default=CAPOD_ROOT, help="the CAPOD folder")
    p.add_argument("--out-dir", type=Path, default=RESULTS)
    p.add_argument(
        "--budget", type=float, default=DEFAULT_BUDGET,
        help="seconds of shapedb train's budget for the budget row (0: no row)",
    )  # fmt: skip
    args = p.parse_args(argv)
    for name in args.sets:
        out = {
            "settings": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
            "load_average_start": os.getloadavg(),
        }
        out[name] = run_set(name, args)
        out["load_average_end"] = os.getloadavg()
        path = args.out_dir / f"classify_curves_{name}.json"
        write_json(path, out)
        print(f"wrote {path}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
