"""shapedb's default descriptor: versions, invariances, and what a store records."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import shapedb
from shapedb.config.core import DescriptorConfig, KernelConfig
from shapedb.mdbd.graph import ContactGraph, contact_edges
from shapedb.signature.descriptor import LAYOUTS, VERSION, describe, dim


def _chain(n: int, bend: float, seed: int = 0) -> ContactGraph:
    """Touching balls along a bent line, radii decreasing: a limb-like packing."""
    rng = np.random.default_rng(seed)
    r = np.sort(rng.uniform(0.2, 1.0, n))[::-1]
    c = np.zeros((n, 3))
    direction = np.array([1.0, 0.0, 0.0])
    for i in range(1, n):
        turn = bend * (i / n)
        d = np.array([np.cos(turn), np.sin(turn), 0.0])
        direction = d / np.linalg.norm(d)
        c[i] = c[i - 1] + direction * (r[i - 1] + r[i])
    return ContactGraph(c, r, contact_edges(c, r, 1e-6))


@pytest.mark.parametrize("version", sorted(LAYOUTS))
def test_every_version_has_its_length_and_ignores_similarity_transforms(version: int) -> None:
    g = _chain(40, 1.0)
    f = describe(g, version)
    assert f.shape == (dim(version),) and np.isfinite(f).all() and np.abs(f).sum() > 0
    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    moved = ContactGraph(3.5 * g.centers @ q.T + [4.0, -2.0, 7.0], 3.5 * g.radii, g.edges)
    m = describe(moved, version)
    # the ball union is sampled on spheres (union) or seen from 24 directions (views):
    # invariant to rotation up to the sampling
    tolerance = {"union": 0.05, "views": 0.1}
    sampled = np.zeros(len(f), dtype=bool)
    at = 0
    for name, size, _, _ in LAYOUTS[version]:
        if name in tolerance:
            sampled[at : at + size] = True
            block = slice(at, at + size)
            change = np.abs(m[block] - f[block]).sum()
            assert change <= tolerance[name] * max(np.abs(f[block]).sum(), 1e-12)
        at += size
    np.testing.assert_allclose(m[~sampled], f[~sampled], atol=1e-9)


def test_versions_differ_and_the_default_is_the_latest_chosen() -> None:
    # versions 5 (the ball-union block), 6 (without the pose blocks) and 7 (views of the
    # ball union) are opt-in
    assert VERSION == 4 == DescriptorConfig().version and {5, 6, 7} <= set(LAYOUTS)
    g = _chain(40, 1.0)
    assert len({LAYOUTS[v] for v in LAYOUTS}) == len(LAYOUTS)
    rows = [describe(g, v) for v in sorted(LAYOUTS)]
    for a in range(len(rows)):
        for b in range(a):
            assert rows[a].shape != rows[b].shape or not np.allclose(rows[a], rows[b])
    f1 = shapedb.features(g, KernelConfig(), descriptor=1)
    f = shapedb.features(g, KernelConfig())
    np.testing.assert_array_equal(f1, describe(g, 1))
    np.testing.assert_array_equal(f, describe(g, VERSION))


def _block(f: np.ndarray, name: str, version: int = 3) -> np.ndarray:
    at = 0
    for block, size, _, _ in LAYOUTS[version]:
        if block == name:
            return f[at : at + size]
        at += size
    raise KeyError(name)


def _swapped(g: ContactGraph, i: int, j: int) -> ContactGraph:
    """``g`` with nodes i and j exchanged (same balls, other order)."""
    order = np.arange(g.n_nodes)
    order[[i, j]] = [j, i]
    where = np.argsort(order)  # new index of every old node
    return ContactGraph(g.centers[order], g.radii[order], where[g.edges])


def test_version_4_does_not_see_which_of_two_equal_balls_came_first() -> None:
    # a chain with a branch: balls 3 and 4 have one radius but touch different
    # numbers of balls, so their walk averages differ; the packing may list either
    # first (its chaos decides), and only version 4's sorted Eq. 1 block ignores it
    g = _chain(30, 1.0)
    r = g.radii.copy()
    r[4] = r[3]
    c = g.centers.copy()
    extra_c = c[3] + np.array([0.0, r[3] + 0.15, 0.0])
    g = ContactGraph(
        np.vstack([c, extra_c]),
        np.append(r, 0.15),
        contact_edges(np.vstack([c, extra_c]), np.append(r, 0.15), 1e-6),
    )
    s = _swapped(g, 3, 4)
    before, after = describe(g, 3), describe(s, 3)
    assert not np.allclose(_block(before, "paper"), _block(after, "paper"))
    np.testing.assert_allclose(
        _block(describe(g, 4), "paper_sorted", 4), _block(describe(s, 4), "paper_sorted", 4)
    )
    np.testing.assert_allclose(describe(g, 4), describe(s, 4), atol=1e-12)


def test_geodesic_blocks_do_not_see_a_bent_chain() -> None:
    # along a chain of touching balls the inner distance of two balls is the sum of the
    # radii between them, straight or bent; the straight-line blocks see the bend
    straight, bent = _chain(60, 0.0), _chain(60, 3.0)
    fs, fb = describe(straight, 3), describe(bent, 3)
    for name in ("geodesic", "geodesic_mean"):
        assert np.abs(_block(fs, name)).sum() > 0
        np.testing.assert_allclose(_block(fb, name), _block(fs, name), atol=1e-9)
    assert np.abs(_block(fb, "inertia") - _block(fs, "inertia")).sum() > 0.1


def test_geodesic_distances_between_components_are_finite_and_long() -> None:
    from shapedb.signature.descriptor import _geodesics

    a = _chain(10, 0.0)
    shifted = a.centers + [0.0, 50.0, 0.0]
    g = ContactGraph(
        np.vstack([a.centers, shifted]),
        np.concatenate([a.radii, a.radii]),
        np.vstack([a.edges, a.edges + 10]),
    )
    d = _geodesics(g, 20)
    assert np.isfinite(d).all()
    np.testing.assert_allclose(d[0, 1], a.radii[0] + a.radii[1])  # touching neighbours
    straight = np.linalg.norm(g.centers[0] - g.centers[10])
    np.testing.assert_allclose(d[0, 10], 3.0 * straight)  # other component: 3x straight
    assert np.isfinite(describe(g)).all()


@pytest.mark.parametrize("version", sorted(LAYOUTS))
def test_a_different_shape_is_farther_than_a_slightly_perturbed_copy(version: int) -> None:
    straight, bent = _chain(60, 0.2), _chain(60, 3.0)
    if version == 6:  # blind to the pose by design: a bent chain is the same shape to it
        bent = _chain(30, 0.2)
    jitter = np.random.default_rng(2).normal(scale=1e-3, size=straight.centers.shape)
    copy = ContactGraph(straight.centers + jitter, straight.radii, straight.edges)
    f = describe(straight, version)
    near = np.abs(describe(copy, version) - f).sum()
    far = np.abs(describe(bent, version) - f).sum()
    assert near < 0.05 * far


def test_a_store_keeps_the_descriptor_version_it_was_built_with(tmp_path: Path) -> None:
    from shapedb import examples

    path = tmp_path / "v1.db"
    db = shapedb.connect(path, resolution=32, n_balls=64, descriptor=1)
    db.ingest([examples.figure(0, 0), examples.part("plate", 0)], names=["figure", "plate"])
    again = shapedb.connect(path)  # no options: the store's own configuration
    assert again.config.descriptor.version == 1
    assert again.get("figure").feature.shape == (dim(1),)
    hits = again.search(examples.figure(0, 0), k=2)
    assert hits[0].name == "figure" and hits[0].similarity > 0.99
    with pytest.raises(shapedb.errors.ConfigError, match="descriptor"):
        shapedb.connect(path, descriptor=VERSION)


def test_walk_averages_sort_within_groups_of_near_equal_radii() -> None:
    from shapedb.signature.descriptor import _sorted_walks

    p0 = np.array([1.0, 0.99, 0.5, 0.49, 0.2, 0.0])
    walks = np.array([3.0, 5.0, 1.0, 2.0, 7.0, 0.0])
    paper = np.concatenate([p0, walks])
    grouped = _sorted_walks(paper, 0.05)  # groups {1, 0.99}, {0.5, 0.49}, {0.2}, {0}
    np.testing.assert_array_equal(grouped, np.concatenate([p0, [5.0, 3.0, 2.0, 1.0, 7.0, 0.0]]))
    every = _sorted_walks(paper, 1.0)  # the default: one group
    np.testing.assert_array_equal(every, np.concatenate([p0, [7.0, 5.0, 3.0, 2.0, 1.0, 0.0]]))
    np.testing.assert_array_equal(_sorted_walks(paper), every)


def test_version_6_is_version_4_without_the_pose_blocks() -> None:
    from shapedb.signature.descriptor import POSE_BLOCKS

    g = _chain(40, 1.0)
    f4, f6 = describe(g, 4), describe(g, 6)
    keep = [b for b in LAYOUTS[4] if b[0] not in POSE_BLOCKS]
    assert LAYOUTS[6] == tuple(keep) and len(f6) == dim(4) - 33
    # the same blocks, rescaled so that the weights still sum to the calibration
    ratio = sum(b[3] for b in LAYOUTS[4]) / sum(b[3] for b in LAYOUTS[6])
    rest = np.concatenate([_block(f4, b[0], 4) for b in keep])
    np.testing.assert_allclose(f6, rest * ratio, rtol=1e-12)


def test_a_store_can_be_built_with_version_6(tmp_path: Path) -> None:
    from shapedb import examples

    db = shapedb.connect(tmp_path / "v6.db", resolution=32, n_balls=64, descriptor=6)
    db.ingest([examples.figure(0, 0), examples.part("plate", 0)], names=["figure", "plate"])
    again = shapedb.connect(tmp_path / "v6.db")
    assert again.config.descriptor.version == 6
    assert again.get("plate").feature.shape == (dim(6),)
    assert again.search(examples.part("plate", 0), k=1)[0].name == "plate"


def test_the_configuration_knows_every_descriptor_version() -> None:
    from shapedb.config.core import DESCRIPTOR_DIMS
    from shapedb.signature.descriptor import LAYOUTS, dim

    assert {v: dim(v) for v in sorted(LAYOUTS)} == DESCRIPTOR_DIMS
