"""Implicit solids: exact primitive distances, CSG, transformations, validation."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.errors import (
    ConfigError,
    DegenerateGeometryError,
    InvalidShapeError,
    NonFiniteGeometryError,
)
from shapedb.geometry.base import Geometry, Grid
from shapedb.geometry.implicit import (
    Box,
    Capsule,
    Cylinder,
    Difference,
    Implicit,
    Intersection,
    Sphere,
    Torus,
    Union,
)

RNG = np.random.default_rng(0)
POINTS = RNG.uniform(-2.5, 2.5, size=(2000, 3))


def brute_distance(inside: np.ndarray, surface: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Signed distance from a dense surface sample (for checking exactness)."""
    from scipy.spatial import cKDTree

    d, _ = cKDTree(surface).query(p)
    return np.where(inside, d, -d)


def test_primitives_are_implicit_geometry() -> None:
    for g in (
        Sphere([0, 0, 0], 1),
        Box([0, 0, 0], [1, 2, 3]),
        Capsule([0, 0, 0], [1, 0, 0], 0.2),
        Cylinder([0, 0, 0], [0, 0, 1], 0.5),
        Torus([0, 0, 0], 1, 0.2),
    ):
        assert isinstance(g, Geometry)
        assert g.representation == "implicit"
        assert g.bounds.shape == (2, 3)


def test_sphere_and_box_distances() -> None:
    s = Sphere([1, 0, 0], 2.0)
    np.testing.assert_allclose(s.signed_distance([[1, 0, 0], [4, 0, 0]]), [2.0, -1.0])
    b = Box([0, 0, 0], [2, 4, 6])
    np.testing.assert_allclose(
        b.signed_distance([[0, 0, 0], [0.5, 0, 0], [2, 0, 0], [2, 3, 0]]),
        [1.0, 0.5, -1.0, -np.sqrt(2)],
    )


def test_cylinder_torus_capsule_against_brute_force() -> None:
    shapes = [
        Cylinder([0.2, -0.3, -0.5], [0.4, 0.5, 1.0], 0.6),
        Torus([0, 0, 0], 1.2, 0.4, [1, 1, 0]),
        Capsule([-1, 0, 0], [1, 0.5, 0], 0.5),
    ]
    for g in shapes:
        grid = Grid.fit(g.bounds, resolution=96, padding=2)
        pts = grid.points()
        sd = g.signed_distance(pts)
        surface = pts[np.abs(sd) < 0.5 * grid.spacing]
        # project the near-surface samples onto the surface along the gradient (exact SDF)
        eps = 1e-5
        grad = np.stack(
            [
                (g.signed_distance(surface + eps * e) - g.signed_distance(surface - eps * e))
                / (2 * eps)
                for e in np.eye(3)
            ],
            axis=1,
        )
        surface = surface + grad * g.signed_distance(surface)[:, None]
        q = g.bounds[0] + RNG.random((300, 3)) * (g.bounds[1] - g.bounds[0])
        expected = brute_distance(g.signed_distance(q) > 0, surface, q)
        np.testing.assert_allclose(g.signed_distance(q), expected, atol=2 * grid.spacing)


def test_bounds_contain_the_solid() -> None:
    g = Torus([0.5, 0, 0], 1.0, 0.3, axis=[0.3, 0.2, 1]) | Cylinder([0, 0, 0], [1, 1, 1], 0.2)
    inside = POINTS[g.signed_distance(POINTS) > 0]
    assert np.all(inside >= g.bounds[0] - 1e-12) and np.all(inside <= g.bounds[1] + 1e-12)


def test_csg_operators_and_exactness_inside() -> None:
    a, b = Sphere([0, 0, 0], 1.0), Box([0.8, 0, 0], [1.0, 1.0, 1.0])
    assert isinstance(a | b, Union) and isinstance(a & b, Intersection)
    assert isinstance(a - b, Difference)
    da, db = a.signed_distance(POINTS), b.signed_distance(POINTS)
    np.testing.assert_allclose((a | b).signed_distance(POINTS), np.maximum(da, db))
    np.testing.assert_allclose((a & b).signed_distance(POINTS), np.minimum(da, db))
    diff = np.minimum(da, -db)
    inside = diff > 0
    np.testing.assert_allclose((a - b).signed_distance(POINTS)[inside], diff[inside])
    assert np.all(((a - b).signed_distance(POINTS) > 0) == inside)
    assert len(Union(a | b, Sphere([2, 0, 0], 0.1)).children) == 3  # flattened


