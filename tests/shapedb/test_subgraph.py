"""Neighbourhood subgraphs and their Eq. 1 features, vectorised against the reference."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.config.part import PartConfig
from shapedb.errors import ConfigError, InvalidShapeError
from shapedb.geometry.complement import Complement
from shapedb.geometry.implicit import Box, Cylinder
from shapedb.mdbd.decomposition import decompose
from shapedb.mdbd.graph import ContactGraph
from shapedb.signature.kernel import features
from shapedb.signature.subgraph import (
    neighbourhood_features,
    neighbourhood_features_many,
    neighbourhood_features_naive,
    neighbourhoods,
    node_sets,
    part_config,
    part_dim,
    part_vector,
    part_weights,
)

#: The paper's part vector alone (Eq. 1 of the subgraph), as before the size block.
PAPER = PartConfig(size=0.0, centre=0.0)


def random_graph(n: int, seed: int, *, ties: bool = False) -> ContactGraph:
    """Random geometric graph with decreasing radii (ties if asked) and isolated nodes."""
    rng = np.random.default_rng(seed)
    c = rng.random((n, 3))
    r = -np.sort(-rng.uniform(0.01, 0.1, n))
    if ties:
        r = np.round(r, 2)
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    i, j = np.nonzero(np.triu(d < 0.22, 1))
    return ContactGraph(c, r, np.stack([i, j], 1))


@pytest.mark.parametrize("hops", [0, 1, 2, 3])
@pytest.mark.parametrize("ties", [False, True])
@pytest.mark.parametrize(
    ("size", "centre", "dim"), [(1.0, 0.0, 30), (0.0, 0.0, 20), (2.0, 1.0, 32)]
)
def test_vectorised_equals_reference(
    hops: int, ties: bool, size: float, centre: float, dim: int
) -> None:
    g = random_graph(120, hops, ties=ties)
    cfg = PartConfig(hops=hops, size=size, centre=centre)
    got = neighbourhood_features(g, cfg)
    ref = neighbourhood_features_naive(g, cfg)
    assert got.shape == (120, dim) == (120, part_dim(cfg))
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_real_decomposition_equals_reference(generic) -> None:
    d = decompose(generic, resolution=40, n_balls=150)
    np.testing.assert_allclose(
        neighbourhood_features(d), neighbourhood_features_naive(d.graph), atol=1e-12
    )


def test_hand_made_star() -> None:
    # star: centre 0 (r = 1) and leaves 1..3 (r = 0.5), plus a far node 4 on leaf 3
    g = ContactGraph(np.zeros((5, 3)), [1.0, 0.5, 0.5, 0.5, 0.25], [[0, 1], [0, 2], [0, 3], [3, 4]])
    f = neighbourhood_features(g, PAPER, hops=1, n_r=3, t=1, w=1.0)
    # N(0, 1) = {0, 1, 2, 3}: p0 = [1, .5, .5, .5]; one step: centre gets 3 * .5 / 1,
    # each leaf gets 1 / 3 from the centre
    np.testing.assert_allclose(f[0], [1, 0.5, 0.5, 1.5, 1 / 3, 1 / 3])
    # N(4, 1) = {3, 4}: normalised by its own largest ball (0.5): p0 = [1, 0.5]
    np.testing.assert_allclose(f[4], [1, 0.5, 0, 0.5, 1, 0])
    # the size block: the part's 3 largest balls over the shape's largest (R = 1), then
    # the centre block [r_v / r1, r_v / R]
    f = neighbourhood_features(g, hops=1, n_r=3, t=1, w=1.0, size=1.0, centre=1.0)
    np.testing.assert_allclose(f[4], [1, 0.5, 0, 0.5, 1, 0, 0.5, 0.25, 0, 0.5, 0.25])
    # N(3, 1) = {0, 3, 4}: radii 1, .5, .25 over R = 1; centre 3: r_v / r1 = .5 / 1
    np.testing.assert_allclose(f[3, -5:], [1, 0.5, 0.25, 0.5, 0.5])
    np.testing.assert_allclose(
        part_weights(part_config(n_r=3, size=2.0, centre=1.0)),
        [0.75, 0.75**2, 0.75**3] * 2 + [1.5, 2 * 0.75**2, 2 * 0.75**3, 1, 1],
    )


def test_lone_balls_of_different_sizes_differ() -> None:
    # two isolated balls and a contact pair: each lone ball is a one-node neighbourhood
    g = ContactGraph(np.zeros((4, 3)), [1.0, 0.5, 0.3, 0.2], [[0, 1]])
    paper = neighbourhood_features(g, PAPER)
    np.testing.assert_array_equal(paper[2], paper[3])  # Eq. 1 alone: identical, k = 1.0
    f = neighbourhood_features(g)
    w = part_weights(PartConfig())
    d = float(np.abs(f[2] - f[3]) @ w)
    cfg = PartConfig()
    # size block: size * la * |r / R - r' / R|; centre block: centre * |r / R - r' / R|
    # (r_v / r1 = 1 for both)
    assert d == pytest.approx((cfg.size * cfg.kernel.la + cfg.centre) * (0.3 - 0.2))
    assert np.exp(-d) < 1.0
    # lone balls of the same size relative to their shapes still match exactly
    h = ContactGraph(np.zeros((2, 3)), [2.0, 0.6], np.zeros((0, 2)))
    np.testing.assert_allclose(neighbourhood_features(h)[1], f[2], atol=1e-15)


def test_paper_vector_is_eq1_of_the_subgraph() -> None:
    g = random_graph(50, 7)
    f = neighbourhood_features(g, PAPER)
    for v in (0, 13, 49):
        sub = g.subgraph(g.neighbourhood(v, 2))
        np.testing.assert_allclose(f[v], features(sub, PAPER.kernel), atol=1e-12)
        # the default vector starts with the same Eq. 1 block
        np.testing.assert_allclose(neighbourhood_features(g)[v, :20], f[v], atol=1e-12)


def test_membership_and_node_sets() -> None:
    g = random_graph(60, 1)
    m = neighbourhoods(g, 2)
    sets = node_sets(g, range(60), 2)
    for v in range(60):
        want = g.neighbourhood(v, 2)
        np.testing.assert_array_equal(m[v].indices, want)
        np.testing.assert_array_equal(sets[v], want)


def test_many_is_disjoint_union() -> None:
    gs = [random_graph(n, s) for s, n in enumerate([5, 40, 1, 70])]
    feats, offsets = neighbourhood_features_many(gs)
    np.testing.assert_array_equal(offsets, [0, 5, 45, 46, 116])
    for g, a, b in zip(gs, offsets[:-1], offsets[1:], strict=True):
        np.testing.assert_allclose(feats[a:b], neighbourhood_features(g), atol=1e-12)


def test_single_node_and_whole_graph() -> None:
    g = ContactGraph(np.zeros((1, 3)), [2.0], np.zeros((0, 2)))
    f = neighbourhood_features(g)
    np.testing.assert_allclose(f[0, :20], features(g, PartConfig().kernel))
    np.testing.assert_allclose(f[0], part_vector(g))
    np.testing.assert_allclose(f[0, 20:], [1] + [0] * 9 + [1, 1])  # r / R = 1: the only ball
    h = random_graph(30, 4)
    # with a range larger than the diameter every neighbourhood is its component
    big = neighbourhood_features(h, hops=64)
    np.testing.assert_allclose(big, neighbourhood_features_naive(h, PartConfig(hops=64)))


def test_config_validation() -> None:
    assert PartConfig().kernel.n_r == 10 and part_dim(PartConfig()) == 32
    assert part_dim(PAPER) == 20
    with pytest.raises(ConfigError):
        PartConfig(size=-1.0)
    with pytest.raises(ConfigError):
        PartConfig(centre=-0.5)
    with pytest.raises(ConfigError):
        PartConfig(hops=-1)
    with pytest.raises(ConfigError):
        part_config(n_r=0)
    with pytest.raises(ConfigError, match="unknown part option"):
        part_config(radius=2)
    with pytest.raises(InvalidShapeError):
        neighbourhood_features("not a graph")
    assert PartConfig(hops=1).fingerprint != PartConfig().fingerprint


def test_complement_sign_and_grid() -> None:
    plate = Box([0, 0, 0.1], [2.0, 1.0, 0.2]) - Cylinder([0.5, 0, -1], [0.5, 0, 1], 0.15)
    c = Complement(plate, padding=0.05)
    assert np.all(c.bounds[0] < plate.bounds[0]) and np.all(c.bounds[1] > plate.bounds[1])
    p = np.array([[0.5, 0, 0.1], [-0.5, 0, 0.1], [0.0, 0.0, 0.25], [5.0, 0, 0]])
    s = c.signed_distance(p)
    assert s[0] > 0  # in the hole
    assert s[1] < 0  # in the plate
    assert s[2] > 0  # above the plate, inside the box
    assert s[3] < 0  # outside the box
    from shapedb.geometry.base import Grid

    grid = Grid.fit(c.bounds, resolution=20)
    np.testing.assert_allclose(
        c.grid_sdf(grid).ravel(), c.signed_distance(grid.points()), atol=1e-6
    )
    d = decompose(c, resolution=64, n_balls=200)
    in_hole = np.linalg.norm(d.centers[:, :2] - [0.5, 0], axis=1) < 0.15
    in_hole &= (d.centers[:, 2] > 0) & (d.centers[:, 2] < 0.2)
    assert in_hole.sum() >= 1  # the hole is filled with balls of the complement
    with pytest.raises(ConfigError):
        Complement(plate, padding=-1)


def test_complement_in_the_exact_box_isolates_through_holes() -> None:
    """The default complement is the stock minus the part: each through hole is a component
    of the contact graph of its own (no slabs of air around the plate to join them)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    plate = (
        Box([0, 0, 0.1], [2.0, 1.0, 0.2])
        - Cylinder([0.5, 0, -1], [0.5, 0, 1], 0.15)
        - Cylinder([-0.5, 0, -1], [-0.5, 0, 1], 0.1)
    )
    c = Complement(plate)
    np.testing.assert_allclose(c.bounds, plate.bounds)
    d = decompose(c, resolution=64, n_balls=200)
    n = len(d.radii)
    graph = sp.coo_matrix((np.ones(len(d.edges)), tuple(d.edges.T)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    holes = [
        np.linalg.norm(d.centers[:, :2] - [x, 0], axis=1) < r for x, r in ((0.5, 0.15), (-0.5, 0.1))
    ]
    assert np.all(holes[0] | holes[1])  # nothing but the holes
    for hole in holes:
        assert hole.sum() >= 1
        np.testing.assert_array_equal(np.isin(comp, comp[hole]), hole)


def test_part_graph_rebuilds_contacts_at_the_part_tolerance() -> None:
    """Two spheres one cell apart touch at 1.5 cells, not at 0.5; 0 keeps the stored graph."""
    from shapedb.config.part import PartConfig
    from shapedb.mdbd.decomposition import Decomposition
    from shapedb.signature.subgraph import part_graph

    h = 0.1  # grid cell
    centers = np.array([[0.0, 0, 0], [2.0 + h, 0, 0], [0, 3.0, 0]])
    radii = np.array([1.0, 1.0, 1.0])
    stored = np.array([[0, 1], [0, 2]])  # what the store holds (an arbitrary graph here)
    d = Decomposition(
        centers=centers, radii=radii, edges=stored.astype(np.int32), spacing=h,
        bounds=np.array([[-1.0, -1, -1], [3.1, 4, 1]]),
    )  # fmt: skip
    assert part_graph(d, PartConfig(contact_tol_cells=1.5)).edges.tolist() == [[0, 1]]
    assert part_graph(d, PartConfig(contact_tol_cells=0.5)).edges.tolist() == []
    assert part_graph(d, PartConfig(contact_tol_cells=0.0)).edges.tolist() == stored.tolist()
    with pytest.raises(ConfigError, match="contact_tol_cells"):
        PartConfig(contact_tol_cells=-1.0)
