"""The ingest pipeline end to end: mixed folders, idempotency, labels, failures, Dask."""

from __future__ import annotations

import shutil
import threading
import time
from pathlib import Path

import duckdb
import numpy as np
import pyarrow.parquet as pq
import pytest
import trimesh
from ingest_helpers import SMALL

import query.database as database
from ingest import IngestReport
from shapedb.errors import ConfigError, NotFoundError
from shapedb.geometry.implicit import Box, Sphere

EXPECTED_REPR = {
    "box": "mesh",
    "ico": "mesh",
    "cyl": "mesh",
    "capsule": "mesh",
    "pair": "mesh",
    "cloud": "pointcloud",
    "ellipsoid": "pointcloud",
    "ball": "voxels",
    "slab": "voxels",
}


@pytest.fixture()
def mixed_dir(tmp_path: Path, good_dir: Path) -> Path:
    """The good files minus PCD (covered by the loader tests), in a fresh folder."""
    folder = tmp_path / "mixed"
    shutil.copytree(good_dir, folder)
    (folder / "cloud.pcd").unlink()
    (folder / "README.txt").write_text("companion files are skipped")
    return folder


def test_mixed_folder_is_ingested_and_readable(tmp_db: database.Database, mixed_dir: Path) -> None:
    report = tmp_db.ingest(mixed_dir, workers=1, label_from_folder=True)
    assert isinstance(report, IngestReport)
    assert report.failed == ()
    assert len(report.ingested) == len(EXPECTED_REPR) and report.skipped == ()
    shapes = tmp_db.shapes()
    got = dict(
        zip(
            shapes.column("name").to_pylist(),
            shapes.column("representation").to_pylist(),
            strict=True,
        )
    )
    assert got == EXPECTED_REPR
    assert set(shapes.column("label").to_pylist()) == {"mixed"}
    assert all(n > 0 for n in shapes.column("n_balls").to_pylist())
    assert set(shapes.column("config_fingerprint").to_pylist()) == {tmp_db.config.fingerprint}
    # every row through pyarrow ...
    store = tmp_db.store
    direct = pq.read_table(store.files("shapes")).sort_by("id")
    assert direct.column("id").to_pylist() == list(report.ingested)
    n_balls = sum(shapes.column("n_balls").to_pylist())
    n_edges = sum(shapes.column("n_edges").to_pylist())
    assert pq.read_table(store.files("balls")).num_rows == n_balls
    # ... and through a plain DuckDB session
    con = duckdb.connect()
    sql_shapes = con.sql(
        f"SELECT id, name, representation, len(feature) AS d "
        f"FROM read_parquet({store.files('shapes')}) ORDER BY id"
    ).fetchall()
    assert [r[0] for r in sql_shapes] == list(report.ingested)
    assert {r[3] for r in sql_shapes} == {tmp_db.config.dim}
    per_shape = con.sql(
        f"SELECT s.id, s.n_balls, count(b.ball) FROM read_parquet({store.files('shapes')}) s "
        f"JOIN read_parquet({store.files('balls')}) b ON b.shape_id = s.id "
        f"GROUP BY s.id, s.n_balls"
    ).fetchall()
    assert all(n == m for _, n, m in per_shape) and len(per_shape) == len(EXPECTED_REPR)
    edges = con.sql(f"SELECT count(*) FROM read_parquet({store.files('edges')})").fetchall()
    assert edges == [(n_edges,)]
    # a stored record rebuilds its decomposition
    rec = tmp_db.get("box")
    assert rec.decomposition.n_balls == rec.n_balls and rec.source.endswith("box.obj")
    assert rec.build_seconds > 0 and "load" in rec.decomposition.timings


