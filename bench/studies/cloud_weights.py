"""Block weightings without the pose blocks, and a store-learned low-rank correction.

Every block of descriptor version 5 (version 4's blocks plus ``union``) is computed
once per model from cached decompositions (mesh, 20 % cloud, the cloud's kept
reconstruction), each divided by its typical distance (weight 1), as in
:mod:`bench.studies.people_blocks`. A *weighting* is a weight per block; meshes
compare by the weighted L1, a cloud by the store's rule (the nearer of its own
feature and its kept reconstruction's).

Weightings: ``v4`` (the default), ``v4 -pose`` (without ``d2c_mean`` and
``inertia``, the blocks that separate poses more than people), ``v4 -d2c_mean``,
``v4 -inertia``, ``v4 pose x0.5`` (the two at half weight) and ``v4 -pose -walk``.

Corrections a store can learn by itself, without labels, from ``--pairs`` (mesh,
20 % cloud of that mesh) pairs: here the pairs of the *other* split of the same set
(label-free; the queries' own clouds are never seen). With the weighted features
``x`` (the chosen weighting), ``delta = mesh - cloud`` per pair:

``nuisance-k``
    ``U`` = the ``k`` leading eigenvectors of the pairs' second moment
    ``delta^T delta / n`` (the directions a sparse sample moves a feature most);
    every feature is mapped by ``P = I - U U^T`` before L1 (meshes too: one metric);
``ratio-k``
    ``U`` = the ``k`` leading generalised eigenvectors of that second moment
    against the meshes' covariance (+ a ridge), orthonormalised: the directions
    where a cloud's shift is largest *relative to* how far models lie apart, so
    that removing them keeps between-model distances.

A query then costs one (d, d) matrix product more than today's. Scored: mesh->mesh
and cloud->mesh NN / 1-T / DCG (every query leaves its own model out), own-first
and the clouds' mean log margin (:func:`bench.common.log_margin`, lower is better).
Sets without cached clouds get mesh rows only.

Usage: ``python -m bench.studies.cloud_weights --split validation`` (then ``--split
test``); ``--sets people-xl capod figures parts generic`` by default (``people-xl``:
the validation split with 12 more subjects, :func:`bench.sets.datasets.people`);
decomposes nothing (reads ``SHAPEDB_BENCH_CACHE``). Results go to
bench/results/studies/cloud_weights_<split>.json.

Decompositions are read under today's cache key, else under the key of commit
:data:`RENAMES` (the engine's code since changed only names and docstrings: a
private function made public), else, for the people only, under the key before the
sheet rule (:data:`bench.studies.people_blocks.PRE_SHEET`; closed solids unchanged).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import bench.common as common
from bench.common import Balls, format_table, log_margin, mdbd_config, retrieval_scores, write_json
from bench.representations import build
from bench.sets.datasets import Dataset, Model
from bench.studies.people_blocks import PRE_SHEET, block_features, l1
from shapedb.config.core import MDBDConfig
from shapedb.geometry.view import is_sparse
from shapedb.mdbd.reconstruct import volumes_agree
from shapedb.signature.descriptor import LAYOUTS

#: Engine commit whose cache keys still hold (the code since: renames and docstrings).
RENAMES = "b95b2be"
OUT = Path(__file__).resolve().parents[1] / "results" / "studies"
FloatArray = NDArray[np.float64]
POSE = ("d2c_mean", "inertia")


def cached(model: Model, variant: str, config: MDBDConfig) -> Path | None:
    """Where the decomposition of ``model`` in ``variant`` is cached (module docstring)."""
    commits: list[str | None] = [None, RENAMES]
    if model.source.startswith("person:"):
        commits.append(PRE_SHEET)
    for c in commits:
        path = common.cache_path(model, variant, config, engine_commit=c)
        if path.exists():
            return path
    return None


def _load(paths: Sequence[Path], config: MDBDConfig) -> list[Balls]:
    return [common.load_balls(p, config.contact_tol_cells) for p in paths]


class SetFeatures:
    """Per-block features of one split: meshes, clouds and kept reconstructions.

    ``mesh[b]`` (n, dim_b); ``cloud[b]`` (n, dim_b) or None when the clouds of the
    split are not all cached; ``rec_idx`` the rows with a kept reconstruction and
    ``rec[b]`` their features.
    """

    def __init__(self, ds: Dataset, config: MDBDConfig) -> None:
        mesh = [cached(m, "mesh", config) for m in ds.models]
        cloud = [cached(m, "pointcloud", config) for m in ds.models]
        keep = [i for i, p in enumerate(mesh) if p is not None]
        with_clouds = all(cloud[i] is not None for i in keep)
        self.missing = len(ds) - len(keep)
        self.ds = Dataset(ds.name, tuple(ds.models[i] for i in keep))
        self.labels = np.asarray(self.ds.labels)
        mpaths = [mesh[i] for i in keep]
        self.mesh = _features(_load(mpaths, config), mpaths)  # type: ignore[arg-type]
        self.cloud: dict[str, FloatArray] | None = None
        self.rec: dict[str, FloatArray] = {}
        self.rec_idx: list[int] = []
        if not with_clouds or not keep:
            return
        cpaths = [cloud[i] for i in keep]
        clouds = _load(cpaths, config)  # type: ignore[arg-type]
        self.cloud = _features(clouds, cpaths)  # type: ignore[arg-type]
        rpaths: list[Path] = []
        for row, (m, c) in enumerate(zip(self.ds.models, clouds, strict=True)):
            if not is_sparse(c.sampling, c.spacing):
                continue
            rp = cached(m, "pointcloud_recon", config)
            if rp is None:
                continue
            (r,) = _load([rp], config)
            if volumes_agree(c.radii, r.radii):
                rpaths.append(rp)
                self.rec_idx.append(row)
        if rpaths:
            self.rec = _features(_load(rpaths, config), rpaths)  # type: ignore[arg-type]


def _features(balls: list[Balls], paths: Sequence[Path]) -> dict[str, FloatArray]:
    """:func:`block_features` of ``balls``, cached on disk by decomposition and descriptor code."""
    import hashlib
    import inspect

    import shapedb.signature.descriptor
    import shapedb.signature.union

    code = inspect.getsource(shapedb.signature.descriptor) + inspect.getsource(
        shapedb.signature.union
    )
    tag = hashlib.sha256(code.encode()).hexdigest()[:12]
    folder = common.CACHE_DIR / "block_features"
    out: list[dict[str, FloatArray] | None] = []
    for p in paths:
        f = folder / f"{Path(p).stem}_{tag}.npz"
        if f.exists():
            with np.load(f) as z:
                out.append({k: z[k] for k in z.files})
        else:
            out.append(None)
    todo = [i for i, o in enumerate(out) if o is None]
    if todo:
        fresh = block_features([balls[i] for i in todo])
        folder.mkdir(parents=True, exist_ok=True)
        for j, i in enumerate(todo):
            one = {k: v[j] for k, v in fresh.items()}
            out[i] = one
            tmp = folder / f"{Path(paths[i]).stem}_{tag}.{os.getpid()}.tmp.npz"
            np.savez(tmp, **one)
            tmp.replace(folder / f"{Path(paths[i]).stem}_{tag}.npz")
    names = list(out[0]) if out else []
    return {k: np.stack([o[k] for o in out]) for k in names}  # type: ignore[index]


def stack(f: dict[str, FloatArray], weights: dict[str, float]) -> FloatArray:
    """The weighted feature matrix (n, sum of the weighted blocks' dims)."""
    return np.concatenate([weights[b] * f[b] for b in weights], axis=1)


def fit_projection(
    fm: FloatArray, fc: FloatArray, k: int, *, relative: bool, ridge: float = 1e-2
) -> FloatArray:
    """``P = I - U U^T`` (d, d) from pairs ``fm`` (n, d) meshes and ``fc`` (n, d) their clouds.

    ``U`` (d, k): leading eigenvectors of the pairs' second moment, or (``relative``)
    of it against the meshes' covariance plus ``ridge`` x its mean eigenvalue.
    """
    delta = fm - fc
    sw = delta.T @ delta / len(delta)
    d = fm.shape[1]
    if relative:
        from scipy.linalg import eigh

        sb = np.cov(fm, rowvar=False)
        sb = sb + ridge * float(np.trace(sb)) / d * np.eye(d)
        vals, vecs = eigh(sw, sb)
        u = vecs[:, np.argsort(vals)[::-1][:k]]
        u, _ = np.linalg.qr(u)
    else:
        vals, vecs = np.linalg.eigh(sw)
        u = vecs[:, np.argsort(vals)[::-1][:k]]
    return np.asarray(np.eye(d) - u @ u.T)


def score(d: FloatArray, labels: NDArray[Any]) -> list[float]:
    s = retrieval_scores(-d, labels)
    return [s["nn"], s["first_tier"], s["dcg"]]


def evaluate(
    sf: SetFeatures,
    weights: dict[str, float],
    proj: FloatArray | None = None,
    *,
    meshes: bool = True,
) -> dict[str, Any]:
    """Mesh and cloud scores of one weighting (and projection) on one split.

    ``meshes`` False: the projection maps cloud-mesh comparisons only (meshes
    compare with each other as without it).
    """
    raw = stack(sf.mesh, weights)
    fm = raw @ proj if proj is not None else raw
    out: dict[str, Any] = {
        "mesh": score(l1(fm if meshes else raw, fm if meshes else raw), sf.labels)
    }
    if sf.cloud is None:
        return out
    fc = stack(sf.cloud, weights)
    if proj is not None:
        fc = fc @ proj
    dc = l1(fc, fm)
    if sf.rec_idx:
        fr = stack(sf.rec, weights)
        if proj is not None:
            fr = fr @ proj
        dc[sf.rec_idx] = np.minimum(dc[sf.rec_idx], l1(fr, fm))
    n = len(sf.labels)
    out["cloud"] = score(dc, sf.labels)
    out["own_first"] = float(np.mean(np.argmin(dc, axis=1) == np.arange(n)))
    out["margin"] = log_margin(dc, sf.labels)
    return out


def weightings() -> dict[str, dict[str, float]]:
    v4 = {b[0]: b[3] for b in LAYOUTS[4]}
    return {
        "v4": v4,
        "v4 -pose": {b: w for b, w in v4.items() if b not in POSE},
        "v4 -d2c_mean": {b: w for b, w in v4.items() if b != "d2c_mean"},
        "v4 -inertia": {b: w for b, w in v4.items() if b != "inertia"},
        "v4 pose x0.5": {b: w * (0.5 if b in POSE else 1.0) for b, w in v4.items()},
        "v4 -pose -walk": {b: w for b, w in v4.items() if b not in (*POSE, "walk")},
    }


def other_split(name: str, split: str) -> Dataset:
    (ds,) = build([name], "test" if split == "validation" else "validation")
    return ds


def run_set(
    name: str, split: str, config: MDBDConfig, pairs: int, ranks: Sequence[int]
) -> tuple[list[list[Any]], dict[str, Any]]:
    (ds,) = build([name], split)
    sf = SetFeatures(ds, config)
    n, nrec = len(sf.labels), len(sf.rec_idx)
    clouds = "no cached clouds" if sf.cloud is None else f"{nrec} kept reconstructions"
    title = f"{name} {split}: {n} models ({sf.missing} not cached), {clouds}"
    rows: list[list[Any]] = []
    results: dict[str, Any] = {"n": n, "missing": sf.missing, "recons": nrec, "rows": {}}

    def add(label: str, r: dict[str, Any]) -> None:
        results["rows"][label] = r
        c = r.get("cloud", [None] * 3)
        rows.append([label, *r["mesh"], *c, r.get("own_first"), r.get("margin")])

    ws = weightings()
    for wname, w in ws.items():
        add(wname, evaluate(sf, w))
    fit = SetFeatures(other_split(name, split), config) if ranks and sf.cloud else None
    if fit is not None and fit.cloud is not None and len(fit.labels) >= 4:
        pick = np.random.default_rng(0).permutation(len(fit.labels))[:pairs]
        for wname in ("v4", "v4 -pose"):
            w = ws[wname]
            fm, fc = stack(fit.mesh, w)[pick], stack(fit.cloud, w)[pick]
            for k in ranks:
                for relative in (False, True):
                    p = fit_projection(fm, fc, k, relative=relative)
                    kind = "ratio" if relative else "nuisance"
                    add(f"{wname} + {kind}-{k}", evaluate(sf, w, p))
                    if not relative:
                        add(f"{wname} + {kind}-{k}, clouds only", evaluate(sf, w, p, meshes=False))
        results["pairs"] = len(pick)
    return [[title]] + rows, results


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.studies.cloud_weights")
    ap.add_argument("--split", default="validation", choices=("validation", "test"))
    ap.add_argument(
        "--sets", nargs="+", default=["people-xl", "capod", "figures", "parts", "generic"]
    )
    ap.add_argument("--pairs", type=int, default=36, help="label-free pairs of the fit")
    ap.add_argument("--ranks", type=int, nargs="*", default=[1, 2, 3, 5])
    args = ap.parse_args(argv)
    config = mdbd_config()
    cols = ("weighting", "mesh NN", "1-T", "DCG", "cloud NN", "1-T", "DCG", "own-first", "margin")
    out: dict[str, Any] = {"split": args.split, "pairs": args.pairs, "sets": {}}
    for name in args.sets:
        rows, res = run_set(name, args.split, config, args.pairs, args.ranks)
        print(format_table(rows[0][0], cols, rows[1:]))
        print()
        out["sets"][name] = res
        write_json(OUT / f"cloud_weights_{args.split}.json", out)
    print(f"wrote {OUT / f'cloud_weights_{args.split}.json'}")


if __name__ == "__main__":
    main()
