"""Other ways to compare a sparse cloud with a mesh, measured and not kept.

Usage (from the repository root)::

    python -m bench.studies.cloud_pairs [--splits validation test] [--workers 2]

A store compares a sparse cloud and a mesh by the nearer of the cloud's own feature
and its reconstruction's (:mod:`shapedb.mdbd.reconstruct`, :mod:`query.search.engine`). Each
row below changes one thing and reports, per set, NN / first tier of cloud queries
(the paper's 20 % clouds) against the mesh database, the mean log margin
``log(d(nearest same class) / d(nearest other class))`` of those queries (lower is
better; far less noisy than NN) and, where it changes, NN of the even mixture:

* **depth 7 / depth 6**: the Poisson solve at a coarser octree (cheaper); the median
  seconds of a reconstruction (Poisson and its decomposition) are printed.
* **+ 3 turned packings**: three more packings of the query cloud, its canonical
  frame turned by :data:`bench.common.CLOUD_TURN_DEGREES` about each axis, and the
  nearest of all comparisons (costs three more decompositions per cloud).
* **cross weights**: a second weighting of the descriptor's blocks for cloud-mesh
  pairs only, chosen on the validation splits of all three sets together
  (coordinate search over multipliers 0-4 of each block, objective the mean capped
  log margin of cloud queries, cap 0.25) and scaled so that other-class pairs sit as
  far apart (median) as under the default.
* **mixture scale 0.9 / 1.1**: cloud-mesh distances multiplied by a constant
  against mesh-mesh and cloud-cloud ones (the mixture only).

Results go to bench/results/studies/cloud_pairs.json. Decompositions come from the bench
cache (:func:`bench.common.decompose_all`).
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
from bench.support.features import (
    complete,
    kernel_features,
    l1_matrix,
    mixture_mask,
    reconstructions,
)
from shapedb.config.core import KernelConfig, MDBDConfig
from shapedb.signature.descriptor import LAYOUTS, VERSION

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "cloud_pairs.json"
TURNS = ("pointcloud_turn_0", "pointcloud_turn_1", "pointcloud_turn_2")
DEPTHS = {"depth 7": "pointcloud_recon_d7", "depth 6": "pointcloud_recon_d6"}
#: Multipliers tried per block by the cross-weight search, and the margin cap.
GRID = (0.0, 0.25, 0.5, 1.0, 2.0, 4.0)
CAP = 0.25

Features = dict[str, Any]


def _features(ds: Any, split: str, mdbd: MDBDConfig, workers: int) -> Features:
    sub = ds.split(split)
    cfg = KernelConfig()
    mesh = decompose_all(sub.models, "mesh", mdbd, workers=workers)
    pc = decompose_all(sub.models, "pointcloud", mdbd, workers=workers)
    recon = {"now": reconstructions(sub.models, pc, mdbd, workers=workers)}
    seconds = {}
    for name, variant in DEPTHS.items():
        recon[name] = reconstructions(sub.models, pc, mdbd, workers=workers, variant=variant)
        raw = decompose_all(sub.models, variant, mdbd, workers=workers)
        seconds[name] = float(np.median([b.seconds for b in raw if b is not None]))
    raw = decompose_all(sub.models, "pointcloud_recon", mdbd, workers=workers)
    seconds["now"] = float(np.median([b.seconds for b in raw if b is not None]))
    turns = [decompose_all(sub.models, v, mdbd, workers=workers) for v in TURNS]
    sub, lists = complete(sub, mesh, pc, *recon.values(), *turns)
    feats = [kernel_features(lst, cfg) for lst in lists]
    names = ["mesh", "pc", *(f"recon {k}" for k in recon), *TURNS]
    out: Features = dict(zip(names, feats, strict=True))
    out["labels"] = np.asarray(sub.labels)
    out["mix"] = mixture_mask([m.name for m in sub.models])
    out["seconds"] = seconds
    return out


def _blocks(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per-block L1 distances (blocks, len(a), len(b)) of weighted feature rows."""
    edges = np.cumsum([0] + [blk[1] for blk in LAYOUTS[VERSION]])
    return np.stack(
        [l1_matrix(a[:, i:j], b[:, i:j]) for i, j in zip(edges[:-1], edges[1:], strict=True)]
    )


