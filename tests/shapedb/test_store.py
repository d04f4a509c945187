"""The Parquet + manifest store: round trips, atomic commits, locking, cleanup."""

from __future__ import annotations

import json
import threading
import time
from dataclasses import replace
from pathlib import Path

import duckdb
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from shapedb.config.core import Config
from shapedb.errors import ConfigError, NotFoundError, QueryError, StoreError, StoreLockedError
from shapedb.mdbd.decomposition import Decomposition
from shapedb.store.schema import (
    SCHEMA_VERSION,
    Failure,
    ShapeRecord,
    balls_table,
    shapes_schema,
    shapes_table,
)
from shapedb.store.store import MANIFEST, Store

CONFIG = Config().with_options(resolution=32, n_balls=64, n_r=4, method="paper")


def make_record(
    name: str,
    n: int = 6,
    *,
    seed: int | None = None,
    label: str | None = "a",
    config: Config = CONFIG,
    content: str | None = None,
) -> ShapeRecord:
    """A hand-made record: n balls on a line, touching neighbours."""
    rng = np.random.default_rng(seed if seed is not None else sum(map(ord, name)))
    radii = np.sort(rng.uniform(0.1, 1.0, n))[::-1]
    centers = rng.normal(size=(n, 3))
    edges = np.array([[i, i + 1] for i in range(n - 1)], dtype=np.int32).reshape(-1, 2)
    d = Decomposition(
        centers=centers,
        radii=radii,
        edges=edges,
        spacing=0.05,
        bounds=np.array([[-1.0, -2, -3], [1, 2, 3]]),
        config=config.mdbd,
        representation="mesh",
        timings={"sdf": 0.5, "decompose": 0.25},
    )
    return ShapeRecord(
        name=name,
        decomposition=d,
        feature=rng.random(config.dim).astype(np.float32),
        config=config,
        content_hash=content or f"hash-{name}",
        representation="mesh",
        label=label,
        metadata={"k": name.upper()},
        source=f"/data/{name}.obj",
        build_seconds=1.5,
    )


def forget_checksums(root: Path) -> None:
    """Make the manifest look written before segment sizes and checksums were recorded."""
    manifest = json.loads((root / MANIFEST).read_text())
    for segments in manifest["tables"].values():
        for seg in segments:
            seg.pop("bytes", None)
            seg.pop("sha256", None)
    (root / MANIFEST).write_text(json.dumps(manifest))


@pytest.fixture()
def tmp_store(tmp_path: Path) -> Store:
    return Store.create(tmp_path / "store", CONFIG)


def test_create_open_and_empty_reads(tmp_path: Path) -> None:
    store = Store.create(tmp_path / "s", CONFIG)
    assert store.version == 0 and len(store) == 0
    again = Store.open(tmp_path / "s")
    assert again.config == CONFIG and again.dim == 8
    assert store.shapes().num_rows == 0
    assert store.shapes().schema.equals(shapes_schema(8), check_metadata=False)
    ids, x = store.features()
    assert ids.shape == (0,) and x.shape == (0, 8)
    assert store.balls().num_rows == 0 and store.failures().num_rows == 0
    with pytest.raises(StoreError, match="already exists"):
        Store.create(tmp_path / "s", CONFIG)
    with pytest.raises(StoreError, match="no shapedb store"):
        Store.open(tmp_path / "nothing")


