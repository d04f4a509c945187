"""What a cloud query costs against a mesh query, through the facade, in one run.

For the first ``n`` models of a set and each store configuration in ``configs``, a
fresh store ingests the ``n`` meshes one at a time (``db.ingest``: "mesh ingest"),
then every mesh (``db.search(mesh)``: "mesh query") and every paper cloud (a random
20 % of the vertices, ``db.search(cloud)``: "cloud query") is searched once. All
configurations run interleaved model by model, so that a shared machine's load
falls on them alike; wall seconds, one thread (the Poisson solve too).

:func:`profile_cloud_query` splits a cloud query into its stages (the cloud's own
field, packing and refinement; the Poisson solve; the reconstruction's
decomposition; their features), as ``query.search.engine`` runs them;
``python -m bench.cloud_cost [--sets ...] [--n 4]`` prints its medians per set.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.sets.datasets import Model, mesh_arrays, min_cloud_points, point_cloud, stable_seed

__all__ = ["main", "measure", "profile_cloud_query"]


def _geometries(model: Model) -> tuple[Any, Any]:
    """The model's mesh and its paper cloud (as the bench's ``pointcloud`` variant)."""
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.geometry.pointcloud import PointCloud

    v, f = mesh_arrays(model)
    points = point_cloud(
        v, f, seed=stable_seed(model.name, "pointcloud"), min_points=min_cloud_points(model)
    )
    return TriangleMesh(v, f, name=model.name), PointCloud(points, name=model.name)


def measure(
    models: Sequence[Model], configs: Mapping[str, Mapping[str, Any]]
) -> dict[str, dict[str, list[float]]]:
    """Wall seconds per model of mesh ingest, mesh query and cloud query, per configuration.

    Parameters
    ----------
    models : sequence of Model
        The models (their meshes are the store; at least 2).
    configs : mapping
        Name -> ``shapedb.connect`` options of a store (e.g. ``{"reconstruct_depth": 7}``).

    Returns
    -------
    dict
        Name -> {"ingest", "mesh", "cloud"} -> seconds (len(models),).
    """
    import shapedb

    geoms = [_geometries(m) for m in models]
    out: dict[str, dict[str, list[float]]] = {
        c: {"ingest": [], "mesh": [], "cloud": []} for c in configs
    }
    with tempfile.TemporaryDirectory(prefix="cloud_cost_") as tmp:
        dbs = {
            c: shapedb.connect(Path(tmp) / f"s{i}", **opts)
            for i, (c, opts) in enumerate(configs.items())
        }
        for m, (mesh, _) in zip(models, geoms, strict=True):
            for c, db in dbs.items():
                t0 = time.perf_counter()
                db.ingest({m.name: mesh}, workers=1)
                out[c]["ingest"].append(time.perf_counter() - t0)
        for mesh, cloud in geoms:
            for c, db in dbs.items():
                t0 = time.perf_counter()
                db.search(mesh, k=5)
                out[c]["mesh"].append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                db.search(cloud.transformed(np.eye(3), np.zeros(3)), k=5)  # a fresh copy
                out[c]["cloud"].append(time.perf_counter() - t0)
    return out


def profile_cloud_query(model: Model, *, depth: int = 8) -> dict[str, float]:
    """Wall seconds of each stage of a cloud query of ``model``'s paper cloud (and its mesh's).

    Keys: ``mesh`` (the mesh's decomposition and feature), ``cloud frame``, ``cloud sdf``,
    ``cloud packing`` and ``cloud refine`` (its own decomposition), ``poisson``,
    ``recon decomposition``, ``features`` (the two features of the cloud).
    """
    from shapedb.mdbd.decomposition import decompose
    from shapedb.mdbd.reconstruct import reconstruct
    from shapedb.signature.kernel import features

    mesh, cloud = _geometries(model)
    t0 = time.perf_counter()
    features(decompose(mesh))
    out = {"mesh": time.perf_counter() - t0}
    d = decompose(cloud)
    t = d.timings
    out.update(
        {
            "cloud frame": t.get("frame", 0.0),
            "cloud sdf": t["sdf"],
            "cloud packing": t["decompose"] - t["refine"],
            "cloud refine": t["refine"],
        }
    )
    frame = np.asarray(d.frame)
    rotation, centre = frame[:3, :3], frame[:3, 3]
    t0 = time.perf_counter()
    surface = reconstruct(cloud.transformed(rotation.T, -rotation.T @ centre), depth=depth)
    out["poisson"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    r = decompose(surface) if surface is not None else None
    out["recon decomposition"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    features(d)
    if r is not None:
        features(r)
    out["features"] = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> None:
    """Print the median stage seconds of cloud queries (:func:`profile_cloud_query`)."""
    import argparse

    from bench.common import format_table, write_json
    from bench.sets.datasets import articulated, capod, parts, people

    makers = {"people": people, "capod": capod, "figures": articulated, "parts": parts}

    ap = argparse.ArgumentParser(description="Where a cloud query's time goes, per set.")
    ap.add_argument(
        "--sets",
        nargs="+",
        default=["people", "capod", "figures", "parts"],
        choices=["people", "capod", "figures", "parts"],
    )
    ap.add_argument("--split", default="validation", choices=("test", "validation"))
    ap.add_argument("--n", type=int, default=4, help="models per set")
    ap.add_argument("--depth", type=int, nargs="+", default=[8, 7])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    rows, out = [], {}
    for ds in (makers[name]().split(args.split) for name in args.sets):
        for depth in args.depth:
            runs = [profile_cloud_query(m, depth=depth) for m in ds.models[: args.n]]
            med = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
            cloud = sum(v for k, v in med.items() if k != "mesh")
            rows.append([ds.name, depth, *med.values(), cloud, cloud / med["mesh"]])
            out[f"{ds.name} depth {depth}"] = med
    keys = list(next(iter(out.values())))
    print(
        format_table(
            f"Stages of a cloud query, median wall s of {args.n} models per set (one thread)",
            ("set", "Poisson depth", *keys, "cloud query", "x mesh"),
            rows,
        )
    )
    write_json(args.out, {"split": args.split, "n": args.n, "stages": out})


#: Where :func:`main` writes its JSON.
OUT = Path(__file__).resolve().parent / "results" / "cloud_cost_profile.json"

if __name__ == "__main__":
    main()
