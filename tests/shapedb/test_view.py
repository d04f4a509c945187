"""Sparse views (shapedb.geometry.view): sparsity test, view sampling, configuration, records."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from shapedb.config.core import CloudConfig, Config
from shapedb.errors import ConfigError
from shapedb.geometry.implicit import Sphere
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud
from shapedb.geometry.view import (
    AREA_PER_SAMPLE,
    MIN_VIEW_SAMPLES,
    SPARSE_CELLS,
    boundary_mesh,
    is_sparse,
    surface_area,
    view_geometry,
)


def _cube(side: float = 1.0) -> TriangleMesh:
    return TriangleMesh.from_trimesh(trimesh.creation.box(extents=(side, side, side)), name="cube")


@pytest.mark.parametrize(
    ("sampling", "spacing", "expected"),
    [
        (0.0, 0.1, False),  # exact surface
        (SPARSE_CELLS * 0.1, 0.1, True),  # exactly at the threshold
        (SPARSE_CELLS * 0.1 * 0.99, 0.1, False),
        (0.5, 0.1, True),
        (float("nan"), 0.1, False),
        (0.5, 0.0, False),  # no grid
    ],
)
def test_is_sparse(sampling: float, spacing: float, expected: bool) -> None:
    assert is_sparse(sampling, spacing) is expected


def test_surface_area_of_a_cube_is_exact() -> None:
    cube = _cube(2.0)
    assert surface_area(cube.vertices, cube.faces) == pytest.approx(24.0, rel=1e-12)


def test_view_of_a_cube_lies_on_its_surface_at_the_requested_spacing() -> None:
    cube = _cube(1.0)
    view = view_geometry(cube, spacing=0.05, view_cells=4.0)
    assert isinstance(view, PointCloud)
    n = round(6.0 / (AREA_PER_SAMPLE * (4.0 * 0.05) ** 2))
    assert 0.7 * n <= len(view.points) <= n  # the formula's count, or thinned a little
    assert 0.9 * 4.0 <= view.surface_sampling / 0.05 <= 1.3 * 4.0
    # every sample lies on a face of the cube: one coordinate at +-0.5, the others inside
    p = np.abs(view.points)
    assert np.allclose(p.max(axis=1), 0.5, atol=1e-9)
    assert (p <= 0.5 + 1e-9).all()


def test_doubled_faces_are_thinned_to_the_same_spacing() -> None:
    """A polygon soup with every face twice has twice the area but the same surface."""
    sphere = trimesh.creation.icosphere(subdivisions=4)
    single = TriangleMesh(sphere.vertices, sphere.faces, name="single")
    double = TriangleMesh(sphere.vertices, np.vstack([sphere.faces, sphere.faces]), name="x2")
    assert surface_area(double.vertices, double.faces) == pytest.approx(
        2 * surface_area(single.vertices, single.faces)
    )
    a = view_geometry(single, spacing=0.02, view_cells=4.0)
    b = view_geometry(double, spacing=0.02, view_cells=4.0)
    assert a is not None and b is not None
    assert len(b.points) == pytest.approx(len(a.points), rel=0.15)  # not twice as many
    assert b.surface_sampling == pytest.approx(a.surface_sampling, rel=0.1)


def test_view_is_deterministic_and_sparse_at_the_requested_spacing() -> None:
    sphere = TriangleMesh.from_trimesh(trimesh.creation.icosphere(subdivisions=5), name="s")
    a = view_geometry(sphere, spacing=0.02, view_cells=4.0)
    b = view_geometry(sphere, spacing=0.02, view_cells=4.0)
    assert a is not None and b is not None
    np.testing.assert_array_equal(a.points, b.points)
    cells = a.surface_sampling / 0.02
    assert 3.0 < cells < 5.0  # AREA_PER_SAMPLE makes the median k-th-neighbour distance ~4
    assert is_sparse(a.surface_sampling, 0.02)


def test_tiny_surface_gets_the_minimum_view() -> None:
    view = view_geometry(_cube(0.01), spacing=0.05, view_cells=4.0)
    assert view is not None and len(view.points) == MIN_VIEW_SAMPLES


def test_implicit_solids_are_viewed_on_their_marching_cubes_surface() -> None:
    sphere = Sphere([0, 0, 0], 1.0)
    view = view_geometry(sphere, spacing=0.04, view_cells=4.0)
    assert isinstance(view, PointCloud)
    r = np.linalg.norm(view.points, axis=1)
    assert np.abs(r - 1.0).max() < 0.04  # within a cell of the sphere
    n = 4 * np.pi / (AREA_PER_SAMPLE * (4.0 * 0.04) ** 2)
    assert 0.7 * n <= len(view.points) <= 1.05 * n
    assert 0.9 * 4.0 <= view.surface_sampling / 0.04 <= 1.3 * 4.0


def test_boundary_mesh_of_nothing_is_none() -> None:
    empty = Sphere([0, 0, 0], 1.0) - Sphere([0, 0, 0], 2.0)
    assert boundary_mesh(empty, 0.1) is None
    assert view_geometry(_cube(), spacing=float("nan"), view_cells=4.0) is None


def test_view_needs_a_positive_spacing() -> None:
    with pytest.raises(ConfigError, match="view_cells"):
        view_geometry(_cube(), spacing=0.05, view_cells=0.0)


@pytest.mark.parametrize("bad", [1.0, 17.0, -4.0, float("nan"), True, "4"])
def test_view_cells_is_validated(bad: object) -> None:
    with pytest.raises(ConfigError, match="view_cells"):
        CloudConfig(view_cells=bad)  # type: ignore[arg-type]


def test_view_cells_round_trips_and_defaults_off_for_older_configs() -> None:
    cfg = Config().with_options(view_cells=4.0)
    assert Config.from_json(cfg.to_json()) == cfg
    old = cfg.to_dict()
    del old["cloud"]["view_cells"]
    assert Config.from_dict(old).cloud.view_cells == 0.0


# --------------------------------------------------------------------------------------
# One-sided point clouds
# --------------------------------------------------------------------------------------


def _sphere_points(n: int, seed: int = 0) -> np.ndarray:
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def _cube_points(n: int, faces: int = 6, seed: int = 0) -> np.ndarray:
    """Uniform samples of the faces of [-1, 1]^3: all six, or the three facing +x, +y, +z."""
    rng = np.random.default_rng(seed)
    face = rng.integers(0, faces, n)
    p = rng.uniform(-1.0, 1.0, (n, 3))
    p[np.arange(n), face % 3] = np.where(face < 3, 1.0, -1.0)
    return p


def _sphere_scan(axis: np.ndarray, step: float = 0.04) -> np.ndarray:
    """The unit sphere as an orthographic depth camera on ``axis`` sees it: a pixel grid
    over the disc, each pixel's first hit (few points where the surface turns away)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    u = np.cross(a, [0.0, 0.0, 1.0] if abs(a[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    g = np.arange(-1.0, 1.0, step) + step / 2
    x, y = (m.ravel() for m in np.meshgrid(g, g))
    inside = x * x + y * y < 1.0
    x, y = x[inside], y[inside]
    return np.outer(x, u) + np.outer(y, w) + np.outer(np.sqrt(1.0 - x * x - y * y), a)


