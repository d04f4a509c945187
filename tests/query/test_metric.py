"""query.learn.metric: block weights learned on labels, and search / evaluate with them."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import pytest

from query.evaluate import evaluate, retrieval_scores
from query.learn.metric import LearnedMetric, as_metric, block_layout, fit_metric
from shapedb.errors import ConfigError, LoadError, QueryError

BLOCKS = (("signal", 6), ("noise", 6))


def _data(
    n_per: int = 12, classes: int = 4, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features of two blocks: ``signal`` separates the classes, ``noise`` does not.

    Returns features (n, 12), labels (n,) and "views" (n, 12): the same shapes with
    a little noise on the signal block.
    """
    rng = np.random.default_rng(seed)
    centres = rng.normal(0, 1.0, (classes, 6))
    y = np.repeat(np.arange(classes), n_per)
    signal = centres[y] + 0.3 * rng.normal(size=(len(y), 6))
    noise = 1.0 * rng.normal(size=(len(y), 6))
    x = np.concatenate([signal, noise], 1)
    views = x.copy()
    views[:, :6] += 0.1 * rng.normal(size=(len(y), 6))
    return x, y.astype(str), views


def _nn(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    d = np.abs(x[:, None] - x[None]) @ w
    return float(retrieval_scores(-d, y).nn)


def test_the_informative_block_gains_weight_and_held_out_retrieval_improves() -> None:
    x, y, _ = _data(seed=1)
    m = fit_metric(x, y, blocks=BLOCKS, fingerprint="f")
    assert m.learned and m.reg is not None
    w_signal, w_noise = m.weights
    assert w_signal > 2 * w_noise
    assert m.dim == 12 and m.dim_weights().shape == (12,)
    assert np.all(m.dim_weights()[:6] == w_signal) and np.all(m.dim_weights()[6:] == w_noise)
    assert m.cv["default"]["gain"] == 0.0
    assert m.cv[f"{m.reg:g}"]["gain"] < -2 * m.cv[f"{m.reg:g}"]["se"]
    # calibration kept: shapes of different classes as far apart (median) as before
    d = np.abs(x[:, None] - x[None])
    other = y[:, None] != y[None, :]
    assert np.median(d[other] @ m.dim_weights()) == pytest.approx(np.median(d[other].sum(-1)))
    xt, yt, _ = _data(seed=2)  # other shapes of the same kind
    assert _nn(xt, yt, m.dim_weights()) > _nn(xt, yt, np.ones(12)) + 0.05


def test_labels_without_signal_keep_the_default() -> None:
    x, _, _ = _data(seed=3)
    y = np.random.default_rng(4).permutation(np.repeat(np.arange(4), 12)).astype(str)
    m = fit_metric(x, y, blocks=BLOCKS)
    assert not m.learned and m.weights == (1.0, 1.0)


def test_views_teach_what_a_sparse_sample_keeps() -> None:
    # both blocks separate the classes, but the views blur the first: fitted with
    # the views (extra queries, compared with the other shapes' views), the second
    # block must gain against the first
    rng = np.random.default_rng(5)
    y = np.repeat(np.arange(4), 12)
    a = rng.normal(0, 1.0, (4, 6))[y] + 0.3 * rng.normal(size=(48, 6))
    b = rng.normal(0, 1.0, (4, 6))[y] + 0.3 * rng.normal(size=(48, 6))
    x = np.concatenate([a, b], 1)
    views = np.concatenate([a + 1.5 * rng.normal(size=a.shape), b], 1)
    blocks = (("blurred", 6), ("kept", 6))
    alone = fit_metric(x, y.astype(str), blocks=blocks)
    both = fit_metric(x, y.astype(str), blocks=blocks, views=views)
    assert both.learned
    assert both.weights[1] / both.weights[0] > 1.5 * alone.weights[1] / alone.weights[0]
    assert both.weights[1] > both.weights[0]
    assert both.n_shapes == 48 and both.n_extra == 48 and alone.n_extra == 0


def test_pairs_with_a_sparse_side_compare_views() -> None:
    # dense shapes carry the classes in block a of their own features, views carry
    # them in block b; half the shapes are sparse (their feature is their view).
    # Compared as a views store compares them, block b is what separates.
    rng = np.random.default_rng(8)
    y = np.repeat(np.arange(4), 12)
    ca, cb = rng.normal(size=(4, 6)), rng.normal(size=(4, 6))
    own = np.concatenate([ca[y] + 0.3 * rng.normal(size=(48, 6)), rng.normal(size=(48, 6))], 1)
    views = np.concatenate([rng.normal(size=(48, 6)), cb[y] + 0.3 * rng.normal(size=(48, 6))], 1)
    sparse = np.arange(48) % 2 == 1
    x = np.where(sparse[:, None], views, own)
    blocks = (("a", 6), ("b", 6))
    m = fit_metric(x, y.astype(str), blocks=blocks, views=views, sparse=sparse)
    assert m.learned and m.weights[1] > 2 * m.weights[0]
    assert m.n_extra == 24  # the dense shapes' views


def test_large_inputs_are_sampled_by_class() -> None:
    x, y, views = _data(n_per=30, seed=6)
    m = fit_metric(x, y, blocks=BLOCKS, max_shapes=40, views=views)
    assert m.n_shapes == 40 and m.n_classes == 4 and m.n_extra == 40


def test_bad_inputs_are_named() -> None:
    x, y, _ = _data()
    with pytest.raises(QueryError, match="two classes"):
        fit_metric(x, np.zeros(len(x)).astype(str), blocks=BLOCKS)
    with pytest.raises(QueryError, match="features of shape"):
        fit_metric(x[:, :5], y, blocks=BLOCKS)
    bad = x.copy()
    bad[0, 0] = np.nan
    with pytest.raises(QueryError, match="NaN"):
        fit_metric(bad, y, blocks=BLOCKS)
    with pytest.raises(QueryError, match="views"):
        fit_metric(x, y, blocks=BLOCKS, views=x[:, :3])
    with pytest.raises(QueryError, match="sparse"):
        fit_metric(x, y, blocks=BLOCKS, sparse=[True])
    with pytest.raises(ConfigError, match="folds"):
        fit_metric(x, y, blocks=BLOCKS, folds=1)
    with pytest.raises(ConfigError, match="positive"):
        LearnedMetric(blocks=BLOCKS, weights=(1.0, 0.0), fingerprint="f")
    with pytest.raises(QueryError, match="LearnedMetric"):
        as_metric(3)


def test_save_and_load(tmp_path: Any) -> None:
    x, y, _ = _data(seed=1)
    m = fit_metric(x, y, blocks=BLOCKS, fingerprint="abc", label="kind")
    path = m.save(tmp_path / "sub" / "m.json")
    back = LearnedMetric.load(path)
    assert back == m and as_metric(path) == m and as_metric(str(path)) == m
    (tmp_path / "garbage.json").write_text("{not json")
    with pytest.raises(LoadError, match="garbage.json"):
        LearnedMetric.load(tmp_path / "garbage.json")
    (tmp_path / "other.json").write_text(json.dumps({"format": "something else"}))
    with pytest.raises(LoadError, match="not a shapedb metric"):
        LearnedMetric.load(tmp_path / "other.json")
    (tmp_path / "broken.json").write_text(json.dumps({"format": "shapedb-metric/1"}))
    with pytest.raises(LoadError, match="malformed"):
        LearnedMetric.load(tmp_path / "broken.json")


def _handmade(db: Any, first: float = 10.0) -> LearnedMetric:
    """A metric weighing the first block ``first`` times, the others once."""
    blocks = block_layout(db.config)
    weights = (first,) + (1.0,) * (len(blocks) - 1)
    return LearnedMetric(blocks=blocks, weights=weights, fingerprint=db.config.fingerprint, reg=0.1)


def test_store_metric_search_and_evaluate(tmp_db: Any) -> None:
    fitted = tmp_db.fit_metric(label="label", folds=2)
    assert isinstance(fitted, LearnedMetric)
    assert fitted.fingerprint == tmp_db.config.fingerprint
    assert fitted.dim == tmp_db.store.dim and fitted.n_shapes == len(tmp_db.store)
    sampled = tmp_db.fit_metric(label="label", folds=2, max_shapes=8)  # 2 of each class
    assert sampled.n_shapes == 8 and sampled.n_classes == 4
    ids, x = tmp_db.store.features()
    x = x.astype(np.float64)
    m = _handmade(tmp_db)
    w = m.dim_weights()
    # search: exact weighted L1, ranked like a brute-force scan
    for sid in ids[:4]:
        hits = tmp_db.search(int(sid), k=5, metric=m)
        d = np.abs(x - x[ids == sid][0]) @ w
        order = np.lexsort((ids, d))[:5]
        assert [h.id for h in hits] == ids[order].tolist()
        assert [h.distance for h in hits] == pytest.approx(d[order].tolist(), rel=1e-5)
    batch = tmp_db.search_batch([int(i) for i in ids[:4]], k=5, metric=m)
    assert [[h.id for h in row] for row in batch] == [
        [h.id for h in tmp_db.search(int(i), k=5, metric=m)] for i in ids[:4]
    ]
    # the identity is the default
    identity = LearnedMetric(
        blocks=m.blocks, weights=(1.0,) * len(m.blocks), fingerprint=m.fingerprint
    )
    assert tmp_db.search(int(ids[0]), k=5, metric=identity) == tmp_db.search(int(ids[0]), k=5)
    # evaluate: the same measures as the weighted distance matrix gives
    labels = tmp_db.store.shapes(["label"]).column("label").to_pylist()
    d = np.abs(x[:, None] - x[None]) @ w
    ref = retrieval_scores(-d, labels, ids=ids).to_dict()
    got = evaluate(tmp_db, metric=m).to_dict()
    for key in ("nn", "first_tier", "second_tier", "dcg"):
        assert got[key] == pytest.approx(ref[key], abs=1e-12)
    assert tmp_db.evaluate(metric=identity).to_dict() == tmp_db.evaluate().to_dict()


def test_metric_index_is_kept_on_disk_and_follows_commits(
    tmp_db: Any, example_records: list[Any]
) -> None:
    from query.search.index import forget, open_index

    m = _handmade(tmp_db)
    sid = int(tmp_db.store.features()[0][0])
    first = tmp_db.search(sid, k=3, metric=m)
    directory = tmp_db.path / f"index_metric_{m.digest}"
    assert (directory / "current.json").exists()
    np.testing.assert_allclose(
        open_index(tmp_db, metric=m).weights_, m.dim_weights() * open_index(tmp_db).weights_
    )
    forget(tmp_db)  # a new process: loaded from disk, same answer
    assert tmp_db.search(sid, k=3, metric=m) == first
    # a commit adds a shape: the metric's index catches up at its next search
    rec = example_records[0]
    tmp_db.commit([dataclasses.replace(rec, name="copy-of-" + rec.name, content_hash="f" * 64)])
    new_id = int(tmp_db.get("copy-of-" + rec.name).id)
    hits = tmp_db.search(rec.name, k=2, metric=m)
    assert {h.id for h in hits} == {int(tmp_db.get(rec.name).id), new_id}
    assert all(h.distance == pytest.approx(0.0, abs=1e-6) for h in hits)
    assert open_index(tmp_db, metric=m).version_ == tmp_db.store.version


def test_a_metric_of_another_store_is_refused(tmp_db: Any) -> None:
    other = LearnedMetric(
        blocks=block_layout(tmp_db.config),
        weights=(1.0,) * len(block_layout(tmp_db.config)),
        fingerprint="0" * 16,
        reg=0.1,
    )
    with pytest.raises(ConfigError, match="another configuration"):
        tmp_db.search(int(tmp_db.store.features()[0][0]), metric=other)
    with pytest.raises(ConfigError, match="another configuration"):
        tmp_db.evaluate(metric=other)
    with pytest.raises(QueryError, match="callable"):
        tmp_db.evaluate(metric=_handmade(tmp_db), method=lambda f: -f @ f.T)
    with pytest.raises(QueryError, match="metric"):
        tmp_db.search(int(tmp_db.store.features()[0][0]), metric=object())


def test_block_layouts_cover_the_feature_vector() -> None:
    from shapedb.config.core import Config

    paper = Config().with_options(method="paper", n_r=10)
    for cfg in (Config(), Config().with_options(descriptor=3), paper):
        layout = block_layout(cfg)
        assert sum(n for _, n in layout) == cfg.dim
    assert block_layout(paper) == (("p0", 10), ("walk", 10))
    assert [b for b, _ in block_layout(Config())][-2:] == ["geodesic", "geodesic_mean"]
