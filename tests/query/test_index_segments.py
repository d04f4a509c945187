"""The feature index kept in step with its store segment by segment.

Synthetic records (one decomposition, random feature vectors) committed straight to the
store (no commit hooks), so each test opens the index when it wants. Every index opened
after a change must answer as a fresh build over ``Store.features`` does, having read
only the segments it had not read.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG, make_record

import query.search.field_rows as field_rows_module
import query.search.index_segments as segments_module
from query.search.index import INDEX_DIR, VIEW_INDEX_DIR, FeatureIndex, forget, open_index
from shapedb.geometry.implicit import Box
from shapedb.signature.kernel import weights

D = CONFIG.dim


def _features(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).random((n, D)).astype(np.float32)


def _records(feats: np.ndarray, prefix: str, *, views: bool = False) -> list[Any]:
    base = make_record("base", "box", Box((0, 0, 0), (2.0, 1.0, 1.0)))
    return [
        replace(
            base,
            name=f"{prefix}{i}",
            content_hash=f"{prefix}{i}",
            feature=f,
            view_feature=(f[::-1].copy() if views and i % 2 else None),
        )  # fmt: skip
        for i, f in enumerate(feats)
    ]


@pytest.fixture
def feat_db(tmp_path: Path) -> Iterator[Any]:
    """300 shapes in three segments."""
    import query.database as database

    db = database.connect(tmp_path / "s", config=CONFIG)
    for k in range(3):
        db.store.commit(_records(_features(100, k), f"s{k}-", views=True))
    yield db
    forget(db)


@pytest.fixture
def reads(monkeypatch: pytest.MonkeyPatch) -> dict[str, list[str]]:
    """The segment files whose features, and whose ids only, the index reads."""
    seen: dict[str, list[str]] = {"features": [], "ids": []}
    read_features, read_ids = segments_module.read_features, field_rows_module.read_ids

    def features(snap: Any, **kw: Any) -> Any:
        seen["features"] += snap.files
        return read_features(snap, **kw)

    def ids(snap: Any) -> Any:
        seen["ids"] += snap.files
        return read_ids(snap)

    monkeypatch.setattr(segments_module, "read_features", features)
    monkeypatch.setattr(field_rows_module, "read_ids", ids)
    return seen


def _same_as_fresh(db: Any, index: FeatureIndex, *, view: bool = False) -> None:
    """``index`` holds exactly the store's rows and answers as a fresh build does."""
    ids, feats = db.store.features(view=view)
    fresh = FeatureIndex(**index.params).fit(ids, feats, weights(db.config))
    assert sorted(index.ids_[index.alive_].tolist()) == ids.tolist()
    assert np.array_equal(np.asarray(index.features_)[index.lookup(ids)], feats)
    queries = _features(12, 99)
    got, fresh_got = index.search(queries, 10), fresh.search(queries, 10)
    assert got[0].tolist() == fresh_got[0].tolist()
    np.testing.assert_array_equal(got[1], fresh_got[1])


def _files(db: Any) -> list[str]:
    """The store's ``shapes`` segment files, as the manifest names them."""
    return list(field_rows_module.snapshot(db).files)


def test_a_commit_reads_only_its_new_segment(feat_db: Any, reads: dict[str, list[str]]) -> None:
    index = open_index(feat_db, kind="flat")
    assert reads["features"] == _files(feat_db)  # built: everything read once
    before = set(_files(feat_db))
    reads["features"].clear()
    feat_db.store.commit(_records(_features(20, 7), "new-"))
    index = open_index(feat_db)
    assert reads["features"] == [f for f in _files(feat_db) if f not in before]
    assert index.version_ == feat_db.store.version and reads["ids"] == []
    _same_as_fresh(feat_db, index)


@pytest.mark.parametrize("kind", ["flat", "hnsw"])
def test_deletions_and_compaction_give_a_fresh_builds_results(
    feat_db: Any, reads: dict[str, list[str]], kind: str
) -> None:
    open_index(feat_db, kind=kind)
    reads["features"].clear()
    feat_db.store.delete([5, 150, 151])
    index = open_index(feat_db)
    assert reads["features"] == []  # the rewritten segments copy rows: ids only
    assert len(reads["ids"]) == 2 and index.n_alive == 297
    _same_as_fresh(feat_db, index)
    feat_db.store.compact(target_shapes=1000)
    assert len(_files(feat_db)) == 1
    index = open_index(feat_db)
    assert reads["features"] == [] and reads["ids"][-1] == _files(feat_db)[0]
    _same_as_fresh(feat_db, index)


