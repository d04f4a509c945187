"""bench.sets.scans: one-sided depth scans, surface samplings and cropped halves."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from bench.sets import scans


@pytest.fixture(scope="module")
def sphere() -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    m = trimesh.creation.icosphere(subdivisions=4)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def _spacing_cv(points: NDArray[np.float64]) -> float:
    """Coefficient of variation of the nearest-neighbour spacing."""
    d, _ = cKDTree(points).query(points, k=2)
    return float(d[:, 1].std() / d[:, 1].mean())


def test_a_scan_of_a_sphere_sees_only_the_camera_side(
    sphere: tuple[NDArray[np.float64], NDArray[np.int64]],
) -> None:
    v, f = sphere
    for seed in (0, 1, 2):
        p = scans.one_sided_scan(v, f, seed=seed)
        view = scans.viewpoint(v, seed=seed)
        view /= np.linalg.norm(view)
        along = p @ view
        assert along.min() >= -1e-6
        full = scans.even_cloud(v, f, seed=seed) @ view
        assert np.ptp(along) < 0.6 * np.ptp(full)
        assert 1000 < len(p) <= scans.SCAN_POINTS


def test_scan_points_lie_on_the_surface_within_the_noise(
    sphere: tuple[NDArray[np.float64], NDArray[np.int64]],
) -> None:
    v, f = sphere
    exact = scans.one_sided_scan(v, f, seed=4, noise=0.0)
    # The icosphere's facets are within 2e-3 of the unit sphere.
    assert np.abs(np.linalg.norm(exact, axis=1) - 1.0).max() < 3e-3
    noisy = scans.one_sided_scan(v, f, seed=4)
    off = np.abs(np.linalg.norm(noisy, axis=1) - 1.0)
    # Depth <= 4 radii at a camera 2-3 radii away: sigma <= 0.003 * 16 / 2.
    assert off.max() < 5 * scans.SCAN_NOISE * 8 and off.mean() > off.max() / 20


def test_samplings_are_deterministic_per_seed(
    sphere: tuple[NDArray[np.float64], NDArray[np.int64]],
) -> None:
    v, f = sphere
    for make in (scans.one_sided_scan, scans.even_cloud, scans.falloff_cloud):
        a, b = make(v, f, seed=7), make(v, f, seed=7)
        assert np.array_equal(a, b)
        assert not np.array_equal(a[:100], make(v, f, seed=8)[:100])
    c1, c2 = scans.cropped_mesh(v, f, seed=3), scans.cropped_mesh(v, f, seed=3)
    assert np.array_equal(c1[0], c2[0]) and np.array_equal(c1[1], c2[1])


def test_a_cropped_box_is_open_and_holds_half_the_area() -> None:
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5)).subdivide().subdivide().subdivide()
    for seed in range(4):
        cv, cf = scans.cropped_mesh(np.asarray(box.vertices), np.asarray(box.faces), seed=seed)
        half = trimesh.Trimesh(cv, cf, process=False)
        assert not half.is_watertight
        assert abs(half.area / box.area - 0.5) < 0.06
        assert cf.max() == len(cv) - 1


def test_sampling_densities_differ_as_described() -> None:
    m = trimesh.creation.icosphere(subdivisions=3)
    right = np.flatnonzero(m.triangles_center[:, 0] > 0)
    for _ in range(2):  # refine the right half twice: its vertices crowd
        v, f = trimesh.remesh.subdivide(m.vertices, m.faces, face_index=right)
        m = trimesh.Trimesh(v, f)
        right = np.flatnonzero(m.triangles_center[:, 0] > 0)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    even = scans.even_cloud(v, f, seed=0, points=1500)
    crowd = scans.vertex_cloud(v, f, seed=0, min_points=0)
    assert (crowd[:, 0] > 0).mean() > 0.7 > (even[:, 0] > 0).mean()
    assert _spacing_cv(even) < _spacing_cv(crowd)
    falloff = scans.falloff_cloud(v, f, seed=0, points=1500)
    assert _spacing_cv(even) < _spacing_cv(falloff)
    # All around: the far side is sparse but present.
    eye = scans.viewpoint(v, seed=0)
    facing = falloff @ (eye / np.linalg.norm(eye))
    assert (facing < -0.5).sum() > 0 and (facing > 0.5).sum() > 2 * (facing < -0.5).sum()
