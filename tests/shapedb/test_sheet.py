"""Thin sheets, open and flat meshes get a solid (shapedb.geometry.sheet); closed solids do not change."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.sheet import (
    LocallyThickened,
    Thickened,
    needs_thickening,
    sheet_fraction,
    sheet_region,
)
from shapedb.mdbd.decomposition import decompose

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


def test_open_box_decomposes_filled_under_the_local_rule_and_as_a_basin_by_default() -> None:
    d = decompose(_open_box(), resolution=32, n_balls=32, sheet_rule="local")
    assert len(d.radii) > 0 and d.radii[0] > 3 * d.spacing  # the winding number fills it
    basin = decompose(_open_box(), resolution=32, n_balls=32)  # the enclosed solid: walls 2 t
    assert len(basin.radii) == 32 and basin.radii[0] < 1.6 * basin.spacing


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


def _winged_box() -> TriangleMesh:
    """A closed box (a fuselage) with a zero-thickness quad (a wing) through it, open."""
    box = trimesh.creation.box([2.4, 1.0, 1.0])
    z = 0.0123  # off the grid's cell centres, so no centre lies on the sheet
    wing_v = np.array([[-0.15, -2.0, z], [0.15, -2.0, z], [0.15, 2.0, z], [-0.15, 2.0, z]])
    v = np.vstack([box.vertices, wing_v])
    f = np.vstack([box.faces, np.array([[0, 1, 2], [0, 2, 3]]) + len(box.vertices)])
    return TriangleMesh(v, f, name="winged box")


def test_a_sheet_beside_a_solid_gets_a_slab_only_with_the_local_rule() -> None:
    from shapedb.config.core import MDBDConfig
    from shapedb.mdbd.decomposition import prepare_field

    mesh = _winged_box()
    assert not mesh.closed
    cfg = MDBDConfig(resolution=48, sheet_rule="local")
    whole = prepare_field(mesh, replace(cfg, sheet_rule="whole"))
    local = prepare_field(mesh, cfg)
    assert isinstance(local.local, LocallyThickened) and not isinstance(whole.local, Thickened)
    h = local.grid.spacing
    # the field is in the canonical frame: the wing is the long thin extent
    pts = local.grid.points().reshape(*local.grid.shape, 3)
    span_axis = int(np.argmax(np.ptp(local.grid.points(), axis=0)))
    far = np.abs(pts[..., span_axis]) > 1.2 / local.scale  # local units
    # whole rule: the wing has no inside cell beyond the box; local rule: a slab of cells
    assert not (whole.F[far] >= 0).any()
    wing = (local.F >= 0) & far
    assert wing.sum() > 0
    across = [k for k in range(3) if k != span_axis]
    thick = np.ptp(pts[wing][:, across], axis=0)
    assert thick.min() <= 2 * h + 1e-9  # a slab two cells thick at most, in the sheet's normal
    # the box's middle keeps its field: the region reaches only a few cells from the sheet
    assert local.F.max() == pytest.approx(whole.F.max(), abs=1e-6)
    d = decompose(mesh, resolution=48, n_balls=256, refine=False)
    c = d.centers
    assert (np.abs(c[:, 1]) > 1.2).any()  # balls on the wing, model coordinates


def test_meshes_with_no_sheet_cells_are_not_thickened_locally() -> None:
    from shapedb.config.core import MDBDConfig
    from shapedb.mdbd.decomposition import prepare_field

    box = trimesh.creation.box([2.0, 1.0, 1.0])
    prep = prepare_field(TriangleMesh(box.vertices, box.faces), MDBDConfig(resolution=32))
    assert not isinstance(prep.local, (Thickened, LocallyThickened))
    assert (
        sheet_region(TriangleMesh(box.vertices, box.faces), prep.F, prep.grid.spacing, 1.0) is None
    )


def test_locally_thickened_distance_is_the_base_plus_the_thickness_in_the_region() -> None:
    from shapedb.geometry.base import Grid

    base = TriangleMesh(QUAD_V, QUAD_F)
    grid = Grid.fit(base.bounds + np.array([[0, 0, -0.5], [0, 0, 0.5]]), resolution=16)
    region = np.zeros(grid.shape, dtype=bool)
    xs = grid.axes()[0]
    region[xs < 0.5] = True  # the half x < 0.5 is thickened
    g = LocallyThickened(base, 0.1, grid, region)
    p = np.array([[0.2, 0.5, 0.05], [0.8, 0.5, 0.05], [0.2, 0.5, 0.3], [9.0, 9.0, 9.0]])
    assert np.allclose(g.signed_distance(p)[:3], [0.05, -0.05, -0.2], atol=1e-6)
    assert g.contains(p).tolist() == [True, False, False, False]
    assert np.allclose(g.closest_points(p[:2]), [[0.2, 0.5, 0.1], [0.8, 0.5, 0.0]], atol=1e-6)
    f = g.grid_sdf(grid)
    assert np.allclose(f, base.grid_sdf(grid) + 0.1 * region, atol=1e-6)
    with pytest.raises(ValueError, match="thickness"):
        LocallyThickened(base, 0.0, grid, region)
    with pytest.raises(ValueError, match="shape"):
        LocallyThickened(base, 0.1, grid, region[1:])


def test_sheet_rule_is_checked_and_old_stores_read_whole() -> None:
    from shapedb.config.core import Config, MDBDConfig
    from shapedb.errors import ConfigError

    with pytest.raises(ConfigError, match="sheet_rule"):
        MDBDConfig(sheet_rule="some")
    stored = Config().to_dict()
    assert Config.from_dict(stored).mdbd.sheet_rule == "enclosed"
    del stored["mdbd"]["sheet_rule"]
    old = Config.from_dict(stored)
    assert old.mdbd.sheet_rule == "whole"
    # a store written before the rule keeps its fingerprint; today's differs
    assert old.fingerprint != Config().fingerprint


def test_a_locally_thickened_solid_moves_as_a_whole() -> None:
    from shapedb.geometry.base import Grid

    base = TriangleMesh(QUAD_V, QUAD_F)
    grid = Grid.fit(base.bounds + np.array([[0, 0, -0.5], [0, 0, 0.5]]), resolution=16)
    g = LocallyThickened(base, 0.1, grid, np.ones(grid.shape, dtype=bool))
    moved = g.transformed(np.eye(3), [0.0, 0.0, 5.0])
    assert np.allclose(
        moved.signed_distance([[0.5, 0.5, 5.05]]), g.signed_distance([[0.5, 0.5, 0.05]])
    )
    assert np.allclose(g.bounds[:, 2], [-0.1, 0.1])
