"""The per-view words study's geometry: views spread over the sphere, scans flattened."""

from __future__ import annotations

import numpy as np

from bench.studies.view_words import flattened, view_directions


def test_view_directions_are_unit_and_spread() -> None:
    d = view_directions(20)
    assert d.shape == (20, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=0.05)
    nearest = np.sort(d @ d.T, axis=1)[:, -2]  # each direction's nearest other one
    assert np.degrees(np.arccos(nearest.max())) > 30


def test_flattened_moves_a_noisy_plane_onto_it_and_keeps_its_extent() -> None:
    rng = np.random.default_rng(0)
    xy = rng.uniform(-1, 1, size=(3000, 2))
    noisy = np.column_stack([xy, rng.normal(scale=0.01, size=3000)])
    flat = flattened(noisy)
    assert flat[:, 2].std() < 0.4 * noisy[:, 2].std()  # about 1 / sqrt(neighbours)
    np.testing.assert_allclose(flat[:, :2], noisy[:, :2], atol=0.01)
    lonely = np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 5.0], [0.1, 0.0, 0.3]])
    np.testing.assert_array_equal(flattened(lonely), lonely)  # fewer than 5 neighbours: kept
