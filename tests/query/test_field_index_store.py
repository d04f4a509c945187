"""The field vector index of a store: the graph path, kept across commits and processes.

Synthetic records (one decomposition, clustered field vectors) in a store whose records
keep field vectors; :data:`query.search.field_index.SCAN_MAX` is lowered so that ~1,500
vectors take the approximate path (the HNSW graph proposes, the exact scan orders).
"""

from __future__ import annotations

import logging
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG, make_record

import query.search.field_index as field_index_module
from query.search.field_fusion import FieldFusion
from query.search.field_index import INDEX_DIR, FieldIndex, field_index
from shapedb.geometry.implicit import Box
from shapedb.signature.field_vector import field_vector_dim

FV = CONFIG.with_options(rerank="lightfield", fv_enabled=True)


def _vectors(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = field_vector_dim(FV.field_vector)
    centres = rng.random((12, d))
    label = rng.integers(0, len(centres), n)
    return np.abs(centres[label] + 0.05 * rng.standard_normal((n, d))).astype(np.float32)


def _records(vectors: np.ndarray, prefix: str, ids: list[int] | None = None) -> list[Any]:
    base = make_record("base", "box", Box((0, 0, 0), (2.0, 1.0, 1.0)), FV)
    return [
        replace(
            base,
            name=f"{prefix}{i}",
            content_hash=f"{prefix}{i}",
            field_vector=v,
            id=None if ids is None else ids[i],
        )  # fmt: skip
        for i, v in enumerate(vectors)
    ]


def _exact(db: Any, queries: np.ndarray, k: int) -> list[list[int]]:
    """The k nearest stored ids by the scaled field vectors, by brute force."""
    fusion = FieldFusion.from_config(db.config)
    t = db.store.shapes(["id", "field_vector"])
    ids = t.column("id").to_numpy()
    v = fusion.scaled(np.stack(t.column("field_vector").to_numpy(zero_copy_only=False)))
    out = []
    for q in fusion.scaled(queries).astype(np.float64):
        d = np.abs(v.astype(np.float64) - q).sum(1)
        out.append(ids[np.lexsort((ids, d))[:k]].tolist())
    return out


@pytest.fixture
def graph_db(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forget: Callable[[Any], None]
) -> Iterator[Any]:
    """1,500 clustered vectors, above a lowered SCAN_MAX."""
    import query.database as database

    monkeypatch.setattr(field_index_module, "SCAN_MAX", 1000)
    monkeypatch.setattr(field_index_module, "OVERSAMPLE", 8)
    db = database.connect(tmp_path / "s", config=FV)
    db.store.commit(_records(_vectors(1500, 0), "a"))  # no thumbnails: the store alone
    yield db
    forget(db)


def _no_rebuild(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("the field index was rebuilt")

    monkeypatch.setattr(field_index_module, "_build", refuse)


def test_the_graph_finds_what_the_exact_scan_does(graph_db: Any) -> None:
    index = field_index(graph_db)
    assert index.approximate and len(index) == 1500
    assert (Path(graph_db.store.path) / INDEX_DIR / "current.json").exists()
    queries = _vectors(1500, 0)[:12] + 0.01
    fusion = FieldFusion.from_config(graph_db.config)
    got, _ = index.search(fusion.scaled(queries), 50)
    assert got.tolist() == _exact(graph_db, queries, 50)
    assert field_index(graph_db) is index  # one per store version


def test_a_commit_updates_the_index_without_rebuilding_it(
    graph_db: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    field_index(graph_db)
    _no_rebuild(monkeypatch)
    ids = graph_db.store.ids()
    gone = ids[::10].tolist()
    changed = int(ids[5])
    graph_db.store.commit(delete=gone)
    new = _vectors(200, 1) + 0.3
    redo = _records(np.full((1, new.shape[1]), 0.9, np.float32), "r", ids=[changed])
    added: list[Any] = []
    graph_db.store.commit([*_records(new, "b"), *redo], delete=[changed], assigned=added)
    index = field_index(graph_db)
    assert len(index) == 1500 - len(gone) + 200 and index.approximate
    fusion = FieldFusion.from_config(graph_db.config)
    queries = np.concatenate([new[:5], _vectors(1500, 0)[:5], redo[0].field_vector[None]])
    got, _ = index.search(fusion.scaled(queries), 40)
    assert got.tolist() == _exact(graph_db, queries, 40)
    assert got[:5, 0].tolist() == [r.id for r in added[:5]]  # the new shapes are found
    assert got[-1, 0] == changed  # with its new vector
    everything, _ = index.search(fusion.scaled(queries), 2000)
    assert not np.isin(everything, gone).any()


def test_a_reopened_store_loads_its_index(
    graph_db: Any, monkeypatch: pytest.MonkeyPatch, forget: Callable[[Any], None]
) -> None:
    first = field_index(graph_db)
    queries = FieldFusion.from_config(graph_db.config).scaled(_vectors(1500, 0)[:6])
    want = first.search(queries, 30)
    forget(graph_db)  # as a new process would
    _no_rebuild(monkeypatch)
    again = field_index(graph_db)
    assert again is not first and again.approximate
    for a, b in zip(want, again.search(queries, 30), strict=True):
        assert np.array_equal(a, b)
    graph_db.store.commit(delete=graph_db.store.ids()[:3].tolist())
    forget(graph_db)
    assert len(field_index(graph_db)) == 1497  # the saved index, brought up to date


def test_a_new_process_reads_the_saved_index(graph_db: Any) -> None:
    field_index(graph_db)
    code = (
        "import shapedb, query.search.field_index as f\n"
        "f.SCAN_MAX = 1000\n"
        "f._build = None\n"  # a rebuild would fail
        f"db = shapedb.connect({str(graph_db.store.path)!r}, create=False)\n"
        "i = f.field_index(db)\n"
        "print(len(i), i.approximate)\n"
    )
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=root, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["1500", "True"]


def test_a_store_the_process_cannot_write_still_searches(
    graph_db: Any, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    def refuse(self: Any, *args: Any, **kwargs: Any) -> None:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(FieldIndex, "save", refuse)
    with caplog.at_level(logging.WARNING, logger="query.search.index"):
        index = field_index(graph_db)
    assert "kept in memory only" in caplog.text
    assert not (Path(graph_db.store.path) / INDEX_DIR).exists()
    queries = _vectors(1500, 0)[:4]
    got, _ = index.search(FieldFusion.from_config(graph_db.config).scaled(queries), 10)
    assert got.tolist() == _exact(graph_db, queries, 10)
