"""The exact re-ranking stage (query.search.rerank, query.search.stage): a scorer object the
caller passes, the store's stage, search and evaluation ranking alike."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from query.search import rerank
from query.search.index import FeatureIndex
from query.search.rerank_lightfield import LightFieldFusion
from query.search.stage import scorer_for
from query.search.tuning import PRODUCT, StageTuning
from shapedb.config.core import Config
from shapedb.errors import ConfigError


class _Stored:
    """The identity scorer: the stored distance itself, over the first ``K`` candidates."""

    def __init__(self, candidates: int) -> None:
        self.tuning = dataclasses.replace(PRODUCT, candidates=candidates)

    def score(self, batch: rerank.Candidates) -> np.ndarray:
        return batch.distances


class _Far(_Stored):
    """A scorer of a user's own: the farthest candidate first."""

    def score(self, batch: rerank.Candidates) -> np.ndarray:
        return -batch.distances


def _index(n: int = 80, d: int = 24, seed: int = 0) -> tuple[FeatureIndex, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.random((n, d)).astype(np.float32)
    x[5] = x[6]  # a tie, broken by id
    ids = np.arange(100, 100 + n)
    return FeatureIndex(kind="flat").fit(ids, x, np.ones(d)), x.astype(np.float64)


@pytest.mark.parametrize("k", [1, 7, 30, 80])
def test_the_identity_scorer_returns_the_index_order(k: int) -> None:
    index, x = _index()
    got = rerank.search(
        index, x[:20], k, config=Config(), query_ids=np.arange(100, 120), scorer=_Stored(12)
    )
    want = index.search(x[:20], k)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])


def test_no_scorer_is_the_plain_search_and_the_store_names_its_stage() -> None:
    index, x = _index()
    got = rerank.search(index, x[:3], 5, config=Config())
    np.testing.assert_array_equal(got[0], index.search(x[:3], 5)[0])
    assert scorer_for(Config().with_options(rerank="none")) is None
    stage = scorer_for(Config())
    assert isinstance(stage, LightFieldFusion) and stage.tuning == PRODUCT
    with pytest.raises(ConfigError, match="rerank"):
        Config().with_options(rerank="nosuch")
    with pytest.raises(ConfigError, match="candidates"):
        StageTuning(candidates=0)


def test_a_scorer_of_a_users_own_is_passed_as_an_object() -> None:
    index, x = _index()
    got, _ = rerank.search(index, x[:2], 10, config=Config(), scorer=_Far(10))
    np.testing.assert_array_equal(got, index.search(x[:2], 10)[0][:, ::-1])
