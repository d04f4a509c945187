"""The ball-union block (shapedb.signature.union): invariances and exact values on analytic balls."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.signature.union import BANDS, SHELLS, shell_energies, sphere_grid, union_features


def _balls(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(200, 3)) * [3.0, 1.0, 0.5]
    return c, np.sort(rng.uniform(0.05, 0.5, 200))[::-1]


def test_sphere_grid_integrates_exactly() -> None:
    d, w = sphere_grid()
    assert np.isclose(w.sum(), 4 * np.pi)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert np.isclose(w @ d[:, 2] ** 2, 4 * np.pi / 3)


def test_constant_function_has_energy_only_at_degree_zero() -> None:
    e = shell_energies(np.ones((2, len(sphere_grid()[1]))), 6)
    assert np.allclose(e[:, 0], 1.0) and np.allclose(e[:, 1:], 0.0, atol=1e-12)


def test_single_ball_fills_the_inner_shells() -> None:
    f = union_features(np.zeros((1, 3)), np.ones(1)).reshape(SHELLS, BANDS)
    # R = 2 sqrt(0.6) ~ 1.55: shells below radius 1 are full, those beyond 1 + w/2 empty
    rho = (np.arange(SHELLS) + 0.5) * 2 * np.sqrt(0.6) / SHELLS
    assert np.allclose(f[rho < 0.95, 0], 1.0) and np.allclose(f[rho > 1.06], 0.0)
    assert np.allclose(f[:, 1:], 0.0, atol=1e-3)  # float32 distances


def test_invariant_to_rotation_translation_and_scale() -> None:
    c, r = _balls()
    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    a = union_features(c, r)
    b = union_features(c @ q.T * 2.5 + [1.0, -2.0, 3.0], 2.5 * r)
    other = union_features(*_balls(2))
    assert np.abs(a - b).sum() < 0.1 * np.abs(a - other).sum()


def test_shapes_and_errors() -> None:
    assert union_features(np.zeros((0, 3)), np.zeros(0)).shape == (SHELLS * BANDS,)
    assert not union_features(np.zeros((0, 3)), np.zeros(0)).any()
    with pytest.raises(ValueError, match="same length"):
        union_features(np.zeros((2, 3)), np.ones(3))
