"""The study of the field's depth buffer and harmonic descriptors (bench/studies/field_depth.py).

The descriptors themselves are the product's (:mod:`shapedb.signature.field_vector`, tested in
tests/shapedb/test_field_descriptors.py); the study keeps its settings' names, the exact
(off-grid) harmonics and the fusion.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from bench.studies.field_depth import (
    DepthConfig,
    depth_buffer_descriptor,
    fuse,
    harmonic_descriptor,
    harmonic_descriptor_grid,
)
from shapedb.config.core import FieldVectorConfig
from shapedb.geometry.base import Grid
from shapedb.geometry.inside import Inside, field_inside
from shapedb.signature import field_vector


def _cylinder(q: NDArray[np.float64]) -> NDArray[np.bool_]:
    return (q[:, 0] ** 2 + q[:, 1] ** 2 <= 0.45**2) & (np.abs(q[:, 2]) <= 0.9)


def _box(q: NDArray[np.float64]) -> NDArray[np.bool_]:
    return np.all(np.abs(q) <= [0.9, 0.5, 0.25], axis=1)


def _voxelised(body: object, rotation: Rotation) -> Inside:
    g = Grid.fit([[-1.5] * 3, [1.5] * 3], resolution=64)
    p = g.to_point(np.indices(g.shape).reshape(3, -1).T)
    f = np.where(body(p @ rotation.as_matrix()), 1.0, -1.0)  # type: ignore[operator]
    return field_inside(f.astype(np.float32).reshape(g.shape), g)


def _rel(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    return float(np.abs(a - b).sum() / np.abs(a).sum())


def test_the_studys_descriptors_are_the_products_at_its_settings() -> None:
    s = _voxelised(_box, Rotation.from_euler("xz", [15, 40], degrees=True))
    small = FieldVectorConfig(depth_resolution=32, depth_frequencies=6)
    np.testing.assert_array_equal(
        depth_buffer_descriptor(s.shell, s.centroid, s.cell, DepthConfig(32, 6)),
        field_vector.depth_buffer_descriptor(s.shell, s.centroid, s.cell, small),
    )
    np.testing.assert_array_equal(
        harmonic_descriptor_grid(s.shell, s.centroid),
        field_vector.harmonic_energies(s.shell, s.centroid),
    )


def test_fusion_divides_each_distance_by_its_median() -> None:
    a = np.array([[0.0, 2.0, 4.0], [2.0, 0.0, 2.0], [4.0, 2.0, 0.0]])
    np.testing.assert_allclose(fuse(a, 10 * a, 0.5), 1.5 * a / 2.0)


def test_the_exact_harmonics_keep_a_turned_box_and_tell_a_cylinder_apart() -> None:
    box = harmonic_descriptor(*_sc(_voxelised(_box, Rotation.identity())))
    turned = harmonic_descriptor(
        *_sc(_voxelised(_box, Rotation.from_euler("xyz", [30, 50, 70], degrees=True)))
    )
    cylinder = harmonic_descriptor(*_sc(_voxelised(_cylinder, Rotation.identity())))
    assert _rel(box, turned) < 0.2  # re-voxelised: staircase edges
    assert _rel(box, cylinder) > 2 * _rel(box, turned)
    with pytest.raises(ValueError, match="degenerate"):
        harmonic_descriptor(np.zeros((0, 3)), np.zeros(3))


def _sc(s: Inside) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return s.shell, s.centroid


def test_the_angle_grid_harmonics_match_the_exact_ones_up_to_the_snapping() -> None:
    s = _voxelised(_cylinder, Rotation.from_euler("xy", [20, 40], degrees=True))
    exact = harmonic_descriptor(s.shell, s.centroid, shells=8, bands=6)
    grid = harmonic_descriptor_grid(s.shell, s.centroid, shells=8, bands=6)
    coarse = harmonic_descriptor_grid(s.shell, s.centroid, shells=8, bands=6, n_theta=8)
    assert grid.shape == exact.shape == (48,)
    assert _rel(exact, grid) < 0.02
    assert _rel(exact, coarse) > _rel(exact, grid)
