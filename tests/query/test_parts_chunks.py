"""The part index on disk: a commit writes only new chunks, loads memory-mapped, and the
compressed (IVF-PQ) path finds what the exact scan finds."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from query_helpers import make_record

from query.parts.chunks import RowChunks, merge_plan
from query.parts.index import PARTS_DIR, PartIndex
from query.parts.store_index import open_parts_index
from shapedb.config.part import PartConfig
from shapedb.geometry.implicit import Capsule


def _live(root: Path) -> Path:
    return root / json.loads((root / "current.json").read_text())["dir"]


def _search_all(index: PartIndex, queries: np.ndarray) -> list[tuple[list[int], list[int]]]:
    return [tuple(a.tolist() for a in index.search(q, 5)[:2]) for q in queries]  # type: ignore[misc]


def test_commit_writes_only_new_chunks(tmp_db) -> None:
    cfg = PartConfig()
    root = tmp_db.path / PARTS_DIR / cfg.fingerprint
    open_parts_index(tmp_db, cfg)
    before = {p.name: p.stat().st_ino for p in _live(root).glob("*-*.npy")}
    assert {"features-0.npy", "edges-0.npy"} <= set(before)
    assert not list(root.glob(".tmp-build-*"))  # the build's spilled rows were linked
    tmp_db.commit([make_record("capsule-new", "capsule", Capsule([0, 0, 0], [1.5, 0, 0], 0.3))])
    index = open_parts_index(tmp_db, cfg)
    after = {p.name: p.stat().st_ino for p in _live(root).glob("*-*.npy")}
    # the old chunk files are the same inodes (hard links), the new shape is a new chunk
    assert after["features-0.npy"] == before["features-0.npy"]
    assert after["edges-0.npy"] == before["edges-0.npy"]
    assert {"features-1.npy", "edges-1.npy"} <= set(after)
    loaded = PartIndex.load(root)
    assert all(isinstance(c, np.memmap) for c in loaded.features_.chunks)
    fresh = open_parts_index(tmp_db, cfg, rebuild=True)
    assert fresh is not index and fresh.features_.chunks[0] is not loaded.features_.chunks[0]
    np.testing.assert_array_equal(np.asarray(loaded.features_), np.asarray(fresh.features_))
    np.testing.assert_array_equal(loaded.shapes_, fresh.shapes_)
    queries = np.asarray(fresh.features_)[::7]
    assert _search_all(loaded, queries) == _search_all(fresh, queries)


def _clustered(n_shapes: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Chains of balls whose radii come from a few prototypes, lightly jittered."""
    rng = np.random.default_rng(seed)
    protos = rng.uniform(0.2, 1.0, (4, 30))
    out = []
    for s in range(n_shapes):
        r = protos[s % 4] * rng.uniform(0.98, 1.02, 30)
        e = np.stack([np.arange(29), np.arange(1, 30)], 1)
        out.append((r, e))
    return out


def test_compressed_path_recall(tmp_path: Path) -> None:
    graphs = _clustered(200, 0)
    index = PartIndex(ivf_threshold=1_000, nprobe=64, min_candidates=2_000)
    index.fit(np.arange(200), graphs)
    assert index.kind_ == "ivf" and len(index.codes_) == len(index.features_)
    rng = np.random.default_rng(1)
    queries = np.asarray(index.features_)[rng.integers(0, len(index.features_), 20)]
    hits = sum(
        len(set(index.search(q, 10)[0]) & set(index.exact_search(q, 10)[0])) for q in queries
    )
    assert hits / 200 == 1.0
    index.save(tmp_path / "p", version=1)
    loaded = PartIndex.load(tmp_path / "p")
    assert loaded.faiss_.ntotal == len(loaded.features_)
    assert _search_all(loaded, queries) == _search_all(index, queries)
    index.add([500], [graphs[3]])  # a commit adds one codes chunk, links the old one
    index.save(tmp_path / "p", version=2)
    live = _live(tmp_path / "p")
    assert (live / "codes-1.npy").exists()
    np.testing.assert_array_equal(
        PartIndex.load(tmp_path / "p").search(queries[0], 3)[0], index.search(queries[0], 3)[0]
    )


def test_growing_index_switches_to_ivf_and_retrains() -> None:
    graphs = _clustered(60, 2)
    index = PartIndex(ivf_threshold=1_000).fit(np.arange(20), graphs[:20])
    assert index.kind_ == "flat" and index.trained_n_ == 600
    index.add(np.arange(20, 40), graphs[20:40])  # 1,200 vectors: past the flat index
    assert index.kind_ == "ivf" and index.trained_n_ == 1_200
    assert index.faiss_.ntotal == len(index.codes_) == 1_200
    index.add(np.arange(40, 50), graphs[40:50])  # added to the trained index
    assert index.trained_n_ == 1_200 and index.faiss_.ntotal == len(index.codes_) == 1_500
    q = np.asarray(index.features_)[1_400]
    assert index.search(q, 1)[0][0] == index.exact_search(q, 1)[0][0]


def test_row_chunks_take_and_merge_plan() -> None:
    rc = RowChunks(np.float32, (2,), [np.arange(6).reshape(3, 2), np.arange(6, 10).reshape(2, 2)])
    assert rc.shape == (5, 2) and len(rc) == 5
    np.testing.assert_array_equal(rc.take([4, 0, 3]), [[8, 9], [0, 1], [6, 7]])
    np.testing.assert_array_equal(rc[1:3], [[2, 3], [4, 5]])
    np.testing.assert_array_equal(rc[-1], [8, 9])
    assert merge_plan([100, 10, 1]) == [[0], [1], [2]]
    assert merge_plan([100, 10, 10]) == [[0], [1, 2]]
    assert merge_plan([10, 10, 10]) == [[0, 1, 2]]
