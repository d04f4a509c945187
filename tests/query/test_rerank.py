"""The exact re-ranking stage (query.search.rerank): scorers, the adaptive fusion, search and eval."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG

from query.evaluate import evaluate, retrieval_scores
from query.search import rerank
from query.search.index import FeatureIndex
from shapedb.config.core import Config
from shapedb.errors import ConfigError
from shapedb.signature.descriptor import LAYOUTS, dim
from shapedb.signature.kernel import features
from shapedb.store.schema import ShapeRecord


class _Stored:
    """The identity scorer: the stored distance itself."""

    def __init__(self, config: Config) -> None:
        self.config = config

    def score(self, batch: rerank.Candidates) -> np.ndarray:
        return batch.distances


class _Gate(rerank.AdaptiveFusion):
    """The adaptive fusion with g(q) pinned to a constant."""

    value = 0.0

    def gate(self, batch: Any, base: Any, part: Any) -> np.ndarray:
        return np.full(len(batch.ids), self.value)


def _gate(value: float) -> Any:
    return type(f"_Gate{value}", (_Gate,), {"value": value})


rerank.register_scorer("test_stored", _Stored)
rerank.register_scorer("test_gate0", _gate(0.0))
rerank.register_scorer("test_gate1", _gate(1.0))


def _index(n: int = 80, d: int = 24, seed: int = 0) -> tuple[FeatureIndex, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.random((n, d)).astype(np.float32)
    x[5] = x[6]  # a tie, broken by id
    ids = np.arange(100, 100 + n)
    return FeatureIndex(kind="flat").fit(ids, x, np.ones(d)), x.astype(np.float64)


@pytest.mark.parametrize("k", [1, 7, 30, 80])
def test_the_identity_scorer_returns_the_index_order(k: int) -> None:
    index, x = _index()
    cfg = Config().with_options(rerank="test_stored", rerank_candidates=12)
    got = rerank.search(index, x[:20], k, config=cfg, query_ids=np.arange(100, 120))
    want = index.search(x[:20], k)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])


def test_no_scorer_is_the_plain_search_and_unknown_ones_are_refused() -> None:
    index, x = _index()
    plain = Config().with_options(rerank="none")
    got = rerank.search(index, x[:3], 5, config=plain)
    np.testing.assert_array_equal(got[0], index.search(x[:3], 5)[0])
    assert rerank.scorer_for(plain) is None and "adaptive" in rerank.scorers()
    with pytest.raises(ConfigError, match="unknown scorer.*'lightfield'"):
        rerank.scorer_for(Config().with_options(rerank="nosuch"))
    with pytest.raises(ConfigError, match="exists"):
        rerank.register_scorer("adaptive", _Stored)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="rerank_candidates"):
        Config().with_options(rerank_candidates=0)


def _v7_vectors(n: int = 60, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).random((n, dim(7))).astype(np.float32).astype(np.float64)


def _ranking(x: np.ndarray, q: np.ndarray, ids: np.ndarray) -> np.ndarray:
    d = np.abs(x - q).sum(axis=1)
    return ids[np.lexsort((ids, d))]


def test_with_g_zero_the_fusion_ranks_by_version_4_and_with_g_one_by_the_stored_vector() -> None:
    x = _v7_vectors()
    ids = np.arange(len(x))
    index = FeatureIndex(kind="flat").fit(ids, x, np.ones(x.shape[1]))
    n4 = dim(4)
    assert [b[0] for b in LAYOUTS[7][:-1]] == [b[0] for b in LAYOUTS[4]]  # v4, then views
    for name in ("test_gate0", "adaptive"):
        options = {"rerank_weight": 0.0} if name == "adaptive" else {}
        cfg = Config().with_options(descriptor=7, rerank=name, rerank_candidates=60, **options)
        got, _ = rerank.search(index, x[:10], 60, config=cfg, query_ids=ids[:10])
        for row in range(10):
            np.testing.assert_array_equal(got[row], _ranking(x[:, :n4], x[row, :n4], ids))
    cfg = Config().with_options(
        descriptor=7, rerank="test_gate1", rerank_candidates=60, rerank_weight=8.0
    )  # the views at their own weight
    got, dist = rerank.search(index, x[:10], 60, config=cfg)
    want_ids, want_d = index.search(x[:10], 60)
    np.testing.assert_array_equal(got, want_ids)
    np.testing.assert_allclose(dist, want_d, rtol=1e-12)


def test_the_gate_is_the_overlap_of_the_two_neighbourhoods() -> None:
    cfg = Config().with_options(
        descriptor=7, rerank="adaptive", rerank_neighbours=2, rerank_power=2, rerank_weight=8.0,
        rerank_ratio=0.0,
    )  # fmt: skip
    scorer = rerank.AdaptiveFusion(cfg)
    base = np.array([[0.0, 1.0, 2.0, 3.0, 4.0]])
    part = np.array([[0.0, 0.2, 9.0, 0.5, 8.0]])  # self, then A = {1, 2}, B = {1, 3}
    feats = np.zeros((1, 5, dim(7)))
    feats[0, :, 0], feats[0, :, -1] = base[0], part[0]  # a v4 number, a views number
    batch = rerank.Candidates(
        np.array([7]), np.zeros((1, dim(7))), np.array([[7, 1, 2, 3, 4]]), feats,
        np.ones(dim(7)), base + part, cfg,
    )  # fmt: skip
    got_base, got_part = scorer.parts(batch)
    np.testing.assert_array_equal(got_base, base)
    np.testing.assert_array_equal(got_part, part)
    assert scorer.gate(batch, base, part)[0] == pytest.approx(0.25)  # (1/2)^2
    stranger = dataclasses.replace(batch, query_ids=np.array([-1]))  # 7 is another shape
    assert scorer.gate(stranger, base, part)[0] == pytest.approx(1.0)  # A = B = {7, 1}
    fused = scorer.score(batch)  # weight 8 at the views' own weight 8: base + g * part
    np.testing.assert_allclose(fused, base + 0.25 * part)
    # the others' medians: part 4.25 (0.2, 0.5, 8, 9), base 2.5 (1, 2, 3, 4): spread 1.7
    for ceiling, factor in ((1.85, 1.0), (1.75, 0.5), (1.65, 0.0)):
        capped = rerank.AdaptiveFusion(cfg.with_options(rerank_ratio=ceiling))
        assert capped.gate(batch, base, part)[0] == pytest.approx(0.25 * factor)


STAGE = CONFIG.with_options(
    descriptor=7, rerank="adaptive", rerank_candidates=6, rerank_neighbours=3, rerank_weight=16.0
)


@pytest.fixture()
def stage_db(
    tmp_path: Path, example_records: list[ShapeRecord], forget: Callable[[Any], None]
) -> Iterator[Any]:
    """The 14 example shapes in a store of version 7 with the adaptive stage (K = 6)."""
    import query.database as database

    db = database.connect(tmp_path / "stage", config=STAGE)
    db.commit(
        [
            dataclasses.replace(
                r, feature=features(r.decomposition, STAGE).astype(np.float32), config=STAGE
            )
            for r in example_records
        ]
    )
    yield db
    forget(db)


def _rank_matrix(db: Any) -> tuple[np.ndarray, np.ndarray, list[Any]]:
    ids, _ = db.store.features()
    labels = db.store.shapes(["label"]).column("label").to_pylist()
    hits = db.search_batch([int(i) for i in ids], k=len(ids))
    ranks = np.empty((len(ids), len(ids)))
    for row, found in enumerate(hits):
        assert sorted(h.id for h in found) == sorted(ids.tolist())
        ranks[row, np.searchsorted(ids, [h.id for h in found])] = np.arange(len(ids))
    return ids, ranks, labels


def test_evaluation_ranks_as_search_does(stage_db: Any) -> None:
    ids, ranks, labels = _rank_matrix(stage_db)
    want = retrieval_scores(ranks, labels, ids=ids, distance=True).to_dict()
    got = evaluate(stage_db).to_dict()
    for key in ("nn", "first_tier", "second_tier", "e_measure", "dcg"):
        assert got[key] == pytest.approx(want[key], abs=1e-12)
    plain = np.stack(
        [np.abs(stage_db.store.features()[1] - f).sum(axis=1) for f in stage_db.store.features()[1]]
    )
    assert not np.array_equal(np.argsort(ranks, axis=1), np.argsort(plain, axis=1, kind="stable"))


def test_a_reopened_store_searches_the_same_way(
    stage_db: Any, forget: Callable[[Any], None]
) -> None:
    import query.database as database

    some = [int(i) for i in stage_db.store.features()[0][[0, 3, 9]]]
    before = [[(h.id, h.distance) for h in row] for row in stage_db.search_batch(some, k=8)]
    path = stage_db.store.path
    forget(stage_db)
    again = database.connect(path)
    assert again.config.rerank == STAGE.rerank and again.config == STAGE
    after = [[(h.id, h.distance) for h in row] for row in again.search_batch(some, k=8)]
    assert after == before
    forget(again)


def test_a_scorer_of_its_own_module_is_imported_on_first_use(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "my_scorer.py").write_text(
        "from query.search.rerank import register_scorer\n"
        "class Far:\n"
        "    def __init__(self, config):\n"
        "        pass\n"
        "    def score(self, batch):\n"
        "        return -batch.distances\n"
        "register_scorer('test_far', Far)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(rerank.SCORER_MODULES, "test_far", "my_scorer")
    index, x = _index()
    cfg = Config().with_options(rerank="test_far", rerank_candidates=10)
    got, _ = rerank.search(index, x[:2], 10, config=cfg)
    np.testing.assert_array_equal(got, index.search(x[:2], 10)[0][:, ::-1])
