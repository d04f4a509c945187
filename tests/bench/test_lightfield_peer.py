"""The published light field descriptor (bench.support.lightfield_peer) on analytic shapes."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from bench.support.lightfield_peer import (
    FaithfulLFDConfig,
    peer_descriptor,
    peer_distance,
    spread_rotations,
)
from bench.support.lightfield_render import normalised_vertices, render_polygons
from shapedb.signature.lightfield_descriptor import dodecahedron_rotations, dodecahedron_views

trimesh = pytest.importorskip("trimesh")

#: Small enough to keep the tests quick; the moments' disc still spans ~60 pixels.
SMALL = FaithfulLFDConfig(n_fields=3, resolution=64)


@functools.lru_cache(maxsize=1)
def _shapes() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    cube = trimesh.creation.box()
    sphere = trimesh.creation.icosphere(subdivisions=3)
    cylinder = trimesh.creation.cylinder(radius=0.5, height=2.0, sections=48)
    return {k: (np.asarray(m.vertices), np.asarray(m.faces)) for k, m in
            {"cube": cube, "sphere": sphere, "cylinder": cylinder}.items()}  # fmt: skip


def test_a_cube_turned_by_a_dodecahedral_rotation_is_at_distance_zero() -> None:
    v, f = _shapes()["cube"]
    a = peer_descriptor(v, f, SMALL)
    others = [peer_descriptor(*_shapes()[k], SMALL) for k in ("sphere", "cylinder")]
    far = peer_distance(a[None], np.stack(others)).min()
    for g in dodecahedron_rotations()[[5, 23, 41]]:
        d = float(peer_distance(a[None], peer_descriptor(v @ g.T, f, SMALL)[None])[0, 0])
        assert d < 0.1 * far  # exact up to pixels (64 px here) and quantisation


def test_translation_and_scale_do_not_change_the_descriptor() -> None:
    v, f = _shapes()["cylinder"]
    a = peer_descriptor(v, f, SMALL)
    b = peer_descriptor(7.5 * v + np.array([3.0, -2.0, 11.0]), f, SMALL)
    assert np.abs(a - b).max() <= 1.0  # one quantisation step at most


def test_flipped_faces_render_the_same_silhouettes() -> None:
    v, f = _shapes()["cube"]
    d = dodecahedron_views()
    nv = normalised_vertices(v)
    assert np.array_equal(render_polygons(nv, f, d, 48), render_polygons(nv, f[:, ::-1], d, 48))


def test_a_sheet_seen_edge_on_is_a_line_not_nothing() -> None:
    sheet = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    img = render_polygons(0.7 * sheet, faces, np.array([[1.0, 0.0, 0.0]]), 64)[0]
    assert 0 < img.sum() <= 3 * 64  # a line of pixels
    face_on = render_polygons(0.7 * sheet, faces, np.array([[0.0, 0.0, 1.0]]), 64)[0]
    assert face_on.mean() == pytest.approx(0.7**2, abs=0.05)  # filled, no holes


def test_cube_sphere_and_cylinder_each_find_their_own_kind() -> None:
    names = ("cube", "sphere", "cylinder")
    desc = np.stack([peer_descriptor(*_shapes()[k], SMALL) for k in names])
    d = peer_distance(desc)
    assert np.allclose(d, d.T) and np.all(np.diag(d) == 0)
    assert np.all(d[~np.eye(3, dtype=bool)] > 0)
    c, s = np.cos(0.5), np.sin(0.5)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
    )  # not a symmetry of the dodecahedron
    cube = _shapes()["cube"]
    sphere = trimesh.creation.icosphere(subdivisions=2)
    cylinder = trimesh.creation.cylinder(radius=0.5, height=2.2, sections=32)
    queries = [(cube[0] @ turn.T, cube[1]), (sphere.vertices, sphere.faces),
               (cylinder.vertices, cylinder.faces)]  # fmt: skip
    q = np.stack([peer_descriptor(v, f, SMALL) for v, f in queries])
    assert np.array_equal(np.argmin(peer_distance(q, desc), axis=1), [0, 1, 2])


def test_the_light_fields_are_turned_apart() -> None:
    r = spread_rotations(10)
    assert np.allclose(r[0], np.eye(3))
    assert np.allclose(np.einsum("nij,nkj->nik", r, r), np.eye(3), atol=1e-9)
    views = dodecahedron_views()
    cams = [views @ x.T for x in r]
    worst = max(np.abs(a @ b.T).max() for i, a in enumerate(cams) for b in cams[:i])
    assert worst < np.cos(np.radians(5.0))  # no camera within 5 degrees of another field's


def test_variant_switches_change_the_layout() -> None:
    v, f = _shapes()["cube"]
    assert peer_descriptor(v, f, SMALL).shape == (3, 10, 45)
    z = peer_descriptor(v, f, FaithfulLFDConfig(n_fields=1, resolution=32, fourier=False))
    assert z.shape == (1, 10, 35)
    q = peer_descriptor(v, f, FaithfulLFDConfig(n_fields=1, resolution=32))
    assert np.array_equal(q, np.floor(q)) and q.max() <= 2 * 255
    raw = peer_descriptor(v, f, FaithfulLFDConfig(n_fields=1, resolution=32, quantise=False))
    assert np.all(raw >= q) and np.all(raw - q < 2 * 1 + 1e-3)
