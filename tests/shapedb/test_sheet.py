"""Thin sheets, open and flat meshes get a solid (shapedb.sheet); closed solids do not change."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shapedb.mdbd import decompose
from shapedb.mesh import TriangleMesh
from shapedb.sheet import Thickened, needs_thickening, sheet_fraction

QUAD_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
QUAD_F = np.array([[0, 1, 2], [0, 2, 3]])


def _disc(n: int = 24) -> TriangleMesh:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = np.vstack([[0, 0, 0], np.column_stack([np.cos(t), np.sin(t), np.zeros(n)])])
    f = np.array([[0, 1 + k, 1 + (k + 1) % n] for k in range(n)])
    return TriangleMesh(v, f, name="disc")


def _open_box() -> TriangleMesh:
    b = trimesh.creation.box([1.0, 1.0, 1.0])
    keep = b.face_normals[:, 2] < 0.9  # no lid
    return TriangleMesh(b.vertices, b.faces[keep], name="open box")


def test_flat_quad_is_accepted_and_decomposed_as_a_slab() -> None:
    quad = TriangleMesh(QUAD_V, QUAD_F, name="quad")
    assert not quad.closed
    d = decompose(quad, resolution=32, n_balls=64, refine=False)
    h = d.spacing
    # the quad dilated by one cell: a slab 2 cells thick, so every ball has radius 1 cell
    assert len(d.radii) == 64
    assert np.allclose(d.radii, h, atol=1e-6 * h)
    assert np.all(np.abs(d.centers[:, 2]) < 1e-6)  # on the sheet's plane
    inside = (d.centers[:, :2] > -h) & (d.centers[:, :2] < 1 + h)
    assert inside.all()


def test_flat_quad_with_refinement_keeps_balls_in_the_slab() -> None:
    d = decompose(TriangleMesh(QUAD_V, QUAD_F), resolution=32, n_balls=32)
    assert len(d.radii) == 32
    assert np.all(np.abs(d.centers[:, 2]) + d.radii <= 1.001 * d.spacing)


def test_flat_disc_gets_balls_over_its_whole_area() -> None:
    d = decompose(_disc(), resolution=32, n_balls=512, refine=False)
    r = np.linalg.norm(d.centers[:, :2], axis=1)
    assert r.max() > 0.85 and r.min() < 0.15
    assert np.isclose(d.radii[0], d.spacing) and d.radii.max() <= d.spacing * (1 + 1e-6)


def test_open_box_decomposes() -> None:
    d = decompose(_open_box(), resolution=32, n_balls=32)
    assert len(d.radii) > 0 and d.radii[0] > 3 * d.spacing


def test_closed_solid_is_unchanged() -> None:
    box = trimesh.creation.box([2.0, 1.0, 1.0])
    m = TriangleMesh(box.vertices, box.faces)
    assert m.closed
    a = decompose(m, resolution=32, n_balls=32)
    b = decompose(m, resolution=32, n_balls=32, sheet_cells=0.0)
    assert np.array_equal(a.centers, b.centers) and np.array_equal(a.radii, b.radii)


def test_sheets_fail_without_thickening() -> None:
    from shapedb.errors import DegenerateGeometryError

    with pytest.raises(DegenerateGeometryError, match="thinner"):
        decompose(TriangleMesh(QUAD_V, QUAD_F), resolution=32, sheet_cells=0.0)


def test_thickened_distance_is_the_base_plus_the_thickness() -> None:
    quad = Thickened(TriangleMesh(QUAD_V, QUAD_F), 0.1)
    p = np.array([[0.5, 0.5, 0.05], [0.5, 0.5, 0.3], [0.5, 0.5, -0.1]])
    assert np.allclose(quad.signed_distance(p), [0.05, -0.2, 0.0], atol=1e-6)
    assert quad.contains(p).tolist() == [True, False, False]
    assert np.allclose(quad.closest_points(p[:2]), [[0.5, 0.5, 0.1], [0.5, 0.5, 0.1]], atol=1e-6)


def test_sheet_fraction_tells_sheets_from_solids() -> None:
    x = np.linspace(-2, 2, 41)
    h = x[1] - x[0]
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    ball = 1.0 - np.sqrt(X**2 + Y**2 + Z**2)
    sheet = -np.abs(Z)
    assert sheet_fraction(ball, h) == 0.0
    assert sheet_fraction(sheet, h) == 1.0
    assert needs_thickening(TriangleMesh(QUAD_V, QUAD_F), sheet, h, 0.5 * h)
