"""The field vectors in the light field stage: the fused distance and the union candidates.

Hand-made arrays: stored vectors, light fields whose distances are a given matrix (each
light field is its shape's id; :func:`shapedb.signature.lightfield.light_field_distance` patched to
read the matrix), and field vectors.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

import shapedb.signature.lightfield
from query.search import rerank
from query.search.field_fusion import FIELD, FieldFusion
from query.search.field_index import FieldIndex
from query.search.index import FeatureIndex
from query.search.lightfield_spread import local_statistic
from query.search.rerank_lightfield import COLUMN, LightFieldFusion
from query.search.tuning import PRODUCT
from shapedb.config.core import Config
from shapedb.signature.kernel import weights

DEPTH, HARMONIC = slice(0, 4), slice(4, 7)
#: The stage with its gate wide open (g = 1): the light field's rank always counts.
OPEN = replace(PRODUCT, weight=4.0, ceiling=0.0, contrast_floor=0.0, pool=0)


def _fusion(**kw: Any) -> FieldFusion:
    args: dict[str, Any] = {
        "depth_weight": 0.5, "harmonic_weight": 2.0, **kw,
    }  # fmt: skip
    return FieldFusion(DEPTH, HARMONIC, **args)


class Reader:
    """An ``ArrayReader`` of hand-made columns, with a field vector index."""

    def __init__(self, lf: np.ndarray, fv: np.ndarray, fusion: FieldFusion) -> None:
        self.lf, self.fv, self.fusion = lf, fv, fusion

    def __call__(self, name: str, ids: np.ndarray) -> np.ndarray | None:
        if name == COLUMN:
            return np.asarray(self.lf[ids], np.float64)
        if name == FIELD:
            return np.asarray(self.fv[ids], np.float64)
        return None

    def field_index(self) -> FieldIndex:
        ok = np.flatnonzero(np.all(np.isfinite(self.fv), axis=1))
        return FieldIndex(ok, self.fusion.scaled(self.fv[ok]))


@pytest.fixture
def matrix_distance(monkeypatch: pytest.MonkeyPatch) -> Any:
    """Light fields are ids: ``light_field_distance`` reads ``state["L"][query, candidates]``."""
    state: dict[str, np.ndarray] = {}

    def distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        qa = np.asarray(a).reshape(len(a), -1)[:, 0].astype(int)
        cb = np.asarray(b).reshape(len(b), -1)[:, 0].astype(int)
        return state["L"][np.ix_(qa, cb)]

    monkeypatch.setattr(shapedb.signature.lightfield, "light_field_distance", distance)
    return state


def _case(n: int = 40, k: int = 8, seed: int = 0, **options: Any) -> dict[str, Any]:
    """A store of n random vectors, light field distances and field vectors in 4 classes."""
    rng = np.random.default_rng(seed)
    config = Config().with_options(rerank="lightfield")
    tuning = replace(OPEN, candidates=k, **options)
    x = rng.random((n, config.dim)).astype(np.float32).astype(np.float64)  # as stored
    w = weights(config)
    index = FeatureIndex(kind="flat").fit(np.arange(n), x.astype(np.float32), w)
    centres = rng.random((4, 7))
    fv = centres[np.arange(n) % 4] + 0.2 * rng.random((n, 7))
    pts = rng.random((n, 5))
    L = np.abs(pts[:, None] - pts[None]).sum(-1)  # a metric, 0 on the diagonal
    lf = np.arange(n, dtype=np.float64).reshape(n, 1, 1, 1)
    return {"config": config, "tuning": tuning, "x": x, "index": index, "fv": fv, "L": L, "lf": lf}


def _scorer(case: dict[str, Any], fusion: FieldFusion) -> LightFieldFusion:
    scorer = LightFieldFusion(case["config"], tuning=case["tuning"])
    scorer.field = fusion
    return scorer


def _search(case: dict[str, Any], fusion: FieldFusion, k: int, **kw: Any) -> Any:
    index = case["index"]
    n = len(case["x"])
    q = kw.pop("queries", np.arange(n))
    return rerank.search(
        index, case["x"][q], k, config=case["config"], query_ids=q,
        scorer=_scorer(case, fusion),
        arrays=Reader(case["lf"], case["fv"], fusion), **kw,
    )  # fmt: skip


def test_the_fused_distance_is_the_formula() -> None:
    rng = np.random.default_rng(3)
    fusion = _fusion()
    q, c, light = rng.random(7), rng.random((5, 7)), rng.random(5)
    b = np.abs(c[:, :4] - q[:4]).sum(1)
    h = np.abs(c[:, 4:] - q[4:]).sum(1)
    want = light + 0.5 * b + 2.0 * h
    assert fusion.active
    np.testing.assert_allclose(fusion.distance(light, q, c), want, rtol=1e-12)
    s = fusion.scaled(np.vstack([q, c]))  # L1 of the scaled vectors: alpha * b + gamma * h
    np.testing.assert_allclose(np.abs(s[1:] - s[0]).sum(1), 0.5 * b + 2.0 * h, rtol=1e-5)
    off = _fusion(depth_weight=0.0, harmonic_weight=0.0)
    assert not off.active and off.key() is None
    assert np.array_equal(off.distance(light, q, c), light)
    assert not _fusion(stored=False).active and not _fusion(stored=False, candidates=5).proposes


def test_a_row_without_field_vectors_keeps_the_light_field_distance(
    caplog: pytest.LogCaptureFixture,
) -> None:
    fusion = _fusion()
    light = np.array([0.3, 0.1, 0.2])
    c = np.ones((3, 7))
    c[1, 5] = np.nan
    with caplog.at_level(logging.WARNING, logger="query.search.field_fusion"):
        assert np.array_equal(fusion.distance(light, np.zeros(7), c), light)
        assert np.array_equal(fusion.distance(light, np.full(7, np.nan), np.ones((3, 7))), light)
        assert np.array_equal(fusion.distance(light, None, None), light)
    assert caplog.text.count("no field vector") == 1  # once per fusion


def test_the_stage_ranks_by_the_fused_distance_everywhere(matrix_distance: Any) -> None:
    # the gate's own spread of the query reads the distance too; one unit for the fused
    # distance and the light field's, so the fused one given as the light field's compares
    case = _case(ceiling=5.0, ramp=5.0, light_field_unit=PRODUCT.scale)
    fusion = _fusion()
    n = len(case["x"])
    b = np.abs(case["fv"][:, None, DEPTH] - case["fv"][None, :, DEPTH]).sum(-1)
    h = np.abs(case["fv"][:, None, HARMONIC] - case["fv"][None, :, HARMONIC]).sum(-1)
    matrix_distance["L"] = case["L"]
    got = _search(case, fusion, n)
    matrix_distance["L"] = fusion.combine(case["L"], b, h)
    want = _search(case, _fusion(depth_weight=0.0, harmonic_weight=0.0), n)
    assert np.array_equal(got[0], want[0])
    np.testing.assert_allclose(got[1], want[1], rtol=1e-12)
    matrix_distance["L"] = case["L"]
    plain = _search(case, _fusion(depth_weight=0.0, harmonic_weight=0.0), n)
    assert not np.array_equal(got[0], plain[0])  # the fusion moved some rankings


def test_weights_zero_rank_as_a_store_without_field_vectors(matrix_distance: Any) -> None:
    case = _case()
    matrix_distance["L"] = case["L"]
    n = len(case["x"])
    zero = _search(case, _fusion(depth_weight=0.0, harmonic_weight=0.0), n)
    without = _search(case, _fusion(stored=False, candidates=10), n)
    assert np.array_equal(zero[0], without[0]) and np.array_equal(zero[1], without[1])
    assert not np.array_equal(_search(case, _fusion(), n)[0], zero[0])


def _twin(case: dict[str, Any], query: int, far: int) -> None:
    """Make ``far`` the query's twin by light field and field vector, far by the vector."""
    case["fv"][far] = case["fv"][query]
    case["L"][far] = case["L"][query]
    case["L"][:, far] = case["L"][:, query]
    case["L"][far, query] = case["L"][query, far] = 0.0


