"""Point clouds bound the same solid as the mesh they were sampled from."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shapedb.geometry.base import Grid
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import UNEXPLAINED_SWITCH, PointCloud


def _open_cup() -> TriangleMesh:
    """A single-sheet cylinder with a bottom and no lid (vase-like, open)."""
    c = trimesh.creation.cylinder(radius=0.4, height=1.0, sections=48)
    keep = c.face_normals[:, 2] < 0.5
    return TriangleMesh(c.vertices, c.faces[keep])


def _open_box() -> TriangleMesh:
    """Five single-sheet faces of a box: no bottom (like a piano body)."""
    b = trimesh.creation.box(extents=(1.0, 0.8, 0.6))
    keep = b.face_normals[:, 2] > -0.5
    m = trimesh.Trimesh(b.vertices, b.faces[keep], process=False).subdivide().subdivide()
    return TriangleMesh(m.vertices, m.faces)


def _plate(thickness: float = 0.03) -> TriangleMesh:
    m = trimesh.creation.box(extents=(1.0, 0.8, thickness)).subdivide().subdivide()
    return TriangleMesh(m.vertices, m.faces)


def _insides(mesh: TriangleMesh, cloud: PointCloud, pad: float = 0.0) -> tuple:
    g = Grid.fit(mesh.bounds + np.array([[-pad], [pad]]), resolution=48)
    return mesh.grid_sdf(g) > 0, cloud.grid_sdf(g) > 0


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max(int((a | b).sum()), 1))


@pytest.mark.parametrize("make", [_open_cup, _open_box], ids=["cup", "box"])
def test_open_single_sheet_agrees_with_the_mesh(make) -> None:  # type: ignore[no-untyped-def]
    """The exterior reaches both sides of an open sheet; the cloud must still fill the
    cavity like the mesh's winding number does (before: IoU 0.06 cup, 0.72 box)."""
    mesh = make()
    cloud = PointCloud(mesh.sample_surface(3000, seed=1))
    assert cloud._unexplained(cloud._exterior_orientation()) > UNEXPLAINED_SWITCH
    a, b = _insides(mesh, cloud)
    assert a.mean() > 0.3  # the mesh's solid is the filled cup / box
    assert _iou(a, b) > 0.9
    assert 0.9 < b.sum() / a.sum() < 1.1


def test_propagated_orientation_is_outward_on_a_sphere() -> None:
    v = trimesh.creation.icosphere(subdivisions=3).vertices
    cloud = PointCloud(v)
    n = cloud._pca * cloud._propagated_orientation()[:, None]
    # the cloud keeps its samples in its own order (deduplicated, sorted)
    assert np.all(np.einsum("ij,ij->i", n, cloud._points) > 0)
    assert cloud._unexplained(cloud._exterior_orientation()) < 0.01


def test_thin_plate_keeps_two_sided_normals() -> None:
    """A plate thinner than the sample spacing: exterior votes give its two sides
    opposite normals (propagation would give both the same and fill the space next to
    the plate instead)."""
    mesh = _plate()
    cloud = PointCloud(mesh.sample_surface(3000, seed=1))
    assert np.median(cloud.spacing) > 0.03  # thinner than the spacing
    assert cloud._unexplained(cloud._exterior_orientation()) < UNEXPLAINED_SWITCH
    a, b = _insides(mesh, cloud, pad=0.1)
    both = (a & b).sum()
    assert both / b.sum() > 0.9  # nothing outside the plate
    assert both / a.sum() > 0.5


def test_closed_sphere_is_unchanged() -> None:
    v = trimesh.creation.icosphere(subdivisions=4).vertices
    cloud = PointCloud(v[np.random.default_rng(0).random(len(v)) < 0.2])
    mesh = TriangleMesh(v, trimesh.creation.icosphere(subdivisions=4).faces)
    a, b = _insides(mesh, cloud)
    assert _iou(a, b) > 0.93


