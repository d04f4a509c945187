"""The completion study's solid: what the balls a one-sided scan allows give back."""

from __future__ import annotations

import numpy as np
import pytest

from bench.studies.scan_completion import completed_scan, facing


def _front_of_cylinder(radius: float, length: float, n: int = 6000) -> np.ndarray:
    """Samples of the half of a cylinder along x that a camera looking along +z sees."""
    rng = np.random.default_rng(0)
    x = rng.uniform(0.0, length, n)
    t = rng.uniform(-np.pi / 2, np.pi / 2, n)
    return np.c_[x, radius * np.sin(t), -radius * np.cos(t)]


def test_a_tube_seen_side_on_gets_its_volume_back() -> None:
    r, length = 0.3, 2.0
    solid = completed_scan(_front_of_cylinder(r, length), np.array([0.0, 0.0, 1.0]))
    occupied = np.asarray(solid.occupancy)
    volume = float(occupied.sum()) * solid.pitch**3
    # the rounded ends add a little, the splatted rims take a little
    assert volume == pytest.approx(np.pi * r * r * length, rel=0.15)
    # the unseen side is closed at the tube's own depth, not left open behind it
    depth = np.flatnonzero(occupied.any(axis=(0, 1)))
    assert (depth.max() - depth.min() + 1) * solid.pitch == pytest.approx(
        2 * r, abs=2 * solid.pitch
    )


def test_the_camera_side_is_told_by_the_rims() -> None:
    points = _front_of_cylinder(0.3, 2.0)
    assert facing(points, np.array([0.0, 0.0, 1.0]))[2] == 1.0
    assert facing(points, np.array([0.0, 0.0, -1.0]))[2] == 1.0