def test_one_sided_clouds_are_told_from_closed_ones() -> None:
    from shapedb.geometry.view import ONE_SIDED_LAYERS, is_one_sided, layered_fraction

    sphere = _sphere_points(3000)
    assert not is_one_sided(PointCloud(sphere))
    assert is_one_sided(PointCloud(_sphere_scan([1.0, 0.0, 0.0])))
    assert not is_one_sided(PointCloud(_cube_points(3000)))
    assert is_one_sided(PointCloud(_cube_points(1500, faces=3)))  # the visible three faces
    assert layered_fraction(sphere)[0] > 0.5 > ONE_SIDED_LAYERS
    assert not is_one_sided(PointCloud(_sphere_scan([1.0, 0.0, 0.0], step=0.2)))  # too few


def test_a_one_sided_cloud_knows_where_it_was_seen_from() -> None:
    from shapedb.geometry.view import viewing_direction

    for axis in [*np.eye(3), np.array([0.3, -0.5, 0.8])]:
        d = viewing_direction(PointCloud(_sphere_scan(axis)))
        a = axis / np.linalg.norm(axis)
        assert d is not None and abs(float(d @ a)) > np.cos(np.radians(10))
    d = viewing_direction(PointCloud(_cube_points(3000, faces=3)))
    assert d is not None and abs(float(d @ np.ones(3))) / np.sqrt(3) > np.cos(np.radians(15))
    assert viewing_direction(PointCloud(_sphere_points(3000))) is None


