"""Algorithm 1 on hand-made graphs, corpus part search against brute force, geometry."""

from __future__ import annotations

import numpy as np
import pytest
from query_helpers import make_record

from query.parts.index import PARTS_DIR, PartIndex, read_part_config
from query.parts.match import (
    PartMatch,
    match,
    match_brute_force,
    match_pairs,
    nearest_ball,
    part_geometry,
)
from query.parts.store_index import open_parts_index
from shapedb.config.part import PartConfig
from shapedb.errors import NotFoundError, QueryError
from shapedb.geometry.implicit import Capsule
from shapedb.mdbd.graph import ContactGraph
from shapedb.signature.subgraph import (
    neighbourhood_features,
    neighbourhoods,
    part_graph,
    part_weights,
)

#: The paper's part vector alone (Eq. 1 of the subgraph), as before the size block.
PAPER = PartConfig(size=0.0, centre=0.0)


def graph(n: int, seed: int) -> ContactGraph:
    """Random geometric graph with distinct decreasing radii (no feature ties)."""
    rng = np.random.default_rng(seed)
    c = rng.random((n, 3))
    r = -np.sort(-rng.uniform(0.01, 0.1, n))
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    i, j = np.nonzero(np.triu(d < 0.3, 1))
    return ContactGraph(c, r, np.stack([i, j], 1))


def union(a: ContactGraph, b: ContactGraph) -> ContactGraph:
    """Disjoint union, ``a``'s nodes after ``b``'s (so node v of a is n_b + v).

    Parts are compared relative to their shape's largest ball, so ``b``'s radii are
    scaled below ``a``'s largest: the union's largest ball is ``a``'s.
    """
    b = ContactGraph(b.centers, b.radii * (0.9 * a.radii.max() / b.radii.max()), b.edges)
    n = b.n_nodes
    return ContactGraph(
        np.concatenate([b.centers, a.centers]),
        np.concatenate([b.radii, a.radii]),
        np.concatenate([b.edges, a.edges + n]),
    )


@pytest.mark.parametrize("cfg", [PartConfig(), PAPER, PartConfig(centre=1.0, hops=1)])
def test_identical_subgraph_scores_one_and_is_found(cfg: PartConfig) -> None:
    g1, other = graph(25, 1), graph(40, 2)
    g2 = union(g1, other)
    lone = [v for v in range(g1.n_nodes) if g1.degrees[v] == 0]
    assert lone  # the test graph has lone balls (of distinct sizes)
    vs, us, ds = match_pairs(g1, g2, top=3, config=cfg)
    assert ds[0] == 0.0
    for v in range(g1.n_nodes):  # every part of g1 is found at its copy in g2
        (m,) = match(None, g1, g2, node=v, top=1, config=cfg, hops=cfg.hops)
        assert m.similarity == 1.0
        # the centre may be another node with the same neighbourhood (a tie at 0)
        assert tuple(g2.neighbourhood(m.node, cfg.hops).tolist()) == m.nodes
        assert m.query_nodes == tuple(int(x) for x in g1.neighbourhood(v, cfg.hops))
        if cfg.size > 0 or len(g1.neighbourhood(v, cfg.hops)) > 1:
            # with the size block a lone ball is found at its own copy, not at any
            # other lone ball; the paper's vector ties every lone node with every other
            assert m.nodes == tuple(int(x) + 40 for x in g1.neighbourhood(v, cfg.hops))


def test_lone_balls_no_longer_match_each_other_perfectly() -> None:
    # g1: a contact pair and one lone ball (r = .3); g2: the same pair and lone balls of
    # radii .2, .1 and (node 4) .3, its exact copy; both shapes have R = 1
    g1 = ContactGraph(np.zeros((3, 3)), [1.0, 0.8, 0.3], [[0, 1]])
    g2 = ContactGraph(np.zeros((5, 3)), [1.0, 0.8, 0.2, 0.1, 0.3], [[0, 1]])
    # the paper's vector: every lone ball scores 1.0 against every other
    v, u, d = match_pairs(g1, g2, nodes1=[2], top=3, overlap=None, config=PAPER)
    assert np.all(d == 0.0) and u.tolist() == [2, 3, 4]
    # with the size block only the copy does; the others by their size difference
    v, u, d = match_pairs(g1, g2, nodes1=[2], top=3, overlap=None)
    assert u.tolist() == [4, 2, 3]
    per = PartConfig().size * PartConfig().kernel.la + PartConfig().centre  # per unit of r / R
    np.testing.assert_allclose(d, [0.0, per * 0.1, per * 0.2])
    (m,) = match(None, g1, g2, node=2, top=1)
    assert (m.node, m.nodes, m.similarity) == (4, (4,), 1.0)
    # without the copy, no lone ball of another size scores 1.0
    g3 = ContactGraph(np.zeros((4, 3)), [1.0, 0.8, 0.2, 0.1], [[0, 1]])
    (m,) = match(None, g1, g3, node=2, top=1)
    assert m.node == 2 and m.similarity == pytest.approx(np.exp(-per * 0.1)) and m.similarity < 1


