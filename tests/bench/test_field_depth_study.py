"""The field's depth buffer and harmonic descriptors (bench/studies/field_depth.py)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from bench.studies.field_depth import (
    depth_buffer_descriptor,
    depth_images,
    fuse,
    harmonic_descriptor,
    harmonic_descriptor_grid,
    principal_coordinates,
)
from shapedb.geometry import Grid
from shapedb.inside import Inside, field_inside

Body = Callable[[NDArray[np.float64]], NDArray[np.bool_]]


def _box(q: NDArray[np.float64]) -> NDArray[np.bool_]:
    return np.all(np.abs(q) <= [0.9, 0.5, 0.25], axis=1)


def _cylinder(q: NDArray[np.float64]) -> NDArray[np.bool_]:
    return (q[:, 0] ** 2 + q[:, 1] ** 2 <= 0.45**2) & (np.abs(q[:, 2]) <= 0.9)


def _voxelised(body: Body, rotation: Rotation, shift: float = 0.0) -> Inside:
    """The inside of ``body`` turned by ``rotation`` and moved, on a 64-cell grid."""
    g = Grid.fit([[-1.5] * 3, [1.5] * 3], resolution=64)
    p = g.to_point(np.indices(g.shape).reshape(3, -1).T)
    f = np.where(body((p - shift) @ rotation.as_matrix()), 1.0, -1.0)
    return field_inside(f.astype(np.float32).reshape(g.shape), g)


def _dbd(s: Inside) -> NDArray[np.float64]:
    return depth_buffer_descriptor(s.shell, s.centroid, s.cell)


def _rel(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    return float(np.abs(a - b).sum() / np.abs(a).sum())


@pytest.mark.parametrize(
    "descriptor",
    [
        _dbd,
        lambda s: harmonic_descriptor(s.shell, s.centroid),
        lambda s: harmonic_descriptor_grid(s.shell, s.centroid),
    ],
)
def test_a_turned_box_keeps_its_descriptor_and_a_cylinder_does_not(
    descriptor: Callable[[Inside], NDArray[np.float64]],
) -> None:
    box = descriptor(_voxelised(_box, Rotation.identity()))
    turned = descriptor(
        _voxelised(_box, Rotation.from_euler("xyz", [30, 50, 70], degrees=True), 0.1)
    )
    cylinder = descriptor(_voxelised(_cylinder, Rotation.identity()))
    assert _rel(box, turned) < 0.2  # the turned box is re-voxelised: staircase edges
    assert _rel(box, cylinder) > 2 * _rel(box, turned)


def test_the_depth_descriptor_ignores_the_principal_axes_signs() -> None:
    s = _voxelised(_box, Rotation.from_euler("z", 20, degrees=True))
    flipped = 2 * s.centroid - s.shell  # every axis flipped about the centroid
    a = depth_buffer_descriptor(s.shell, s.centroid, s.cell)
    b = depth_buffer_descriptor(flipped, s.centroid, s.cell)
    assert _rel(a, b) < 0.01  # pixel edges: a mirrored cell may round to the next pixel


def test_the_principal_frame_puts_the_longest_axis_first_in_the_unit_cube() -> None:
    s = _voxelised(_box, Rotation.from_euler("y", 90, degrees=True))
    y, scale = principal_coordinates(s.shell, s.centroid)
    assert np.abs(y).max() == pytest.approx(1.0)
    assert np.ptp(y, axis=0)[0] > np.ptp(y, axis=0)[1] > np.ptp(y, axis=0)[2]
    assert scale == pytest.approx(0.9, abs=0.1)


def test_a_cube_seen_from_plus_x_is_a_square_at_its_face_height() -> None:
    g = np.linspace(-0.45, 0.45, 10)  # cells of 0.1 on the centres of 0.1 px
    cells = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    img = depth_images(cells, 0.05, 20)
    assert img.shape == (6, 20, 20)
    for view in range(6):
        seen = img[view] > 0
        assert seen.sum() == 100
        assert seen[5:15, 5:15].all()
        np.testing.assert_allclose(img[view][seen], 0.725)
    wide = depth_images(cells, 0.1, 20)  # cells of 0.2 reach the next pixel
    assert (wide[0] > 0).sum() == 144


def test_fusion_divides_each_distance_by_its_median() -> None:
    a = np.array([[0.0, 2.0, 4.0], [2.0, 0.0, 2.0], [4.0, 2.0, 0.0]])
    np.testing.assert_allclose(fuse(a, 10 * a, 0.5), 1.5 * a / 2.0)


def test_an_empty_shell_is_refused() -> None:
    with pytest.raises(ValueError, match="empty"):
        principal_coordinates(np.zeros((0, 3)), np.zeros(3))


def test_the_angle_grid_harmonics_match_the_exact_ones_up_to_the_snapping() -> None:
    s = _voxelised(_cylinder, Rotation.from_euler("xy", [20, 40], degrees=True))
    exact = harmonic_descriptor(s.shell, s.centroid, shells=8, bands=6)
    grid = harmonic_descriptor_grid(s.shell, s.centroid, shells=8, bands=6)
    coarse = harmonic_descriptor_grid(s.shell, s.centroid, shells=8, bands=6, n_theta=8)
    assert grid.shape == exact.shape == (48,)
    assert _rel(exact, grid) < 0.02
    assert _rel(exact, coarse) > _rel(exact, grid)