def test_reingest_is_a_no_op_and_force_rebuilds(tmp_db: database.Database, good_files) -> None:  # type: ignore[no-untyped-def]
    files = [good_files["box.obj"], good_files["ico.off"]]
    first = tmp_db.ingest(files, workers=1)
    version = tmp_db.store.version
    again = tmp_db.ingest(files, workers=1)
    assert again.ingested == () and len(again.skipped) == 2
    assert tmp_db.store.version == version
    forced = tmp_db.ingest(files[:1], workers=1, force=True)
    assert forced.ingested == first.ingested[:1]  # rebuilt in place: same id
    assert len(tmp_db) == 2
    # the same file forced to another representation is another shape
    cloud = tmp_db.ingest(files[1:], workers=1, as_="pointcloud")
    assert len(cloud.ingested) == 1
    assert tmp_db.get(cloud.ingested[0]).representation == "pointcloud"


def test_changed_config_is_refused_on_connect(tmp_db: database.Database) -> None:
    with pytest.raises(ConfigError, match="resolution"):
        database.connect(tmp_db.path, resolution=48)
    assert database.connect(tmp_db.path, **SMALL).config == tmp_db.config


def test_labels_from_csv_and_folders(tmp_db: database.Database, tmp_path: Path) -> None:
    root = tmp_path / "models"
    for cls, make in (("boxes", trimesh.creation.box), ("balls", trimesh.creation.icosphere)):
        (root / cls).mkdir(parents=True)
        make().export(root / cls / f"{cls}_1.obj")
    trimesh.creation.box(extents=(1, 2, 1)).export(root / "boxes" / "tall.obj")
    csv = tmp_path / "labels.csv"
    csv.write_text("path,label,author\nmodels/boxes/tall.obj,tower,ann\n")
    report = tmp_db.ingest(root, labels=csv, label_from_folder=True, workers=1)
    assert len(report.ingested) == 3
    rows = {r["name"]: r for r in tmp_db.shapes(["name", "label", "metadata"]).to_pylist()}
    assert rows["tall"]["label"] == "tower" and dict(rows["tall"]["metadata"]) == {"author": "ann"}
    assert rows["boxes_1"]["label"] == "boxes" and rows["balls_1"]["label"] == "balls"
    assert tmp_db.info()["labels"] == {"balls": 1, "boxes": 1, "tower": 1}


def test_in_memory_shapes_and_names(tmp_db: database.Database) -> None:
    report = tmp_db.ingest(
        [("ball", Sphere([0, 0, 0], 1.0)), ("brick", Box([0, 0, 0], [2.0, 1.0, 0.5]))], workers=1
    )
    assert len(report.ingested) == 2
    assert tmp_db.get("brick").representation == "implicit"
    again = tmp_db.ingest({"ball-again": Sphere([0, 0, 0], 1.0)}, workers=1)
    assert again.skipped == ("ball-again",)  # same content: already present
    named = tmp_db.ingest([Sphere([0, 0, 0], 2.0)], names=["big"], workers=1)
    assert tmp_db.get("big").id == named.ingested[0]
    labelled = tmp_db.ingest([("cube", "boxes", Box([0, 0, 0], [1.0, 1.0, 1.0]))], workers=1)
    assert tmp_db.get(labelled.ingested[0]).label == "boxes"
    with pytest.raises(ConfigError, match="names"):
        tmp_db.ingest([Sphere([0, 0, 0], 3.0)], names=["a", "b"])


def test_bad_input_folder(tmp_db: database.Database, bad_dir) -> None:  # type: ignore[no-untyped-def]
    folder, expected = bad_dir
    # a file of no supported type found by walking a folder is ignored, not failed
    assert expected.pop("model.fbx") == "UnsupportedFormatError"
    report = tmp_db.ingest(folder, workers=2)
    assert sorted(tmp_db.shapes(["name"]).column("name").to_pylist()) == ["good_box", "good_ico"]
    assert [(Path(p).name, why) for p, why in report.ignored] == [
        ("model.fbx", "unsupported file type '.fbx'")
    ]
    failed = {Path(p).name: e for p, e in report.failed}
    assert set(failed) == set(expected)
    for name, error in failed.items():
        assert error.startswith(expected[name]), (name, error)
    stored = tmp_db.info()["failures"]
    assert {Path(f["path"]).name for f in stored} == set(expected)
    # a re-run retries the failures, records them once, and skips the good files
    again = tmp_db.ingest(folder, workers=1)
    assert len(again.skipped) == 2 and len(again.failed) == len(expected)
    assert len(tmp_db.info()["failures"]) == len(expected)


