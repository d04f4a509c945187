"""Surface words: local surface features over the shipped codebook, and their distance."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from shapedb.errors import DegenerateGeometryError
from shapedb.geometry.implicit import Box, Implicit, Sphere
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud
from shapedb.signature.surface_words import (
    CODEBOOK_FILE,
    FEATURE_BINS,
    SAMPLES,
    WORDS,
    surface_features,
    surface_points,
    surface_words,
    words_distance,
)


def _mesh(tm: trimesh.Trimesh, name: str) -> TriangleMesh:
    return TriangleMesh(np.asarray(tm.vertices), np.asarray(tm.faces), name=name)


def _words(geometry: object) -> np.ndarray:
    return surface_words(surface_points(geometry, 0.02))  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def shapes() -> dict[str, np.ndarray]:
    rot = Rotation.from_euler("xyz", [0.4, -1.1, 2.0]).as_matrix()
    box = trimesh.creation.box(extents=(1.8, 1.0, 0.5))
    moved = box.copy()
    moved.apply_scale(3.7)
    moved.apply_transform(np.vstack([np.hstack([rot, [[5.0], [-2.0], [1.0]]]), [0, 0, 0, 1]]))
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.8)
    cloud = PointCloud(np.asarray(sphere.sample(4000, seed=1)) + 2.0, name="sphere cloud")
    return {
        "box": _words(_mesh(box, "box")),
        "moved box": _words(_mesh(moved, "moved box")),
        "implicit box": _words(Box([0, 0, 0], [1.8, 1.0, 0.5])),
        "sphere": _words(_mesh(sphere, "sphere")),
        "implicit sphere": _words(Sphere([0.3, 0, 0], 0.8)),
        "sphere cloud": _words(cloud),
        "cylinder": _words(_mesh(trimesh.creation.cylinder(0.3, 2.0, sections=64), "cyl")),
    }


def test_words_are_a_histogram(shapes: dict[str, np.ndarray]) -> None:
    for name, w in shapes.items():
        assert w.shape == (WORDS,) and w.dtype == np.float32, name
        assert (w >= 0).all() and w.sum() == pytest.approx(1.0, abs=1e-5), name


def test_words_do_not_depend_on_pose_or_scale(shapes: dict[str, np.ndarray]) -> None:
    """A box turned, moved and scaled 3.7 x is far nearer its own words than a sphere's or a
    cylinder's (its thinning grid turns with it, so not exactly equal)."""
    box = shapes["box"]
    near = words_distance(box, shapes["moved box"][None])[0]
    others = words_distance(box, np.stack([shapes["sphere"], shapes["cylinder"]]))
    assert near < 0.25 * others.min()


def test_representations_of_one_solid_share_their_words(shapes: dict[str, np.ndarray]) -> None:
    """A sphere as a mesh, an implicit function and a point cloud; a box as a mesh and an
    implicit function: each nearer its own kind than the other solid."""
    for a, b, other in [
        ("sphere", "implicit sphere", "box"),
        ("sphere", "sphere cloud", "box"),
        ("box", "implicit box", "sphere"),
    ]:
        same = words_distance(shapes[a], shapes[b][None])[0]
        cross = words_distance(shapes[a], shapes[other][None])[0]
        assert same < 0.5 * cross, (a, b, other, same, cross)


def test_words_distance_is_the_chi_square() -> None:
    a = np.zeros(WORDS)
    a[:2] = 0.5
    b = np.zeros(WORDS)
    b[2] = 1.0
    c = np.zeros(WORDS)
    c[0], c[2] = 0.5, 0.5
    d = words_distance(a, np.stack([a, b, c]))
    assert d[0] == 0.0 and d[1] == pytest.approx(1.0)
    expected = 0.5 * ((0.5 - 0.5) ** 2 / 1.0 + 0.5**2 / 0.5 + 0.5**2 / 0.5)
    assert d[2] == pytest.approx(expected)
    assert words_distance(c, a[None])[0] == pytest.approx(d[2])


def test_no_points_give_no_features() -> None:
    assert surface_features(np.zeros((0, 3))).shape == (0, FEATURE_BINS)
    assert surface_features(np.ones((5, 3))).shape == (0, FEATURE_BINS)
    assert not surface_words(np.ones((5, 3))).any()


def test_reach_reads_a_sample_as_part_of_a_larger_whole() -> None:
    """At reach 1 the sample is read at its own scale; at reach 2 as a part of a whole
    twice its bounding radius: its neighbourhoods hold more of it, so fewer thinned points
    and other features. A reach that is no length is refused."""
    points = surface_points(_mesh(trimesh.creation.box(extents=(1.8, 1.0, 0.5)), "box"), 0.0)
    own = surface_features(points)
    np.testing.assert_array_equal(surface_features(points, reach=1.0), own)
    larger = surface_features(points, reach=2.0)
    assert len(larger) < len(own)
    assert not np.array_equal(surface_words(points, reach=2.0), surface_words(points))
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="reach"):
            surface_features(points, reach=bad)


def test_a_geometry_without_a_surface_is_refused() -> None:
    """A field that is never positive has no zero crossing: no surface, a clear error."""
    nothing = Implicit(lambda p: -np.ones(len(p)), [[0, 0, 0], [1, 1, 1]], name="nothing")
    with pytest.raises(DegenerateGeometryError, match="nothing"):
        surface_points(nothing, 0.05)
    assert surface_points(Sphere([0, 0, 0], 1.0), 0.05).shape == (SAMPLES, 3)


def test_the_shipped_codebook() -> None:
    centroids = np.load(CODEBOOK_FILE)
    assert centroids.shape == (WORDS, FEATURE_BINS) and np.isfinite(centroids).all()
