"""The memory-mapped array cache gives the rows the store gives, across commits and damage."""

from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from query.search import array_cache, rerank_lightfield
from query.search.array_cache import CACHE_DIR, open_column
from query.search.field_fusion import FIELD
from query.search.rerank_lightfield import COLUMN, StoredArrays, stored_arrays

PINNED = Path(__file__).resolve().parents[1] / "data" / "pinned" / "store"
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture()
def db(tmp_path: Path, forget: Callable[[Any], None]) -> Iterator[Any]:
    """A copy of the pinned store (45 shapes with light fields and field vectors) plus
    copies of 10 of them under new names, 3 without light fields."""
    import query.database as database

    shutil.copytree(PINNED, tmp_path / "store")
    db = database.connect(tmp_path / "store", create=False)
    db.commit(_copies(db, range(1, 11), null={2, 5, 9}))
    yield db
    forget(db)


def _copies(db: Any, ids: Any, *, null: set[int] = frozenset(), tag: str = "copy") -> list[Any]:
    out = []
    for i in ids:
        r = db.store.get(int(i))
        lf = None if i in null else r.light_field[:, ::-1].copy()  # other rows than the source's
        out.append(replace(r, id=None, name=f"{tag}_{r.name}", light_field=lf))
    return out


def _store_read(db: Any, column: str, ids: Any) -> Any:
    """The rows as read from the store itself (the reader without a cache)."""
    reader = StoredArrays(db)
    reader._mapped[column] = None  # noqa: SLF001 - the reader's fallback, for reference
    return reader(column, np.asarray(ids, np.int64))


def _asked(db: Any) -> Any:
    ids = db.store.ids()
    return np.concatenate([ids[::-1], [0, int(ids.max()) + 7], ids[:3]])  # unknown ids, repeats


def _same(db: Any) -> None:
    for column in (COLUMN, FIELD):
        want = _store_read(db, column, _asked(db))
        got = stored_arrays(db)(column, _asked(db))
        np.testing.assert_array_equal(got, want)  # NaN rows where the store has none


def test_the_cache_gives_the_store_rows_and_is_written_beside_it(db: Any) -> None:
    _same(db)
    got = stored_arrays(db)(COLUMN, _asked(db))
    assert np.isnan(got).all(axis=(1, 2, 3)).sum() == 3 + 2  # the null copies, unknown ids
    for column in (COLUMN, FIELD):
        cache = open_column(db, column)
        assert cache is not None and cache.version == db.store.version
        assert isinstance(cache.chunks[0], np.memmap)
        assert (db.store.path / CACHE_DIR / column / "current.json").exists()
    assert stored_arrays(db)(COLUMN, np.array([0, 10_000])) is None


def test_a_commit_updates_the_cache_in_place_of_a_rebuild(
    db: Any, forget: Callable[[Any], None], monkeypatch: pytest.MonkeyPatch
) -> None:
    stored_arrays(db)(COLUMN, _asked(db))
    stored_arrays(db)(FIELD, _asked(db))
    first = _chunk_inode(db)
    monkeypatch.setattr(array_cache, "build", _no_build)
    ids = db.store.ids()
    rebuilt = replace(db.store.get(int(ids[3])), light_field=None)  # same id, new record
    db.commit(delete=[int(ids[0]), int(ids[-1]), int(ids[-3])])  # a null row among them
    db.commit([*_copies(db, ids[10:14], null={int(ids[11])}, tag="later"), rebuilt],
              delete=[int(ids[3])])  # fmt: skip
    for column in (COLUMN, FIELD):  # the commits updated the caches on disk
        pointer = db.store.path / CACHE_DIR / column / "current.json"
        assert json.loads(pointer.read_text())["version"] == db.store.version
    cache = open_column(db, COLUMN)
    assert cache is not None and int(ids[0]) not in set(cache.ids.tolist())
    _same(db)
    assert stored_arrays(db)(COLUMN, ids[3:4]) is None  # its new record has none
    assert _chunk_inode(db) == first  # linked into the new version, not rewritten
    db.store.compact()  # every row copied into one segment: only re-pointed
    _same(db)
    forget(db)  # as a new process: read back from disk
    _same(db)


def _chunk_inode(db: Any) -> int:
    root = db.store.path / CACHE_DIR / COLUMN
    meta = json.loads((root / "current.json").read_text())
    return (root / meta["dir"] / "chunk-0.npy").stat().st_ino


def _no_build(*args: Any) -> None:
    raise AssertionError("the cache was rebuilt")


def test_a_fresh_process_reads_the_cache_from_disk(db: Any) -> None:
    want = stored_arrays(db)(COLUMN, db.store.ids())
    script = (
        "import sys, json, numpy as np, shapedb\n"
        "from query.search import array_cache\n"
        "array_cache.build = None  # reading only\n"
        "from query.search.rerank_lightfield import stored_arrays\n"
        "db = shapedb.connect(sys.argv[1], create=False)\n"
        "got = stored_arrays(db)('light_field', db.store.ids())\n"
        "print(json.dumps([float(np.nansum(got)), int(np.isnan(got).sum())]))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", script, str(db.store.path)], env=env,
                         capture_output=True, text=True, check=True)  # fmt: skip
    assert json.loads(out.stdout) == [float(np.nansum(want)), int(np.isnan(want).sum())]


def test_a_read_only_store_still_reads_its_rows(
    db: Any,
    forget: Callable[[Any], None],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    def refuse(*args: Any, **kwargs: Any) -> None:
        raise PermissionError(13, "Permission denied")

    stored_arrays(db)(COLUMN, _asked(db))  # a cache on disk, then the store turns read-only
    monkeypatch.setattr(array_cache, "save_version", refuse)
    monkeypatch.setattr(array_cache, "_WARNED", set())
    db.commit(_copies(db, range(20, 24), tag="ro"))
    with caplog.at_level(logging.WARNING, logger="query.search.array_cache"):
        _same(db)  # the update kept in memory
        assert "array cache of light_field kept in memory only" in caplog.text
        shutil.rmtree(db.store.path / CACHE_DIR)
        forget(db)
        _same(db)  # no cache and none can be written: the store's own read
        assert open_column(db, COLUMN) is None
        assert "no array cache of light_field" in caplog.text


@pytest.mark.parametrize("victim", ["ids.npy", "chunk-0.npy", "current.json"])
def test_a_damaged_cache_is_rebuilt_not_trusted(
    db: Any, forget: Callable[[Any], None], caplog: pytest.LogCaptureFixture, victim: str
) -> None:
    stored_arrays(db)(COLUMN, _asked(db))
    root = db.store.path / CACHE_DIR / COLUMN
    meta = json.loads((root / "current.json").read_text())
    target = root / victim if victim == "current.json" else root / meta["dir"] / victim
    data = target.read_bytes()
    target.write_bytes(data[: len(data) // 2])
    forget(db)
    with caplog.at_level(logging.WARNING, logger="query.search.array_cache"):
        _same(db)
    assert "rebuilding the array cache" in caplog.text
    assert open_column(db, COLUMN) is not None


def test_the_reader_is_importable_where_callers_import_it() -> None:
    assert rerank_lightfield.StoredArrays is StoredArrays
