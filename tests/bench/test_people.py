"""Tests of the fine-grained people set: subjects, meshes and the scans taken of them."""

from __future__ import annotations

import numpy as np
import pytest

from bench.sets.datasets import families, people
from bench.sets.people import (
    MESH_VERTICES,
    NOISE_SIGMA,
    noisy_cloud,
    partial_cloud,
    person,
    proportions,
)

trimesh = pytest.importorskip("trimesh")


@pytest.fixture(scope="module")
def sphere() -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_subjects_differ_by_a_few_percent() -> None:
    base = proportions(0)
    for s in range(1, 12):
        p = proportions(s)
        ratio = np.array([p[k] / base[k] for k in base])
        assert np.all(np.abs(ratio - 1) < 0.25)
        assert np.median(np.abs(ratio - 1)) > 0.01  # not the same person


def test_person_is_a_solid_about_one_point_seven_five_tall() -> None:
    g = person(3, 4)
    assert 1.5 < np.ptp(g.bounds[:, 2]) < 2.1
    assert g.signed_distance(np.array([[0.0, 0.0, 0.2]]))[0] > 0  # in the torso
    assert g.signed_distance(np.array([[0.0, 0.0, 3.0]]))[0] < 0


def test_person_mesh_is_watertight_with_about_7k_vertices() -> None:
    pytest.importorskip("fast_simplification")
    pytest.importorskip("skimage")
    from bench.sets.people import person_mesh

    v, f = person_mesh(1, 2)
    assert abs(len(v) - MESH_VERTICES) <= 0.02 * MESH_VERTICES
    assert trimesh.Trimesh(v, f).is_watertight


def test_people_set_is_split_by_subject_with_poses_as_families() -> None:
    ds = people(subjects=4, poses=6)
    assert len(ds) == 24
    assert len(set(ds.labels)) == 4
    val = ds.split("validation")
    assert all(np.sum(val.labels == lab) == 2 for lab in set(val.labels))
    assert len(set(families(ds.models))) == 4


def test_extra_validation_subjects_leave_the_test_split_as_it_is() -> None:
    from bench.sets.datasets import PEOPLE_EXTRA_POSES

    base, more = people(subjects=4, poses=6), people(subjects=4, poses=6, extra_validation=2)
    assert more.split("test").models == base.split("test").models
    extra = [m for m in more.models if m not in base.models]
    assert len(extra) == 2 * PEOPLE_EXTRA_POSES and {m.split for m in extra} == {"validation"}
    assert {m.label for m in extra} == {"person04", "person05"}
    assert len({m.name for m in more.models}) == len(more)


def test_noisy_cloud_has_the_stated_noise(sphere: tuple[np.ndarray, np.ndarray]) -> None:
    v, _ = sphere
    pts = np.repeat(v, 20, axis=0)
    noisy = noisy_cloud(pts, v, seed=0)
    sigma = NOISE_SIGMA * np.linalg.norm(np.ptp(v, axis=0))
    assert np.std(noisy - pts) == pytest.approx(sigma, rel=0.05)


def test_partial_cloud_sees_one_side_of_a_sphere(sphere: tuple[np.ndarray, np.ndarray]) -> None:
    v, f = sphere
    seen = partial_cloud(v, v, f, seed=3)
    assert 0.4 * len(v) < len(seen) < 0.6 * len(v)
    # the seen points are a hemisphere: their mean is well off the centre, horizontally
    centre = seen.mean(axis=0)
    assert np.linalg.norm(centre[:2]) > 0.4
    assert abs(centre[2]) < 0.1
    # and every seen point faces the same side
    assert np.all(seen[:, :2] @ (centre[:2] / np.linalg.norm(centre[:2])) > -0.1)
