"""Warm-up run once in the process-pool's fork server (private).

The ingest process pool uses the ``forkserver`` start method and preloads this
module there: importing it imports every representation and runs one tiny
decomposition of each, so that the numba-compiled kernels, trimesh's lazy imports
and scipy are loaded once, and every worker forked from the server starts warm
instead of paying about three seconds on its first shape.
"""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)


def warm() -> None:
    """Decompose one tiny shape of each representation; never raises."""
    try:
        import numpy as np

        from shapedb.config.core import Config
        from shapedb.geometry.base import Geometry
        from shapedb.geometry.mesh import TriangleMesh
        from shapedb.mdbd.decomposition import decompose
        from shapedb.signature.kernel import features

        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
        f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        shapes: list[Geometry] = [TriangleMesh(v, f)]
        try:
            from shapedb.geometry.pointcloud import PointCloud

            rng = np.random.default_rng(0)
            p = rng.normal(size=(200, 3))
            p /= np.linalg.norm(p, axis=1, keepdims=True)
            shapes.append(PointCloud(p, p))
        except Exception:  # pragma: no cover - optional warm-up only
            log.debug("point-cloud warm-up skipped", exc_info=True)
        try:
            from shapedb.geometry.voxels import VoxelGrid

            occ = np.zeros((6, 6, 6), dtype=bool)
            occ[1:5, 1:5, 1:5] = True
            shapes.append(VoxelGrid(occ, origin=np.zeros(3), pitch=1.0))
        except Exception:  # pragma: no cover
            log.debug("voxel warm-up skipped", exc_info=True)
        config = Config().with_options(resolution=16, n_balls=8)
        for g in shapes:
            features(decompose(g, config=config.mdbd), config)
        import trimesh.exchange.load  # noqa: F401 - trimesh's loaders import lazily
    except Exception:  # pragma: no cover - a warm-up must never break the pool
        log.debug("worker warm-up failed", exc_info=True)


warm()
