"""The enclosed solid: a flood from outside, whatever the faces' orientation or closedness."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shapedb.geometry.base import Grid
from shapedb.geometry.enclosed import Enclosed, enclosed_sides
from shapedb.geometry.mesh import TriangleMesh
from shapedb.mdbd.decomposition import decompose

RES = 40


def _soup(mesh: trimesh.Trimesh, seed: int = 0) -> TriangleMesh:
    """Every face its own component, half of them flipped: a builder's quads."""
    rng = np.random.default_rng(seed)
    f = np.asarray(mesh.faces).copy()
    flip = rng.random(len(f)) < 0.5
    f[flip] = f[flip][:, ::-1]
    v = np.asarray(mesh.vertices)[f].reshape(-1, 3)
    return TriangleMesh(v, np.arange(len(v)).reshape(-1, 3))


def _without(mesh: trimesh.Trimesh, keep: np.ndarray) -> trimesh.Trimesh:
    out = mesh.copy()
    out.update_faces(keep)
    out.remove_unreferenced_vertices()
    return out


def _grid(mesh: TriangleMesh) -> Grid:
    return Grid.fit(mesh.bounds, resolution=RES, padding=2)


def _field_at(mesh: TriangleMesh, point: tuple[float, float, float]) -> float:
    grid = _grid(mesh)
    solid, field = mesh.enclosed_solid(grid, grid.spacing)
    ijk = np.rint((np.asarray(point) - grid.origin) / grid.spacing).astype(int)
    return float(field[tuple(ijk)]) / grid.spacing


BOX = trimesh.creation.box((1.0, 1.0, 1.0))


def test_a_soup_of_flipped_faces_gives_the_closed_solid() -> None:
    closed, soup = TriangleMesh(BOX.vertices, BOX.faces), _soup(BOX)
    grid = _grid(closed)
    _, f_closed = closed.enclosed_solid(grid, grid.spacing)
    _, f_soup = soup.enclosed_solid(grid, grid.spacing)
    np.testing.assert_allclose(f_soup, f_closed, atol=1e-5)
    # the centre is 0.5 from every face, plus the thickness of one cell
    ijk = np.rint(-grid.origin / grid.spacing).astype(int)
    centre = grid.to_point(ijk[None])[0]
    want = (0.5 - np.abs(centre).max()) / grid.spacing + 1  # to the nearest face, plus t
    assert f_soup[tuple(ijk)] / grid.spacing == pytest.approx(want, abs=1e-3)


def test_an_open_basin_stays_a_basin_and_its_wall_is_a_slab() -> None:
    cup = _soup(_without(BOX, BOX.face_normals[:, 2] < 0.5))  # no top
    assert _field_at(cup, (0, 0, 0)) < 0  # the flood fills the basin
    assert _field_at(cup, (0.5, 0, 0)) > 0  # the wall is solid
    assert _field_at(cup, (0, 0, -0.5)) > 0  # so is the bottom


def test_a_hole_wider_than_a_cell_lets_the_flood_in_and_a_ring_keeps_its_hole() -> None:
    ring = _soup(trimesh.creation.annulus(0.3, 1.0, 0.2))
    assert _field_at(ring, (0, 0, 0)) < 0
    assert _field_at(ring, (0.65, 0, 0)) > 0


def test_sides_of_a_closed_surface_and_its_complement() -> None:
    dist = np.full((9, 9, 9), 3.0)
    dist[2:7, 2:7, 2:7] = 0.0  # a wall block
    dist[3:6, 3:6, 3:6] = 1.0  # with a pocket inside
    sides = enclosed_sides(dist)
    assert sides[4, 4, 4] and not sides[0, 0, 0]
    dist[4, 4, 2] = 1.0  # a channel through the wall at the pocket's side
    dist[4, 4, 1] = 1.0
    assert not enclosed_sides(dist)[4, 4, 4]


def _quad_box(over: float = 0.05) -> TriangleMesh:
    """A unit box of six separate quads that overshoot their edges (a builder's walls,
    interpenetrating, never sharing a vertex), each wound at random."""
    rng = np.random.default_rng(1)
    tris = []
    for axis in range(3):
        u, w = [a for a in range(3) if a != axis]
        for side in (-0.5, 0.5):
            c = np.zeros((4, 3))
            c[:, axis] = side
            c[:, u] = np.array([-1, 1, 1, -1]) * (0.5 + over)
            c[:, w] = np.array([-1, -1, 1, 1]) * (0.5 + over)
            quad = [c[[0, 1, 2]], c[[0, 2, 3]]]
            tris += [t[::-1] if rng.random() < 0.5 else t for t in quad]
    v = np.concatenate(tris)
    return TriangleMesh(v, np.arange(len(v)).reshape(-1, 3))


def test_a_box_of_loose_walls_is_a_solid_box() -> None:
    walls = _quad_box()
    assert not walls.closed
    d = decompose(walls, resolution=32, n_balls=16, sheet_rule="enclosed")
    cell = 1.1 / (32 - 4)  # the longest extent over the grid's inner cells
    assert d.radii[0] == pytest.approx(0.5 + cell, rel=0.05)  # the half-side plus t
    local = decompose(walls, resolution=32, n_balls=16, sheet_rule="local")
    assert local.radii[0] < d.radii[0]


def test_a_closed_mesh_decomposes_as_under_the_local_rule() -> None:
    box = TriangleMesh(BOX.vertices, BOX.faces)
    assert box.closed
    a = decompose(box, resolution=32, n_balls=16, sheet_rule="enclosed")
    b = decompose(box, resolution=32, n_balls=16, sheet_rule="local")
    np.testing.assert_array_equal(a.radii, b.radii)
    np.testing.assert_array_equal(a.centers, b.centers)


def test_off_grid_queries_agree_with_the_grid() -> None:
    soup = _soup(BOX)
    grid = _grid(soup)
    solid, field = soup.enclosed_solid(grid, grid.spacing)
    assert isinstance(solid, Enclosed)
    cells = np.argwhere(np.ones(grid.shape, bool))[::97]
    pts = grid.to_point(cells)
    got = solid.signed_distance(pts)
    want = field[cells[:, 0], cells[:, 1], cells[:, 2]]
    near = np.abs(want) < 3 * grid.spacing  # where the grid's distances are exact
    np.testing.assert_allclose(got[near], want[near], atol=1e-4)
    np.testing.assert_array_equal(solid.contains(pts), got > 0)
