"""Does a transformed copy of a model find its original first? shapedb against D2.

Usage (from the repository root)::

    python -m bench.stability                        # capod, articulated, parts; test split
    python -m bench.stability --datasets parts --quick
    python -m bench.stability --views 4              # also clouds against sparse views

Every ``len(test) // probes``-th model of each set's test split is copied: shifted by a
fraction of a grid cell, rotated, decimated to 25 % of its faces, or re-sampled as a
point cloud of 20 % of its vertices. Each copy is compared with every test mesh as a
default store compares them (shapedb's descriptor, L1; a cloud also by its kept
Poisson reconstruction, the nearer of the two) and by D2 in the same run. The table
gives the fraction of copies whose nearest mesh is their own original, and for shapedb
also its own model *or a re-posed copy of it* (another pose of the same subject: what a
pose-invariant signature cannot tell apart). Written to bench/results/stability.json.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import decompose_all, format_table, mdbd_config, variant_geometry
from bench.sets.datasets import Dataset, build_sets, families, mesh_arrays
from bench.support.baselines import D2Config, d2_descriptor, l1_similarity
from bench.support.features import kernel_features, l1_matrix, reconstructions
from shapedb.config.core import KernelConfig, MDBDConfig

__all__ = ["VARIANTS", "main", "run_stability"]

RESULTS = Path(__file__).resolve().parent / "results"

#: The copies made of each probe (variant names of :func:`bench.common.decompose_all`).
VARIANTS = ("mesh_shift", "mesh_rotate", "mesh_decimate", "pointcloud")
_COLUMNS = ("shapedb", "shapedb, own or re-posed", "D2")


def run_stability(
    ds: Dataset,
    mdbd: MDBDConfig,
    kcfg: KernelConfig,
    *,
    workers: int = 2,
    probes: int = 30,
    view_cells: float = 0.0,
) -> dict[str, Any]:
    """Fractions of transformed copies whose nearest test mesh is their original.

    Returns ``{variant: {"copies": n, "shapedb": f, "shapedb, own or re-posed": f,
    "D2": f}}`` (D2 for the mesh variants). With ``view_cells``, a last entry asks it
    of the point clouds against the meshes' sparse views (:mod:`shapedb.geometry.view`), as a
    store with ``view_cells`` compares them.
    """
    test = ds.split("test")
    found = decompose_all(test.models, "mesh", mdbd, workers=workers)
    keep = [i for i, b in enumerate(found) if b is not None]
    test = Dataset(ds.name, tuple(test.models[i] for i in keep))
    mesh = [found[i] for i in keep]
    probe = list(range(0, len(test), max(1, len(test) // probes)))
    db = kernel_features(mesh, kcfg)  # type: ignore[arg-type]
    fam = families(test.models)
    out: dict[str, Any] = {}
    for variant in VARIANTS:
        copies = decompose_all([test.models[i] for i in probe], variant, mdbd, workers=workers)
        ok = [k for k, b in enumerate(copies) if b is not None]
        if not ok:
            continue
        target = np.asarray([probe[k] for k in ok])
        fq = kernel_features([copies[k] for k in ok], kcfg)  # type: ignore[misc]
        d = l1_matrix(fq, db)
        if variant == "pointcloud":  # and by its reconstruction, as a store compares
            recon = reconstructions(
                [test.models[probe[k]] for k in ok], [copies[k] for k in ok], mdbd, workers=workers
            )
            d = np.minimum(d, l1_matrix(kernel_features(recon, kcfg), db))  # type: ignore[arg-type]
        hit = np.argmin(d, axis=1)
        res: dict[str, Any] = {
            "copies": len(ok),
            "shapedb": float(np.mean(hit == target)),
            "shapedb, own or re-posed": float(np.mean(fam[hit] == fam[target])),
        }
        if variant != "pointcloud":
            res["D2"] = _d2_first(test, target, variant, mdbd)
        out[variant] = res
        if variant == "pointcloud" and view_cells:
            views = decompose_all(test.models, f"view_{view_cells:g}", mdbd, workers=workers)
            if all(v is not None for v in views):
                d_view = l1_matrix(fq, kernel_features(views, kcfg))  # type: ignore[arg-type]
                hit = np.argmin(np.minimum(d, d_view), axis=1)  # the nearer, as query.search.engine
                out[f"pointcloud -> views {view_cells:g}"] = {
                    "copies": len(ok),
                    "shapedb": float(np.mean(hit == target)),
                    "shapedb, own or re-posed": float(np.mean(fam[hit] == fam[target])),
                }
    rows = [[name, r["copies"], *(r.get(c) for c in _COLUMNS)] for name, r in out.items()]
    print()
    print(
        format_table(
            f"stability, {ds.name}: a copy's nearest mesh is its original ({len(test)} meshes)",
            ("variant", "copies", "shapedb", "own/re-posed", "D2"),
            rows,
        )
    )
    return out


def _d2_first(test: Dataset, target: NDArray[np.int64], variant: str, mdbd: MDBDConfig) -> float:
    """Fraction of D2 descriptors of ``variant`` copies whose nearest mesh is the original."""
    cfg = D2Config(n_pairs=2**18)
    db = np.stack([d2_descriptor(*mesh_arrays(m), cfg) for m in test.models])
    qs = []
    for t in target:
        g = variant_geometry(test.models[int(t)], variant, mdbd)
        qs.append(d2_descriptor(g.vertices, g.faces, D2Config(n_pairs=2**18, seed=1)))
    sim = l1_similarity(np.stack(qs), db)
    return float(np.mean(np.argmax(sim, axis=1) == target))


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.stability", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--datasets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--quick", action="store_true", help="small subsets and a coarse grid")
    ap.add_argument("--probes", type=int, default=30, help="models copied per set")
    ap.add_argument("--views", type=float, default=0.0, help="sparse views every VIEWS cells")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "stability.json")
    args = ap.parse_args(argv)
    base = MDBDConfig(resolution=64, n_balls=256) if args.quick else MDBDConfig()
    mdbd = mdbd_config(base)
    report = {
        ds.name: run_stability(
            ds,
            mdbd,
            KernelConfig(),
            workers=args.workers,
            probes=12 if args.quick else args.probes,
            view_cells=args.views,
        )
        for ds in build_sets(args.datasets, args.quick)
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1) + "\n")
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
