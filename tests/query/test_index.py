"""FeatureIndex on synthetic feature matrices: exactness, recall, updates, persistence."""

from __future__ import annotations

import numpy as np
import pytest
from query_helpers import synthetic_features

from query.search.index import FeatureIndex
from shapedb.config.core import KernelConfig
from shapedb.errors import ConfigError, NotFittedError, QueryError, StoreError
from shapedb.signature.kernel import distance, weights

PAPER = KernelConfig(method="paper")  # synthetic vectors are shaped like Eq. 1
W = weights(PAPER)


def brute_force(x: np.ndarray, ids: np.ndarray, q: np.ndarray, k: int):
    """Exact Eq. 2 ranking with shapedb.signature.kernel.distance, ties by ascending id."""
    out_i, out_d = [], []
    for row in np.atleast_2d(q):
        d = distance(row, x.astype(np.float64), PAPER)
        order = np.lexsort((ids, d))[:k]
        out_i.append(ids[order])
        out_d.append(d[order])
    return np.array(out_i), np.array(out_d)


def assert_same_ranking(ids, dist, ref_ids, ref_dist, rtol=1e-9):
    """faiss-contrib style: distances match; ids match except among ties at the cut."""
    np.testing.assert_allclose(dist, ref_dist, rtol=rtol, atol=1e-12)
    for i, d, ri, rd in zip(ids, dist, ref_ids, ref_dist, strict=True):
        cut = rd[-1]
        assert set(i[d < cut - 1e-12]) == set(ri[rd < cut - 1e-12])


def test_flat_equals_brute_force():
    x = synthetic_features(2000, seed=1)
    ids = np.arange(2000) * 5 + 3
    q = synthetic_features(20, seed=2)
    index = FeatureIndex(kind="flat").fit(ids, x, W)
    got_i, got_d = index.search(q, 10)
    assert_same_ranking(got_i, got_d, *brute_force(x, ids, q, 10))
    assert index.kind_ == "flat"


def test_ties_broken_by_id():
    x = np.repeat(synthetic_features(3, seed=3), 4, axis=0)  # 3 groups of 4 equal rows
    ids = np.array([40, 7, 22, 1, 9, 8, 30, 2, 5, 6, 11, 3])
    index = FeatureIndex(kind="flat").fit(ids, x, W)
    got, d = index.search(x[0], 4)
    assert got.tolist() == [[1, 7, 22, 40]] and np.all(d == 0)


def test_hnsw_recall_on_synthetic_data():
    x = synthetic_features(5_000, seed=4)
    ids = np.arange(5_000)
    q = synthetic_features(100, seed=5)
    index = FeatureIndex(kind="hnsw", hnsw_m=16, ef_construction=40).fit(ids, x, W)
    assert index.kind_ == "hnsw"
    got, _ = index.search(q, 10)
    ref, _ = index.exact_search(q, 10)
    recall = np.mean([len(set(a) & set(b)) / 10 for a, b in zip(got, ref, strict=True)])
    assert recall >= 0.99


def test_auto_kind_by_size():
    x = synthetic_features(300, seed=6)
    assert FeatureIndex(hnsw_threshold=1000).fit(np.arange(300), x, W).kind_ == "flat"
    assert FeatureIndex(hnsw_threshold=100).fit(np.arange(300), x, W).kind_ == "hnsw"


@pytest.mark.parametrize("kind", ["flat", "hnsw"])
def test_sync_adds_and_deletes(kind):
    x = synthetic_features(500, seed=7)
    ids = np.arange(500)
    index = FeatureIndex(kind=kind).fit(ids[:400], x[:400], W)
    assert index.sync(ids[:400], x[:400]) == "unchanged"
    assert index.sync(ids, x) == "updated"
    assert index.n_alive == 500
    keep = np.setdiff1d(ids, [0, 1, 2])
    assert index.sync(keep, x[keep]) == ("rebuilt" if kind == "flat" else "updated")
    got, _ = index.search(x[:3], 5)
    assert not set(got.ravel()) & {0, 1, 2}
    assert_same_ranking(*index.search(x[:3], 5), *brute_force(x[keep], keep, x[:3], 5))
    changed = x[keep].copy()
    changed[0] += 0.5
    assert index.sync(keep, changed) == "rebuilt"


def test_filtered_search_is_exact():
    x = synthetic_features(3000, seed=8)
    ids = np.arange(3000)
    q = synthetic_features(3, seed=9)
    index = FeatureIndex(kind="hnsw").fit(ids, x, W)
    allowed = ids[ids % 7 == 0]
    got_i, got_d = index.search(q, 10, allowed=allowed)
    assert set(got_i.ravel()) <= set(allowed)
    assert_same_ranking(got_i, got_d, *brute_force(x[allowed], allowed, q, 10))
    none_i, none_d = index.search(q, 10, allowed=[])
    assert np.all(none_i == -1) and np.all(np.isinf(none_d))


def test_fewer_vectors_than_k_are_padded():
    x = synthetic_features(3, seed=10)
    got, d = FeatureIndex().fit([5, 6, 7], x, W).search(x[1], 5)
    assert got[0, :3].tolist()[0] == 6 and got[0, 3:].tolist() == [-1, -1]
    assert np.isinf(d[0, 3:]).all()


def test_save_and_load_roundtrip(tmp_path):
    x = synthetic_features(800, seed=11)
    index = FeatureIndex(kind="hnsw").fit(np.arange(800), x, W).remove([3])
    index.save(tmp_path / "index", version=7)
    again = FeatureIndex.load(tmp_path / "index")
    assert again.version_ == 7 and again.kind_ == "hnsw" and again.n_alive == 799
    for a, b in zip(index.search(x[:5], 10), again.search(x[:5], 10), strict=True):
        np.testing.assert_array_equal(a, b)
    index.save(tmp_path / "index", version=8)  # older directories are removed
    assert len([p for p in (tmp_path / "index").iterdir() if p.is_dir()]) == 1


def test_errors():
    with pytest.raises(NotFittedError):
        FeatureIndex().search(np.zeros(64), 3)
    with pytest.raises(ConfigError, match="kind"):
        FeatureIndex(kind="ivf")
    index = FeatureIndex().fit([1, 2], synthetic_features(2), W)
    with pytest.raises(QueryError, match="length 64"):
        index.search(np.zeros(10), 3)
    with pytest.raises(QueryError, match="unique"):
        FeatureIndex().fit([1, 1], synthetic_features(2), W)
    with pytest.raises(StoreError):
        FeatureIndex.load("/nonexistent/index")