def test_add_assigns_ids_and_round_trips(tmp_store: Store) -> None:
    recs = [make_record("a"), make_record("bb", 3), make_record("c", 1)]
    out = tmp_store.add(recs)
    assert [r.id for r in out] == [1, 2, 3]
    assert tmp_store.version == 1 and len(tmp_store) == 3
    for original in recs:
        got = tmp_store.get(original.name)
        d0, d1 = original.decomposition, got.decomposition
        np.testing.assert_array_equal(d1.centers, d0.centers)
        np.testing.assert_array_equal(d1.radii, d0.radii)
        np.testing.assert_array_equal(d1.edges, d0.edges)
        np.testing.assert_array_equal(d1.bounds, d0.bounds)
        assert d1.spacing == d0.spacing and d1.config == CONFIG.mdbd
        assert d1.timings == d0.timings
        np.testing.assert_array_equal(got.feature, original.feature)
        assert got.config == CONFIG and got.metadata == {"k": original.name.upper()}
        assert (got.label, got.source, got.content_hash) == (
            original.label,
            original.source,
            original.content_hash,
        )
    ids, x = tmp_store.features()
    assert ids.tolist() == [1, 2, 3] and x.dtype == np.float32 and x.shape == (3, 8)
    np.testing.assert_array_equal(x[1], recs[1].feature)
    assert tmp_store.hashes() == {"hash-a": 1, "hash-bb": 2, "hash-c": 3}
    balls = tmp_store.balls([2])
    assert balls.num_rows == 3 and balls.column("r_norm").to_pylist()[0] == 1.0
    assert tmp_store.edges([1]).num_rows == 5 and tmp_store.edges([3]).num_rows == 0