def test_a_neighbour_outside_the_k_is_found_through_the_field_vectors(
    matrix_distance: Any,
) -> None:
    case = _case(k=5)
    order = np.argsort(np.abs(case["x"] - case["x"][0]) @ weights(case["config"]), kind="stable")
    far = int(order[-1])  # the farthest shape by the stored vector
    _twin(case, 0, far)
    matrix_distance["L"] = case["L"]
    n = len(case["x"])
    without, _ = _search(case, _fusion(), n, queries=np.array([0]))
    assert far not in without[0][:5] and without[0][-1] == far
    found, dist = _search(case, _fusion(candidates=3), n, queries=np.array([0]))
    assert found[0][:2].tolist() == [0, far]
    assert sorted(found[0].tolist()) == list(range(n))  # every shape once
    stored, sd = _search(case, _fusion(candidates=3), 6, queries=np.array([0]),
                         stored_distances=True)  # fmt: skip
    exact = np.abs(case["x"][stored[0]] - case["x"][0]) @ weights(case["config"])
    np.testing.assert_allclose(sd[0], exact, rtol=1e-12)


def test_the_union_honours_where_and_deletions(matrix_distance: Any) -> None:
    case = _case(k=5)
    order = np.argsort(np.abs(case["x"] - case["x"][0]) @ weights(case["config"]), kind="stable")
    far = int(order[-1])
    _twin(case, 0, far)
    matrix_distance["L"] = case["L"]
    n = len(case["x"])
    allowed = np.setdiff1d(np.arange(n), [far, 3])
    got, _ = _search(case, _fusion(candidates=3), n, queries=np.array([0]), allowed=allowed)
    real = got[0][got[0] >= 0]
    assert set(real.tolist()) == set(allowed.tolist()) and len(real) == len(allowed)
    case["index"].remove([far])  # deleted: the field index still holds it
    got, _ = _search(case, _fusion(candidates=3), n, queries=np.array([0]))
    real = got[0][got[0] >= 0]
    assert far not in real and len(real) == n - 1 == len(set(real.tolist()))


