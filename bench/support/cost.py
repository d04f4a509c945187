"""What a mesh ingest, a mesh query and a cloud query cost through the facade, in one run.

:func:`measure`: for the first models of a set and each store configuration, a fresh
store ingests the meshes one at a time (``db.ingest``: "mesh ingest"), then every mesh
(``db.search(mesh)``: "mesh query") and every paper cloud (a random 20 % of the
vertices, ``db.search(cloud)``: "cloud query") is searched once. All configurations run
interleaved model by model, so that a shared machine's load falls on them alike; wall
seconds, one thread (the Poisson solve too). Used by ``python -m bench.representations
--cost`` and by :mod:`bench.studies.cloud_cost`.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.sets.datasets import Model, mesh_arrays, min_cloud_points, point_cloud, stable_seed

__all__ = ["geometries", "measure"]


def geometries(model: Model) -> tuple[Any, Any]:
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

    geoms = [geometries(m) for m in models]
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
