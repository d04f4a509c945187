"""MDBD against analytic truth, its invariants, and the fast loop against the reference."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.config.core import MDBDConfig
from shapedb.errors import ConfigError, DegenerateGeometryError, InvalidShapeError
from shapedb.geometry.implicit import Implicit, Sphere
from shapedb.mdbd.decomposition import Decomposition, _decompose_naive, decompose


def assert_valid(d: Decomposition, geometry: Implicit, tol: float = 1e-6) -> None:
    """Balls inside, pairwise disjoint, radii non-increasing, edges well formed."""
    c, r = d.centers, d.radii
    assert c.shape == (d.n_balls, 3) and r.shape == (d.n_balls,)
    assert np.all(np.diff(r) <= 0), "radii must be non-increasing"
    assert np.all(geometry.signed_distance(c) >= r - tol), "balls must lie inside"
    gap = np.linalg.norm(c[:, None] - c[None], axis=2) - r[:, None] - r[None]
    np.fill_diagonal(gap, np.inf)
    assert gap.min() >= -tol, "balls must be disjoint"
    e = d.edges
    assert e.dtype == np.int32 and e.ndim == 2 and e.shape[1] == 2
    assert np.all(e[:, 0] < e[:, 1])
    assert np.array_equal(e, e[np.lexsort((e[:, 1], e[:, 0]))])
    if len(e):  # edges index the sorted order: every edge is a contact of sorted balls
        g = np.linalg.norm(c[e[:, 0]] - c[e[:, 1]], axis=1) - r[e[:, 0]] - r[e[:, 1]]
        assert np.all(g <= d.config.contact_tol_cells * d.spacing + 1e-9)


@pytest.mark.parametrize("refine", [True, False])
def test_sphere_first_ball_is_the_sphere(sphere: Sphere, refine: bool) -> None:
    d = decompose(sphere, resolution=48, n_balls=16, refine=refine)
    assert abs(d.radii[0] - 1.0) <= d.spacing
    assert np.linalg.norm(d.centers[0] - sphere.center) <= d.spacing
    if refine:  # off the grid, the ball is the sphere itself to a small fraction of a cell
        assert abs(d.radii[0] - 1.0) <= 0.05 * d.spacing
        assert np.linalg.norm(d.centers[0] - sphere.center) <= 0.05 * d.spacing
    assert_valid(d, sphere)


def test_box_first_radius_is_half_the_smallest_side(box: Implicit) -> None:
    d = decompose(box, resolution=48, n_balls=32)
    assert d.radii[0] == pytest.approx(0.4, abs=1e-3 * d.spacing)
    assert_valid(d, box)


def test_two_far_spheres_give_two_balls_and_no_edge() -> None:
    g = Sphere([0, 0, 0], 1.0) | Sphere([3.0, 0.5, 0], 0.6)
    d = decompose(g, resolution=64, n_balls=64)
    np.testing.assert_allclose(d.radii[:2], [1.0, 0.6], atol=0.05 * d.spacing)
    np.testing.assert_allclose(d.centers[:2], [[0, 0, 0], [3.0, 0.5, 0]], atol=0.05 * d.spacing)
    assert not np.any(np.all(d.edges == [0, 1], axis=1))
    assert_valid(d, g)


def test_two_touching_spheres_are_joined_by_an_edge() -> None:
    g = Sphere([0, 0, 0], 1.0) | Sphere([1.7, 0, 0], 0.7)
    d = decompose(g, resolution=64, n_balls=32)
    np.testing.assert_allclose(d.radii[:2], [1.0, 0.7], atol=0.05 * d.spacing)
    assert np.any(np.all(d.edges == [0, 1], axis=1))
    assert_valid(d, g)


def test_capsule_balls_lie_along_the_axis(capsule: Implicit) -> None:
    d = decompose(capsule, resolution=64, n_balls=32)
    big = d.radii > 0.3 - 0.05 * d.spacing
    assert big.sum() >= 3  # 2 / (2 * 0.3): at least three full-radius balls fit on the axis
    assert np.all(np.abs(d.centers[big, 1:]) <= 0.05 * d.spacing)
    assert_valid(d, capsule)


@pytest.mark.parametrize("refine", [True, False])
def test_invariants_on_csg_shapes(csg_shapes: dict[str, Implicit], refine: bool) -> None:
    for name, g in csg_shapes.items():
        d = decompose(g, resolution=48, n_balls=200, refine=refine)
        assert d.n_balls > 20, name
        assert_valid(d, g, tol=1e-6 if refine else 1e-5 * float(d.radii[0]))
        assert d.representation == "implicit"
        assert {"sdf", "decompose", "graph"} <= set(d.timings)
        assert d.graph.n_nodes == d.n_balls


@pytest.mark.parametrize(("refine", "frame"), [(False, False), (True, False), (True, True)])
def test_block_max_loop_equals_naive_reference(
    csg_shapes: dict[str, Implicit], refine: bool, frame: bool
) -> None:
    for name, g in csg_shapes.items():
        opts = {"resolution": 40, "n_balls": 150, "refine": refine, "canonical_frame": frame}
        fast = decompose(g, **opts)
        ref = _decompose_naive(g, **opts)
        assert fast.n_balls == ref.n_balls, name
        np.testing.assert_allclose(fast.radii, ref.radii, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fast.centers, ref.centers, rtol=0, atol=1e-9)
        assert np.array_equal(fast.edges, ref.edges)


def test_ties_go_to_the_smallest_flat_index(box: Implicit) -> None:
    # The box's largest balls form a plateau: both loops must pick the same cells.
    for tie in (0.0, 0.3):
        opts = {"resolution": 32, "n_balls": 40, "refine": False, "tie_cells": tie}
        fast = decompose(box, **opts)
        ref = _decompose_naive(box, **opts)
        np.testing.assert_array_equal(fast.centers, ref.centers)


def test_ties_make_the_choice_along_a_ridge_robust_to_noise() -> None:
    """A cylinder's axis is a ridge of equal values: noise far below a cell decides it.

    Without a tie tolerance the first ball of a slightly bumpy copy sits at the bumps'
    crest, far from the clean cylinder's; with ``tie_cells`` above the noise both start
    at the same end of the ridge.
    """
    from shapedb.geometry.implicit import Cylinder

    cyl = Cylinder([-1.0, 0, 0], [1.0, 0, 0], 0.3)
    bumpy = Implicit(
        lambda p: cyl.signed_distance(p) + 0.004 * np.sin(7.0 * p[:, 0] + 1.0), cyl.bounds
    )
    opts = {"resolution": 64, "n_balls": 4, "refine": False, "canonical_frame": False}
    a, b = decompose(cyl, tie_cells=0.0, **opts), decompose(bumpy, tie_cells=0.0, **opts)
    assert np.linalg.norm(a.centers[0] - b.centers[0]) > 5 * a.spacing
    a, b = decompose(cyl, tie_cells=0.5, **opts), decompose(bumpy, tie_cells=0.5, **opts)
    assert np.linalg.norm(a.centers[0] - b.centers[0]) <= 1.01 * a.spacing


def test_the_middle_tie_rule_starts_a_ridge_at_its_middle_whatever_the_frame() -> None:
    """tie_rule="middle" (the default): a cylinder's first ball sits at the middle of its axis, for a
    clean and a bumpy copy, and for the copy turned end over end (axis sign flipped)."""
    from shapedb.geometry.implicit import Cylinder

    cyl = Cylinder([-1.0, 0, 0], [1.0, 0, 0], 0.3)
    bumpy = Implicit(
        lambda p: cyl.signed_distance(p) + 0.004 * np.sin(7.0 * p[:, 0] + 1.0), cyl.bounds
    )
    flipped = Implicit(lambda p: bumpy.signed_distance(p * [-1.0, 1.0, 1.0]), cyl.bounds)
    opts = {"resolution": 64, "n_balls": 4, "refine": False, "canonical_frame": False}
    for g in (cyl, bumpy, flipped):
        d = decompose(g, tie_cells=0.5, **opts)  # the default rule
        assert d.config.tie_rule == "middle"
        assert abs(d.centers[0, 0]) <= 1.01 * d.spacing, d.centers[0]
        first = decompose(g, tie_cells=0.5, tie_rule="first", **opts)
        assert abs(first.centers[0, 0]) > 5 * first.spacing  # "first": towards one end


@pytest.mark.parametrize("rule", ["first", "middle"])
def test_both_tie_rules_agree_with_the_naive_reference(
    csg_shapes: dict[str, Implicit], rule: str
) -> None:
    for name, g in csg_shapes.items():
        opts = {"resolution": 40, "n_balls": 120, "refine": False, "tie_rule": rule}
        fast, ref = decompose(g, **opts), _decompose_naive(g, **opts)
        np.testing.assert_allclose(fast.centers, ref.centers, rtol=0, atol=1e-9, err_msg=name)


def test_a_tie_wider_than_the_solid_still_finds_its_balls() -> None:
    slab = Implicit(lambda p: 0.06 - np.abs(p[:, 2]), [[-1, -1, -0.06], [1, 1, 0.06]])
    d = decompose(slab, resolution=48, n_balls=20, tie_cells=2.0)
    assert d.n_balls == 20 and d.radii[-1] >= 0.5 * d.spacing
    assert_valid(d, slab)


def test_stops_at_min_radius_and_n_balls(sphere: Sphere) -> None:
    g = Sphere([0, 0, 0], 1.0) | Sphere([1.2, 0, 0], 0.5)
    d = decompose(g, resolution=32, n_balls=10_000, min_radius_cells=1.0)
    assert d.n_balls < 10_000 and d.radii[-1] >= 0.5 * d.spacing
    assert decompose(g, resolution=32, n_balls=7).n_balls == 7


def test_refinement_beats_the_grid() -> None:
    # Sub-cell shifts of the grid barely move refined radii; grid radii move by cells.
    g = Sphere([0, 0, 0], 1.0) | Sphere([1.1, 0.4, 0.2], 0.6) | Sphere([-0.3, 0.9, -0.5], 0.45)
    shifted = Implicit(g.signed_distance, g.bounds + [[-0.011, -0.007, 0.0], [0.0, 0.013, 0.004]])
    errs = {}
    for refine in (False, True):  # on the model's axes: the grid does not follow the solid
        opts = {"resolution": 48, "n_balls": 8, "refine": refine, "canonical_frame": False}
        a = decompose(g, **opts)
        b = decompose(shifted, **opts)
        errs[refine] = np.abs(a.radii[:3] - b.radii[:3]).max() / a.spacing
    assert errs[True] < 0.05
    assert errs[True] < errs[False]


def test_options_and_errors(sphere: Sphere) -> None:
    d = decompose(sphere, config=MDBDConfig(resolution=16, n_balls=4), refine=False)
    assert d.config.resolution == 16 and d.config.refine is False
    with pytest.raises(ConfigError, match="bogus"):
        decompose(sphere, bogus=1)
    with pytest.raises(ConfigError):
        decompose(sphere, resolution=2)
    with pytest.raises(InvalidShapeError):
        decompose(np.zeros((3, 3)))  # type: ignore[arg-type]
    thin = Implicit(lambda p: 1e-4 - np.abs(p[:, 2]), [[-1, -1, -1e-4], [1, 1, 1e-4]], name="sheet")
    with pytest.raises(DegenerateGeometryError, match="sheet.*thinner"):
        decompose(thin, resolution=16)


def test_translation_and_scale_give_congruent_decompositions(generic: Implicit) -> None:
    a = decompose(generic, resolution=48, n_balls=64)
    t = np.array([0.31, -1.7, 2.2])
    b = decompose(generic.translate(t), resolution=48, n_balls=64)
    c = decompose(generic.scale(2.5), resolution=48, n_balls=64)
    np.testing.assert_allclose(b.centers, a.centers + t, atol=1e-6)
    np.testing.assert_allclose(c.radii, 2.5 * a.radii, rtol=1e-6)
    assert np.array_equal(a.edges, b.edges) and np.array_equal(a.edges, c.edges)


def test_canonical_frame_is_recorded_and_degenerate_inertia_does_not_crash(
    sphere: Sphere, box: Implicit
) -> None:
    d = decompose(sphere, resolution=32, n_balls=8)  # isotropic: model axes
    np.testing.assert_allclose(d.frame[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(d.frame[:3, 3], sphere.center, atol=0.02 * d.spacing)
    assert {"frame", "refine"} <= set(d.timings)
    cube = Implicit(lambda p: 0.5 - np.abs(p).max(axis=1), [[-0.5] * 3, [0.5] * 3], name="cube")
    assert decompose(cube, resolution=32, n_balls=8).radii[0] == pytest.approx(0.5, abs=1e-6)
    b = decompose(box, resolution=32, n_balls=8)  # distinct moments: the box's own axes
    np.testing.assert_allclose(np.abs(b.frame[:3, :3]), np.eye(3), atol=1e-9)
    off = decompose(box, resolution=32, n_balls=8, canonical_frame=False)
    np.testing.assert_array_equal(off.frame, np.eye(4))


def test_other_representations_decompose_in_the_frame() -> None:
    from shapedb.geometry.base import Transformed
    from shapedb.geometry.voxels import VoxelGrid

    occ = np.zeros((20, 14, 10), dtype=bool)
    occ[2:18, 2:12, 2:8] = True
    vox = VoxelGrid(occ, origin=(0.1, 0.2, 0.3), pitch=0.1)
    d = decompose(vox, resolution=32, n_balls=16)
    # half the slab's 0.6: at most the exact 0.3, at least the cell-centre value 0.25
    assert 0.25 - 1e-9 <= d.radii[0] <= 0.3 + 1e-9
    assert d.representation == "voxels"
    moved = Transformed(vox, np.eye(3)[[1, 2, 0]], [1.0, 2.0, 3.0])
    assert np.allclose(
        moved.signed_distance(d.centers[:3] @ np.eye(3)[[1, 2, 0]].T + [1, 2, 3]),
        vox.signed_distance(d.centers[:3]),
    )


def _box_with_rod() -> Implicit:
    """A cube of side 2 with a rod of radius 0.1 sticking out along x to x = 2.8."""
    from shapedb.geometry.implicit import Box, Capsule

    return Box([0, 0, 0], [2.0, 2.0, 2.0]) | Capsule([0.9, 0, 0], [2.8, 0, 0], 0.1)


def test_a_tail_continues_the_packing_and_leaves_the_balls_unchanged() -> None:
    g = _box_with_rod()
    today = decompose(g, resolution=48, n_balls=16)
    d = decompose(g, resolution=48, n_balls=16, tail_balls=200)
    assert np.array_equal(d.centers, today.centers) and np.array_equal(d.radii, today.radii)
    assert np.array_equal(d.edges, today.edges) and len(today.tail_radii) == 0
    assert len(d.tail_radii) == 200 and d.tail_centers.shape == (200, 3)
    assert np.all(np.diff(d.tail_radii) <= 0) and d.tail_radii[0] <= d.radii[-1] + 1e-12
    # the 16 balls never reach the rod; the tail does
    assert d.centers[:, 0].max() < 1.0 and (d.tail_centers[:, 0] > 1.2).sum() >= 4
    c, r = d.longer_packing()
    assert np.all(g.signed_distance(c) >= r - 1e-6), "tail balls lie inside"
    gap = np.linalg.norm(c[:, None] - c[None], axis=2) - r[:, None] - r[None]
    np.fill_diagonal(gap, np.inf)
    assert gap.min() >= -1e-6, "tail balls are disjoint from every ball"


def test_a_tail_stops_where_the_packing_would(box: Implicit) -> None:
    d = decompose(box, resolution=24, n_balls=8, tail_balls=100000)
    assert 0 < len(d.tail_radii) < 100000
    assert d.tail_radii.min() >= d.config.min_radius_cells * d.spacing * (1 - 1e-9)


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_a_bad_tail_is_refused(sphere: Sphere, bad: object) -> None:
    with pytest.raises(ConfigError, match="tail_balls"):
        decompose(sphere, resolution=24, n_balls=4, tail_balls=bad)  # type: ignore[arg-type]
