"""People set: descriptor version 5 and per-block reweightings, cloud->mesh and mesh->mesh.

Every block of descriptor version 5 (version 4's blocks plus ``union``) is computed
once per model from the cached decompositions (mesh, 20 % cloud, the cloud's kept
reconstruction), each divided by its typical distance (weight 1). A *weighting*
is a weight per block; meshes compare by the weighted L1, a cloud by the store's
rule (the nearer of its own feature and its kept reconstruction's). Printed:

* per block (meshes): ``sep`` = median distance between two subjects / median
  distance between two poses of one subject (>1: the block tells people apart more
  than poses); ``shift`` = median distance of a cloud to its own mesh / median
  distance between two subjects (small: a cloud moves the block little);
  mesh->mesh and cloud->mesh NN of the block alone;
* per weighting: mesh->mesh and cloud->mesh NN / 1-T / DCG, own-first, and the
  log margin (:func:`bench.common.log_margin`) of the clouds.

Version 4 and version 5 are weightings too (their own weights). ``stable`` keeps
the blocks with ``sep`` above and ``shift`` below the thresholds measured on the
split. Usage: ``python -m bench.studies.people_blocks --split validation`` (then
``--split test``); decomposes nothing (``--cached``: reads ``SHAPEDB_BENCH_CACHE``).
Results go to bench/results/studies/people_blocks_<split>.json.

The shared cache holds the people set decomposed before the sheet rule
(``shapedb.geometry.sheet``, ``MDBDConfig.sheet_cells``) joined the engine; the rule leaves
closed solids unchanged (every person mesh, cloud and reconstruction is one), so a
decomposition missing under today's key is read under that earlier key
(:func:`pre_sheet_path`: the engine of commit :data:`PRE_SHEET`; since then the
engine only gained the rule and a flat-mesh check).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import bench.common as common
import bench.representations as representations
from bench.common import Balls, format_table, log_margin, mdbd_config, retrieval_scores, write_json
from bench.representations import build, load_set
from bench.support.features import kernel_features
from shapedb.config.core import Config, MDBDConfig
from shapedb.signature.descriptor import LAYOUTS

#: The last commit before the sheet rule (the people set's decompositions are cached with it).
PRE_SHEET = "f031e22"
OUT = Path(__file__).resolve().parents[1] / "results" / "studies"
FloatArray = NDArray[np.float64]


def pre_sheet_path(model: Any, variant: str, config: MDBDConfig) -> Path:
    """Today's cache path of ``model`` if it exists, else its key before the sheet rule."""
    path = common.cache_path(model, variant, config)
    if path.exists() or variant.startswith(("pointcloud_noisy", "pointcloud_partial")):
        return path
    return common.cache_path(model, variant, config, engine_commit=PRE_SHEET)


def block_features(balls: list[Balls]) -> dict[str, FloatArray]:
    """Per block of version 5, (n, dim) features divided by the block's typical distance."""
    cfg = Config().with_options(descriptor=5)
    f = kernel_features(balls, cfg)
    layout = LAYOUTS[5]
    cal = np.log(10.0) / sum(b[3] for b in layout)
    out, at = {}, 0
    for name, size, _typical, weight in layout:
        out[name] = f[:, at : at + size] / (weight * cal)  # = raw block / typical
        at += size
    return out


