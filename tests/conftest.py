"""Shared fixtures: analytic shapes whose decompositions are known exactly."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run the tests without installing the package
    sys.path.insert(0, str(ROOT))

from shapedb.geometry.implicit import Box, Capsule, Cylinder, Implicit, Sphere, Torus  # noqa: E402


def rotation(angles: tuple[float, float, float]) -> np.ndarray:
    """Rotation matrix (3, 3) from x-y-z Euler angles in radians."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("xyz", angles).as_matrix()


@pytest.fixture(scope="session")
def sphere() -> Sphere:
    """Ball of radius 1 about (0.3, -0.2, 0.1)."""
    return Sphere([0.3, -0.2, 0.1], 1.0)


@pytest.fixture(scope="session")
def box() -> Box:
    """Box 2 x 1.2 x 0.8: the largest inscribed ball has radius 0.4."""
    return Box([0.0, 0.0, 0.0], [2.0, 1.2, 0.8])


@pytest.fixture(scope="session")
def capsule() -> Capsule:
    """Capsule of radius 0.3 along x from 0 to 2."""
    return Capsule([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], 0.3)


@pytest.fixture(scope="session")
def csg_shapes() -> dict[str, Implicit]:
    """A few CSG solids mixing every primitive and operation."""
    plate = Box([0, 0, 0], [3.0, 2.0, 0.5]) - Cylinder([0.8, 0.3, -1], [0.8, 0.3, 1], 0.35)
    return {
        "plate": plate | Sphere([-1.2, -0.6, 0.4], 0.45),
        "figure": Capsule([0, 0, 0], [0, 0, 1.2], 0.3)
        | Sphere([0, 0.05, 1.6], 0.28)
        | Capsule([0, 0, 1.0], [0.7, 0.2, 0.6], 0.12)
        | Capsule([0.1, 0, 0], [0.3, 0.1, -1], 0.15),
        "ring": Torus([0, 0, 0], 1.0, 0.3, axis=[0.2, 0.1, 1.0])
        | Box([0.9, 0.1, 0.0], [0.5, 0.9, 0.4]).rotate(rotation((0.2, 0.1, 0.5))),
        "lens": Sphere([0, 0, 0], 1.0)
        & Sphere([0.8, 0.1, 0.0], 0.9)
        & Sphere([0.3, 0.6, 0.2], 0.8),
    }


@pytest.fixture(scope="session")
def generic() -> Implicit:
    """A solid without symmetries (so its MDBD has no ties): union of polyhedra and a ball."""
    rng = np.random.default_rng(3)

    def polyhedron(n: int, size: float, centre: np.ndarray) -> Implicit:
        normals = rng.normal(size=(n, 3))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        offsets = size * (0.7 + 0.3 * rng.random(n))

        def sdf(p: np.ndarray) -> np.ndarray:  # exact inside a convex polyhedron
            return (offsets - (p - centre) @ normals.T).min(axis=1)

        return Implicit(sdf, [centre - 1.8 * size, centre + 1.8 * size], name="polyhedron")

    return (
        polyhedron(14, 0.5, np.zeros(3))
        | polyhedron(12, 0.35, np.array([0.6, 0.3, 0.1]))
        | Sphere([-0.3, 0.35, -0.3], 0.3)
    )