def _cube_perspective_scan(eye: np.ndarray, pixels: int = 80) -> np.ndarray:
    """What a perspective depth camera at ``eye`` looking at the origin sees of [-1, 1]^3:
    each pixel's first hit (rays through a square image of half-angle 0.45 rad)."""
    f = -eye / np.linalg.norm(eye)
    r = np.cross(f, np.eye(3)[int(np.argmin(np.abs(f)))])
    r /= np.linalg.norm(r)
    up = np.cross(r, f)
    g = np.tan(np.linspace(-0.45, 0.45, pixels))
    x, y = (m.ravel() for m in np.meshgrid(g, g))
    rays = f + x[:, None] * r + y[:, None] * up
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-1.0 - eye) / rays, (1.0 - eye) / rays
    near, far = np.nanmax(np.minimum(t1, t2), axis=1), np.nanmin(np.maximum(t1, t2), axis=1)
    hit = (far >= near) & (far > 0)
    return eye + near[hit, None] * rays[hit]


def test_a_perspective_scan_is_seen_along_its_camera_axis() -> None:
    # a cube seen in perspective from 2.5 bounding radii is one layer deep over a wide cap
    # of directions; the fine count finds the camera's axis within 12 degrees at the
    # median of 24 random cameras (the test's own 24 cells: 17)
    from shapedb.geometry.view import layered_fraction

    rng = np.random.default_rng(0)
    errors = []
    for _ in range(24):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        d = layered_fraction(_cube_perspective_scan(axis * 2.5 * np.sqrt(3)))[1]
        errors.append(np.degrees(np.arccos(min(1.0, abs(float(d @ axis))))))
    assert np.median(errors) < 14.0


def test_only_point_clouds_are_one_sided() -> None:
    from shapedb.geometry.view import is_one_sided, viewing_direction

    assert viewing_direction(Sphere([0, 0, 0], 1.0)) is None
    assert not is_one_sided(Sphere([0, 0, 0], 1.0))


def _tray(n: int = 3000, h: float = 0.2, seed: int = 1) -> np.ndarray:
    """Even samples of a 2 x 2 zero-thickness tray: its bottom at z = 0 and four walls
    ``h`` high (one layer deep from above: the walls are thinner than two cells)."""
    rng = np.random.default_rng(seed)
    areas = np.array([4.0] + [2.0 * h] * 4)
    part = rng.choice(5, n, p=areas / areas.sum())
    u, v = rng.uniform(-1.0, 1.0, n), rng.uniform(0.0, h, n)
    p = np.column_stack([u, rng.uniform(-1.0, 1.0, n), np.zeros(n)])
    for k, (axis, side) in enumerate([(0, -1.0), (0, 1.0), (1, -1.0), (1, 1.0)], start=1):
        wall = part == k
        p[wall, axis] = side
        p[wall, 1 - axis] = u[wall]
        p[wall, 2] = v[wall]
    return p


def test_a_whole_thin_model_one_layer_deep_is_not_taken_for_a_scan() -> None:
    from shapedb.geometry.view import (
        GRAZING_SHARE,
        ONE_SIDED_LAYERS,
        grazing_share,
        is_one_sided,
        layered_fraction,
    )

    tray = _tray()
    g = np.arange(-1.0, 1.0, 0.04) + 0.02
    x, y = (m.ravel() for m in np.meshgrid(g, g))
    scan = np.column_stack([x, y, np.zeros(x.size)])  # a camera above sees the bottom
    scan[np.abs(scan[:, :2]).max(axis=1) > 0.98, 2] = 0.2  # and the walls' top edges
    up = np.array([0.0, 0.0, 1.0])
    # the walls are a fifth of the tray's area, all edge-on from above; a scan sees none
    assert grazing_share(tray, up) == pytest.approx(0.8 / 4.8, abs=0.03)
    assert grazing_share(scan, up) == 0.0
    assert layered_fraction(tray)[0] < ONE_SIDED_LAYERS  # the layer count alone: a scan
    assert grazing_share(tray, layered_fraction(tray)[1]) >= GRAZING_SHARE
    assert not is_one_sided(PointCloud(tray))
    assert is_one_sided(PointCloud(scan))
    with pytest.raises(ValueError, match="3 or more points"):
        grazing_share(tray[:2], up)
