"""A part's surface words at a ladder of scales, and the stored words they are ranked by."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import names_by_id, solids

from query.parts.part_words import PART_REACHES, part_words, stored_words, words_distances
from shapedb.geometry.implicit import Box, Intersection
from shapedb.signature.surface_words import WORDS, surface_points, surface_words

SHAPES = solids()


@pytest.fixture()
def db(solids_db: Any) -> Any:
    return solids_db


def _half_dumbbell() -> Intersection:
    """The dumbbell's half x > 0 (one bell and half the bar)."""
    return Intersection(SHAPES["dumbbell"], Box([1.0, 0, 0], [2.0, 1.2, 1.2]))


def test_the_first_rung_is_the_shapes_own_words() -> None:
    box = SHAPES["box"]
    ladder = part_words(box, 0.05)
    assert ladder.shape == (len(PART_REACHES), WORDS) and ladder.dtype == np.float32
    assert PART_REACHES[0] == 1.0
    np.testing.assert_array_equal(ladder[0], surface_words(surface_points(box, 0.05)))
    assert np.allclose(ladder.sum(axis=1), 1.0, atol=1e-5)
    assert not np.array_equal(ladder[0], ladder[-1])  # a larger whole: other words


def test_words_distances_is_the_least_over_the_ladder() -> None:
    a, b, c = np.eye(3)
    stored = np.stack([a, b, 0.5 * (a + c)])
    # chi-square of one-hot rows: 0 alike, 1 apart; a against (a + c) / 2: 1/3
    np.testing.assert_allclose(words_distances(np.stack([a]), stored), [0.0, 1.0, 1 / 3])
    np.testing.assert_allclose(words_distances(np.stack([c, b]), stored), [1.0, 0.0, 1 / 3])
    assert words_distances(np.stack([a]), np.zeros((0, 3))).shape == (0,)


def test_a_half_finds_its_whole_only_at_the_wholes_scale(db: Any) -> None:
    """Read at its own scale, half a dumbbell's bell and bar look like a snowman's balls;
    read as a part of a larger whole, it is the dumbbell's."""
    names = names_by_id(db)
    ids, rows = stored_words(db)
    assert sorted(names[int(i)] for i in ids) == sorted(SHAPES)
    ladder = part_words(_half_dumbbell(), 0.05)
    nearest_own_scale = names[int(ids[np.argmin(words_distances(ladder[:1], rows))])]
    nearest = names[int(ids[np.argmin(words_distances(ladder, rows))])]
    assert nearest_own_scale != "dumbbell"
    assert nearest == "dumbbell"


def test_stored_words_read_the_store_without_the_cache(
    db: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    import query.search.array_cache as array_cache

    ids, rows = stored_words(db)
    some = ids[[0, 2]]
    monkeypatch.setattr(array_cache, "open_column", lambda *a, **k: None)
    again_ids, again = stored_words(db)
    np.testing.assert_array_equal(again_ids, ids)
    np.testing.assert_array_equal(again, rows)
    picked_ids, picked = stored_words(db, some[::-1])
    np.testing.assert_array_equal(picked_ids, some)
    np.testing.assert_array_equal(picked, rows[[0, 2]])


def test_a_store_without_words_has_none(tmp_path: Path) -> None:
    import shapedb

    store = shapedb.connect(tmp_path / "plain", resolution=32, n_balls=16, rerank="none")
    store.ingest([("box", "box", SHAPES["box"])], workers=1, progress=False)
    ids, rows = stored_words(store)
    assert ids.shape == (0,) and len(rows) == 0


@pytest.mark.parametrize("block", [2, 32768])
def test_nearest_by_words_is_the_exact_ranking_block_by_block(
    db: Any, block: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    import query.parts.part_words as part_words_module
    import query.search.array_cache as array_cache
    from query.parts.part_words import nearest_by_words

    monkeypatch.setattr(part_words_module, "BLOCK", block)
    ids, rows = stored_words(db)
    ladder = part_words(_half_dumbbell(), 0.05)
    d = words_distances(ladder, rows)
    exact = ids[np.lexsort((ids, d))]
    for n in (1, 3, len(ids), len(ids) + 4):
        np.testing.assert_array_equal(nearest_by_words(db, ladder, n), exact[:n])
    allowed = exact[1::2]
    np.testing.assert_array_equal(nearest_by_words(db, ladder, 2, allowed), exact[1::2][:2])
    assert nearest_by_words(db, ladder, 0).shape == (0,)
    monkeypatch.setattr(array_cache, "open_column", lambda *a, **k: None)
    np.testing.assert_array_equal(nearest_by_words(db, ladder, 3), exact[:3])