def test_transformations_move_distances_exactly() -> None:
    b = Box([0.1, 0.2, 0.3], [1.0, 0.6, 0.4])
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", [0.3, -0.5, 1.1]).as_matrix()
    t = np.array([0.5, -1.0, 2.0])
    moved = b.rotate(R).translate(t)
    np.testing.assert_allclose(
        moved.signed_distance(POINTS @ R.T + t), b.signed_distance(POINTS), atol=1e-12
    )
    scaled = b.scale(2.5, center=[1, 1, 1])
    q = 2.5 * (POINTS - 1) + 1
    np.testing.assert_allclose(
        scaled.signed_distance(q), 2.5 * b.signed_distance(POINTS), atol=1e-12
    )
    inside = moved.signed_distance(POINTS) > 0
    assert np.all(POINTS[inside] >= moved.bounds[0] - 1e-12)
    assert np.all(POINTS[inside] <= moved.bounds[1] + 1e-12)


def test_user_function_is_validated() -> None:
    g = Implicit(lambda p: 1 - np.linalg.norm(p, axis=1), [[-1, -1, -1], [1, 1, 1]], name="ball")
    assert g.signed_distance([[0, 0, 0]])[0] == pytest.approx(1.0)
    bad_shape = Implicit(lambda p: np.zeros((len(p), 2)), [[0, 0, 0], [1, 1, 1]], name="wide")
    with pytest.raises(InvalidShapeError, match="wide.*shape"):
        bad_shape.signed_distance(np.zeros((4, 3)))
    nan = Implicit(lambda p: np.full(len(p), np.nan), [[0, 0, 0], [1, 1, 1]], name="nan")
    with pytest.raises(NonFiniteGeometryError, match="nan.*non-finite"):
        nan.signed_distance(np.zeros((4, 3)))
    with pytest.raises(InvalidShapeError, match="callable"):
        Implicit(3.0, [[0, 0, 0], [1, 1, 1]])  # type: ignore[arg-type]
    with pytest.raises(InvalidShapeError, match="bounds"):
        Implicit(lambda p: p[:, 0], [0, 0, 0])
    # nested inside CSG, a user function is still checked
    with pytest.raises(NonFiniteGeometryError):
        (Sphere([0, 0, 0], 1) | nan).signed_distance(np.zeros((4, 3)))


def test_invalid_parameters_are_refused() -> None:
    with pytest.raises(DegenerateGeometryError, match="radius"):
        Sphere([0, 0, 0], 0)
    with pytest.raises(DegenerateGeometryError, match="size"):
        Box([0, 0, 0], [1, 0, 1])
    with pytest.raises(DegenerateGeometryError, match="minor"):
        Torus([0, 0, 0], 1, 2)
    with pytest.raises(NonFiniteGeometryError):
        Sphere([np.nan, 0, 0], 1)
    with pytest.raises(ConfigError, match="orthogonal"):
        Sphere([0, 0, 0], 1).rotate(np.ones((3, 3)))
    with pytest.raises(ConfigError, match="scale"):
        Sphere([0, 0, 0], 1).scale(-1)
    with pytest.raises(DegenerateGeometryError, match="empty"):
        Sphere([0, 0, 0], 1) & Sphere([5, 0, 0], 1)


def test_grid_sdf_matches_pointwise(csg_shapes: dict[str, Implicit]) -> None:
    for g in csg_shapes.values():
        grid = Grid.fit(g.bounds, resolution=24, padding=2)
        F = g.grid_sdf(grid)
        assert F.shape == grid.shape and F.dtype == np.float32
        np.testing.assert_allclose(F.ravel(), g.signed_distance(grid.points()), atol=1e-6)
