"""search / search_batch on a small real store."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG, make_record

from query.search.engine import Hit, query_features, search, search_batch
from query.search.index import INDEX_DIR, open_index
from shapedb.errors import ConfigError, NotFoundError, QueryError, StoreError
from shapedb.geometry.implicit import Box, Capsule
from shapedb.mdbd.decomposition import decompose
from shapedb.signature.kernel import distance, kernel


def brute_force(db, vector, k):
    """Exact Eq. 3 ranking of every stored shape: [(id, similarity)], ties by id."""
    ids, x = db.store.features()
    sim = kernel(vector, x.astype(np.float64), db.config.kernel)
    order = np.lexsort((ids, -sim))[:k]
    return ids[order], sim[order]


def assert_matches(hits, ref_ids, ref_sim):
    sims = np.array([h.similarity for h in hits])
    np.testing.assert_allclose(sims, ref_sim, rtol=1e-9, atol=0)
    cut = ref_sim[-1]
    got = {h.id for h in hits if h.similarity > cut + 1e-12}
    assert got == set(ref_ids[ref_sim > cut + 1e-12])


def test_search_equals_brute_force(tmp_db):
    ids, x = tmp_db.store.features()
    for sid, row in zip(ids, x, strict=True):
        hits = search(tmp_db, int(sid), k=5)
        assert all(isinstance(h, Hit) for h in hits) and len(hits) == 5
        assert_matches(hits, *brute_force(tmp_db, row.astype(np.float64), 5))
        assert hits[0].similarity == pytest.approx(1.0) and hits[0].distance == 0.0
        assert [h.similarity for h in hits] == sorted((h.similarity for h in hits), reverse=True)


def test_stored_query_ranks_itself_first(tmp_db):
    hits = search(tmp_db, "capsule2", k=3)
    assert hits[0].name == "capsule2" and hits[0].similarity == 1.0
    assert hits[0].label == "capsule"
    assert hits[1].to_dict().keys() == {"id", "name", "label", "similarity", "distance", "path"}


def test_query_kinds_agree(tmp_db):
    rec = tmp_db.store.get("box1")
    by_id = search(tmp_db, rec.id, k=4)
    by_name = search(tmp_db, "box1", k=4)
    by_vector = search(tmp_db, np.asarray(rec.feature), k=4)
    by_record = search(tmp_db, rec, k=4)
    assert by_id == by_name == by_vector == by_record


def test_unseen_geometry_and_decomposition(tmp_db):
    g = Capsule([0, 0, 0], [2.5, 0, 0], 0.4)  # not in the store
    hits = search(tmp_db, g, k=4)
    vector = query_features(tmp_db, g)
    assert_matches(hits, *brute_force(tmp_db, vector, 4))
    assert hits[0].label == "capsule" and hits[0].similarity < 1.0
    dec = decompose(g, config=CONFIG.mdbd)
    assert search(tmp_db, dec, k=4) == hits
    other = decompose(g, config=CONFIG.with_options(resolution=40).mdbd)
    with pytest.raises(ConfigError):
        search(tmp_db, other)


def test_unseen_query_file(tmp_db, tmp_path):
    ingest = pytest.importorskip("ingest")
    if not hasattr(ingest, "load"):
        pytest.skip("ingest.load not available yet")
    trimesh = pytest.importorskip("trimesh")
    path = tmp_path / "query_box.stl"
    # box0 (2 x 1 x 1, implicit) as a mesh file, 10 % larger: another representation
    # and scale. (A 2.2 x 1 x 1 box sits between box0 and cylinder0, a 2 x 1 x 1
    # cylinder, at this test store's 32 cells.)
    trimesh.creation.box(extents=[2.2, 1.1, 1.1]).export(path)
    hits = search(tmp_db, str(path), k=3)
    assert len(hits) == 3 and hits[0].label == "box"
    assert search(tmp_db, Path(path), k=3) == hits


def test_search_batch(tmp_db):
    queries = ["box0", 3, Box([0, 0, 0], [2, 1.2, 1])]
    batch = search_batch(tmp_db, queries, k=3)
    assert batch == [search(tmp_db, q, k=3) for q in queries]
    assert search_batch(tmp_db, [], k=3) == []


def test_where_filter(tmp_db):
    hits = search(tmp_db, "box0", k=10, where="label = 'torus'")
    assert [h.label for h in hits] == ["torus"] * 3
    ids, x = tmp_db.store.features()
    torus = tmp_db.sql("SELECT id FROM shapes WHERE label = 'torus'").column("id").to_pylist()
    q = x[ids == tmp_db.store.resolve("box0")][0].astype(np.float64)
    d = distance(q, x[np.isin(ids, torus)].astype(np.float64), tmp_db.config.kernel)
    np.testing.assert_allclose(sorted(h.distance for h in hits), sorted(d), rtol=1e-12)
    meta = search(
        tmp_db, "box0", k=20, where="metadata['family'] = 'capsule' AND name <> 'capsule0'"
    )
    assert {h.name for h in meta} == {"capsule1", "capsule2", "capsule3"}
    assert search(tmp_db, "box0", where="label = 'nothing'") == []


def test_errors(tmp_db, tmp_path):
    with pytest.raises(NotFoundError, match="12345"):
        search(tmp_db, 12345)
    with pytest.raises(NotFoundError, match="no_such_shape"):
        search(tmp_db, "no_such_shape")
    with pytest.raises(QueryError, match="labl = 'x'"):
        search(tmp_db, "box0", where="labl = 'x'")
    with pytest.raises(QueryError, match="length|shape"):
        search(tmp_db, np.zeros(5))
    with pytest.raises(QueryError, match="k"):
        search(tmp_db, "box0", k=0)
    with pytest.raises(QueryError):
        search(tmp_db, object())
    import query.database as database

    with pytest.raises(StoreError, match="no shapedb store"):
        database.connect(tmp_path / "missing", create=False)


@pytest.mark.parametrize("k", [0, -3, 3_000_000_000, 99999999999999999999, 2.5, "3", True])
def test_k_out_of_range_is_a_query_error(tmp_db, k):
    """k <= 0, absurd or not an integer is one clear error."""
    with pytest.raises(QueryError, match="k"):
        search(tmp_db, "box0", k=k)


def test_k_is_capped_at_the_store_size(tmp_db):
    """A k far above the store's size allocates (and returns) only what is stored."""
    from query.search.engine import MAX_K, search_batch

    n = len(tmp_db.store)
    hits = search(tmp_db, "box0", k=MAX_K)
    assert len(hits) == n
    assert [len(h) for h in search_batch(tmp_db, ["box0", "torus1"], k=MAX_K)] == [n, n]


