"""The field vector: depth buffers and spherical-harmonic energies of the field's inside."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from shapedb.config.core import Config, FieldVectorConfig
from shapedb.errors import ConfigError
from shapedb.geometry.base import Grid
from shapedb.geometry.implicit import Box, Sphere
from shapedb.geometry.inside import Inside, field_inside
from shapedb.mdbd.decomposition import decompose
from shapedb.signature.field_vector import (
    decomposition_field_vector,
    depth_buffer_descriptor,
    depth_images,
    field_vector,
    field_vector_dim,
    field_vector_parts,
    harmonic_energies,
    principal_coordinates,
)

Body = Callable[[NDArray[np.float64]], NDArray[np.bool_]]


def _box(q: NDArray[np.float64]) -> NDArray[np.bool_]:
    return np.all(np.abs(q) <= [0.9, 0.5, 0.25], axis=1)


def _cylinder(q: NDArray[np.float64]) -> NDArray[np.bool_]:
    return (q[:, 0] ** 2 + q[:, 1] ** 2 <= 0.45**2) & (np.abs(q[:, 2]) <= 0.9)


def _ball(q: NDArray[np.float64]) -> NDArray[np.bool_]:
    return (q**2).sum(axis=1) <= 0.8**2


def _voxelised(body: Body, rotation: Rotation, shift: float = 0.0, scale: float = 1.0) -> Inside:
    """The inside of ``body`` scaled, turned and moved, on a 64-cell grid about it."""
    g = Grid.fit([[shift - 1.5 * scale] * 3, [shift + 1.5 * scale] * 3], resolution=64)
    p = g.to_point(np.indices(g.shape).reshape(3, -1).T)
    f = np.where(body((p - shift) @ rotation.as_matrix() / scale), 1.0, -1.0)
    return field_inside(f.astype(np.float32).reshape(g.shape), g)


def _moved(s: Inside, matrix: NDArray[np.float64], scale: float, shift: float) -> Inside:
    """The same cells under an exact similarity (no re-voxelisation)."""
    return Inside(
        scale * s.shell @ matrix.T + shift, scale * s.cell, scale * s.centroid @ matrix.T + shift,
        s.count,
    )  # fmt: skip


def _rel(a: NDArray[np.floating], b: NDArray[np.floating]) -> float:
    return float(np.abs(a - b).sum() / np.abs(a).sum())


def _sphere_points(n: int) -> NDArray[np.float64]:
    """``n`` points spread evenly on the unit sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    polar, turn = np.arccos(1 - 2 * i / n), np.pi * (1 + 5**0.5) * i
    return np.stack(
        [np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar), np.cos(polar)], axis=1
    )


def test_dims_and_parts_follow_the_config() -> None:
    box = _voxelised(_box, Rotation.identity())
    assert field_vector_dim() == 438 + 512 == field_vector_dim(Config())
    depth, harmonic = field_vector_parts()
    assert (depth, harmonic) == (slice(0, 438), slice(438, 950))
    small = FieldVectorConfig(depth_frequencies=4, harmonic_shells=8, harmonic_bands=6)
    v = field_vector(box, small)
    assert v.dtype == np.float32 and v.shape == (field_vector_dim(small),)
    depth, harmonic = field_vector_parts(small)
    assert (
        depth.stop == harmonic.start
        and harmonic.stop == len(v)
        and harmonic.stop - depth.stop == 48
    )
    np.testing.assert_array_equal(
        v[depth],
        depth_buffer_descriptor(box.shell, box.centroid, box.cell, small).astype(np.float32),
    )
    np.testing.assert_array_equal(
        v[harmonic], harmonic_energies(box.shell, box.centroid, small).astype(np.float32)
    )
    assert np.all(np.isfinite(field_vector(box)))


def test_a_spheres_harmonic_energies_sit_in_band_0() -> None:
    # two concentric spheres of evenly spread points: each a ring of its own (radii 1 and
    # 0.5, mean 0.75: rings 21 and 10 of 32), half of the points each
    unit = _sphere_points(20000)
    shell = 2.0 * np.concatenate([unit, 0.5 * unit]) + [1.0, 2.0, 3.0]
    h = harmonic_energies(shell, np.array([1.0, 2.0, 3.0])).reshape(32, 16)
    expected = np.zeros(32)
    expected[[10, 21]] = 0.5 / np.sqrt(4 * np.pi)  # |sum of Y_00| / cells
    np.testing.assert_allclose(h[:, 0], expected, rtol=1e-9)
    assert h[:, 1:].sum() < 0.01 * h.sum()  # the angle grid's snapping alone
    # a voxelised ball: band 0 the largest, odd bands nearly nothing (central symmetry)
    b = harmonic_energies(*_parts(_voxelised(_ball, Rotation.identity()))).reshape(32, 16)
    per_band = b.sum(axis=0)
    assert per_band.argmax() == 0 and per_band[1::2].sum() < 0.01 * per_band.sum()