def test_frame_round_trips_and_old_rows_read_as_identity(tmp_store: Store) -> None:
    angle = 0.3
    frame = np.eye(4)
    frame[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
    frame[:3, 3] = [0.5, -1.0, 2.0]
    rec = make_record("framed")
    rec = replace(rec, decomposition=replace(rec.decomposition, frame=frame))
    tmp_store.add([rec])
    np.testing.assert_array_equal(tmp_store.get("framed").decomposition.frame, frame)
    column = tmp_store.shapes(["frame"]).column("frame").to_pylist()
    assert column == [frame.ravel().tolist()]
    # a segment written before the column existed: the row reads back with identity
    seg = next(p for p in tmp_store.path.rglob("*.parquet") if "shapes" in str(p))
    old = pq.read_table(seg)
    pq.write_table(old.drop_columns(["frame"]), seg)
    forget_checksums(tmp_store.path)
    again = Store.open(tmp_store.path)
    assert again.shapes(["frame"]).column("frame").to_pylist() == [None]
    np.testing.assert_array_equal(again.get("framed").decomposition.frame, np.eye(4))


def test_sampling_round_trips_and_old_rows_read_as_exact(tmp_store: Store) -> None:
    rec = make_record("cloud")
    rec = replace(rec, decomposition=replace(rec.decomposition, sampling=0.125))
    tmp_store.add([rec])
    assert tmp_store.get("cloud").decomposition.sampling == 0.125
    # a segment written before the column existed: the row reads back as exact (0)
    seg = next(p for p in tmp_store.path.rglob("*.parquet") if "shapes" in str(p))
    pq.write_table(pq.read_table(seg).drop_columns(["sampling"]), seg)
    forget_checksums(tmp_store.path)
    again = Store.open(tmp_store.path)
    assert again.shapes(["sampling"]).column("sampling").to_pylist() == [None]
    assert again.get("cloud").decomposition.sampling == 0.0


def test_field_vector_round_trips_and_old_rows_read_as_none(tmp_store: Store) -> None:
    from shapedb.signature.field_vector import field_vector_dim

    vector = np.linspace(0.0, 1.0, field_vector_dim(CONFIG), dtype=np.float32)
    tmp_store.add([replace(make_record("fv"), field_vector=vector), make_record("plain")])
    np.testing.assert_array_equal(tmp_store.get("fv").field_vector, vector)
    assert tmp_store.get("plain").field_vector is None
    column = tmp_store.shapes(["field_vector"]).column("field_vector")
    assert column.type.value_type == pa.float32() and column.to_pylist()[1] is None
    # a segment written before the column existed: its rows read back without a vector
    seg = next(p for p in tmp_store.path.rglob("*.parquet") if "shapes" in str(p))
    pq.write_table(pq.read_table(seg).drop_columns(["field_vector"]), seg)
    forget_checksums(tmp_store.path)
    again = Store.open(tmp_store.path)
    assert again.shapes(["field_vector"]).column("field_vector").to_pylist() == [None, None]
    assert again.get("fv").field_vector is None
    # a vector of another length, or not finite, is refused
    for bad in (vector[:-1], np.full_like(vector, np.nan)):
        with pytest.raises(ValueError, match="field vector"):
            shapes_table([replace(make_record("bad"), id=9, field_vector=bad)], CONFIG.dim)


def test_reads_through_pyarrow_and_duckdb(tmp_store: Store) -> None:
    tmp_store.add([make_record("a"), make_record("b")])
    tmp_store.add([make_record("c")])
    files = tmp_store.files("shapes")
    assert len(files) == 2
    t = pq.read_table(files[0])
    assert t.schema.metadata[b"shapedb.schema_version"] == str(SCHEMA_VERSION).encode()
    rows = duckdb.sql(
        f"SELECT id, name, metadata['k'] AS k, len(feature) AS d "
        f"FROM read_parquet({tmp_store.files('shapes')}) ORDER BY id"
    ).fetchall()
    assert rows == [(1, "a", "A", 8), (2, "b", "B", 8), (3, "c", "C", 8)]
    n = duckdb.sql(f"SELECT count(*) FROM read_parquet({tmp_store.files('balls')})").fetchall()
    assert n == [(18,)]


def test_get_by_id_name_and_errors(tmp_store: Store) -> None:
    tmp_store.add(
        [
            make_record("a"),
            make_record("7"),
            make_record("dup"),
            make_record("dup", content="other"),
        ]
    )
    assert tmp_store.get(1).name == "a"
    assert tmp_store.get("1").name == "a"  # digits that are no name: an id
    assert tmp_store.get("7").id == 2  # a name wins over an id
    with pytest.raises(NotFoundError, match="nope"):
        tmp_store.get("nope")
    with pytest.raises(NotFoundError):
        tmp_store.get(99)
    with pytest.raises(QueryError, match="ambiguous"):
        tmp_store.get("dup")
    with pytest.raises(QueryError, match="unknown column"):
        tmp_store.shapes(["id", "colour"])


def test_config_mismatch_is_refused(tmp_store: Store) -> None:
    other = CONFIG.with_options(resolution=64)
    with pytest.raises(ConfigError, match="configuration"):
        tmp_store.add([make_record("x", config=other)])
    kernel = CONFIG.with_options(lam=2.0)
    with pytest.raises(ConfigError):
        tmp_store.add([make_record("x", config=kernel)])
    assert tmp_store.version == 0


def test_delete_is_copy_on_write(tmp_store: Store) -> None:
    tmp_store.add([make_record("a"), make_record("b"), make_record("c")])
    before = set(tmp_store.files("shapes"))
    assert tmp_store.delete([2, 42]) == 1
    assert tmp_store.ids().tolist() == [1, 3]
    assert set(tmp_store.balls().column("shape_id").to_pylist()) == {1, 3}
    assert set(tmp_store.edges().column("shape_id").to_pylist()) == {1, 3}
    assert tmp_store.version == 2
    assert not before & set(tmp_store.files("shapes"))
    for f in before:  # retired, still readable by older readers
        assert Path(f).exists()
    assert tmp_store.delete([1, 3]) == 2 and len(tmp_store) == 0
    # an emptied segment is replaced by an empty one that names it (shapedb repair)
    assert [pq.read_table(f).num_rows for f in tmp_store.files("shapes")] == [0]
    # ids are never reused
    assert tmp_store.add([make_record("d")])[0].id == 4


def test_explicit_ids_replace_in_one_commit(tmp_store: Store) -> None:
    tmp_store.add([make_record("a"), make_record("b")])
    new = replace(make_record("a", seed=5), id=1)
    with pytest.raises(StoreError, match="already in use"):
        tmp_store.commit([new])
    result = tmp_store.commit([new], delete=[1])
    assert result.added == (1,) and result.deleted == (1,)
    np.testing.assert_array_equal(tmp_store.get(1).feature, new.feature)
    assert len(tmp_store) == 2


def test_failures_are_recorded_and_superseded(tmp_store: Store) -> None:
    tmp_store.add(
        [],
        [Failure("/data/x.obj", "LoadError", "junk"), Failure("/data/y.obj", "LoadError", "empty")],
    )
    assert tmp_store.failures().num_rows == 2
    tmp_store.add([], [Failure("/data/x.obj", "LoadError", "still junk")])
    f = tmp_store.failures().to_pylist()
    assert sorted((r["source"], r["message"]) for r in f) == [
        ("/data/x.obj", "still junk"),
        ("/data/y.obj", "empty"),
    ]
    rec = make_record("y")
    assert rec.source == "/data/y.obj"
    tmp_store.add([rec])  # y now ingests: its failure goes
    assert tmp_store.failures().column("source").to_pylist() == ["/data/x.obj"]


def test_empty_commit_is_a_no_op(tmp_store: Store) -> None:
    assert tmp_store.commit().version == 0
    assert tmp_store.version == 0


def test_lock_is_exclusive(tmp_store: Store) -> None:
    other = Store.open(tmp_store.path)
    with tmp_store.writer():
        with pytest.raises(StoreLockedError, match="lock"):
            other.add([make_record("a")])
        with tmp_store.writer():  # re-entrant
            tmp_store.add([make_record("b")])
    other.add([make_record("a")])
    assert len(tmp_store) == 2


def test_lock_waits_with_timeout(tmp_store: Store) -> None:
    other = Store.open(tmp_store.path, lock_timeout=5.0)
    release = threading.Event()

    def hold() -> None:
        with tmp_store.writer():
            release.wait(5)
            time.sleep(0.3)

    t = threading.Thread(target=hold)
    t.start()
    time.sleep(0.1)
    release.set()
    t0 = time.monotonic()
    other.add([make_record("a")])  # waits for the holder, then commits
    assert time.monotonic() - t0 >= 0.1
    t.join()
    assert len(tmp_store) == 1


def test_next_writer_removes_only_what_a_journal_proves(tmp_store: Store) -> None:
    tmp_store.add([make_record("a")])
    root = tmp_store.path
    store_id = json.loads((root / MANIFEST).read_text())["store_id"]
    # an aborted transaction of this store: its journal names its staging and data files
    stage = root / "staging" / "dead"
    stage.mkdir(parents=True)
    (stage / "shapes-x.parquet").write_bytes(b"partial")
    orphan = root / "data" / "shapes" / "99999999-orphan.parquet"
    pq.write_table(shapes_table([replace(make_record("zz"), id=50)], 8), orphan)
    (root / "journal").mkdir(exist_ok=True)
    journal = {"store": store_id, "txn": "dead", "files": ["data/shapes/99999999-orphan.parquet"]}
    (root / "journal" / "dead.json").write_text(json.dumps(journal))
    # files no journal names, and a journal of another store: never deleted
    stranger = root / "data" / "shapes" / "99999998-stranger.parquet"
    stranger.write_bytes(b"not ours to delete")
    alien = root / "data" / "balls" / "99999997-alien.parquet"
    alien.write_bytes(b"x")
    other = {"store": "another", "txn": "z", "files": ["data/balls/99999997-alien.parquet"]}
    (root / "journal" / "z.json").write_text(json.dumps(other))
    (root / ".manifest.json.dead.tmp").write_text("{")
    assert len(tmp_store) == 1  # readers ignore all of it
    tmp_store.add([make_record("b")])
    assert not orphan.exists() and not stage.exists()
    assert not (root / "journal" / "dead.json").exists()
    assert stranger.exists() and alien.exists()
    assert not (root / ".manifest.json.dead.tmp").exists()
    assert tmp_store.ids().tolist() == [1, 2]


def test_cleanup_never_runs_without_a_valid_manifest(tmp_store: Store) -> None:
    """a missing or damaged manifest must not cost any data file."""
    tmp_store.add([make_record("a"), make_record("b")])
    root = tmp_store.path
    on_disk = sorted(root.rglob("*.parquet"))
    (root / MANIFEST).unlink()
    with pytest.raises(StoreError, match="manifest.json is missing.*shapedb repair"):
        Store.open(root)
    with pytest.raises(StoreError, match="shapedb repair"):
        Store.create(root, CONFIG)  # never a new empty store over the data
    with pytest.raises(StoreError, match="manifest.json is missing"):
        tmp_store.add([make_record("c")])
    assert sorted(root.rglob("*.parquet")) == on_disk


def test_manifest_naming_a_missing_segment_keeps_the_others(tmp_store: Store) -> None:
    tmp_store.add([make_record("a")])
    tmp_store.add([make_record("b")])
    files = tmp_store.files("shapes")
    Path(files[0]).unlink()
    with pytest.raises(StoreError, match=f"segment .*{Path(files[0]).name} is missing"):
        tmp_store.shapes()
    with pytest.raises(StoreError, match="is missing"):
        tmp_store.add([make_record("c")])  # refused, and nothing deleted
    assert Path(files[1]).exists()


@pytest.mark.parametrize("key", ["tables", "config", "next_id", "version", "dim"])
def test_manifest_missing_a_key_is_one_store_error(tmp_store: Store, key: str) -> None:
    tmp_store.add([make_record("a")])
    manifest = json.loads((tmp_store.path / MANIFEST).read_text())
    del manifest[key]
    (tmp_store.path / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(StoreError, match=f"damaged: key '{key}' is missing.*repair"):
        Store.open(tmp_store.path)


def test_damaged_segment_is_one_store_error_naming_it(tmp_store: Store) -> None:
    tmp_store.add([make_record("a")])
    seg = Path(tmp_store.files("shapes")[0])
    data = bytearray(seg.read_bytes())
    meta = pq.ParquetFile(seg).metadata.row_group(0)
    (chunk,) = [
        meta.column(c)
        for c in range(meta.num_columns)
        if meta.column(c).path_in_schema == "feature.list.element"
    ]
    mid = chunk.data_page_offset + chunk.total_compressed_size // 2  # a page shapes() reads
    data[mid : mid + 16] = b"\xff" * 16  # same size, garbage inside
    seg.write_bytes(bytes(data))
    with pytest.raises(StoreError, match=f"segment data/shapes/{seg.name}"):
        tmp_store.shapes()
    seg.write_bytes(bytes(data[:100]))  # truncated: the recorded size tells at once
    with pytest.raises(StoreError, match=f"{seg.name} is damaged: 100 bytes"):
        tmp_store.features()


def test_store_is_created_only_in_a_missing_or_empty_folder(tmp_path: Path) -> None:
    folder = tmp_path / "photos"
    folder.mkdir()
    (folder / "holiday.jpg").write_bytes(b"jpeg")
    with pytest.raises(StoreError, match="not empty.*holds no shapedb store"):
        Store.create(folder, CONFIG)
    assert sorted(p.name for p in folder.iterdir()) == ["holiday.jpg"]
    (tmp_path / "empty").mkdir()
    assert len(Store.create(tmp_path / "empty", CONFIG)) == 0
    with pytest.raises(StoreError, match="already exists"):
        Store.create(tmp_path / "empty", CONFIG)


def test_commit_rereads_the_configuration_under_the_lock(tmp_path: Path) -> None:
    """a store re-created with another configuration refuses old writers."""
    path = tmp_path / "race"
    first = Store.create(path, CONFIG)
    manifest = json.loads((path / MANIFEST).read_text())
    other = CONFIG.with_options(resolution=CONFIG.mdbd.resolution + 8)
    manifest["config"] = other.to_dict()
    (path / MANIFEST).write_text(json.dumps(manifest))  # what the other creator wrote
    with pytest.raises(StoreError, match="configuration changed since it was opened"):
        first.add([make_record("a")])
    assert len(Store.open(path)) == 0


def test_retired_files_expire(tmp_path: Path) -> None:
    store = Store.create(tmp_path / "s", CONFIG, retain_seconds=0.0)
    store.add([make_record("a"), make_record("b")])
    old = store.files("shapes")
    store.delete([1])
    assert all(Path(f).exists() for f in old)
    time.sleep(0.01)
    store.add([make_record("c")])  # the next writer removes expired files
    assert not any(Path(f).exists() for f in old)
    manifest = json.loads((store.path / MANIFEST).read_text())
    assert all(Path(store.path / r["file"]).exists() for r in manifest["retired"])


def test_compact_merges_segments(tmp_store: Store) -> None:
    for name in "abcde":
        tmp_store.add([make_record(name)])
    before = (tmp_store.shapes(), tmp_store.balls(), tmp_store.edges())
    assert len(tmp_store.files("shapes")) == 5
    tmp_store.compact()
    assert len(tmp_store.files("shapes")) == 1 and len(tmp_store.files("balls")) == 1
    after = (tmp_store.shapes(), tmp_store.balls(), tmp_store.edges())
    for a, b in zip(before, after, strict=True):
        assert a.equals(b)


def test_bad_manifest_is_a_store_error(tmp_store: Store) -> None:
    path = tmp_store.path / MANIFEST
    data = json.loads(path.read_text())
    data["format_version"] = 999
    path.write_text(json.dumps(data))
    with pytest.raises(StoreError, match="format version 999"):
        Store.open(tmp_store.path)
    path.write_text("{not json")
    with pytest.raises(StoreError, match="not valid JSON"):
        Store.open(tmp_store.path)


def test_table_conversions_check_ids_and_dims() -> None:
    with pytest.raises(ValueError, match="ids"):
        balls_table([make_record("a")])
    rec = replace(make_record("a"), id=1)
    with pytest.raises(ValueError, match="length"):
        shapes_table([rec], 10)


def test_plain_duckdb_reads_through_the_manifest(
    tmp_store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The recipe of docs/store.md: no shapedb, just the manifest and Parquet."""
    tmp_store.add([make_record("a"), make_record("b")])
    tmp_store.delete([1])  # leaves a retired segment on disk, which must not be read
    monkeypatch.chdir(tmp_store.path)
    con = duckdb.connect()
    for table in ("shapes", "balls"):
        con.execute(
            f"SET VARIABLE {table}_files = (SELECT list('./' || s.file) FROM "
            f"(SELECT unnest(tables.{table}) AS s FROM read_json_auto('manifest.json')))"
        )
        con.execute(
            f"CREATE VIEW {table} AS SELECT * FROM read_parquet(getvariable('{table}_files'))"
        )
    assert con.sql("SELECT id, name FROM shapes").fetchall() == [(2, "b")]
    assert con.sql("SELECT count(*) FROM balls").fetchall() == [(6,)]


def test_two_creators_never_mix_configurations(tmp_path: Path) -> None:
    """connect(p, resolution=a) and (p, resolution=b) at the same moment."""
    import query.database as database
    from shapedb.geometry.implicit import Sphere

    def create(path: Path, resolution: int, start: threading.Barrier, outcome: dict) -> None:
        start.wait()
        try:
            db = database.connect(path, resolution=resolution, n_balls=16)
            db.ingest([(f"s{resolution}", Sphere((0.0, 0.0, 0.0), 0.5))], workers=1)
            outcome[resolution] = "ok"
        except (ConfigError, StoreError) as exc:
            outcome[resolution] = type(exc).__name__

    for run in range(8):
        path = tmp_path / f"race{run}"
        outcome: dict[int, str] = {}
        start = threading.Barrier(2)
        threads = [
            threading.Thread(target=create, args=(path, r, start, outcome)) for r in (16, 20)
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert sorted(outcome.values()).count("ok") == 1, outcome
        store = Store.open(path)
        configs = set(store.shapes(["config"]).column("config").to_pylist())
        assert configs == {store.config.to_json()}


def test_ids_are_never_reused_even_when_next_id_is_wrong(tmp_store: Store) -> None:
    tmp_store.add([make_record("a"), make_record("b")])  # ids 1 and 2
    manifest = json.loads((tmp_store.path / MANIFEST).read_text())
    manifest["next_id"] = 1  # a manifest edited, or written by a broken tool
    (tmp_store.path / MANIFEST).write_text(json.dumps(manifest))
    added = tmp_store.add([make_record("c")])
    assert added[0].id == 3
    assert tmp_store.ids().tolist() == [1, 2, 3]


@pytest.mark.parametrize("where", ["/proc/self/x.db", "/proc/self/x.db/inner"])
def test_an_unwritable_path_is_one_store_error(where: str) -> None:
    import query.database as database

    for make in (lambda: Store.create(where, CONFIG), lambda: database.connect(where)):
        with pytest.raises(StoreError, match="cannot create the store here") as info:
            make()
        assert "\n" not in str(info.value) and where in str(info.value)


def test_segments_split_floating_point_columns_and_read_back(tmp_path: Path) -> None:
    """Float columns (numbers and lists of numbers) are byte-stream split, the rest
    dictionary-encoded; pyarrow and DuckDB read the rows back exactly."""
    store = Store.create(tmp_path / "s", CONFIG)
    records = [make_record(f"r{i}", 40, seed=i) for i in range(5)]
    store.commit(records)
    for table, column, split in (
        ("balls", "x", True),
        ("balls", "r_norm", True),
        ("shapes", "feature", True),
        ("shapes", "name", False),
        ("edges", "i", False),
    ):
        (path,) = [tmp_path / "s" / f for f in store.files(table)]
        meta = pq.ParquetFile(path).metadata.row_group(0)
        col = next(
            meta.column(c)
            for c in range(meta.num_columns)
            if meta.column(c).path_in_schema.split(".")[0] == column
        )
        assert ("BYTE_STREAM_SPLIT" in col.encodings) == split, (table, column, col.encodings)
    balls = store.balls().sort_by([("shape_id", "ascending"), ("ball", "ascending")])
    got = np.concatenate([np.asarray(r.decomposition.centers)[:, 0] for r in records])
    np.testing.assert_array_equal(balls.column("x").to_numpy(), got)
    files = [str(tmp_path / "s" / f) for f in store.files("balls")]
    ((total,),) = duckdb.sql(f"select sum(x) from read_parquet({files!r})").fetchall()
    assert total == pytest.approx(float(got.sum()))


def test_merge_runs_cuts_runs_of_small_segments_at_the_target() -> None:
    from shapedb.store.compaction import merge_runs

    rows = [3, 3, 3, 10, 2, 2, 4, 1]
    runs = merge_runs([{"rows": r} for r in rows], target_rows=6)
    assert runs == [[0, 1], [4, 5], [6, 7]]  # [2] alone, [3] full: neither rewritten
    assert merge_runs([{"rows": 10}, {"rows": 10}], target_rows=6) == []


def test_compaction_merges_runs_one_at_a_time_and_again_does_nothing(tmp_path: Path) -> None:
    store = Store.create(tmp_path / "s", CONFIG)
    for k in range(7):
        store.add([make_record(f"r{k}", 5 + k, seed=k)])
    store.delete([int(store.resolve("r3"))])  # an emptied-out segment among them
    before = (store.shapes(), store.balls(), store.edges())
    with pytest.raises(ConfigError, match="target_shapes"):
        store.compact(target_shapes=0)
    version = store.compact(target_shapes=3).version
    assert len(store.files("shapes")) == 2  # rows [1, 1, 1, 0 | 1, 1, 1]
    assert all(2 <= len(store.files(t)) < 7 for t in ("balls", "edges"))
    for a, b in zip(before, (store.shapes(), store.balls(), store.edges()), strict=True):
        assert a.equals(b)
    assert store.compact(target_shapes=3).version == version  # nothing left to merge
    manifest = json.loads((store.path / MANIFEST).read_text())
    assert len(manifest["retired"]) >= 7  # the merged files are kept for older readers
    assert all((store.path / r["file"]).exists() for r in manifest["retired"])
