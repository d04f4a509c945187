"""The light field descriptor baseline (bench.support.lightfield: mesh splats) on analytic shapes.

The dodecahedron, the features and the distance are tested in tests/shapedb/test_lightfield.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.support.lightfield import (
    LFDConfig,
    dodecahedron_rotations,
    dodecahedron_views,
    lfd_descriptor,
    lfd_distance,
    render_silhouettes,
    silhouette_features,
)

trimesh = pytest.importorskip("trimesh")

SMALL = LFDConfig(n_fields=3, resolution=48, n_points=8000)


def test_a_sphere_has_disc_silhouettes_and_round_features() -> None:
    s = trimesh.creation.icosphere(subdivisions=4, radius=2.0)
    p = np.asarray(s.vertices) / 2.0  # the unit sphere
    img = render_silhouettes(p, dodecahedron_views(), 64)
    area = img.reshape(10, -1).mean(axis=1)
    assert np.allclose(area, np.pi / 4, atol=0.03)  # a unit disc in [-1, 1]^2
    f = silhouette_features(img, SMALL)
    z = f[:, :-10]
    assert np.allclose(f[:, -10:], 0.0, atol=0.03)  # a circle's centroid distance is constant
    assert np.all(z[:, 0] > 0.9)  # A_00 = area / pi = 1 for the unit disc
    assert np.all(np.max(z[:, 1:], axis=1) < 0.15 * z[:, 0])


def test_a_rotated_copy_is_near_and_a_cube_is_far() -> None:
    sphere = trimesh.creation.icosphere(subdivisions=3)
    cube = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    bar = trimesh.creation.box(extents=(3.0, 1.0, 0.5))
    turn = dodecahedron_rotations()[17]
    q, r = np.linalg.qr(np.random.default_rng(5).normal(size=(3, 3)))
    other = q * np.sign(np.diag(r))
    other = other if np.linalg.det(other) > 0 else -other
    models = [
        (sphere.vertices, sphere.faces),
        (cube.vertices, cube.faces),
        (np.asarray(cube.vertices) @ turn.T, cube.faces),
        (2.5 * np.asarray(cube.vertices) @ other.T + 3.0, cube.faces),
        (bar.vertices, bar.faces),
        (np.asarray(bar.vertices) @ other.T, bar.faces),
    ]
    d = lfd_distance(np.stack([lfd_descriptor(v, f, SMALL) for v, f in models]))
    assert np.allclose(d, d.T) and np.allclose(np.diag(d), 0.0)
    far = min(d[0, 1], d[1, 4], d[0, 4])
    # turned by a rotation of the dodecahedron: the views are permuted, only the
    # pixel grid turns in the image plane
    assert d[1, 2] < 0.25 * far
    assert d[1, 3] < 0.3 * far  # turned arbitrarily, scaled and moved
    assert d[4, 5] < 0.5 * far
    assert np.argmin(d[5, :5]) == 4  # the turned bar finds its original


def test_a_sheet_has_a_silhouette_like_its_box() -> None:
    sheet = (
        np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0.0]]),
        np.array([[0, 1, 2], [0, 2, 3]]),
    )
    thin = trimesh.creation.box(extents=(2.0, 1.0, 0.01))
    thick = trimesh.creation.box(extents=(2.0, 1.0, 1.0))
    d = lfd_distance(
        np.stack([lfd_descriptor(v, f, SMALL) for v, f in (sheet, (thin.vertices, thin.faces),
                                                          (thick.vertices, thick.faces))])
    )  # fmt: skip
    assert d[0, 1] < 0.5 * d[0, 2]


def test_shape_mismatch_is_refused() -> None:
    with pytest.raises(ValueError, match="do not match"):
        lfd_distance(np.zeros((2, 1, 10, 46)), np.zeros((2, 1, 10, 45)))


def test_numbers_are_those_of_the_baseline_before_its_core_moved_to_shapedb() -> None:
    # values of bench/lightfield.py at commit 2abcda4, before shapedb.signature.lightfield existed
    bar = trimesh.creation.box(extents=(3.0, 1.0, 0.5))
    cyl = trimesh.creation.cylinder(radius=0.5, height=2.0)
    d = np.stack([lfd_descriptor(m.vertices, m.faces, SMALL) for m in (bar, cyl)])
    assert np.allclose(d[0, 1, 2, [0, 1, 5, 36, 40]],
                       [0.34317785, 0.00229082, 0.0013356, 0.00137438, 0.00161546])  # fmt: skip
    assert np.allclose(d[1, 2, 7, [0, 3, 9, 37, 45]],
                       [0.55262133, 0.381792261, 0.0, 0.211380077, 0.00482219845], atol=1e-8)  # fmt: skip
    # the distance sums every coefficient: later trimesh / numpy releases move it by ~0.1 %
    # (17.1915 with trimesh 5.2 and numpy 2.4.6), a changed descriptor by far more
    assert np.isclose(lfd_distance(d)[0, 1], 17.171553759513092, rtol=5e-3)