def test_known_pair_on_tiny_graphs() -> None:
    # G1: a path a-b-c; G2: the same path plus a pendant heavy node on the end.
    g1 = ContactGraph(np.zeros((3, 3)), [1.0, 0.6, 0.3], [[0, 1], [1, 2]])
    g2 = ContactGraph(np.zeros((5, 3)), [2.0, 1.0, 0.6, 0.3, 0.1], [[0, 1], [1, 2], [2, 3], [0, 4]])
    # with K = 1, node 2 of g1 ({1, 2}: radii .6, .3) equals node 3 of g2 ({2, 3}) under
    # Eq. 1 alone (each subgraph normalised by its own largest ball)
    (m,) = match(None, g1, g2, node=2, hops=1, top=1, config=PAPER)
    assert (m.node, m.similarity, m.nodes) == (3, 1.0, (2, 3))
    # with the size block it is the same part only when the shapes' largest balls agree:
    # here g2's is twice g1's, so the copy is half as big relative to its shape
    (m,) = match(None, g1, g2, node=2, hops=1, top=1)
    assert m.similarity < 1.0
    g3 = ContactGraph(np.zeros((5, 3)), [1.0, 1.0, 0.6, 0.3, 0.1], g2.edges)
    (m,) = match(None, g1, g3, node=2, hops=1, top=1)
    assert (m.node, m.similarity, m.nodes) == (3, 1.0, (2, 3))
    # symmetric kernel: a -> b and b -> a give the same best distance
    assert match_pairs(g1, g2, top=1)[2][0] == pytest.approx(match_pairs(g2, g1, top=1)[2][0])


def test_pairs_sorted_and_limited() -> None:
    a, b = graph(30, 3), graph(35, 4)
    vs, us, ds = match_pairs(a, b, top=7, overlap=None)
    assert len(ds) == 7 and np.all(np.diff(ds) >= 0)
    fa, fb = neighbourhood_features(a), neighbourhood_features(b)
    full = np.abs(fa[:, None] - fb[None]) @ part_weights(PartConfig())
    np.testing.assert_allclose(ds, np.sort(full.ravel())[:7])
    np.testing.assert_allclose(full[vs, us], ds)


def _brute_nms(full, m1, m2, top, overlap):
    """Greedy NMS over all pairs sorted by (distance, v, u): the reference."""
    v, u = np.unravel_index(np.arange(full.size), full.shape)
    order = np.lexsort((u, v, full.ravel()))
    sets1 = [set(m1[i].indices) for i in range(m1.shape[0])]
    sets2 = [set(m2[j].indices) for j in range(m2.shape[0])]

    def jac(x, y):
        return len(x & y) / len(x | y)

    kept = []
    for p in order:
        i, j = int(v[p]), int(u[p])
        if any(
            jac(sets1[i], sets1[a]) > overlap and jac(sets2[j], sets2[b]) > overlap for a, b in kept
        ):
            continue
        kept.append((i, j))
        if len(kept) == top:
            break
    return kept


@pytest.mark.parametrize("overlap", [0.0, 0.5])
@pytest.mark.parametrize("cfg", [PartConfig(), PAPER])
def test_nms_returns_non_overlapping_node_sets(overlap: float, cfg: PartConfig) -> None:
    a, b = graph(30, 3), graph(35, 4)
    plain = match_pairs(a, b, top=8, overlap=None, config=cfg)
    vs, us, ds = match_pairs(a, b, top=8, overlap=overlap, config=cfg)
    assert len(ds) == 8 and np.all(np.diff(ds) >= 0)
    assert (vs[0], us[0], ds[0]) == (plain[0][0], plain[1][0], plain[2][0])  # best kept
    m1, m2 = neighbourhoods(a, 2), neighbourhoods(b, 2)
    fa, fb = neighbourhood_features(a, cfg), neighbourhood_features(b, cfg)
    full = np.abs(fa[:, None] - fb[None]) @ part_weights(cfg)
    assert list(zip(vs.tolist(), us.tolist(), strict=True)) == _brute_nms(full, m1, m2, 8, overlap)
    np.testing.assert_allclose(full[vs, us], ds)
    # one query node whose plain top-5 targets overlap (the same region shifted)
    raw = match(None, a, b, node=4, top=5, overlap=None, config=cfg)
    assert any(set(x.nodes) & set(y.nodes) for i, x in enumerate(raw) for y in raw[:i])
    nms = match(None, a, b, node=4, top=5, overlap=0.0, config=cfg)
    assert nms[0] == raw[0] and len(nms) == 5
    assert not any(set(x.nodes) & set(y.nodes) for i, x in enumerate(nms) for y in nms[:i])
    # one query node: the target node sets themselves do not overlap
    hits = match(None, a, b, node=int(vs[0]), top=5, overlap=overlap, config=cfg)
    for i, x in enumerate(hits):
        for y in hits[:i]:
            sx, sy = set(x.nodes), set(y.nodes)
            assert len(sx & sy) / len(sx | sy) <= overlap
    if overlap == 0.0:
        assert all(not set(x.nodes) & set(y.nodes) for i, x in enumerate(hits) for y in hits[:i])
    with pytest.raises(QueryError, match="overlap"):
        match_pairs(a, b, overlap=1.5)


