"""Prototype: a cloud-to-mesh correction a store learns from its own meshes, no labels.

Every mesh of the database gives a pair: its own feature and the feature of another
random 20 % of its vertices (variant ``pointcloud_b``, never the query's draw). From
those pairs alone, per descriptor dimension d:

``shift``
    b_d = median(mesh_d - cloud_d): a cloud's feature is moved by b before comparing;
``affine``
    mesh_d ~ a_d cloud_d + b_d by least squares, shrunk towards the identity;
``snr``
    after the shift, weight w_d = spread of the meshes along d / mean pair residual
    along d (the dimensions a sparse sample moves less than shapes differ count more);
``nca``
    weights exp(theta_d) (per block or per dimension) maximising the mean log softmax
    probability that a cloud picks its own mesh among the database's meshes, with
    a penalty pulling theta to 0.

Scored on the query clouds (variant ``pointcloud``, the bench's 20 % draw) against
the meshes, leaving the query's own mesh out (NN, 1-T), and own-first; the
reconstruction rule of the store (nearest of own and reconstruction) applied after
the correction. Usage: ``python -m bench.studies.crossmetric --sets people --split
validation [--pairs K]``; results go to bench/results/studies/crossmetric.json.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from bench.common import (
    decompose_all,
    format_table,
    log_margin,
    mdbd_config,
    retrieval_scores,
    write_json,
)
from bench.representations import build, load_set
from bench.support.features import kernel_features as weighted_features
from bench.support.features import l1_matrix as l1
from shapedb.config.core import KernelConfig

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "crossmetric.json"

Correction = Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]


def fit_shift(fm: NDArray[np.float64], fc: NDArray[np.float64]) -> tuple[Any, Any, Any]:
    """(scale, shift, weights) of the shift correction."""
    d = fm.shape[1]
    return np.ones(d), np.median(fm - fc, axis=0), np.ones(d)


def fit_affine(
    fm: NDArray[np.float64], fc: NDArray[np.float64], shrink: float = 0.5
) -> tuple[Any, Any, Any]:
    xm, ym = fc.mean(0), fm.mean(0)
    vx = ((fc - xm) ** 2).mean(0)
    cxy = ((fc - xm) * (fm - ym)).mean(0)
    a = np.where(vx > 1e-12, cxy / np.maximum(vx, 1e-12), 1.0)
    a = shrink * 1.0 + (1 - shrink) * np.clip(a, 0.0, 3.0)
    b = ym - a * xm
    return a, b, np.ones(fm.shape[1])


def fit_snr(
    fm: NDArray[np.float64], fc: NDArray[np.float64], power: float = 1.0, shift: bool = True
) -> tuple[Any, Any, Any]:
    d = fm.shape[1]
    b = np.median(fm - fc, axis=0) if shift else np.zeros(d)
    resid = np.abs(fm - (fc + b)).mean(0)
    spread = np.abs(fm - np.median(fm, axis=0)).mean(0)
    eps = 1e-3 * max(float(spread.mean()), 1e-12)
    w = ((spread + eps) / (resid + eps)) ** power
    w = w / w.mean()
    return np.ones(d), b, w


def fit_noise(
    fm: NDArray[np.float64], fc: NDArray[np.float64], shift: bool = True
) -> tuple[Any, Any, Any]:
    """Weights 1 / (pair residual + its median): dims a sparse sample moves most count less."""
    d = fm.shape[1]
    b = np.median(fm - fc, axis=0) if shift else np.zeros(d)
    resid = np.abs(fm - (fc + b)).mean(0)
    w = 1.0 / (resid + np.median(resid) + 1e-12)
    return np.ones(d), b, w / w.mean()


def fit_nca(
    fm: NDArray[np.float64],
    fc: NDArray[np.float64],
    *,
    blocks: list[int] | None = None,
    reg: float = 0.1,
    temperature: float = 10.0,
    shift: bool = True,
) -> tuple[Any, Any, Any]:
    """Per-dimension (or per-block, ``blocks`` = lengths) log-weights by self-NCA."""
    n, d = fm.shape
    b = np.median(fm - fc, axis=0) if shift else np.zeros(d)
    x = fc + b
    diff = np.abs(x[:, None, :] - fm[None, :, :])  # (n, n, d)
    if blocks is not None:
        idx = np.repeat(np.arange(len(blocks)), blocks)
        diff = np.stack([diff[..., idx == k].sum(-1) for k in range(len(blocks))], -1)
    scale = float(np.median(diff.sum(-1)))
    diff = diff / scale
    k = diff.shape[-1]

    def loss(theta: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        w = np.exp(theta)
        dist = diff @ w  # (n, n)
        z = -temperature * dist
        z = z - z.max(1, keepdims=True)
        p = np.exp(z)
        p /= p.sum(1, keepdims=True)
        own = np.log(np.diag(p) + 1e-300)
        val = -own.mean() + reg * float(theta @ theta) / k * 10
        # gradient of -log p_ii = T d_ii + log sum exp(-T d_ij)
        g_dist = -p.copy()  # d/d dist_ij of log-sum-exp term: -T p_ij ... sign below
        g_dist[np.arange(n), np.arange(n)] += 1.0
        g = temperature * np.einsum("ij,ijk->k", g_dist, diff) / n * w
        g += 2 * reg * theta / k * 10
        return val, g

    res = minimize(loss, np.zeros(k), jac=True, method="L-BFGS-B", options={"maxiter": 200})
    w = np.exp(res.x)
    if blocks is not None:
        w = np.repeat(w, blocks)
    # keep the median other-pair distance as before
    before = np.median(np.abs(x[:, None, :] - fm[None, :, :]).sum(-1))
    after = np.median((np.abs(x[:, None, :] - fm[None, :, :]) * w).sum(-1))
    return np.ones(d), b, w * before / after


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.crossmetric", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--sets", nargs="+", default=["people"])
    ap.add_argument("--split", default="validation")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--pairs", type=int, default=0, help="fit on the first K pairs only")
    args = ap.parse_args(argv)
    cfg = KernelConfig()
    mdbd = mdbd_config()
    from shapedb.signature.descriptor import LAYOUTS, VERSION

    blocks = [int(s) for _, s, _, _ in LAYOUTS[VERSION]]
    results: dict[str, Any] = {}
    columns = ("correction", "NN", "1-T", "own-first", "margin", "mesh NN (weighted)")
    for ds in build(args.sets, args.split):
        data = load_set(ds, mdbd, ["cloud"], args.workers)
        train = decompose_all(data.ds.models, "pointcloud_b", mdbd, workers=args.workers)
        fm = weighted_features(data.mesh, cfg)
        fc = weighted_features(data.clouds["cloud"], cfg)
        ft = weighted_features(train, cfg)  # type: ignore[arg-type]
        fmt = fm
        if args.pairs:
            pick = np.random.default_rng(0).permutation(len(fm))[: args.pairs]
            fmt, ft = fm[pick], ft[pick]
        rec = data.recons["cloud"]
        ridx = [i for i, r in enumerate(rec) if r is not None]
        fr = weighted_features([rec[i] for i in ridx], cfg) if ridx else None  # type: ignore[misc]
        labels = data.labels
        n = len(labels)
        fits: dict[str, tuple[Any, Any, Any]] = {
            "identity": (np.ones(fm.shape[1]), np.zeros(fm.shape[1]), np.ones(fm.shape[1])),
            "shift": fit_shift(fmt, ft),
            "affine 0.5": fit_affine(fmt, ft, 0.5),
            "affine 0.2": fit_affine(fmt, ft, 0.2),
            "snr": fit_snr(fmt, ft),
            "snr^0.5": fit_snr(fmt, ft, 0.5),
            "snr no shift": fit_snr(fmt, ft, shift=False),
            "noise": fit_noise(fmt, ft),
            "noise no shift": fit_noise(fmt, ft, shift=False),
            "nca blocks": fit_nca(fmt, ft, blocks=blocks, reg=0.1),
            "nca dims 0.1": fit_nca(fmt, ft, reg=0.1),
            "nca dims 1": fit_nca(fmt, ft, reg=1.0),
            "nca dims 0.01": fit_nca(fmt, ft, reg=0.01),
        }
        rows = []
        mm = retrieval_scores(-l1(fm, fm), labels)
        for name, (a, b, w) in fits.items():
            for use_rec in (False, True):
                d = l1((a * fc + b) * w, fm * w)
                if use_rec and fr is not None:
                    d[ridx] = np.minimum(d[ridx], l1(fr * w, fm * w))
                s = retrieval_scores(-d, labels)
                own = float(np.mean(np.argmin(d, 1) == np.arange(n)))
                dmm = l1(fm * w, fm * w)
                s2 = retrieval_scores(-dmm, labels)
                rows.append(
                    [
                        name + (" +recon" if use_rec else ""),
                        s["nn"],
                        s["first_tier"],
                        own,
                        log_margin(d, labels),
                        s2["nn"],
                    ]
                )
        print(
            format_table(
                f"{ds.name} {args.split} ({n} models): cloud->mesh; mesh->mesh NN "
                f"{mm['nn']:.3f} 1-T {mm['first_tier']:.3f}",
                columns,
                rows,
            )
        )
        results[ds.name] = {"n": n, "mesh_mesh": mm, "columns": list(columns), "table": rows}
    write_json(OUT, {"split": args.split, "pairs": args.pairs, "sets": results})
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
