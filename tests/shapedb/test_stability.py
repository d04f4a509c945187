"""Stability of the decomposition and the kernel under similarity transforms and grid shifts.

The issue's target is a kernel similarity >= 0.99 for a rotated, translated and
uniformly scaled copy. The greedy packing is chaotic (a frame off by 0.001 degree
already gives 0.8-0.97 on CAPOD meshes), so the frame has to follow the model to
rounding. What the engine reaches (measured, 64 cells, 128 balls, the default
KernelConfig) and what these tests pin:

* meshes and point clouds: the frame comes from their own data (exact moments),
  and a mesh is queried through a copy rebuilt in that frame, so a rotated,
  moved and scaled copy gives the same decomposition up to rounding: kernel 1.0;
* moved copies of any geometry (``rotate``/``translate``/``scale`` of implicit
  solids, :meth:`Geometry.transformed`): the child's frame moved along, kernel 1.0;
* an implicit solid that is *not* a moved copy (its own distance function, here
  rotated by hand): the frame comes from sampled moments and follows a rotation
  to ~0.01-0.1 degree only, and the chaotic tail gives a kernel of ~0.85-0.95;
  likewise a grid shifted under a fixed solid (0.96).
"""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.geometry.implicit import Implicit
from shapedb.mdbd.decomposition import decompose
from shapedb.signature.kernel import features, kernel

OPTS = {"resolution": 64, "n_balls": 128}


def _rotation() -> np.ndarray:
    from shape_helpers import rotation

    return rotation((1.1, -0.5, 2.0))


def _angle(a: np.ndarray) -> float:
    """Rotation angle (degrees) of the 3x3 rotation ``a`` (accurate near 0)."""
    chord = np.linalg.norm(a - np.eye(3)) / (2.0 * np.sqrt(2.0))
    return float(np.degrees(2.0 * np.arcsin(min(chord, 1.0))))


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


def test_rotated_copy_keeps_the_decomposition(base: tuple) -> None:
    g, d0 = base
    R = _rotation()
    d1 = decompose(g.rotate(R).scale(0.6).translate([1.0, 2.0, -0.5]), **OPTS)
    assert _angle(d1.frame[:3, :3].T @ R @ d0.frame[:3, :3]) < 1e-6
    assert kernel(features(d0), features(d1)) >= 0.99  # measured 1.0
    np.testing.assert_allclose(d1.radii, 0.6 * d0.radii, rtol=1e-6)
    moved = 0.6 * d0.centers @ R.T + [1.0, 2.0, -0.5]
    np.testing.assert_allclose(d1.centers, moved, atol=1e-6 * d0.spacing)


def test_sampled_frame_follows_a_rotation_of_an_unmoved_solid(base: tuple) -> None:
    """A solid given by its own rotated distance function: the coarse-pass frame."""
    g, d0 = base
    R = _rotation()
    lo, hi = g.bounds
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    turned = corners @ R.T
    by_hand = Implicit(
        lambda p: g.signed_distance(np.asarray(p) @ R), [turned.min(axis=0), turned.max(axis=0)]
    )
    d1 = decompose(by_hand, **OPTS)
    assert _angle(d1.frame[:3, :3].T @ R @ d0.frame[:3, :3]) < 0.5  # measured ~0.1
    assert np.linalg.norm(d1.frame[:3, 3] - R @ d0.frame[:3, 3]) < 0.2 * d0.spacing
    assert d1.spacing == pytest.approx(d0.spacing, rel=0.01)
    k = min(50, d0.n_balls, d1.n_balls)
    a, b = d0.radii[:k] / d0.radii[0], d1.radii[:k] / d1.radii[0]
    assert np.abs(a[:10] - b[:10]).max() < 0.03
    assert np.abs(a - b).max() < 0.05
    assert kernel(features(d0), features(d1)) >= 0.85  # the chaotic tail: see the docstring


def test_grid_shift_under_a_fixed_solid_keeps_the_kernel_high(base: tuple) -> None:
    """Six sub-cell shifts of the grid under a solid known only by its distance function.

    Measured kernels (median, min): 0.92, 0.90 with the paper's plain argmax
    (``tie_cells=0``); 0.95, 0.90 at 0.75; 0.90, 0.85 at the default 1.5, which gains
    0.18 NN on jointed figures (``bench/studies/ties.py``); 0.77 for one shift with the grid on
    the model's axes.
    """
    g, d0 = base
    h = d0.spacing
    ks = []
    for frac in (0.1, 0.3, 0.5):
        for direction in (np.array([1.0, 2.0, 3.0]), np.array([-2.0, 1.0, 0.5])):
            step = frac * h * direction / np.linalg.norm(direction)
            shifted = Implicit(g.signed_distance, g.bounds - np.stack([step, 0 * step]))
            ks.append(kernel(features(d0), features(decompose(shifted, **OPTS))))
    assert np.median(ks) >= 0.88 and min(ks) >= 0.8, ks


@pytest.fixture(scope="module")
def figure_mesh() -> tuple[np.ndarray, np.ndarray]:
    from shapedb import examples

    m = examples.to_mesh(examples.figure(1, 1), resolution=48)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces)


def test_mesh_rotated_moved_and_scaled_keeps_the_kernel_at_one(figure_mesh: tuple) -> None:
    """On a mesh: a new mesh on transformed vertices, not a moved copy."""
    from shapedb.geometry.mesh import TriangleMesh

    v, f = figure_mesh
    opts = {"resolution": 48, "n_balls": 64}
    d0 = decompose(TriangleMesh(v, f), **opts)
    f0 = features(d0)
    R = _rotation()
    for s, t in ((1.0, np.zeros(3)), (2.0, np.array([0.4, -0.2, 1.0]))):
        d1 = decompose(TriangleMesh(s * v @ R.T + t, f), **opts)
        assert _angle(d1.frame[:3, :3].T @ R @ d0.frame[:3, :3]) < 1e-6
        assert kernel(f0, features(d1)) >= 0.99  # measured 1.0
        np.testing.assert_allclose(d1.radii[:10], s * d0.radii[:10], rtol=1e-5)
    d2 = decompose(TriangleMesh(v, f).transformed(R, np.zeros(3)), **opts)
    assert kernel(f0, features(d2)) >= 0.99


def test_point_cloud_rotated_keeps_the_kernel_at_one(figure_mesh: tuple) -> None:
    from shapedb.geometry.pointcloud import PointCloud

    v, _ = figure_mesh
    opts = {"resolution": 40, "n_balls": 48, "refine": False}
    d0 = decompose(PointCloud(v), **opts)
    R = _rotation()
    d1 = decompose(PointCloud(1.5 * v @ R.T + [0.2, 0.1, -0.3]), **opts)
    assert _angle(d1.frame[:3, :3].T @ R @ d0.frame[:3, :3]) < 1e-6
    assert kernel(features(d0), features(d1)) >= 0.99  # measured 1.0


def test_frame_without_exact_moments_is_not_claimed_exact() -> None:
    """The data frame only serves meshes, clouds and moved copies; a solid of its own
    goes through the coarse passes (whose frame is measured above)."""
    from shapedb.config.core import MDBDConfig
    from shapedb.geometry.implicit import Sphere
    from shapedb.mdbd.frame import _data_frame, _moved_frame

    s = Sphere([0.1, 0.2, 0.3], 1.0)
    assert _data_frame(s, MDBDConfig()) is None
    assert _moved_frame(s, MDBDConfig()) is None
    assert _moved_frame(s.translate([1.0, 0.0, 0.0]), MDBDConfig()) is not None
