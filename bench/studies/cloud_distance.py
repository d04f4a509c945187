"""How far is a sparse cloud's distance from the exact distance, at its ball centres?

For every model of a set's split: the paper's cloud (20 % of the vertices), the centres
of its cached MDBD balls (``pointcloud`` variant; ``--centres mesh``: of the mesh's,
for sets whose clouds are not cached), the exact distance to the mesh
there (:meth:`shapedb.geometry.mesh.TriangleMesh.unsigned_distance`) and each estimator's
distance. Printed: quantiles (q10 / median / q90) of estimate / exact over all
centres and over the 32 largest balls of each model, and the median absolute error
in grid cells. Estimators (:meth:`shapedb.geometry.pointcloud.PointCloud.unsigned_distance`
with ``distance=``):

``nearest``  distance to the nearest sample;
``splat``    the nearest splat (the default before this study);
``sphere``   the nearer of the splat and the algebraic sphere fitted to the samples
             around the splat's closest point (:mod:`shapedb.geometry.surface_fit`).

Usage: ``python -m bench.studies.cloud_distance --sets people --split validation``;
writes ``bench/results/studies/cloud_distance_<split>_<centres>.json``. Decomposes nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, load_balls, mdbd_config, variant_geometry, write_json
from bench.representations import build
from bench.sets.datasets import mesh_arrays
from bench.studies.cloud_twins import cached_path
from shapedb.geometry.mesh import TriangleMesh

OUT = Path(__file__).resolve().parents[1] / "results" / "studies"
ESTIMATORS = ("nearest", "splat", "sphere")
TOP = 32


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.studies.cloud_distance")
    ap.add_argument("--sets", nargs="+", default=["people"])
    ap.add_argument("--split", default="validation")
    ap.add_argument("--limit", type=int, default=0, help="first N models only (0: all)")
    ap.add_argument("--estimators", nargs="+", default=list(ESTIMATORS))
    ap.add_argument(
        "--centres",
        default="pointcloud",
        choices=("pointcloud", "mesh"),
        help="whose cached balls give the centres: the cloud's (default) or the mesh's",
    )
    args = ap.parse_args(argv)
    cfg = mdbd_config()
    out: dict[str, Any] = {}
    for ds in build(args.sets, args.split):
        models = ds.models[: args.limit] if args.limit else ds.models
        ratios: dict[str, list[Any]] = {e: [] for e in args.estimators}
        top: dict[str, list[Any]] = {e: [] for e in args.estimators}
        cells: dict[str, list[Any]] = {e: [] for e in args.estimators}
        for m in models:
            path = cached_path(m, args.centres, cfg)
            if not path.exists():
                continue
            b = load_balls(path)
            v, f = mesh_arrays(m)
            exact = TriangleMesh(v, f).unsigned_distance(b.centers)
            ok = exact > 1e-9
            cloud = variant_geometry(m, "pointcloud", cfg)
            for e in args.estimators:
                d = cloud.unsigned_distance(b.centers, distance=e)
                r = d[ok] / exact[ok]
                ratios[e].append(r)
                top[e].append(r[: min(TOP, len(r))])
                cells[e].append(np.abs(d - exact) / b.spacing)
        rows, res = [], {}
        for e in args.estimators:
            a, t = np.concatenate(ratios[e]), np.concatenate(top[e])
            qa, qt = np.percentile(a, [10, 50, 90]), np.percentile(t, [10, 50, 90])
            err = float(np.median(np.concatenate(cells[e])))
            rows.append([e, *qa, *qt, err])
            res[e] = {"all": qa, "top": qt, "abs_error_cells": err}
        print(
            format_table(
                f"{ds.name} {args.split} ({len(ratios[args.estimators[0]])} clouds): "
                f"estimate / exact distance at the {args.centres}'s ball centres",
                (
                    "estimator",
                    "q10",
                    "median",
                    "q90",
                    f"top{TOP} q10",
                    "median",
                    "q90",
                    "|err| cells",
                ),
                rows,
            )
        )
        out[ds.name] = res
    write_json(
        OUT / f"cloud_distance_{args.split}_{args.centres}.json",
        {"split": args.split, "centres": args.centres, "sets": out},
    )


if __name__ == "__main__":
    main()