def test_missing_input_is_a_failure_not_a_crash(tmp_db: database.Database, tmp_path: Path) -> None:
    report = tmp_db.ingest([tmp_path / "nope.obj"], workers=1)
    assert report.ingested == () and "no such file" in report.failed[0][1]


def test_deletion(tmp_db: database.Database, good_files) -> None:  # type: ignore[no-untyped-def]
    tmp_db.ingest([good_files["box.obj"], good_files["ico.off"], good_files["cyl.stl"]], workers=1)
    assert tmp_db.delete("ico") == 1
    assert tmp_db.delete([1]) == 1
    assert tmp_db.shapes(["name"]).column("name").to_pylist() == ["cyl"]
    with pytest.raises(NotFoundError):
        tmp_db.delete("ico")
    # a deleted file can be ingested again
    assert len(tmp_db.ingest([good_files["ico.off"]], workers=1).ingested) == 1


def test_process_pool_matches_serial(tmp_path: Path, good_files) -> None:  # type: ignore[no-untyped-def]
    files = [good_files[n] for n in ("box.obj", "ico.off", "capsule.ply")]
    serial = database.connect(tmp_path / "a", **SMALL)
    pooled = database.connect(tmp_path / "b", **SMALL)
    serial.ingest(files, workers=1)
    report = pooled.ingest(files, workers=2, batch_size=1)
    assert len(report.ingested) == 3, report.failed
    assert pooled.store.version == 3
    for name in ("box", "ico", "capsule"):  # ids follow completion order: compare by name
        np.testing.assert_allclose(serial.get(name).feature, pooled.get(name).feature, rtol=1e-6)


def test_dask_local_cluster(tmp_db: database.Database, good_files) -> None:  # type: ignore[no-untyped-def]
    distributed = pytest.importorskip("distributed")
    files = [good_files[n] for n in ("box.obj", "ico.off")]
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, dashboard_address=":0"
    ) as cluster:
        report = tmp_db.ingest(files, scheduler=cluster.scheduler_address)
    assert len(report.ingested) == 2 and report.failed == ()
    assert sorted(tmp_db.shapes(["name"]).column("name").to_pylist()) == ["box", "ico"]


def test_reader_sees_only_whole_batches(tmp_db: database.Database) -> None:
    shapes = [(f"s{k}", Sphere([0, 0, 0], 1.0 + 0.1 * k)) for k in range(12)]
    batch = 3
    seen: list[int] = []
    errors: list[str] = []
    stop = threading.Event()

    def read() -> None:
        store = tmp_db.store
        while not stop.is_set():
            t = store.shapes(["id", "n_balls"])
            balls = store.balls(t.column("id").to_pylist())
            counts = dict(
                zip(
                    *np.unique(balls.column("shape_id").to_numpy(), return_counts=True), strict=True
                )
            )
            for sid, n in zip(
                t.column("id").to_pylist(), t.column("n_balls").to_pylist(), strict=True
            ):
                if counts.get(sid, 0) != n:
                    errors.append(f"shape {sid}: {counts.get(sid, 0)} balls of {n}")
            seen.append(t.num_rows)
            time.sleep(0.001)

    reader = threading.Thread(target=read)
    reader.start()
    try:
        report = tmp_db.ingest(shapes, workers=1, batch_size=batch)
    finally:
        stop.set()
        reader.join()
    assert len(report.ingested) == 12 and not errors
    assert seen and all(n % batch == 0 for n in seen), sorted(set(seen))
    assert tmp_db.store.version == 12 // batch


def test_a_flat_sheet_is_a_model_not_a_failure(tmp_db: database.Database, tmp_path: Path) -> None:
    sheet = tmp_path / "table_top.obj"  # one quad, zero thickness: decomposed as a thin slab
    sheet.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    report = tmp_db.ingest([sheet], workers=1)
    assert report.failed == () and len(report.ingested) == 1
    assert tmp_db.get("table_top").decomposition.n_balls > 0
