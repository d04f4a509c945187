"""Views of the ball union (shapedb.signature.union_views): exact images of a ball, invariances."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.signature.union_views import (
    DIRECTIONS,
    HARMONICS,
    RINGS,
    SAMPLES,
    view_dim,
    view_directions,
    view_features,
    view_images,
)


def _balls(seed: int = 0, n: int = 150) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(n, 3)) * [3.0, 1.0, 0.5]
    return c, np.sort(rng.uniform(0.05, 0.6, n))[::-1]


def _table(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A top of balls over four legs of balls."""
    top = [[x, y, 2.0] for x in np.linspace(-2, 2, 9) for y in np.linspace(-1, 1, 5)]
    legs = [[sx * 2.0, sy * 1.0, z] for sx in (-1, 1) for sy in (-1, 1) for z in (0.4, 0.9, 1.4)]
    c = np.asarray(top + legs, dtype=np.float64)
    r = np.concatenate([np.full(len(top), 0.35), np.full(len(legs), 0.25)])
    return c + np.random.default_rng(seed).normal(scale=0.01, size=c.shape), r


def test_directions_are_unit_on_a_half_sphere_and_never_opposite() -> None:
    d = view_directions()
    assert d.shape == (DIRECTIONS, 3)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0) and (d[:, 2] > 0).all()
    assert (d @ d.T > -0.99).all()


def test_a_balls_silhouettes_are_discs_of_its_radius_and_its_depth_a_hemisphere() -> None:
    r = 2.0
    sil, front, back = view_images(np.array([[1.0, -3.0, 5.0]]), np.array([r]))
    assert sil.shape == front.shape == back.shape == (DIRECTIONS, RINGS, SAMPLES)
    big_r = 2.0 * np.sqrt(0.6) * r  # the frame's scale: twice the RMS radius of the volume
    width = big_r / RINGS
    rho = (np.arange(RINGS) + 0.5) * width
    disc = np.clip((r - rho) / width + 0.5, 0.0, 1.0)
    np.testing.assert_allclose(sil, np.broadcast_to(disc[None, :, None], sil.shape), atol=1e-5)
    cap = np.where(rho < r, (np.sqrt(np.maximum(r**2 - rho**2, 0.0)) / big_r + 1.0) / 2.0, 0.0)
    np.testing.assert_allclose(front, np.broadcast_to(cap[None, :, None], sil.shape), atol=1e-5)
    np.testing.assert_allclose(back, front, atol=1e-5)
    # a disc is round: every ring is constant, so only the 0th Fourier magnitude is not 0
    f = view_features(np.array([[1.0, -3.0, 5.0]]), np.array([r]))
    assert f.shape == (view_dim(),) == (4 * RINGS * HARMONICS,)
    sil_mean = f[: RINGS * HARMONICS].reshape(RINGS, HARMONICS)
    np.testing.assert_allclose(sil_mean[:, 0], disc, atol=1e-5)
    np.testing.assert_allclose(sil_mean[:, 1:], 0.0, atol=1e-5)
    np.testing.assert_allclose(f[RINGS * HARMONICS : 2 * RINGS * HARMONICS], 0.0, atol=1e-5)


def test_two_balls_side_by_side_look_different_from_one() -> None:
    one = view_features(np.zeros((1, 3)), np.ones(1))
    two = view_features(np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), np.ones(2))
    assert np.abs(two - one).sum() > 0.5
    # seen from the side two balls show an even harmonic: the pair has two lobes
    sil = two[: RINGS * HARMONICS].reshape(RINGS, HARMONICS)
    assert sil[:, 2].max() > 0.05


def test_exactly_invariant_to_translation_and_scale() -> None:
    c, r = _balls()
    a = view_features(c, r)
    b = view_features(2.5 * c + [1.0, -2.0, 3.0], 2.5 * r)
    np.testing.assert_allclose(a, b, atol=1e-5)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_rotated_decomposition_gives_the_same_vector_up_to_the_directions(seed: int) -> None:
    c, r = _table()
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    a = view_features(c, r)
    b = view_features(c @ q.T, r)
    other = view_features(*_balls())
    assert np.abs(a - b).sum() < 0.25 * np.abs(a - other).sum()


def test_no_ball_gives_zeros_and_mismatched_arrays_raise() -> None:
    assert not view_features(np.zeros((2, 3)), np.zeros(2)).any()
    assert not view_features(np.zeros((0, 3)), np.zeros(0)).any()
    with pytest.raises(ValueError, match="same length"):
        view_features(np.zeros((3, 3)), np.ones(2))
