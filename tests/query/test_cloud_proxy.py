"""The proxy of a query: the candidate nearest to it by light field distance."""

from __future__ import annotations

import numpy as np

from query.search.cloud_proxy import proxies
from query.search.rerank_lightfield import COLUMN


def _fields(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).random((n, 2, 10, 6))


def test_the_candidate_with_the_same_light_fields_is_the_proxy() -> None:
    stored = _fields(6)
    arrays = lambda name, ids: stored[ids] if name == COLUMN else None  # noqa: E731
    queries = stored[[4, 1]] + 1e-3
    got = proxies(queries, np.array([[0, 1, 2, 4, -1], [1, 3, 5, -1, -1]]), arrays)
    assert got.tolist() == [4, 1]


def test_no_light_fields_or_no_candidates_give_no_proxy() -> None:
    stored = _fields(4)
    stored[2] = np.nan  # a record written without light fields
    arrays = lambda name, ids: stored[ids] if name == COLUMN else None  # noqa: E731
    queries = np.stack([stored[0], np.full_like(stored[0], np.nan), stored[1], stored[3]])
    cand = np.array([[0, 1], [0, 1], [-1, -1], [2, 3]])
    assert proxies(queries, cand, arrays).tolist() == [0, -1, -1, 3]
    assert proxies(queries[:1], cand[:1], lambda name, ids: None).tolist() == [-1]