def test_a_shape_stored_again_under_its_id_is_picked_up(feat_db: Any) -> None:
    open_index(feat_db, kind="hnsw")
    new = _features(1, 42)[0]
    again = replace(feat_db.store.get(17), feature=new, content_hash="again")
    feat_db.store.commit([again], delete=[17])
    index = open_index(feat_db)
    np.testing.assert_array_equal(index.features_of(17), new)
    assert index.search(new, 1)[0][0, 0] == 17
    _same_as_fresh(feat_db, index)


def test_a_new_process_loads_the_saved_copy_and_catches_up(
    feat_db: Any, reads: dict[str, list[str]]
) -> None:
    open_index(feat_db)
    pointer = Path(feat_db.store.path) / INDEX_DIR / "current.json"
    saved = json.loads(pointer.read_text())["version"]
    feat_db.store.commit(_records(_features(3, 8), "few-"))  # 1% of the index: not saved
    open_index(feat_db)
    assert json.loads(pointer.read_text())["version"] == saved
    forget(feat_db)  # a new process
    reads["features"].clear()
    index = open_index(feat_db)
    assert reads["features"] == _files(feat_db)[-1:] and index.n_alive == 303
    _same_as_fresh(feat_db, index)
    feat_db.store.commit(_records(_features(30, 9), "many-"))
    open_index(feat_db)
    assert json.loads(pointer.read_text())["version"] == feat_db.store.version


def test_a_saved_copy_behind_deletions_and_a_compaction_catches_up(
    feat_db: Any, reads: dict[str, list[str]], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The saved copy never names the segment a later rewrite copies: read whole."""
    import query.search.index as index_module

    open_index(feat_db, kind="hnsw")  # tombstones (a flat index is rebuilt, so written)
    monkeypatch.setattr(index_module, "_RESAVE_FRACTION", 10.0)  # never written again
    for victim in (5, 6, 250):  # two rewrites of the first segment, one of the last
        feat_db.store.delete([victim])
        open_index(feat_db)
    feat_db.store.compact(target_shapes=1000)
    forget(feat_db)  # a new process: the saved copy names none of the merged segment's
    reads["features"].clear()
    index = open_index(feat_db)
    assert reads["features"] == _files(feat_db) and index.n_alive == 297
    _same_as_fresh(feat_db, index)


def test_auto_turns_to_hnsw_at_its_threshold(feat_db: Any) -> None:
    assert open_index(feat_db, hnsw_threshold=320).kind_ == "flat"
    feat_db.store.commit(_records(_features(30, 10), "grow-"))
    index = open_index(feat_db)
    assert index.kind_ == "hnsw" and index.n_alive == 330
    _same_as_fresh(feat_db, index)


def test_the_view_index_follows_commits(feat_db: Any, reads: dict[str, list[str]]) -> None:
    index = open_index(feat_db, view=True, kind="flat")
    _same_as_fresh(feat_db, index, view=True)
    assert (Path(feat_db.store.path) / VIEW_INDEX_DIR / "current.json").exists()
    reads["features"].clear()
    feat_db.store.commit(_records(_features(10, 11), "view-", views=True), delete=[3])
    index = open_index(feat_db, view=True)
    assert len(reads["features"]) == 1
    _same_as_fresh(feat_db, index, view=True)


def _refuse_to_write(index: FeatureIndex, *args: Any, **kwargs: Any) -> None:
    raise PermissionError(13, "Permission denied")


def test_a_store_the_process_cannot_write_still_searches(
    feat_db: Any, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(FeatureIndex, "save", _refuse_to_write)
    with caplog.at_level("WARNING", logger="query.search.index"):
        open_index(feat_db)
        feat_db.store.commit(_records(_features(40, 12), "ro-"), delete=[1, 2])
        index = open_index(feat_db)
    assert "kept in memory only" in caplog.text
    assert not (Path(feat_db.store.path) / INDEX_DIR).exists()
    _same_as_fresh(feat_db, index)


def test_copies_share_no_rows(feat_db: Any) -> None:
    """An index kept by a search in flight is unchanged by the update of its copy."""
    old = open_index(feat_db)
    kept = np.array(old.features_, copy=True)
    feat_db.store.commit(_records(_features(5, 13), "c-"))
    new = open_index(feat_db)
    assert new is not old and len(old.ids_) == 300 and len(new.ids_) == 305
    np.testing.assert_array_equal(old.features_, kept)
    grown = old.copy().add([10_000], _features(1, 14))  # the old one grows apart
    assert len(grown.features_) == 301 and len(new.features_) == 305
    np.testing.assert_array_equal(new.features_[300:], _features(5, 13))
