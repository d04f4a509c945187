"""A one-sided scan's silhouette, framed and described as a light field view."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.config.lightfield import LightFieldConfig
from shapedb.signature.lightfield_descriptor import silhouette_dim, silhouette_features
from shapedb.signature.scan_view import scan_silhouette, scan_view_features

RES = 64


def _disc_points(step: float = 0.03) -> np.ndarray:
    """The unit disc of the plane z = 0 as a depth camera's pixel grid sees it."""
    g = np.arange(-1.0, 1.0 + step / 2, step)
    x, y = np.meshgrid(g, g)
    inside = np.hypot(x, y) <= 1.0
    return np.stack([x[inside], y[inside], np.zeros(int(inside.sum()))], axis=1)


def _disc_image(res: int, grow_px: float = 0.0) -> np.ndarray:
    c = (np.arange(res) + 0.5) / res * 2 - 1
    x, y = np.meshgrid(c, c)
    return np.hypot(x, y) <= 1.0 + grow_px * 2 / res


def test_a_disc_seen_face_on_fills_the_unit_disc() -> None:
    img = scan_silhouette(_disc_points(), [0, 0, 1], RES)
    disc = _disc_image(RES)
    # nothing beyond the unit circle but the half pixel a covered pixel may overhang
    assert np.count_nonzero(img & ~_disc_image(RES, grow_px=1.0)) == 0
    assert np.count_nonzero(disc & ~img) / disc.sum() < 0.01  # a pixel of rim at most
    cfg = LightFieldConfig(resolution=RES)
    ideal = silhouette_features(disc[None], cfg)[0]
    dense = scan_view_features(_disc_points(0.015), [0, 0, 1], cfg)
    assert dense.shape == (silhouette_dim(cfg),)
    assert dense[0] == pytest.approx(1.0, abs=0.01)  # |A_00|: the covered share of the disc
    assert np.abs(dense - ideal).sum() < 0.05
    # a sparser grid moves the rim by up to a sample: the radial moments feel it
    assert np.abs(scan_view_features(_disc_points(0.05), [0, 0, 1], cfg) - ideal).sum() < 1.0


def test_the_features_do_not_depend_on_pose_scale_or_the_direction_sign() -> None:
    rng = np.random.default_rng(1)
    square = np.c_[rng.uniform(-1, 1, (5000, 2)) * [2.0, 1.0], np.zeros(5000)]
    cfg = LightFieldConfig(resolution=RES)
    base = scan_view_features(square, [0, 0, 1], cfg)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    moved = 3.5 * square @ q.T + [10.0, -4.0, 2.0]
    assert np.abs(scan_view_features(moved, q @ [0, 0, 1], cfg) - base).sum() < 0.2  # pixels
    assert np.abs(scan_view_features(square, [0, 0, -1], cfg) - base).sum() < 1e-6
    # an elongated rectangle is told from the disc
    disc = scan_view_features(_disc_points(), [0, 0, 1], cfg)
    assert np.abs(disc - base).sum() > 0.5


def test_bad_scans_are_refused() -> None:
    with pytest.raises(ValueError, match="3 or more finite points"):
        scan_silhouette(np.zeros((2, 3)), [0, 0, 1], RES)
    with pytest.raises(ValueError, match="finite"):
        scan_silhouette(np.full((10, 3), np.nan), [0, 0, 1], RES)
    with pytest.raises(ValueError, match="one spot"):
        scan_silhouette(np.zeros((10, 3)), [0, 0, 1], RES)
