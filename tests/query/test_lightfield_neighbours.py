"""The shared-neighbour term of the light field stage on hand-made distances.

Seven shapes whose light field distances are a given matrix (each light field is its
shape's id; :func:`shapedb.signature.lightfield.light_field_distance` patched to read the matrix),
every shape a candidate of every query (K = 7), the gate wide open (g = 1) and the light
field's rank weighted so much that it decides the order; ``light_field_unit`` 1, so the term ranks
by ``dl - beta * S``. With ``k = 2`` the lists ``N_2`` of the matrix :data:`L` are

    0: {1, 4}   1: {5, 6}   2: {4, 0}   3: {4, 0}   4: {2, 3}   5: {6, 1}   6: {5, 1}

so for the stored query 0 (``{0, 1, 4}``) ``S`` is 1/3 for 1, 4, 5 and 6, and 2/3 for 2
and 3 (0 is in their lists: the reciprocal case, and 4 is common). By ``dl`` alone 0
ranks 1, 4, 2, 3, 5, 6; at ``beta`` 1 the term promotes 2 above 4 (1.5 - 2/3 < 1.2 -
1/3); at ``beta`` 3 it would also put 2 before 1, but the first result is kept.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

import shapedb.signature.lightfield
from query.search import rerank
from query.search.index import FeatureIndex
from query.search.lightfield_neighbours import (
    FULL_AT_COMMIT,
    NEIGHBOURS,
    commit_distances,
    keep_first,
    nearest_others,
    shared_scores,
    stage_lists,
)
from query.search.rerank_lightfield import COLUMN, LightFieldFusion
from query.search.tuning import PRODUCT, StageTuning
from shapedb.config.core import Config
from shapedb.errors import ConfigError
from shapedb.signature.kernel import weights

L = np.array(
    [
        [0.0, 1.0, 1.5, 2.1, 1.2, 4.0, 5.0],
        [1.0, 0.0, 3.0, 3.0, 3.0, 0.3, 0.4],
        [1.5, 3.0, 0.0, 3.0, 0.8, 3.0, 3.0],
        [2.1, 3.0, 3.0, 0.0, 0.9, 3.0, 3.0],
        [1.2, 3.0, 0.8, 0.9, 0.0, 3.0, 3.0],
        [4.0, 0.3, 3.0, 3.0, 3.0, 0.0, 0.2],
        [5.0, 0.4, 3.0, 3.0, 3.0, 0.2, 0.0],
    ]
)
LISTS = [[1, 4], [5, 6], [4, 0], [4, 0], [2, 3], [6, 1], [5, 1]]
#: No field vectors (the light field distance alone, in the unit ``light_field_unit``).
STAGE = Config().with_options(rerank="lightfield", fv_enabled=False)
#: The gate wide open and the light field's rank deciding.
OPEN = replace(PRODUCT, candidates=7, weight=1000.0, ceiling=0.0, contrast_floor=0.0, pool=0,
               light_field_unit=1.0, shared_neighbours=2)  # fmt: skip


class Reader:
    """The store's arrays: light fields (ids) and the lists, computed by the product's
    :func:`stage_lists` on first use; counts the lists asked for."""

    def __init__(self, index: FeatureIndex, config: Config, tuning: StageTuning) -> None:
        self.index, self.config, self.tuning = index, config, tuning
        self.lists: np.ndarray | None = None
        self.asked = 0

    def __call__(self, name: str, ids: np.ndarray) -> np.ndarray | None:
        if name == COLUMN:
            return np.asarray(ids, np.float64).reshape(-1, 1, 1, 1)
        if name == NEIGHBOURS:
            self.asked += 1
            if self.lists is None:
                scorer = LightFieldFusion(self.config, tuning=self.tuning)
                self.lists = stage_lists(self.index, self, self.config, scorer)[1]
            return np.asarray(self.lists[ids], np.float64)
        return None


@pytest.fixture
def matrix(monkeypatch: pytest.MonkeyPatch) -> None:
    """``light_field_distance`` reads :data:`L` (light fields are ids)."""

    def distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        qa = np.asarray(a).reshape(len(a), -1)[:, 0].astype(int)
        cb = np.asarray(b).reshape(len(b), -1)[:, 0].astype(int)
        return L[np.ix_(qa, cb)]

    monkeypatch.setattr(shapedb.signature.lightfield, "light_field_distance", distance)


def _store(beta: float, **options: Any) -> tuple[LightFieldFusion, FeatureIndex, Reader]:
    """Stored vectors in id order from every shape (no ties), the stage at ``beta``."""
    stage = LightFieldFusion(STAGE, tuning=replace(OPEN, shared_weight=beta, **options))
    x = np.zeros((7, STAGE.dim), np.float32)
    x[:, 0] = np.arange(7) / 10.0
    index = FeatureIndex(kind="flat").fit(np.arange(7), x, weights(STAGE))
    return stage, index, Reader(index, STAGE, stage.tuning)


def _order(beta: float, query: int = 0, *, outside: bool = False, **options: Any) -> list[int]:
    stage, index, reader = _store(beta, **options)
    x = np.asarray(index.features_, np.float64)[[query]]
    got, _ = rerank.search(
        index, x, 7, config=STAGE, query_ids=np.array([-1 if outside else query]), scorer=stage,
        arrays=reader, query_arrays={COLUMN: np.full((1, 1, 1, 1), float(query))},
    )  # fmt: skip
    return [int(i) for i in got[0]]


def test_the_lists_are_each_shape_s_nearest_others_among_its_candidates(matrix: None) -> None:
    stage, index, reader = _store(1.0)
    ids, lists = stage_lists(index, reader, STAGE, stage)
    assert ids.tolist() == list(range(7)) and lists.tolist() == LISTS
    few_ids, few = stage_lists(index, reader, STAGE, stage, np.array([9, 3]))
    assert few_ids.tolist() == [3] and few.tolist() == [LISTS[3]]  # 9 is not stored


def test_the_term_promotes_the_shape_that_shares_the_query_s_neighbours(matrix: None) -> None:
    assert _order(0.0) == [0, 1, 4, 2, 3, 5, 6]  # by dl alone
    assert _order(1.0) == [0, 1, 2, 4, 3, 5, 6]
    assert _order(1.0, shared_neighbours=0) == [0, 1, 4, 2, 3, 5, 6]  # k 0: off


def test_the_first_result_is_kept(matrix: None) -> None:
    # at beta 3: 2 (1.5 - 2) and 3 (2.1 - 2) come before 1 (1.0 - 1); 1 stays first
    assert _order(3.0) == [0, 1, 2, 3, 4, 5, 6]
    for q in range(7):
        for beta in (0.5, 1.0, 3.0, 100.0):
            plain, term = _order(0.0, q), _order(beta, q)
            assert term[0] == q and term[1] == plain[1], (q, beta)


def test_an_outside_copy_differs_from_the_stored_id_by_the_reciprocal_term_only(
    matrix: None,
) -> None:
    # the outside copy of 0 (dl 0 to it: its own) has the same N_2 = {1, 4} but matches no
    # stored id: 2 and 3 lose the 1/3 of 0 in their lists, and 2 is not promoted
    assert _order(1.0, outside=True) == [0, 1, 4, 2, 3, 5, 6]
    stage, index, reader = _store(1.0)
    _, lists = stage_lists(index, reader, STAGE, stage)
    ids = np.arange(7)
    own = ids == 0
    mine = nearest_others(L[0], own, ids, 2)
    stored = shared_scores(mine, 0, ids, lists, 2)
    outside = shared_scores(mine, -1, ids, lists, 2)
    assert np.array_equal(stored * 3, [3, 1, 2, 2, 1, 1, 1])
    reciprocal = np.array([0 in {int(x), *lists[x].tolist()} for x in ids])
    assert np.array_equal((stored - outside) * 3, reciprocal.astype(float))


def test_a_closed_gate_leaves_the_term_out_and_reads_no_lists(matrix: None) -> None:
    # a contrast floor of 1 shuts every gate: the stored distance's order (its own term
    # among the candidates off), no lists read
    stage, index, reader = _store(3.0, contrast_floor=1.0, descriptor_shared_weight=0.0)
    x = np.asarray(index.features_, np.float64)
    got, _ = rerank.search(
        index, x, 7, config=STAGE, query_ids=np.arange(7), arrays=reader, scorer=stage
    )
    assert np.array_equal(got, index.search(x, 7)[0])
    assert reader.asked == 0 and reader.lists is None


def test_the_query_s_neighbours_skip_its_own_and_keep_the_list_order_on_ties() -> None:
    dl = np.array([0.0, 2.0, 1.0, 1.0, 0.5])
    own = np.array([True, False, False, False, False])
    ids = np.array([7, 3, 9, 4, 8])
    assert nearest_others(dl, own, ids, 3).tolist() == [8, 9, 4]  # 9 before 4: list order
    assert nearest_others(dl, own, ids, 6).tolist() == [8, 9, 4, 3, -1, -1]
    lists = np.array([[-1, -1], [7, 8], [3, -1], [-1, -1], [9, 4]])
    # stored query 7: {7, 8, 9}; candidates {x} ∪ N_2(x)
    got = shared_scores(np.array([8, 9]), 7, ids, lists, 2) * 3
    assert got.tolist() == [1.0, 2.0, 1.0, 0.0, 2.0]
    got = shared_scores(np.array([8, 9]), -1, ids, lists, 2) * 3  # outside: 7 matches nothing
    assert got.tolist() == [0.0, 1.0, 1.0, 0.0, 2.0]


def test_keep_first_moves_only_the_first_other_candidate() -> None:
    own = np.array([True, False, False, False])
    ids = np.array([5, 1, 2, 3])
    plain = np.array([0.0, 0.1, 0.2, 0.3])  # 1 first among the others
    term = np.array([0.0, 0.25, 0.05, 0.2])  # the term: 2, 3, 1
    got = keep_first(plain, term, own, ids)
    assert np.lexsort((ids, got)).tolist() == [0, 1, 2, 3]  # 5 (own), 1, then 2, 3
    assert got[[0, 2, 3]].tolist() == term[[0, 2, 3]].tolist()
    tied = np.array([0.0, 0.25, 0.05, 0.05])  # 2 and 3 tied; 1 takes their value
    got = keep_first(np.array([0.0, 0.1, 0.2, 0.3]), tied, own, np.array([5, 3, 1, 2]))
    assert np.lexsort((np.array([5, 3, 1, 2]), got)).tolist() == [0, 1, 2, 3]
    assert np.array_equal(keep_first(plain, plain + 1.0, own, ids), plain + 1.0)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"shared_neighbours": -1}, "shared_neighbours"),
        ({"shared_neighbours": 2.0}, "shared_neighbours"),
        ({"shared_weight": -0.1}, "shared_weight"),
        ({"shared_weight": float("nan")}, "shared_weight"),
        ({"shared_weight": True}, "shared_weight"),
    ],
)
def test_bad_values_name_the_number(options: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        replace(PRODUCT, **options)


def test_the_product_turns_the_term_on() -> None:
    assert (PRODUCT.shared_neighbours, PRODUCT.shared_weight) == (6, 1.6)
    assert PRODUCT.shares_neighbours and not replace(PRODUCT, shared_weight=0.0).shares_neighbours


def test_a_commit_recomputes_the_lists_within_a_budget_of_stage_distances() -> None:
    product = Config()  # K 100 and K2 200: a list reaches 300 shapes, or the whole store
    assert commit_distances(100, product) == 100 * 100 == FULL_AT_COMMIT
    assert commit_distances(101, product) > FULL_AT_COMMIT
    assert commit_distances(400, product) == 400 * 300
    assert commit_distances(400, product.with_options(fv_enabled=False)) == 400 * 100