def _parts(s: Inside) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return s.shell, s.centroid


def test_an_exact_similarity_keeps_the_field_vector() -> None:
    box = _voxelised(_box, Rotation.from_euler("xyz", [10, 20, 30], degrees=True))
    v = field_vector(box)
    depth, harmonic = field_vector_parts()
    # scaled, moved and turned by a quarter about z (a whole number of azimuth cells)
    quarter = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    moved = field_vector(_moved(box, quarter, 2.5, 0.7))
    np.testing.assert_allclose(moved[depth], v[depth], rtol=1e-4, atol=1e-6)
    assert _rel(v[harmonic], moved[harmonic]) < 0.01  # cells on a ring or angle cell edge
    turned = field_vector(
        _moved(box, Rotation.from_euler("xyz", [30, 50, 70], degrees=True).as_matrix(), 0.5, -3.0)
    )
    assert _rel(v[depth], turned[depth]) < 1e-4  # the principal frame turns with the cells
    assert _rel(v[harmonic], turned[harmonic]) < 0.05  # the angle grid's snapping


def test_a_revoxelised_box_keeps_its_vector_and_other_kinds_do_not() -> None:
    box = field_vector(_voxelised(_box, Rotation.identity()))
    other = field_vector(
        _voxelised(_box, Rotation.from_euler("xyz", [30, 50, 70], degrees=True), 0.3, 2.5)
    )
    cylinder = field_vector(_voxelised(_cylinder, Rotation.identity()))
    ball = field_vector(_voxelised(_ball, Rotation.identity()))
    for part in field_vector_parts():
        same = _rel(box[part], other[part])
        assert same < 0.2  # re-voxelised: staircase edges and tilted faces
        assert _rel(box[part], cylinder[part]) > 2 * same
        assert _rel(box[part], ball[part]) > 2 * same


def test_a_mirrored_shape_keeps_its_depth_buffer_descriptor() -> None:
    s = _voxelised(_box, Rotation.from_euler("z", 20, degrees=True))
    a = depth_buffer_descriptor(s.shell, s.centroid, s.cell)
    for axes in ([-1.0, 1.0, 1.0], [-1.0, -1.0, -1.0]):
        mirrored = s.centroid + (s.shell - s.centroid) * axes
        b = depth_buffer_descriptor(mirrored, s.centroid, s.cell)
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


def test_an_empty_or_degenerate_inside_is_refused() -> None:
    with pytest.raises(ValueError, match="empty"):
        principal_coordinates(np.zeros((0, 3)), np.zeros(3))
    with pytest.raises(ValueError, match="empty"):
        field_vector(Inside(np.zeros((0, 3)), 0.1, np.zeros(3), 0))
    with pytest.raises(ValueError, match="degenerate"):
        harmonic_energies(np.ones((4, 3)), np.ones(3))


def test_a_decomposition_gives_its_insides_vector_and_none_without_it() -> None:
    shape = Box((0, 0, 0), (2.0, 1.0, 0.5)) | Sphere((1.0, 0, 0), 0.6)
    kept = decompose(shape, resolution=32, n_balls=32, keep_inside=True)
    assert kept.inside is not None
    np.testing.assert_array_equal(decomposition_field_vector(kept), field_vector(kept.inside))
    np.testing.assert_array_equal(
        decomposition_field_vector(kept, Config()), field_vector(kept.inside)
    )
    with pytest.raises(ValueError, match="keep_inside"):
        decomposition_field_vector(decompose(shape, resolution=32, n_balls=32))


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("enabled", 1),
        ("depth_resolution", 4),
        ("depth_frequencies", 40),
        ("depth_frequencies", 0),
        ("harmonic_shells", 0),
        ("harmonic_bands", 33),
        ("harmonic_angles", 2.5),
    ],
)
def test_invalid_settings_name_the_option_in_one_line(name: str, value: object) -> None:
    with pytest.raises(ConfigError, match=f"^fv_{name}=") as err:
        FieldVectorConfig(**{name: value})
    assert "\n" not in str(err.value)


def test_new_stores_keep_field_vectors_only_beside_the_fields_light_fields() -> None:
    assert Config().stores_field_vectors
    assert not Config().with_options(fv_enabled=False).stores_field_vectors
    assert not Config().with_options(lf_source="balls").stores_field_vectors
    assert not Config().with_options(rerank="none").stores_field_vectors
    from query.search.tuning import PRODUCT

    assert PRODUCT.field_candidates == 200
    # the research's weights 0.25 and 0.25 at its scales 20.67, 6.045 and 2.168
    weights = (PRODUCT.field_depth_weight, PRODUCT.field_harmonic_weight, PRODUCT.scale)
    assert weights == (0.25 * 20.67 / 6.045, 0.25 * 20.67 / 2.168, 31.005)
    assert (PRODUCT.contrast_floor, PRODUCT.contrast_ramp, PRODUCT.contrast_depth) == (0.2, 0.2, 20)