def test_extras_follow_the_k_in_stored_order_without_repeats() -> None:
    config = Config().with_options(rerank="lightfield")
    w = np.ones(config.dim)
    xq = np.zeros((1, config.dim))
    feats = np.stack([np.full(config.dim, v) for v in (0.1, 0.2, 0.3, 0.4)])[None]
    batch = rerank.Candidates(
        np.array([-1]), xq, np.array([[5, 6, 7, 8]]), feats, w,
        (feats[0] @ w)[None], config, head=2,
    )  # fmt: skip
    extra_ids = np.array([[9, 6, 8, -1, 9]])  # 6 is in the K, 9 twice, 8 in the rest
    extra_f = np.stack([np.full(config.dim, v) for v in (0.35, 0.2, 0.4, 0.0, 0.35)])[None]
    got = rerank.with_extras(batch, extra_ids, extra_f)
    assert got.head == 2 + 5
    assert got.ids[0].tolist() == [5, 6, 9, 8, -1, -1, -1, 7, -1]
    np.testing.assert_allclose(got.distances[0][:4], [0.1, 0.2, 0.35, 0.4] * np.array(w.sum()))
    ids, _ = rerank.rerank_candidates(_Stored(), got, 9)
    assert ids[0].tolist() == [5, 6, 9, 8, 7, -1, -1, -1, -1]  # pads squeezed out


class _Stored:
    def score(self, batch: rerank.Candidates) -> np.ndarray:
        return np.asarray(batch.distances)


