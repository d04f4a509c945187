"""Contact graph: edges, degrees, transition matrix, neighbourhoods, export."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from shapedb.errors import InvalidShapeError, NotFoundError
from shapedb.mdbd.decomposition import decompose
from shapedb.mdbd.graph import ContactGraph, contact_edges


def path_graph(n: int) -> ContactGraph:
    """n unit-spaced balls on a line, each touching the next; radii decreasing."""
    centers = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
    radii = np.linspace(0.5, 0.3, n)
    return ContactGraph(centers, radii, [(i, i + 1) for i in range(n - 1)])


def test_contact_edges_threshold_and_order() -> None:
    c = np.array([[0, 0, 0], [2.0, 0, 0], [0, 3.05, 0], [10, 0, 0]], dtype=float)
    r = np.array([1.0, 1.0, 2.0, 0.5])
    e = contact_edges(c, r, tol=0.1)
    assert e.dtype == np.int32
    assert e.tolist() == [[0, 1], [0, 2]]  # gaps 0 and 0.05; ball 3 is far
    assert contact_edges(c, r, tol=0.0).tolist() == [[0, 1]]
    assert contact_edges(c[:1], r[:1], 0.1).shape == (0, 2)


def test_contact_edges_kdtree_path_matches_dense(monkeypatch: pytest.MonkeyPatch) -> None:
    import shapedb.mdbd.graph as graph

    rng = np.random.default_rng(1)
    c, r = rng.random((300, 3)), rng.uniform(0.01, 0.06, 300)
    dense = contact_edges(c, r, 0.01)
    monkeypatch.setattr(graph, "_DENSE_LIMIT", 10)
    assert np.array_equal(contact_edges(c, r, 0.01), dense)


def test_edges_are_normalised() -> None:
    g = ContactGraph(np.zeros((3, 3)), [3.0, 2.0, 1.0], [(1, 0), (0, 1), (2, 2), (2, 1)])
    assert g.edges.tolist() == [[0, 1], [1, 2]]
    with pytest.raises(InvalidShapeError, match="outside"):
        ContactGraph(np.zeros((2, 3)), [1.0, 1.0], [(0, 5)])
    with pytest.raises(InvalidShapeError, match="radii"):
        ContactGraph(np.zeros((2, 3)), [1.0], [])


def test_degrees_adjacency_transition() -> None:
    g = ContactGraph(np.zeros((4, 3)), [4.0, 3.0, 2.0, 1.0], [(0, 1), (1, 2)])  # node 3 isolated
    assert g.degrees.tolist() == [1, 2, 1, 0]
    a = g.adjacency().toarray()
    assert np.array_equal(a, a.T) and a.sum() == 4
    t = g.transition().toarray()
    np.testing.assert_allclose(t.sum(axis=0), 1.0)  # column-stochastic
    assert t[1, 0] == 1.0 and t[0, 1] == 0.5 and t[2, 1] == 0.5
    assert t[3, 3] == 1.0  # the isolated node keeps its mass
    np.testing.assert_allclose(g.node_attributes()[:, 3], [1, 0.75, 0.5, 0.25])


def test_neighbourhood_on_a_path() -> None:
    g = path_graph(7)
    assert g.neighbourhood(3, 0).tolist() == [3]
    assert g.neighbourhood(3, 1).tolist() == [2, 3, 4]
    assert g.neighbourhood(3, 2).tolist() == [1, 2, 3, 4, 5]
    assert g.neighbourhood(0, 10).tolist() == list(range(7))
    with pytest.raises(NotFoundError, match="node 9"):
        g.neighbourhood(9, 1)


def test_subgraph_is_induced_and_keeps_ids() -> None:
    g = path_graph(6)
    s = g.subgraph([4, 2, 3])
    assert s.ids.tolist() == [2, 3, 4]
    assert s.edges.tolist() == [[0, 1], [1, 2]]
    np.testing.assert_array_equal(s.radii, g.radii[[2, 3, 4]])
    assert g.subgraph([0, 5]).n_edges == 0


def test_to_networkx() -> None:
    g = path_graph(4)
    G = g.to_networkx()
    assert isinstance(G, nx.Graph)
    assert G.number_of_nodes() == 4 and G.number_of_edges() == 3
    assert G.nodes[0]["center"] == (0.0, 0.0, 0.0)
    assert G.nodes[0]["radius"] == 0.5 and G.nodes[0]["r_norm"] == 1.0
    assert G.edges[0, 1]["weight"] == pytest.approx(1.0)
    assert nx.shortest_path_length(G, 0, 3) == 3


def test_decomposition_graph(csg_shapes: dict) -> None:
    # 64 cells: at 40 the figure's limbs are 1-2 cells thick, and with ties on one of
    # its 41 balls can sit more than half a cell from every other (3 components)
    d = decompose(csg_shapes["figure"], resolution=64, n_balls=100)
    g = d.graph
    assert g is d.graph  # cached
    assert g.n_nodes == d.n_balls and np.array_equal(g.edges, d.edges)
    assert g.degrees.sum() == 2 * len(d.edges)
    assert nx.is_connected(g.to_networkx())  # a connected solid gives a connected graph
