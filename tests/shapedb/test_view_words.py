"""View words: views spread over the sphere, scans flattened, a shape seen from each view."""

from __future__ import annotations

import numpy as np

from shapedb.signature.view_words import flattened, view_directions


def test_view_directions_are_unit_and_spread() -> None:
    d = view_directions(20)
    assert d.shape == (20, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=0.05)
    nearest = np.sort(d @ d.T, axis=1)[:, -2]  # each direction's nearest other one
    assert np.degrees(np.arccos(nearest.max())) > 30


def test_flattened_moves_a_noisy_plane_onto_it_and_keeps_its_extent() -> None:
    rng = np.random.default_rng(0)
    xy = rng.uniform(-1, 1, size=(3000, 2))
    noisy = np.column_stack([xy, rng.normal(scale=0.01, size=3000)])
    flat = flattened(noisy)
    assert flat[:, 2].std() < 0.4 * noisy[:, 2].std()  # about 1 / sqrt(neighbours)
    np.testing.assert_allclose(flat[:, :2], noisy[:, :2], atol=0.01)
    lonely = np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 5.0], [0.1, 0.0, 0.3]])
    np.testing.assert_array_equal(flattened(lonely), lonely)  # fewer than 5 neighbours: kept


def test_a_camera_sees_the_near_half_of_a_sphere() -> None:
    import trimesh

    from shapedb.signature.view_words import VIEW_POINTS, visible_points

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=2.0)
    v = sphere.vertices + [10.0, -3.0, 1.0]
    d = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    views = visible_points(v, sphere.faces, d)
    assert len(views) == 2
    for points, direction in zip(views, d, strict=True):
        assert 1000 < len(points) <= VIEW_POINTS
        local = points - [10.0, -3.0, 1.0]
        np.testing.assert_allclose(np.linalg.norm(local, axis=1), 2.0, atol=0.02)
        # the camera 2.5 radii out sees the cap of cos > 1 / 2.5, nothing behind
        assert (local @ direction / 2.0).min() > 0.4 - 0.02
    again = visible_points(v, sphere.faces, d)
    np.testing.assert_array_equal(views[0], again[0])  # deterministic


def test_view_words_are_a_histogram_per_view_for_any_representation() -> None:
    import trimesh

    from shapedb.geometry.implicit import Box
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.signature.surface_words import WORDS
    from shapedb.signature.view_words import VIEWS, view_words

    box = Box([0, 0, 0], [2.4, 1.2, 0.8])
    mesh = trimesh.creation.box(extents=(2.4, 1.2, 0.8))
    implicit = view_words(box, 0.05)
    meshed = view_words(TriangleMesh(mesh.vertices, mesh.faces, name="box"), 0.05)
    for w in (implicit, meshed):
        assert w.shape == (VIEWS, WORDS) and w.dtype == np.float32
        np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-5)
    # a box's marching-cubes surface and its own faces: the same kind of views
    from shapedb.signature.view_words import view_words_distances

    sphere = trimesh.creation.icosphere(subdivisions=4)
    round_ = view_words(TriangleMesh(sphere.vertices, sphere.faces, name="sphere"), 0.05)
    rows = np.stack([implicit.ravel(), round_.ravel()])
    near = view_words_distances(meshed[3], rows)
    assert near[0] < near[1]


def test_view_words_refuse_a_shape_with_no_surface() -> None:
    import pytest

    from shapedb.errors import DegenerateGeometryError
    from shapedb.geometry.implicit import Sphere
    from shapedb.signature.view_words import view_words

    class Nothing(Sphere):  # a field with no inside
        def grid_sdf(self, grid):  # type: ignore[no-untyped-def]
            return np.ones(grid.shape)

    with pytest.raises(DegenerateGeometryError, match="no surface to see"):
        view_words(Nothing([0, 0, 0], 1.0), 0.1)


def test_view_words_distances_is_the_least_over_each_shapes_views() -> None:
    from shapedb.signature.surface_words import WORDS
    from shapedb.signature.view_words import VIEWS, view_words_distances

    a, b = np.eye(WORDS)[0], np.eye(WORDS)[1]
    one = np.tile(b, (VIEWS, 1))
    two = one.copy()
    two[7] = 0.5 * (a + b)
    three = one.copy()
    three[0] = a
    # chi-square of one-hot rows: 1 apart, 0 alike; a against (a + b) / 2: 1/3
    np.testing.assert_allclose(view_words_distances(a, np.stack([one, two, three])), [1, 1 / 3, 0])
    assert view_words_distances(a, np.zeros((0, VIEWS * WORDS))).shape == (0,)