@pytest.mark.parametrize("scan_max", [0, 65_536])  # faiss proposes, or a numpy scan
def test_the_field_index_is_exact_with_ties_by_id_and_filters(
    scan_max: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("query.search.field_index.SCAN_MAX", scan_max)
    rng = np.random.default_rng(5)
    v = rng.random((50, 6)).astype(np.float32)
    v[17] = v[3]  # a tie
    ids = np.arange(100, 150)[::-1].copy()
    index = FieldIndex(ids, v)
    q = v[[3]].astype(np.float64)
    got, d = index.search(q, 5)
    brute = np.abs(v.astype(np.float64) - q).sum(1)
    want = np.lexsort((ids, brute))[:5]
    assert got[0].tolist() == ids[want].tolist() and d[0][0] == d[0][1] == 0.0
    assert got[0][0] < got[0][1]  # ties by ascending id
    queries = rng.random((7, 6))
    many, _ = index.search(queries, 9)
    for row, qv in enumerate(queries):
        d = np.abs(v.astype(np.float64) - qv).sum(1)
        assert many[row].tolist() == ids[np.lexsort((ids, d))[:9]].tolist()
    allowed = ids[::2]
    got, _ = index.search(q, 60, allowed=allowed)
    real = got[0][got[0] >= 0]
    assert set(real.tolist()) == set(allowed.tolist())
    assert index.search(np.full((1, 6), np.nan), 3)[0].tolist() == [[-1, -1, -1]]


def _clustered(n: int, d: int = 24, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = rng.random((max(n // 100, 4), d))
    label = rng.integers(0, len(centres), n)
    return (centres[label] + 0.1 * rng.standard_normal((n, d))).astype(np.float32)


def _brute(ids: np.ndarray, v: np.ndarray, q: np.ndarray, k: int) -> list[int]:
    d = np.abs(v.astype(np.float64) - q).sum(1)
    return ids[np.lexsort((ids, d))[:k]].tolist()


@pytest.fixture
def small_scan(monkeypatch: pytest.MonkeyPatch) -> None:
    """The graph proposes above 500 vectors, 8 times k + 16 of them."""
    monkeypatch.setattr("query.search.field_index.SCAN_MAX", 500)
    monkeypatch.setattr("query.search.field_index.OVERSAMPLE", 8)


def test_the_graph_proposes_and_the_exact_scan_orders(small_scan: None) -> None:
    v = _clustered(2000)
    ids = np.arange(2000) * 3 + 1
    index = FieldIndex(ids, v)
    assert index.approximate
    rng = np.random.default_rng(1)
    queries = v[rng.choice(2000, 15, replace=False)] + 0.02 * rng.standard_normal((15, 24))
    got, d = index.search(queries, 40)
    for row, q in enumerate(queries):
        assert got[row].tolist() == _brute(ids, v, q, 40)
    assert np.all(np.diff(d, axis=1) >= 0)
    allowed = ids[::7]
    got, _ = index.search(queries[:2], 5, allowed=allowed)
    assert got[0].tolist() == _brute(allowed, v[::7], queries[0], 5)


def test_tombstones_and_additions_keep_the_graph_exact(small_scan: None) -> None:
    v = _clustered(2400, seed=3)
    ids = np.arange(2400)
    index = FieldIndex(ids[:2000], v[:2000])
    index.settle()  # builds the graph
    gone = np.arange(0, 2000, 9)
    assert index.remove(gone) == len(gone) and index.remove(gone) == 0
    index.add(ids[2000:], v[2000:])
    index.settle()
    live = np.setdiff1d(ids, gone)
    assert len(index) == len(live) and index.approximate
    queries = np.concatenate([v[gone[:5]], v[2000:2005]]).astype(np.float64)
    got, _ = index.search(queries, 30)
    assert not np.isin(got, gone).any()
    for row, q in enumerate(queries):
        assert got[row].tolist() == _brute(live, v[live], q, 30)
    assert got[5:, 0].tolist() == list(range(2000, 2005))  # the new vectors are found


def test_an_index_shrunk_below_the_scan_threshold_is_a_fresh_one(small_scan: None) -> None:
    v = _clustered(900, seed=4)
    index = FieldIndex(np.arange(900), v)
    index.settle()
    index.remove(np.arange(0, 900, 2))
    index.add([2001, 1999], v[:2])
    index.settle()
    assert not index.approximate
    fresh = FieldIndex(np.r_[np.arange(1, 900, 2), 1999, 2001], np.r_[v[1::2], v[1:2], v[:1]])
    assert index.ids_.tolist() == fresh.ids_.tolist()
    assert np.array_equal(index.vectors_, fresh.vectors_) and index.alive_.all()
    q = _clustered(3, seed=9).astype(np.float64)
    for a, b in zip(index.search(q, 12), fresh.search(q, 12), strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("n", [300, 1200])  # a flat index, a graph
def test_a_saved_index_loads_the_same(small_scan: None, tmp_path: Any, n: int) -> None:
    v = _clustered(n, seed=5)
    index = FieldIndex(np.arange(n), v)
    index.settle()
    index.remove([3, 4])
    index.segments_, index.scales_ = ("a.parquet",), [1.0]
    index.save(tmp_path / "idx", version=7)
    back = FieldIndex.load(tmp_path / "idx")
    assert (back.segments_, back.scales_, back.version_) == (("a.parquet",), [1.0], 7)
    assert back.approximate == (n > 500) and len(back) == n - 2
    q = v[:6].astype(np.float64)
    for a, b in zip(index.search(q, 20), back.search(q, 20), strict=True):
        assert np.array_equal(a, b)


#: The former parametrisation: weights 0.25 and 0.25 of the three distances over their
#: scales (light field 20.67, depth 6.045, harmonic 2.168), the spread's unit 18.03.
A, C, M_L, M_B, M_H, TYPICAL = 0.25, 0.25, 20.67, 6.045, 2.168, 18.03


def _product_fusion() -> FieldFusion:
    return FieldFusion(DEPTH, HARMONIC, depth_weight=PRODUCT.field_depth_weight,
                       harmonic_weight=PRODUCT.field_harmonic_weight)  # fmt: skip


def _former(light: np.ndarray, b: np.ndarray, h: np.ndarray) -> np.ndarray:
    return M_L * (light / M_L + A * b / M_B + C * h / M_H) / (1.0 + A + C)


def test_the_product_s_fusion_is_the_former_one_times_one_plus_a_plus_c() -> None:
    assert PRODUCT.field_depth_weight == A * M_L / M_B
    assert PRODUCT.field_harmonic_weight == C * M_L / M_H
    assert PRODUCT.scale == pytest.approx((1.0 + A + C) * M_L, rel=1e-15)
    fusion = _product_fusion()
    rng = np.random.default_rng(11)
    light, b, h = 40.0 * rng.random(1000), 12.0 * rng.random(1000), 4.0 * rng.random(1000)
    fused = fusion.combine(light, b, h)
    np.testing.assert_allclose(fused, (1.0 + A + C) * _former(light, b, h), rtol=1e-13)
    # the shared-neighbour term's D / scale is the former dl / m_l
    np.testing.assert_allclose(fused / PRODUCT.scale, _former(light, b, h) / M_L, rtol=1e-13)
    # the index's L1 of the scaled vectors: alpha * b + gamma * h, the former b / m_b + h / m_h
    # times a * m_l (a == c), so the same order
    q, x = rng.random(7), rng.random((50, 7))
    s = fusion.scaled(np.vstack([q, x]))
    bb, hh = fusion.parts(q, x)
    l1 = np.abs(s[1:].astype(np.float64) - s[0]).sum(1)
    np.testing.assert_allclose(l1, A * M_L * (bb / M_B + hh / M_H), rtol=1e-5)


def test_the_gate_s_statistic_is_the_former_one_in_the_new_unit() -> None:
    d = np.array([0.8, 1.1, 1.3, 1.7, 2.0, 2.2])  # calibrated stored distances, list order
    light, b, h = (np.array([21.0, 30.0, 17.5, 25.0, 12.0, 40.0]),
                   np.array([5.0, 7.5, 4.0, 6.5, 3.0, 9.0]),
                   np.array([2.0, 1.5, 2.5, 3.0, 1.0, 2.2]))  # fmt: skip
    f = replace(PRODUCT, spread_candidates=3, ratio_candidates=6)
    now = local_statistic(d, _product_fusion().combine(light, b, h), f)
    dl = _former(light, b, h)
    m, w = f.spread_candidates, f.ratio_weight
    spread = float(np.median(dl[:m])) / TYPICAL / float(np.median(d[:m]))
    ratio = float(np.median(dl[:m])) / float(np.median(np.sort(dl)[:m]))
    former = spread ** (1.0 - w) * ratio**w
    factor = (TYPICAL / M_L) ** 0.8
    assert factor == pytest.approx(0.8964461369882787, rel=1e-15)
    assert now == pytest.approx(former * 0.8964461369882787, rel=1e-12)
    # the gate's ceiling and ramp: the former 0.17 and 0.034 in the new unit
    assert PRODUCT.ceiling == pytest.approx(0.17 * factor, rel=1e-15)
    assert PRODUCT.ramp == pytest.approx(0.034 * factor, rel=1e-15)
    gate = np.clip((PRODUCT.ceiling - now) / PRODUCT.ramp, 0.0, 1.0)
    assert gate == pytest.approx(np.clip((0.17 - former) / 0.034, 0.0, 1.0), abs=1e-12)
    # a store without field vectors: the light field distance alone in light_field_unit,
    # the former statistic (unit 18.03) times the same factor, so its gate is the former
    alone = local_statistic(d, light, f, f.unit(False))
    spread = float(np.median(light[:m])) / TYPICAL / float(np.median(d[:m]))
    ratio = float(np.median(light[:m])) / float(np.median(np.sort(light)[:m]))
    assert alone == pytest.approx(spread ** (1.0 - w) * ratio**w * factor, rel=1e-12)
