"""Tie tolerance of the MDBD argmax, chosen on the validation splits.

Where the distance field has a ridge (the axis of a cylindrical torso, limb or shaft:
many cells within a hair of the maximum), the greedy argmax takes whichever ridge cell
noise puts on top. A mesh and a point cloud of the same solid, or a mesh and its
decimated copy, then start their packings at different ends of the ridge, and the
difference cascades through every later ball. ``MDBDConfig.tie_cells`` counts the cells
within that many cells of the maximum and connected to it (its ridge) as tied and takes
the first of them along the canonical frame's axes that is within a quarter of the
tolerance of the maximum, so the choice follows the solid instead of the noise.

For each tolerance this bench decomposes the validation splits of the three labelled
sets as meshes and as point clouds (:func:`bench.sets.datasets.point_cloud`) and prints, with
the default descriptor: mesh-mesh NN / 1-T / DCG, cloud queries against the mesh
database (own mesh left out) and the even mixture, their gaps to mesh-mesh, and the
mean kernel between a mesh and its own cloud.

Usage: ``python -m bench.studies.ties [--ties 0 0.5 1 2] [--split validation] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import Balls, decompose_all, format_table, retrieval_scores, write_json
from bench.sets.datasets import articulated, capod, parts, stable_seed
from shapedb.config.core import KernelConfig, MDBDConfig

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "ties.json"
COLUMNS = (
    "set", "tie_cells", "mesh NN", "mesh 1-T", "mesh DCG", "pc->mesh NN", "mixture NN",
    "worst gap", "k(mesh, own pc)", "s/model",
)  # fmt: skip


def _features(balls: list[Balls], config: KernelConfig) -> np.ndarray:
    from shapedb.signature.kernel import features, weights

    w = np.asarray(weights(config))
    return np.stack([np.asarray(features(b.decomposition(), config)) * w for b in balls])


def _mixture(names: list[str]) -> np.ndarray:
    n = len(names)
    mask = np.zeros(n, dtype=bool)
    mask[np.random.default_rng(stable_seed("mixture", n)).permutation(n)[: n // 2]] = True
    return mask


def measure(mesh: list[Balls], pc: list[Balls], labels: np.ndarray, names: list[str]) -> dict:
    """Retrieval figures of one set from its mesh and cloud decompositions."""
    kcfg = KernelConfig()
    fm, fp = _features(mesh, kcfg), _features(pc, kcfg)

    def sim(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.exp(-kcfg.lam * np.abs(a[:, None, :] - b[None, :, :]).sum(-1))

    mm = retrieval_scores(sim(fm, fm), labels)
    pm = retrieval_scores(sim(fp, fm), labels)  # the diagonal (own mesh) is left out
    fx = np.where(_mixture(names)[:, None], fp, fm)
    mx = retrieval_scores(sim(fx, fx), labels)
    return {
        "mesh NN": mm["nn"],
        "mesh 1-T": mm["first_tier"],
        "mesh DCG": mm["dcg"],
        "pc->mesh NN": pm["nn"],
        "mixture NN": mx["nn"],
        "worst gap": max(mm["nn"] - pm["nn"], mm["nn"] - mx["nn"]),
        "k(mesh, own pc)": float(np.diag(sim(fp, fm)).mean()),
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.ties", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--ties", type=float, nargs="+", default=[0.0, 0.75, 1.5])
    ap.add_argument("--split", default="validation", choices=("validation", "test", "all"))
    ap.add_argument("--datasets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    makers = {"capod": capod, "articulated": articulated, "parts": parts}
    rows: list[list[Any]] = []
    for tie in args.ties:
        cfg = dataclasses.replace(MDBDConfig(), tie_cells=tie)
        for name in args.datasets:
            ds = makers[name]().split(args.split)
            mesh = decompose_all(ds.models, "mesh", cfg, workers=args.workers, progress=None)
            pc = decompose_all(ds.models, "pointcloud", cfg, workers=args.workers, progress=None)
            keep = [i for i in range(len(ds)) if mesh[i] is not None and pc[i] is not None]
            labels = np.asarray([ds.models[i].label for i in keep])
            names = [ds.models[i].name for i in keep]
            res = measure([mesh[i] for i in keep], [pc[i] for i in keep], labels, names)  # type: ignore[misc]
            secs = float(np.mean([mesh[i].seconds + pc[i].seconds for i in keep]))  # type: ignore[union-attr]
            rows.append([name, tie, *res.values(), secs])
            print(format_table("", COLUMNS, rows[-1:]).splitlines()[-1], flush=True)
    print()
    print(format_table(f"MDBD tie tolerance ({args.split} splits)", COLUMNS, rows))
    write_json(args.out, {"split": args.split, "columns": list(COLUMNS), "rows": rows})
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
