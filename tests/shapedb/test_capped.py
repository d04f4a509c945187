"""A mesh cut open is closed over its cuts (``TriangleMesh.capped``); other meshes stay as they are."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shapedb.geometry.mesh import CAP_MIN_VOLUME, TriangleMesh


def _cut(mesh: trimesh.Trimesh, normal: tuple[float, float, float]) -> TriangleMesh:
    """The faces whose centroid lies on the normal's side of the plane through the origin."""
    keep = mesh.faces[mesh.triangles_center @ np.asarray(normal, float) > 0.0]
    used, new = np.unique(keep.ravel(), return_inverse=True)
    return TriangleMesh(mesh.vertices[used], new.reshape(-1, 3), name="half")


@pytest.mark.parametrize(
    ("whole", "normal"),
    [
        (trimesh.creation.icosphere(subdivisions=4), (0.3, 0.5, 0.8)),
        (
            trimesh.creation.box(extents=(2.0, 1.0, 0.5)).subdivide().subdivide().subdivide(),
            (1.0, 0.0, 0.0),
        ),
        (trimesh.creation.torus(1.0, 0.3, major_sections=64, minor_sections=32), (0.0, 1.0, 0.0)),
    ],
)
def test_a_half_is_closed_into_half_the_solid(whole: trimesh.Trimesh, normal: tuple) -> None:
    half = _cut(whole, normal)
    assert not half.closed
    capped = half.capped()
    assert capped is not half and capped.closed and capped.name == "half"
    # the cut runs through whole faces, so the halves differ from half by a row of faces
    volume = capped.to_trimesh().volume
    assert volume == pytest.approx(whole.volume / 2, rel=0.08)
    # its inside is the whole's on the kept side, nothing on the other
    points = np.random.default_rng(0).uniform(whole.bounds[0], whole.bounds[1], size=(2000, 3))
    side = points @ np.asarray(normal, float) / np.linalg.norm(normal)
    solid = TriangleMesh(whole.vertices, whole.faces).contains(points)
    far = np.abs(side) > 0.1
    assert solid[far].sum() > 100
    assert np.array_equal(capped.contains(points[far]), solid[far] & (side[far] > 0))


def _open_l_prism() -> tuple[np.ndarray, np.ndarray]:
    """An L-shaped prism (area 5, height 1) without its top face."""
    outline = np.array([(0, 0), (3, 0), (3, 1), (1, 1), (1, 3), (0, 3)], float)
    n = len(outline)
    v = np.vstack([np.c_[outline, np.zeros(n)], np.c_[outline, np.ones(n)]])
    bottom = [(0, i + 1, i) for i in range(1, n - 1)]  # fan from (0, 0), facing down
    sides = []
    for i in range(n):
        j = (i + 1) % n
        sides += [(i, j, n + j), (i, n + j, n + i)]
    return v, np.array(bottom + sides)


def test_a_non_convex_hole_is_covered_once() -> None:
    """A fan over an L-shaped outline overlaps itself; the signed coverage is the hole's."""
    v, f = _open_l_prism()
    open_l = TriangleMesh(v, f)
    assert not open_l.closed
    capped = open_l.capped()
    assert capped.closed
    assert capped.to_trimesh().volume == pytest.approx(5.0, rel=1e-9)
    assert capped.contains([[2.5, 0.5, 0.5], [0.5, 2.5, 0.5]]).all()
    assert not capped.contains([[2.0, 2.0, 0.5]]).any()


def test_closed_meshes_sheets_and_flat_outlines_stay_as_they_are() -> None:
    box = trimesh.creation.box()
    closed = TriangleMesh(box.vertices, box.faces)
    assert closed.capped() is closed
    plate = TriangleMesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.001]], [[0, 1, 2], [0, 2, 3]])
    assert plate.capped() is plate  # its fan lies on it: it encloses nothing
    assert CAP_MIN_VOLUME > 0