@pytest.mark.parametrize("shape", ["sphere", "box", "torus"])
def test_point_areas_add_up_to_the_surface_area(shape: str) -> None:
    mesh = {
        "sphere": trimesh.creation.icosphere(subdivisions=4),
        "box": trimesh.creation.box(extents=(1.0, 2.0, 3.0)),
        "torus": trimesh.creation.torus(1.0, 0.3),
    }[shape]
    cloud = PointCloud(trimesh.sample.sample_surface(mesh, 2000, seed=3)[0])
    # measured 0.84 (box: neighbourhoods folded over its edges look narrower) to 0.97
    assert cloud.areas.sum() == pytest.approx(mesh.area, rel=0.2)


def test_samples_along_a_wire_add_no_volume() -> None:
    """A wire thinner than the sample spacing (a spider's leg at 20 % of its vertices):
    its samples lie on a curve, and counting each as a disc of the spacing's radius
    made winding numbers of 0.6-0.9 around it (spurious balls on CAPOD spiders)."""
    sphere, _ = trimesh.sample.sample_surface(trimesh.creation.icosphere(4), 3000, seed=2)
    t = np.linspace(1.05, 3.0, 40)
    wire = np.c_[t, 0.01 * np.cos(7 * t), 0.01 * np.sin(7 * t)]
    cloud = PointCloud(np.r_[sphere, wire])
    near = np.c_[np.linspace(1.3, 2.8, 16), np.full(16, 0.05), np.zeros(16)]
    assert np.all(np.abs(cloud.winding_number(near)) < 0.25)
    assert np.all(cloud.signed_distance(near) < 0)
    assert cloud.contains([[0.0, 0.0, 0.0], [0.5, 0.2, 0.1]]).all()


def test_surface_sampling_is_the_median_sample_spacing() -> None:
    # a 20 x 20 lattice on each face of a unit cube: every point's 10th neighbour is
    # within two lattice steps (the exact figure depends on edges and corners)
    t = np.linspace(0.0, 1.0, 20)
    u, v = (a.ravel() for a in np.meshgrid(t, t))
    faces = []
    for axis in range(3):
        for side in (0.0, 1.0):
            p = np.empty((u.size, 3))
            p[:, axis] = side
            p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = u, v
            faces.append(p)
    cloud = PointCloud(np.vstack(faces))
    step = 1.0 / 19
    assert step < cloud.surface_sampling <= 2.0 * step + 1e-9
    assert cloud.surface_sampling == float(np.median(cloud.spacing))
    assert _plate().surface_sampling == 0.0
    from shapedb.mdbd.decomposition import decompose

    d = decompose(cloud, resolution=24, n_balls=16)
    assert d.representation == "pointcloud" and d.sampling == cloud.surface_sampling


def test_direct_winding_number_is_the_sum_over_samples() -> None:
    """The few-point winding number (matrix products about the centroid) is the textbook
    sum ``a (p - q) . n / (4 pi |p - q|^3)``, far from the origin too; a query point on a
    sample takes no term from it instead of 0 / 0."""
    pts, _ = trimesh.sample.sample_surface(trimesh.creation.icosphere(3), 800, seed=4)
    offset = np.array([1e4, -2e4, 5e3])
    cloud = PointCloud(pts + offset)
    rng = np.random.default_rng(1)
    q = offset + np.r_[rng.normal(scale=0.6, size=(6, 3)), [[0.0, 0.0, 0.0]]]
    d = cloud.points[None] - q[:, None]
    r = np.linalg.norm(d, axis=2)
    expected = (cloud.areas * np.einsum("qpk,pk->qp", d, cloud.normals) / (4 * np.pi * r**3)).sum(1)
    assert cloud.winding_number(q) == pytest.approx(expected, abs=1e-6)
    assert cloud.winding_number(q[-1:])[0] > 0.75  # the centre (areas sum to 0.9 of it)
    on = cloud.winding_number(cloud.points[:3])
    assert np.all(np.isfinite(on)) and np.all(np.abs(on - 0.5) < 0.3)
