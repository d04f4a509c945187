"""The cloud orientation study's visibility rule on an analytic open box."""

from __future__ import annotations

import numpy as np

from bench.studies.cloud_orientation import iou, visible_normals
from shapedb.geometry.pointcloud import PointCloud


def open_box(n: int = 24) -> np.ndarray:
    """Points on the unit cube's bottom and four walls (no top): a basin of single sheets."""
    u = (np.arange(n) + 0.5) / n
    a, b = (g.ravel() for g in np.meshgrid(u, u))
    zero, one = np.zeros_like(a), np.ones_like(a)
    faces = [
        (a, b, zero),  # bottom
        (zero, a, b), (one, a, b),  # walls x = 0, 1
        (a, zero, b), (a, one, b),  # walls y = 0, 1
    ]  # fmt: skip
    return np.concatenate([np.stack(f, axis=1) for f in faces])


def test_a_basin_s_sheets_turn_to_the_side_more_rays_escape_from() -> None:
    cloud = PointCloud(open_box())
    # today's orientation scrambled: the rule alone must turn the walls outwards
    signs = np.random.default_rng(0).choice([-1.0, 1.0], size=len(cloud.points))
    cloud.__dict__["normals"] = cloud._pca * signs[:, None]
    normals, two_sided, turned = visible_normals(cloud)
    assert turned.mean() > 0.5 and not (turned & ~two_sided).any()
    outward = np.einsum("ij,ij->i", normals, cloud.points - 0.5) > 0
    assert outward[turned].all()


def test_iou() -> None:
    a = np.array([True, True, False, False])
    assert iou(a, np.array([True, False, True, False])) == 1 / 3
    assert iou(np.zeros(3, bool), np.zeros(3, bool)) == 1.0