def test_store_removed_under_an_open_database(tmp_db):
    import shutil

    search(tmp_db, "box0")
    shutil.rmtree(tmp_db.store.path)
    with pytest.raises(StoreError, match="manifest.json missing"):
        search(tmp_db, "box0")
    with pytest.raises(StoreError, match="manifest.json missing"):
        tmp_db.sql("SELECT 1")


def test_index_follows_ingest_and_deletion(tmp_db):
    open_index(tmp_db)
    pointer = Path(tmp_db.store.path) / INDEX_DIR / "current.json"
    assert pointer.exists()
    new = make_record("capsule_new", "capsule", Capsule([0, 0, 0], [2.2, 0, 0], 0.4))
    _, committed = tmp_db.commit([new])  # on_commit updates the index
    new_id = committed[0].id
    index = open_index(tmp_db)
    assert index.version_ == tmp_db.store.version and new_id in index
    assert search(tmp_db, "capsule_new", k=1)[0].id == new_id
    tmp_db.delete("capsule_new")
    assert all(h.id != new_id for h in search(tmp_db, "capsule1", k=20))
    assert open_index(tmp_db).version_ == tmp_db.store.version


def test_index_is_rebuilt_when_damaged(tmp_db):
    open_index(tmp_db)
    sub = Path(tmp_db.store.path) / INDEX_DIR
    (sub / index_dir_name(sub) / "faiss.index").write_bytes(b"garbage")
    from query.search.index import forget

    forget(tmp_db)
    assert search(tmp_db, "box0", k=1)[0].name == "box0"


def index_dir_name(root: Path) -> str:
    import json

    return json.loads((root / "current.json").read_text())["dir"]


def test_a_store_the_process_cannot_write_still_searches(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Read-only media: the index is built in memory, with one warning, and search answers."""
    import shutil

    import shapedb
    from query.search.index import FeatureIndex

    pinned = Path(__file__).resolve().parents[1] / "data" / "pinned" / "store"
    shutil.copytree(pinned, tmp_path / "ro")

    def refuse(self: Any, *args: Any, **kwargs: Any) -> None:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(FeatureIndex, "save", refuse)
    db = shapedb.connect(tmp_path / "ro", create=False)
    with caplog.at_level("WARNING", logger="query.search.index"):
        hits = db.search(1, k=3)
    assert hits[0].id == 1 and "kept in memory only" in caplog.text
