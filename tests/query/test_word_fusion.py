"""The surface words in the light field stage: the fusion, the gate, and a store's searches."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG, shape_pairs

from query.search.rerank_lightfield import stored_arrays
from query.search.tuning import PRODUCT, StageTuning, tuned
from query.search.word_fusion import WORDS_COLUMN, fuse_words
from shapedb.config.surface_words import SurfaceWordsConfig
from shapedb.errors import ConfigError
from shapedb.signature.surface_words import WORDS


def test_words_reorder_the_stage_by_reciprocal_ranks() -> None:
    """Stage order a, b, c, d; the words put d first. With o = 4 and v = 0.75 the fused
    similarity of d is 1/7 + 0.75/4 = 0.330 against b's 1/5 + 0.75/6 = 0.325 and c's
    1/6 + 0.75/5 = 0.317: d rises to second, a (first by both but d's words) stays first."""
    tuning = replace(PRODUCT, word_offset=4.0, word_weight=0.75)
    stage = np.array([0.0, 0.1, 0.2, 0.3])
    words = np.array([0.2, 0.5, 0.6, 0.1])
    fused = fuse_words(stage, words, 1.0, tuning)
    assert list(np.argsort(fused, kind="stable")) == [0, 3, 1, 2]
    expected = (1 + 0.75) / 4 - np.array(
        [1 / 4 + 0.75 / 5, 1 / 5 + 0.75 / 6, 1 / 6 + 0.75 / 7, 1 / 7 + 0.75 / 4]
    )
    np.testing.assert_allclose(fused, expected)
    assert (fused >= 0).all()


def test_a_shut_gate_or_no_weight_keeps_the_stage() -> None:
    stage = np.array([0.0, 0.1, 0.2, 0.3])
    words = np.array([0.9, 0.5, 0.6, 0.1])
    np.testing.assert_array_equal(fuse_words(stage, words, 0.0, PRODUCT), stage)
    off = replace(PRODUCT, word_weight=0.0)
    np.testing.assert_array_equal(fuse_words(stage, words, 1.0, off), stage)


def test_the_word_offset_must_be_positive() -> None:
    with pytest.raises(ConfigError, match="word_offset"):
        StageTuning(word_offset=0.0)
    with pytest.raises(ConfigError, match="word_weight"):
        StageTuning(word_weight=-1.0)


#: The stage of the small analytic stores with its gates open, so that the words count.
OPEN = replace(PRODUCT, candidates=7, ceiling=0.0, contrast_floor=0.0, pool=0)


@pytest.fixture(autouse=True)
def _stage() -> Iterator[None]:
    with tuned(OPEN):
        yield


def _store(path: Any, *, words: bool = True) -> Any:
    import query.database as database

    config = replace(CONFIG, surface_words=SurfaceWordsConfig(enabled=words))
    db = database.connect(path, config=config)
    db.ingest([(n, n.split("_")[0], g) for n, g in shape_pairs().items()], workers=1)
    return db


@pytest.fixture(scope="module")
def stores(
    tmp_path_factory: pytest.TempPathFactory, forget: Callable[[Any], None]
) -> Iterator[tuple[Any, Any]]:
    """The seven shapes in a default store (words) and in one without words."""
    with tuned(OPEN):
        words = _store(tmp_path_factory.mktemp("words") / "store")
        plain = _store(tmp_path_factory.mktemp("plain") / "store", words=False)
    yield words, plain
    forget(words)
    forget(plain)


def _ranked(db: Any) -> list[list[tuple[str, float]]]:
    names = sorted(n for n in shape_pairs())
    return [[(h.name, h.similarity) for h in db.search(n, k=7)] for n in names]


def test_a_default_store_keeps_and_reads_its_words(stores: tuple[Any, Any]) -> None:
    words, plain = stores
    assert words.config.stores_surface_words and not plain.config.stores_surface_words
    ids, _ = words.store.features()
    got = stored_arrays(words)(WORDS_COLUMN, ids)
    assert got is not None and got.shape == (7, WORDS)
    np.testing.assert_allclose(got.sum(axis=1), 1.0, atol=1e-5)
    assert stored_arrays(plain)(WORDS_COLUMN, ids) is None
    timings = words.sql("SELECT timings FROM shapes").to_pylist()
    assert all("surface_words" in dict(r["timings"]) for r in timings)


def test_without_their_weight_the_words_change_nothing(stores: tuple[Any, Any]) -> None:
    """The words' store searched with the words' weight 0 ranks exactly as the store
    without words: the records differ by the column alone."""
    words, plain = stores
    with tuned(replace(OPEN, word_weight=0.0)):
        off = _ranked(words)
    assert off == _ranked(plain)


def test_the_words_move_the_ranks_of_a_store(stores: tuple[Any, Any]) -> None:
    """With their weight the same searches differ: the fusion is wired to the store."""
    words, plain = stores
    assert _ranked(words) != _ranked(plain)


def test_an_outside_query_ranks_as_its_stored_copy(stores: tuple[Any, Any]) -> None:
    """A geometry query computes its own words: it ranks as the stored shape does."""
    words, _ = stores
    for name, geometry in shape_pairs().items():
        stored = [h.name for h in words.search(name, k=7)]
        outside = [h.name for h in words.search(geometry, k=7)]
        assert outside == stored, name


def test_an_older_store_without_words_searches_as_before(stores: tuple[Any, Any]) -> None:
    """Records without words (a store written before them) keep the stage's order."""
    _, plain = stores
    ids, _ = plain.store.features()
    assert all(plain.store.get(int(i)).surface_words is None for i in ids)
    assert len(plain.search(int(ids[0]), k=3)) == 3