def l1(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.abs(a[:, None, :] - b[None, :, :]).sum(-1)


def scores(d: FloatArray, labels: NDArray[Any]) -> list[float]:
    s = retrieval_scores(-d, labels)
    return [s["nn"], s["first_tier"], s["dcg"]]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.studies.people_blocks")
    ap.add_argument("--split", default="validation")
    ap.add_argument("--sep", type=float, default=1.4, help="'stable': keep blocks with sep above")
    ap.add_argument("--shift", type=float, default=0.6, help="'stable': and shift below")
    args = ap.parse_args(argv)
    representations.ENGINE_COMMITS[:] = [PRE_SHEET]
    (ds,) = build(["people"], args.split)
    data = load_set(ds, mdbd_config(), ["cloud"], workers=1, cached=True)
    labels = np.asarray(data.labels)
    n = len(labels)
    fm = block_features(data.mesh)
    fc = block_features(data.clouds["cloud"])
    rec = data.recons["cloud"]
    idx = [i for i, r in enumerate(rec) if r is not None]
    fr = block_features([rec[i] for i in idx]) if idx else None  # type: ignore[misc]
    names = [b[0] for b in LAYOUTS[5]]
    dm = {b: l1(fm[b], fm[b]) for b in names}
    dc = {b: l1(fc[b], fm[b]) for b in names}
    dr = {b: l1(fr[b], fm[b]) for b in names} if fr is not None else {}
    print(f"people {args.split}: {n} models, {len(idx)} kept reconstructions")

    same = labels[:, None] == labels[None, :]
    off = ~np.eye(n, dtype=bool)
    per_block: dict[str, dict[str, float]] = {}
    rows = []
    for b in names:
        between = float(np.median(dm[b][~same]))
        within = float(np.median(dm[b][same & off]))
        shift = float(np.median(np.diag(dc[b]))) / between
        mnn = scores(dm[b], labels)[0]
        cnn = scores(dc[b], labels)[0]
        per_block[b] = {"sep": between / within, "shift": shift, "mesh_nn": mnn, "cloud_nn": cnn}
        rows.append([b, between / within, shift, mnn, cnn])
    print(
        format_table(
            f"people {args.split}: per block",
            ("block", "sep", "shift", "mesh NN", "cloud NN (own)"),
            rows,
        )
    )

    def layout_weights(version: int) -> dict[str, float]:
        return {b[0]: b[3] for b in LAYOUTS[version]}

    stable = {
        b: 1.0 for b, s in per_block.items() if s["sep"] > args.sep and s["shift"] < args.shift
    }
    weightings: dict[str, dict[str, float]] = {
        "v4": layout_weights(4),
        "v5": layout_weights(5),
        "union": {"union": 1.0},
        "radius": {"radius": 1.0},
        "radius+union": {"radius": 1.0, "union": 1.0},
        "radius+union (v5 weights)": {"radius": 4.0, "union": 4.0},
        "radius+paper_sorted+union": {"radius": 4.0, "paper_sorted": 6.0, "union": 4.0},
        "geodesic+union": {"geodesic": 1.0, "union": 1.0},
        "v4 without d2c_mean, inertia": {
            b: w for b, w in layout_weights(4).items() if b not in ("d2c_mean", "inertia")
        },
        "v5 without d2c_mean, inertia, walk": {
            b: w for b, w in layout_weights(5).items() if b not in ("d2c_mean", "inertia", "walk")
        },
        "v5 without d2c_mean, inertia": {
            b: w for b, w in layout_weights(5).items() if b not in ("d2c_mean", "inertia")
        },
        f"stable (sep>{args.sep}, shift<{args.shift}): {'+'.join(stable)}": stable,
    }
    results: dict[str, Any] = {"n": n, "recons": len(idx), "blocks": per_block, "weightings": {}}
    rows = []
    for name, w in weightings.items():
        if not w:
            continue
        mesh = sum(w[b] * dm[b] for b in w)
        cloud = sum(w[b] * dc[b] for b in w)
        if dr:
            recd = sum(w[b] * dr[b] for b in w)
            cloud = cloud.copy()
            cloud[idx] = np.minimum(cloud[idx], recd)
        ms, cs = scores(mesh, labels), scores(cloud, labels)
        own = float(np.mean(np.argmin(cloud, axis=1) == np.arange(n)))
        margin = log_margin(cloud, labels)
        results["weightings"][name] = {
            "weights": w, "mesh": ms, "cloud": cs, "own_first": own, "cloud_margin": margin
        }  # fmt: skip
        rows.append([name, *ms, *cs, own, margin])
    cols = ("weighting", "mesh NN", "1-T", "DCG", "cloud NN", "1-T", "DCG", "own-first", "margin")
    print(format_table(f"people {args.split}: weightings", cols, rows))
    write_json(OUT / f"people_blocks_{args.split}.json", results)


if __name__ == "__main__":
    main()
