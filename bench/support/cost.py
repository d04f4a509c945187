"""What a mesh ingest and mesh, cloud, scan and crop queries cost through the facade, in one run.

:func:`measure`: for the first models of a set and each store configuration, a fresh
store ingests the meshes one at a time (``db.ingest``: "mesh ingest"), then every mesh
(``db.search(mesh)``: "mesh query"), every paper cloud (a random 20 % of the
vertices, ``db.search(cloud)``: "cloud query"), every one-sided scan and every half
mesh (:mod:`bench.sets.scans`, seeded as ``bench.quality --queries``: "one-sided", and
"cropped" through ``partial=True``, the path halves take) is searched once. All configurations run
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


#: The timed query kinds besides the mesh itself, in the order of :func:`geometries`.
QUERIES = ("cloud", "one-sided", "cropped")
#: ``db.search`` options of a kind (a half is searched by the partial path).
OPTIONS = {"cropped": {"partial": True}}


def geometries(model: Model) -> tuple[Any, ...]:
    """The model's mesh, its paper cloud (as the bench's ``pointcloud`` variant), its
    one-sided scan and its half (as ``bench.quality --queries one-sided cropped``)."""
    from bench.sets import scans
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.geometry.pointcloud import PointCloud

    v, f = mesh_arrays(model)
    points = point_cloud(
        v, f, seed=stable_seed(model.name, "pointcloud"), min_points=min_cloud_points(model)
    )
    scan = scans.one_sided_scan(v, f, seed=stable_seed(model.name, "one-sided"))
    half = scans.cropped_mesh(v, f, seed=stable_seed(model.name, "cropped"))
    return (
        TriangleMesh(v, f, name=model.name),
        PointCloud(points, name=model.name),
        PointCloud(scan, name=model.name),
        TriangleMesh(*half, name=model.name),
    )


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
        Name -> {"ingest", "mesh", "cloud", "one-sided", "cropped"} -> seconds (len(models),).
    """
    import shapedb

    geoms = [geometries(m) for m in models]
    out: dict[str, dict[str, list[float]]] = {
        c: {k: [] for k in ("ingest", "mesh", *QUERIES)} for c in configs
    }
    with tempfile.TemporaryDirectory(prefix="cloud_cost_") as tmp:
        dbs = {
            c: shapedb.connect(Path(tmp) / f"s{i}", **opts)
            for i, (c, opts) in enumerate(configs.items())
        }
        for m, (mesh, *_) in zip(models, geoms, strict=True):
            for c, db in dbs.items():
                t0 = time.perf_counter()
                db.ingest({m.name: mesh}, workers=1)
                out[c]["ingest"].append(time.perf_counter() - t0)
        for mesh, *others in geoms:
            for c, db in dbs.items():
                t0 = time.perf_counter()
                db.search(mesh, k=5)
                out[c]["mesh"].append(time.perf_counter() - t0)
                for kind, query in zip(QUERIES, others, strict=True):
                    t0 = time.perf_counter()
                    fresh = query.transformed(np.eye(3), np.zeros(3))  # no cached state
                    db.search(fresh, k=5, **OPTIONS.get(kind, {}))
                    out[c][kind].append(time.perf_counter() - t0)
    return out
