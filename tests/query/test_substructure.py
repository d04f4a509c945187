"""Algorithm 1 on hand-made graphs, corpus part search against brute force, geometry."""

from __future__ import annotations

import numpy as np
import pytest
from query_helpers import make_record

from query.parts_index import PARTS_DIR, PartIndex, open_parts_index
from query.substructure import (
    PartMatch,
    match,
    match_brute_force,
    match_pairs,
    nearest_ball,
    part_geometry,
)
from shapedb.config import PartConfig
from shapedb.errors import NotFoundError, QueryError
from shapedb.graph import ContactGraph
from shapedb.implicit import Capsule


def graph(n: int, seed: int) -> ContactGraph:
    """Random geometric graph with distinct decreasing radii (no feature ties)."""
    rng = np.random.default_rng(seed)
    c = rng.random((n, 3))
    r = -np.sort(-rng.uniform(0.01, 0.1, n))
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    i, j = np.nonzero(np.triu(d < 0.3, 1))
    return ContactGraph(c, r, np.stack([i, j], 1))


def union(a: ContactGraph, b: ContactGraph) -> ContactGraph:
    """Disjoint union, ``a``'s nodes after ``b``'s (so node v of a is n_b + v)."""
    n = b.n_nodes
    return ContactGraph(
        np.concatenate([b.centers, a.centers]),
        np.concatenate([b.radii, a.radii]),
        np.concatenate([b.edges, a.edges + n]),
    )


def test_identical_subgraph_scores_one_and_is_found() -> None:
    g1, other = graph(25, 1), graph(40, 2)
    g2 = union(g1, other)
    vs, us, ds = match_pairs(g1, g2, top=3)
    assert ds[0] == 0.0
    for v in range(g1.n_nodes):  # every part of g1 is found at its copy in g2
        (m,) = match(None, g1, g2, node=v, top=1)
        assert m.similarity == 1.0
        # the centre may be another node with the same neighbourhood (a tie at 0); a
        # lone node ties with every other lone node
        assert tuple(g2.neighbourhood(m.node, 2).tolist()) == m.nodes
        if len(g1.neighbourhood(v, 2)) > 1:
            assert m.nodes == tuple(int(x) + 40 for x in g1.neighbourhood(v, 2))
        assert m.query_nodes == tuple(int(x) for x in g1.neighbourhood(v, 2))


def test_known_pair_on_tiny_graphs() -> None:
    # G1: a path a-b-c; G2: the same path plus a pendant heavy node on the end.
    g1 = ContactGraph(np.zeros((3, 3)), [1.0, 0.6, 0.3], [[0, 1], [1, 2]])
    g2 = ContactGraph(np.zeros((5, 3)), [2.0, 1.0, 0.6, 0.3, 0.1], [[0, 1], [1, 2], [2, 3], [0, 4]])
    # with K = 1, node 2 of g1 ({1, 2}: radii .6, .3) equals node 3 of g2 ({2, 3})
    (m,) = match(None, g1, g2, node=2, hops=1, top=1)
    assert (m.node, m.similarity, m.nodes) == (3, 1.0, (2, 3))
    # symmetric kernel: a -> b and b -> a give the same best distance
    assert match_pairs(g1, g2, top=1)[2][0] == pytest.approx(match_pairs(g2, g1, top=1)[2][0])


def test_pairs_sorted_and_limited() -> None:
    a, b = graph(30, 3), graph(35, 4)
    vs, us, ds = match_pairs(a, b, top=7)
    assert len(ds) == 7 and np.all(np.diff(ds) >= 0)
    from shapedb.kernel import weights
    from shapedb.subgraph import neighbourhood_features

    full = np.abs(neighbourhood_features(a)[:, None] - neighbourhood_features(b)[None]) @ weights(
        PartConfig().kernel
    )
    np.testing.assert_allclose(ds, np.sort(full.ravel())[:7])
    np.testing.assert_allclose(full[vs, us], ds)


@pytest.mark.parametrize("query", [(1, 0), (5, 7), (9, 3), ("torus0", 10)])
def test_corpus_search_agrees_with_brute_force(tmp_db, query) -> None:
    sid, node = query
    got = match(tmp_db, sid, node=node, k=6)
    want = match_brute_force(tmp_db, sid, node=node, k=6)
    assert [m.id for m in got] == [m.id for m in want]
    np.testing.assert_allclose([m.distance for m in got], [m.distance for m in want], atol=1e-6)
    assert got[0].similarity == 1.0 and got[0].id == tmp_db.store.resolve(sid)
    assert all(isinstance(m, PartMatch) and m.name and m.label for m in got)
    # the matched node set is N(u, K) in the stored graph
    g = tmp_db.get(got[1].id).decomposition.graph
    assert got[1].nodes == tuple(int(x) for x in g.neighbourhood(got[1].node, 2))
    assert db_match_is_same(tmp_db, sid, node, got)


