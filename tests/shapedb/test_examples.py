"""Generated example solids: deterministic, valid, and meshable."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb import examples
from shapedb.errors import ConfigError
from shapedb.geometry.base import Grid
from shapedb.geometry.implicit import Implicit
from shapedb.mdbd.decomposition import decompose


def test_figures_are_deterministic_and_distinct() -> None:
    pts = np.random.default_rng(0).uniform(-1, 1, (500, 3))
    a = examples.figure(1, 2)
    np.testing.assert_array_equal(
        a.signed_distance(pts), examples.figure(1, 2).signed_distance(pts)
    )
    assert not np.allclose(a.signed_distance(pts), examples.figure(2, 2).signed_distance(pts))
    assert not np.allclose(a.signed_distance(pts), examples.figure(1, 3).signed_distance(pts))
    assert a.name == "figure-s1-p2"
    with pytest.raises(ConfigError):
        examples.figure(-1, 0)


def test_parts_and_catalogue() -> None:
    cat = examples.catalogue()
    assert len(cat) == 20
    assert len({name for name, _, _ in cat}) == 20
    assert {label for _, label, _ in cat} == {
        "figure-s0",
        "figure-s1",
        "plate",
        "bracket",
        "flange",
    }
    for name, _, g in cat:
        assert isinstance(g, Implicit), name
        grid = Grid.fit(g.bounds, resolution=24, padding=1)
        F = g.grid_sdf(grid)
        assert F.max() > 0, f"{name} has no inside"
        # the padding layer is outside: bounds contain the solid
        for face in (F[0], F[-1], F[:, 0], F[:, -1], F[:, :, 0], F[:, :, -1]):
            assert face.max() < 0, name
    with pytest.raises(ConfigError, match="unknown part kind"):
        examples.part("gear")


def test_examples_decompose() -> None:
    for g in (examples.figure(0, 1), examples.part("bracket", 2)):
        d = decompose(g, resolution=48, n_balls=64)
        assert d.n_balls > 30
        assert np.all(g.signed_distance(d.centers) >= d.radii - 1e-9)


def test_to_mesh_is_a_closed_outward_surface() -> None:
    pytest.importorskip("skimage")
    g = examples.part("flange", 0)
    mesh = examples.to_mesh(g, resolution=48)
    assert mesh.is_watertight and mesh.volume > 0
    d = g.signed_distance(mesh.vertices)
    h = float((g.bounds[1] - g.bounds[0]).max()) / 44
    assert np.abs(d).max() < h


@pytest.mark.parametrize("kind", examples.PART_KINDS)
def test_every_part_kind_is_valid_and_decomposes(kind: str) -> None:
    assert len(examples.PART_KINDS) >= 10
    for seed in (0, 1):
        g = examples.part(kind, seed)
        name = f"{kind}-{seed}"
        assert isinstance(g, Implicit) and g.name == name
        extent = g.bounds[1] - g.bounds[0]
        assert 0.2 < extent.min() and extent.max() < 4.0, name  # about unit scale
        grid = Grid.fit(g.bounds, resolution=32, padding=1)
        F = g.grid_sdf(grid)
        assert np.all(np.isfinite(F)) and F.max() > 0, f"{name} has no inside"
        for face in (F[0], F[-1], F[:, 0], F[:, -1], F[:, :, 0], F[:, :, -1]):
            assert face.max() < 0, f"{name} pokes out of its bounds"
        d = decompose(g, resolution=32, n_balls=32)
        assert d.n_balls >= 8, name
        assert np.all(g.signed_distance(d.centers) >= d.radii - 1e-9), name


@pytest.mark.parametrize("kind", examples.PART_KINDS)
def test_part_seeds_vary_the_shape_deterministically(kind: str) -> None:
    a, b = examples.part(kind, 0), examples.part(kind, 1)
    lo = np.minimum(a.bounds[0], b.bounds[0])
    hi = np.maximum(a.bounds[1], b.bounds[1])
    pts = np.random.default_rng(1).uniform(lo, hi, (2000, 3))
    da = a.signed_distance(pts)
    np.testing.assert_array_equal(da, examples.part(kind, 0).signed_distance(pts))
    assert not np.allclose(da, b.signed_distance(pts))


def test_unknown_part_kind_lists_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="unknown part kind 'widget'") as info:
        examples.part("widget", 0)
    assert isinstance(info.value, ConfigError)
    for kind in examples.PART_KINDS:
        assert repr(kind) in str(info.value)
