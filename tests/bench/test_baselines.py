"""Tests of the bench baselines: D2 shape distribution and the GraKeL wrapper."""

from __future__ import annotations

import numpy as np
import pytest

from bench.support.baselines import (
    D2Config,
    d2_descriptor,
    grakel_similarity,
    l1_similarity,
    radius_labels,
    sample_surface,
)

trimesh = pytest.importorskip("trimesh")

SMALL = D2Config(n_pairs=2**16, bins=256, vertices=64)


@pytest.fixture(scope="module")
def sphere() -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_sample_surface_lies_on_the_sphere(sphere: tuple[np.ndarray, np.ndarray]) -> None:
    p = sample_surface(*sphere, 1000, rng=np.random.default_rng(0))
    assert p.shape == (1000, 3)
    assert np.allclose(np.linalg.norm(p, axis=1), 1.0, atol=0.02)


def test_d2_is_a_pdf_and_reproducible(sphere: tuple[np.ndarray, np.ndarray]) -> None:
    a = d2_descriptor(*sphere, SMALL)
    assert a.shape == (64,)
    assert np.isclose(a.sum(), 1.0)
    assert np.array_equal(a, d2_descriptor(*sphere, SMALL))


def test_d2_of_sphere_matches_itself_and_its_scaled_moved_copy(
    sphere: tuple[np.ndarray, np.ndarray],
) -> None:
    v, f = sphere
    a = d2_descriptor(v, f, SMALL)
    b = d2_descriptor(3.5 * v + [10.0, -2.0, 1.0], f, D2Config(**{**SMALL.__dict__, "seed": 7}))
    box = trimesh.creation.box(extents=(4.0, 1.0, 0.2))
    c = d2_descriptor(np.asarray(box.vertices), np.asarray(box.faces), SMALL)
    same, other = np.abs(a - b).sum(), np.abs(a - c).sum()
    assert same < 0.05  # sampling noise only
    assert other > 5 * same
    s = l1_similarity(np.stack([a, b, c]))
    assert np.allclose(np.diag(s), 0.0)
    assert s[0, 1] > s[0, 2]


def test_radius_labels_round_to_one_25th() -> None:
    lab = radius_labels([2.0, 1.3, 0.51, 0.01])
    assert np.allclose(lab, [1.0, 0.64, 0.24, 0.0])
    assert np.allclose(lab * 25, np.round(lab * 25))


def test_grakel_kernels_on_two_tiny_graphs() -> None:
    pytest.importorskip("grakel")
    path = (np.array([1.0, 0.5, 0.5]), np.array([[0, 1], [0, 2]]))
    same = (np.array([2.0, 1.0, 1.0]), np.array([[0, 1], [0, 2]]))  # same labels r/r1
    other = (np.array([1.0, 0.9, 0.2, 0.2]), np.array([[0, 1], [1, 2], [2, 3]]))
    runs = grakel_similarity([path, same, other])
    assert set(runs) == {"shortest_path", "wl_subtree", "pyramid_match"}
    for run in runs.values():
        k = run.matrix
        assert k.shape == (3, 3)
        assert np.allclose(np.diag(k), 1.0)  # normalised
        assert np.allclose(k, k.T)
        assert k[0, 1] == pytest.approx(1.0)  # identical labelled graphs
        assert k[0, 2] < 1.0
        assert run.seconds >= 0.0


def test_grakel_unknown_kernel_is_refused() -> None:
    pytest.importorskip("grakel")
    with pytest.raises(ValueError, match="unknown GraKeL kernel"):
        grakel_similarity([(np.ones(2), np.array([[0, 1]]))], kernels=["random_walk"])