@pytest.mark.parametrize("query", [(1, 0), (5, 7), (9, 3), ("torus0", 10)])
def test_corpus_search_agrees_with_brute_force(tmp_db, query) -> None:
    sid, node = query
    got = match(tmp_db, sid, node=node, k=6)
    want = match_brute_force(tmp_db, sid, node=node, k=6)
    assert [m.id for m in got] == [m.id for m in want]
    np.testing.assert_allclose([m.distance for m in got], [m.distance for m in want], atol=1e-6)
    assert got[0].similarity == 1.0 and got[0].id == tmp_db.store.resolve(sid)
    assert all(isinstance(m, PartMatch) and m.name and m.label for m in got)
    # the matched node set is N(u, K) in the part graph (contacts at PartConfig's tolerance)
    g = part_graph(tmp_db.get(got[1].id).decomposition, PartConfig())
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


@pytest.mark.parametrize("cfg", [PartConfig(), PAPER])
def test_corpus_nms_per_shape_agrees_with_brute_force(cfg: PartConfig) -> None:
    graphs = [graph(60, s) for s in range(12)]
    index = PartIndex(cfg).fit(np.arange(12), graphs)
    q = neighbourhood_features(graphs[3], cfg)[7]
    w = part_weights(cfg)
    for overlap in (0.0, 0.3):
        sids, nodes, dists = index.search(q, 6, per_shape=3, overlap=overlap)
        ref = index.exact_search(q, 6, per_shape=3, overlap=overlap)
        np.testing.assert_array_equal(sids, ref[0])
        np.testing.assert_array_equal(nodes, ref[1])
        assert sids[0] == 3 and dists[0] == 0.0
        # brute force: per shape, greedy in distance order over all its nodes
        want = []
        for s, g in enumerate(graphs):
            f = neighbourhood_features(g, cfg).astype(np.float32).astype(np.float64)
            d = np.abs(f - q.astype(np.float32).astype(np.float64)) @ w
            sets: list[set] = []
            for u in np.lexsort((np.arange(len(d)), d)):
                ns = set(g.neighbourhood(int(u), 2).tolist())
                if len(sets) < 3 and all(len(ns & t) / len(ns | t) <= overlap for t in sets):
                    sets.append(ns)
                    want.append((float(d[u]), s, int(u)))
        want.sort()
        assert [(s, u) for _, s, u in want[:6]] == list(
            zip(sids.tolist(), nodes.tolist(), strict=True)
        )
        np.testing.assert_allclose(dists, [x for x, _, _ in want[:6]], atol=1e-5)
    if cfg == PAPER:  # without suppression the shape returns its overlapping neighbours
        sids, nodes, _ = index.search(q, 6, per_shape=3, overlap=None)
        pairs = zip(sids.tolist(), nodes.tolist(), strict=True)
        same = [set(graphs[s].neighbourhood(u, 2).tolist()) for s, u in pairs if s == 3]
        assert len(same) == 3 and set.intersection(*same)


def test_legacy_part_index_config() -> None:
    old = {"hops": 2, "n_r": 10, "t": 10, "w": 0.9, "la": 0.75, "lb": 0.75, "lam": 1.0}
    cfg = read_part_config(old)
    # the paper's vector on the stored contact graph, as indexes held before
    assert cfg == PartConfig(size=0.0, centre=0.0, contact_tol_cells=0.0)
    assert cfg.fingerprint != PartConfig().fingerprint
    index = PartIndex(cfg).fit([0, 1], [graph(20, 0), graph(20, 1)])
    assert index.features_.shape == (40, 20)  # the paper's vector, as stored before


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
    from shapedb.mdbd.decomposition import decompose

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
