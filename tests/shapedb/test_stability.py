"""Stability of the decomposition and the kernel under similarity transforms and grid shifts.

The issue's target is a kernel similarity >= 0.99 for a rotated, translated and
uniformly scaled copy. What the engine reaches (measured, 64 cells, 128 balls, the
default KernelConfig) and what these tests pin:

* translation + uniform scale, and a sub-cell translation of the model: the
  canonical frame follows the solid exactly, so the decomposition is the same up to
  rounding (kernel 1.0 on solids without exact ties);
* a generic rotation: the frame follows the solid to ~0.1 degree, the leading radii
  agree to a fraction of a cell, but the greedy packing of the tail is chaotic and
  the Eq. 1 walk averages count the small balls touching the largest ones: 0.94 on
  a tie-free solid (0.96-0.97 at 128 cells / 512 balls), still 0.5-0.9 on solids
  with plateaus of equally good balls (plates, capsules, tori).
"""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.implicit import Implicit
from shapedb.kernel import features, kernel
from shapedb.mdbd import decompose

OPTS = {"resolution": 64, "n_balls": 128}


def _rotation() -> np.ndarray:
    from shape_helpers import rotation

    return rotation((1.1, -0.5, 2.0))


@pytest.fixture(scope="module")
def base(generic: Implicit) -> tuple[Implicit, object]:
    return generic, decompose(generic, **OPTS)


def test_translation_and_scale_keep_the_kernel_at_one(base: tuple) -> None:
    g, d0 = base
    f0 = features(d0)
    moved = decompose(g.scale(2.7).translate([0.3, -1.1, 4.0]), **OPTS)
    assert kernel(f0, features(moved)) >= 0.99
    np.testing.assert_allclose(moved.radii, 2.7 * d0.radii, rtol=1e-6)


def test_sub_cell_translation_keeps_the_kernel_at_one(base: tuple) -> None:
    g, d0 = base
    direction = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    t = 0.3 * d0.spacing * direction
    d1 = decompose(g.translate(t), **OPTS)
    assert kernel(features(d0), features(d1)) >= 0.99
    np.testing.assert_allclose(d1.centers, d0.centers + t, atol=1e-6)


def test_frame_follows_a_generic_rotation(base: tuple) -> None:
    g, d0 = base
    R = _rotation()
    d1 = decompose(g.rotate(R), **OPTS)
    err = d1.frame[:3, :3].T @ R @ d0.frame[:3, :3]
    angle = np.degrees(np.arccos(np.clip((np.trace(err) - 1.0) / 2.0, -1.0, 1.0)))
    assert angle < 0.5
    assert np.linalg.norm(d1.frame[:3, 3] - R @ d0.frame[:3, 3]) < 0.2 * d0.spacing
    assert d1.spacing == pytest.approx(d0.spacing, rel=0.01)


def test_generic_rotation_keeps_leading_radii_and_kernel(base: tuple) -> None:
    g, d0 = base
    d1 = decompose(g.rotate(_rotation()), **OPTS)
    k = min(50, d0.n_balls, d1.n_balls)
    a, b = d0.radii[:k] / d0.radii[0], d1.radii[:k] / d1.radii[0]
    assert np.abs(a[:10] - b[:10]).max() < 0.03  # measured 0.015 (0.2 cell)
    assert np.abs(a - b).max() < 0.05
    assert kernel(features(d0), features(d1)) >= 0.9  # measured 0.94; target 0.99


def test_grid_shift_under_a_fixed_solid_keeps_the_kernel_high(base: tuple) -> None:
    g, d0 = base
    h = d0.spacing
    direction = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    shifted = Implicit(g.signed_distance, g.bounds - np.stack([0.3 * h * direction, 0 * direction]))
    d1 = decompose(shifted, **OPTS)
    assert kernel(features(d0), features(d1)) >= 0.9  # measured 0.96 (0.77 on model axes)


def test_mesh_moves_with_its_frame() -> None:
    from shapedb import examples
    from shapedb.mesh import TriangleMesh

    m = examples.to_mesh(examples.figure(1, 1), resolution=48)
    mesh = TriangleMesh(m.vertices, m.faces)
    opts = {"resolution": 48, "n_balls": 64}
    d0 = decompose(mesh, **opts)
    moved = TriangleMesh(2.0 * m.vertices + [0.4, -0.2, 1.0], m.faces)
    d1 = decompose(moved, **opts)
    assert kernel(features(d0), features(d1)) >= 0.99
    R = _rotation()
    d2 = decompose(mesh.transformed(R, np.zeros(3)), **opts)
    a, b = d0.radii[:10] / d0.radii[0], d2.radii[:10] / d2.radii[0]
    assert np.abs(a - b).max() < 0.06