def db_match_is_same(db, sid, node, got) -> bool:
    return [m.id for m in db.match(sid, node=node, k=6)] == [m.id for m in got]


def test_whole_model_query_and_point(tmp_db) -> None:
    rec = tmp_db.get("capsule2")
    d = rec.decomposition
    hits = match(tmp_db, d, k=3, hops=1)
    assert hits[0].query_node == -1 and len(hits[0].query_nodes) == d.n_balls
    v = nearest_ball(d, d.centers[4] + [0, 0, 0.01])
    assert v == 4
    by_point = match(tmp_db, "capsule2", point=d.centers[4], k=3)
    by_node = match(tmp_db, "capsule2", node=4, k=3)
    assert by_point == by_node


def test_index_follows_the_store(tmp_db) -> None:
    cfg = PartConfig()
    index = open_parts_index(tmp_db, cfg)
    assert index.version_ == tmp_db.store.version
    n0 = index.n_vectors
    assert (tmp_db.path / PARTS_DIR / cfg.fingerprint / "current.json").exists()
    loaded = PartIndex.load(tmp_db.path / PARTS_DIR / cfg.fingerprint)
    np.testing.assert_array_equal(loaded.features_, index.features_)
    # add a shape identical to capsule1 in all but name: found with similarity 1.0
    _, (rec,) = tmp_db.commit(
        [make_record("capsule1-copy", "capsule", Capsule([0, 0, 0], [2.0, 0, 0], 0.4))]
    )
    hits = match(tmp_db, "capsule1", node=2, k=2)
    assert {h.name for h in hits} == {"capsule1", "capsule1-copy"}
    assert all(h.similarity == 1.0 for h in hits)
    assert open_parts_index(tmp_db, cfg).n_vectors == n0 + rec.n_balls
    tmp_db.delete("capsule1-copy")
    hits = match(tmp_db, "capsule1", node=2, k=2)
    assert "capsule1-copy" not in {h.name for h in hits}


def test_where_restricts_the_corpus(tmp_db) -> None:
    hits = match(tmp_db, "box0", node=0, k=10, where="label = 'torus'")
    assert hits and {h.label for h in hits} == {"torus"}


def test_ivf_index_recall() -> None:
    graphs = [graph(60, s) for s in range(400)]
    index = PartIndex(ivf_threshold=1000).fit(np.arange(400), graphs)
    assert index.kind_ == "ivf"
    rng = np.random.default_rng(0)
    hits = 0
    for _ in range(20):
        q = index.features_[rng.integers(len(index.features_))] * rng.uniform(0.97, 1.03)
        got = index.search(q, 10)
        want = index.exact_search(q, 10)
        hits += len(set(got[0]) & set(want[0]))
        assert np.all(np.diff(got[2]) >= 0)
    assert hits / 200 >= 0.9
    index.remove(np.arange(100))  # a quarter dead: compacted
    assert len(index.shapes_) == 300 and index.n_vectors == 300 * 60
    assert not np.isin(index.search(index.features_[0], 10)[0], np.arange(100)).any()


def test_part_geometry_on_mesh_and_points() -> None:
    trimesh = pytest.importorskip("trimesh")
    from shapedb.mdbd import decompose

    cap = Capsule([0, 0, 0], [2.0, 0, 0], 0.3)
    d = decompose(cap, resolution=48, n_balls=60)
    mesh = trimesh.creation.capsule(height=2.0, radius=0.3, count=[16, 16])
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    mesh.apply_translation([1.0, 0, 0])
    end = int(np.argmin(d.centers[:, 0]))  # the ball nearest the x = 0 cap
    part = part_geometry(d, [end], mesh)
    assert part.centers.shape == (1, 3) and part.radii[0] == d.radii[end]
    centroids = mesh.triangles_center[part.faces]
    assert len(part.faces) > 0 and centroids[:, 0].max() < d.centers[end, 0] + 2 * d.radii[end]
    pts = part_geometry(d, np.arange(d.n_balls), mesh.vertices)
    assert pts.faces is None and len(pts.points) > 0.8 * len(mesh.vertices)


def test_errors(tmp_db) -> None:
    with pytest.raises(NotFoundError):
        match(tmp_db, "box0", node=10_000)
    with pytest.raises(QueryError, match="not both"):
        match(tmp_db, "box0", node=1, point=[0, 0, 0])
    with pytest.raises(QueryError):
        match(tmp_db, "box0", node=1, k=0)
    with pytest.raises(QueryError, match="needs a database"):
        match(None, graph(10, 0))
    with pytest.raises(NotFoundError):
        match(tmp_db, "no-such-shape", node=1)
