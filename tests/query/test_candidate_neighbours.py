"""The stored distance's shared-neighbour term among a query's candidates: exact on a line."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from query.search.candidate_neighbours import candidate_shared, context_distance
from query.search.rerank_lightfield import LightFieldFusion
from query.search.tuning import PRODUCT
from shapedb.config.core import Config

#: The query at 0 and six candidates on a line: a chain near it, a cluster far away.
LINE = np.array([0.1, 0.2, 0.3, 5.0, 5.1, 5.2])


def _shared(x: np.ndarray, own: np.ndarray, k: int, head: int) -> np.ndarray:
    d = np.abs(x)
    return candidate_shared(d, x[:, None], np.zeros(1), np.ones(1), own, k, head)


def test_the_shares_of_a_chain_and_a_far_cluster_are_exact() -> None:
    s = _shared(LINE, np.zeros(6, bool), k=2, head=6)
    # N_2(q) = {0.1, 0.2}; 0.1's nearest are q and 0.2 (all three shared); 0.2's are 0.1
    # and 0.3 (0.1 and itself shared); 0.3's are 0.2 and 0.1; the far cluster shares none.
    assert np.allclose(s, [1.0, 2 / 3, 2 / 3, 0.0, 0.0, 0.0])


def test_the_query_itself_is_in_no_list_and_the_tail_scores_zero() -> None:
    x = np.concatenate([[0.0], LINE])
    own = np.zeros(7, bool)
    own[0] = True
    s = _shared(x, own, k=2, head=3)
    assert s[0] == 0.0
    assert np.allclose(s[1:4], [1.0, 2 / 3, 2 / 3])  # the lists among the head alone
    assert np.all(s[4:] == 0.0)


def test_the_context_distance_is_unitless_and_keeps_the_query_first() -> None:
    d = np.array([0.0, 1.0, 2.0, 4.0])
    own = np.array([True, False, False, False])
    e = context_distance(d, np.array([0.0, 0.0, 1.0, 0.5]), own, 0.5, head=2)
    assert e[0] == -np.inf
    assert np.allclose(e[1:], [0.5, 1.0 - 0.5, 2.0 - 0.25])  # d over the 2nd other's 2.0


def test_the_term_reorders_the_rest_of_a_closed_gate_and_keeps_the_nearest() -> None:
    stage = LightFieldFusion(Config(), tuning=replace(PRODUCT, descriptor_shared_weight=1.0))
    d = np.array([0.0, 1.0, 1.1, 1.2, 1.3])
    own = np.array([True, False, False, False, False])
    ids = np.arange(5)
    context = context_distance(d, np.array([0.0, 0.0, 0.0, 0.0, 1.0]), own, 1.0, head=4)
    plain = stage.fuse(d, d, own, gate=0.0)
    got = stage.fuse(d, d, own, gate=0.0, ids=ids, context=context)
    assert list(np.argsort(plain, kind="stable")) == [0, 1, 2, 3, 4]
    assert list(np.argsort(got, kind="stable")) == [0, 1, 4, 2, 3]