def _cross(f: Features, w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cloud (rows) - mesh (columns) distances under block weights ``w``: own or recon."""
    if "_pm" not in f:
        f["_pm"] = _blocks(f["pc"], f["mesh"])
        f["_rm"] = _blocks(f["recon now"], f["mesh"])
    return np.minimum(np.tensordot(w, f["_pm"], 1), np.tensordot(w, f["_rm"], 1))


def _mixture(f: Features, cross: NDArray[np.float64]) -> float:
    """NN of the even mixture with cloud-mesh distances ``cross`` (cloud rows)."""
    mix = f["mix"]
    x = np.where(mix[:, None], f["pc"], f["mesh"])
    d = l1_matrix(x, x)
    cm = mix[:, None] & ~mix[None, :]
    d = np.where(cm, cross, d)
    d = np.where(cm.T, cross.T, d)
    return float(retrieval_scores(-d, f["labels"])["nn"])


def _capped_margin(d: NDArray[np.float64], labels: NDArray[Any]) -> float:
    same = labels[:, None] == labels[None, :]
    off = ~np.eye(len(labels), dtype=bool)
    q = np.where(same & off, d, np.inf).min(1) / np.where(~same, d, np.inf).min(1)
    return float(np.mean(np.maximum(np.log(q), -CAP)))


def fit_cross_weights(sets: Sequence[Features]) -> NDArray[np.float64]:
    """Block multipliers for cloud-mesh pairs minimising the summed capped margin."""
    w = np.ones(len(LAYOUTS[VERSION]))

    def objective(x: NDArray[np.float64]) -> float:
        return sum(_capped_margin(_cross(f, x), f["labels"]) for f in sets)

    for _ in range(3):
        for b in range(len(w)):
            best, value = objective(w), w[b]
            for g in GRID:
                trial = w.copy()
                trial[b] = g
                if trial.sum() > 0 and (o := objective(trial)) < best - 1e-4:
                    best, value = o, g
            w[b] = value
    return w


def _calibrated(f: Features, w: NDArray[np.float64]) -> NDArray[np.float64]:
    other = f["labels"][:, None] != f["labels"][None, :]
    base = np.median(_cross(f, np.ones(len(w)))[other])
    return w * base / np.median(_cross(f, w)[other])


def _row(name: str, d: NDArray[np.float64], f: Features, mixture: float | None) -> list[Any]:
    s = retrieval_scores(-d, f["labels"])
    return [name, s["nn"], s["first_tier"], log_margin(d, f["labels"]), mixture]


def rows(f: Features, cross_w: NDArray[np.float64]) -> list[list[Any]]:
    """The table's rows for one set and split."""
    m = f["mesh"]
    own = l1_matrix(f["pc"], m)
    now = np.minimum(own, l1_matrix(f["recon now"], m))
    out = [_row(f"now (recon {f['seconds']['now']:.2f} s)", now, f, _mixture(f, now))]
    for name in DEPTHS:
        d = np.minimum(own, l1_matrix(f[f"recon {name}"], m))
        out.append(_row(f"{name} ({f['seconds'][name]:.2f} s)", d, f, _mixture(f, d)))
    turned = np.minimum.reduce([now, *(l1_matrix(f[t], m) for t in TURNS)])
    out.append(_row("+ 3 turned packings", turned, f, None))
    cross = _cross(f, _calibrated(f, cross_w))
    out.append(_row("cross weights", cross, f, _mixture(f, cross)))
    for scale in (0.9, 1.1):
        out.append(_row(f"mixture scale {scale}", now, f, _mixture(f, now * scale)))
    out.append(_row("own feature only", own, f, _mixture(f, own)))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.cloud_pairs", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--datasets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--splits", nargs="+", default=["validation", "test"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    mdbd = mdbd_config()
    sets = build_sets(args.datasets, False)
    feats = {(ds.name, s): _features(ds, s, mdbd, args.workers) for ds in sets for s in args.splits}
    fit_on = [feats[(ds.name, "validation")] for ds in sets if (ds.name, "validation") in feats]
    cross_w = fit_cross_weights(fit_on) if fit_on else np.ones(len(LAYOUTS[VERSION]))
    blocks = [b[0] for b in LAYOUTS[VERSION]]
    print("cross weights (validation):", dict(zip(blocks, cross_w.round(2).tolist(), strict=True)))
    record: dict[str, Any] = {"cross_weights": dict(zip(blocks, cross_w.tolist(), strict=True))}
    columns = ("comparison", "cloud NN", "cloud 1-T", "cloud margin", "mixture NN")
    for (name, split), f in feats.items():
        table = rows(f, cross_w)
        print(format_table(f"{name}, {split} split ({len(f['labels'])} models)", columns, table))
        record[f"{name} {split}"] = [dict(zip(columns, r, strict=True)) for r in table]
    write_json(args.out, record)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
