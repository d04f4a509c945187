"""Ingest never aborts on one file: names, links, caps, counts."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
import trimesh

import query.database as database
from ingest import load
from shapedb.errors import ConfigError, LoadError
from shapedb.store.integrity import check

BOX = trimesh.creation.box(extents=(1.0, 0.8, 0.6))


def _write_obj(path: Path, mesh: trimesh.Trimesh = BOX) -> Path:
    path.write_bytes(mesh.export(file_type="obj").encode())
    return path


def _names(db: database.Database) -> list[str]:
    return sorted(db.shapes().column("name").to_pylist())


def test_a_name_that_is_not_utf8_is_one_row_not_a_crash(tmp_db, tmp_path: Path) -> None:
    """the good models of the batch are stored, and a re-run is clean."""
    folder = tmp_path / "models"
    folder.mkdir()
    _write_obj(folder / "good one.obj")
    _write_obj(folder / "Stuhl-вращение-椅子.obj", trimesh.creation.icosphere(subdivisions=1))
    bad = os.fsencode(folder) + b"/caf\xe9-\xff.obj"
    with open(bad, "wb") as fh:
        fh.write(trimesh.creation.cylinder(radius=0.4, height=1.0).export(file_type="obj").encode())
    report = tmp_db.ingest(folder, workers=1)
    assert report.failed == () and len(report.ingested) == 3
    names = _names(tmp_db)
    assert "good one" in names and "Stuhl-вращение-椅子" in names
    assert "caf\\xe9-\\xff" in names  # the undecodable bytes, escaped
    again = tmp_db.ingest(folder, workers=1)
    assert len(again.skipped) == 3 and again.failed == ()
    assert check(tmp_db.store.path).ok


def test_an_unreadable_undecodable_file_is_one_failure_row(tmp_db, tmp_path: Path) -> None:
    folder = tmp_path / "m"
    folder.mkdir()
    _write_obj(folder / "ok.obj")
    with open(os.fsencode(folder) + b"/junk\xff.obj", "wb") as fh:
        fh.write(b"\x00\x01 not an obj")
    report = tmp_db.ingest(folder, workers=1)
    assert len(report.ingested) == 1 and len(report.failed) == 1
    assert "junk\\xff.obj" in report.failed[0][0]
    assert tmp_db.store.failures().column("source").to_pylist() == [report.failed[0][0]]


def test_symlinked_folders_are_followed_once(tmp_db, tmp_path: Path) -> None:
    real = tmp_path / "real"
    real.mkdir()
    _write_obj(real / "box.obj")
    top = tmp_path / "top"
    top.mkdir()
    _write_obj(top / "sphere.obj", trimesh.creation.icosphere(subdivisions=1))
    (top / "linked").symlink_to(real, target_is_directory=True)
    (top / "loop").symlink_to(top, target_is_directory=True)  # a cycle
    report = tmp_db.ingest(top, workers=1)
    assert report.failed == ()
    assert _names(tmp_db) == ["box", "sphere"]


@pytest.mark.parametrize("workers", [0, -3, 1.5, True])
def test_workers_must_be_a_positive_integer(tmp_db, tmp_path: Path, workers) -> None:
    with pytest.raises(ConfigError, match="workers"):
        tmp_db.ingest(_write_obj(tmp_path / "a.obj"), workers=workers)


def test_obj_without_faces_is_a_point_cloud_said_in_the_report(tmp_db, tmp_path: Path) -> None:
    """an OBJ cut before its faces is stored as a cloud, with a note."""
    text = BOX.export(file_type="obj")
    pts = trimesh.creation.icosphere(subdivisions=2).vertices
    head = "".join(f"v {x} {y} {z}\n" for x, y, z in pts)
    cut = tmp_path / "cut.obj"
    cut.write_text(head)
    whole = _write_obj(tmp_path / "whole.obj")
    report = tmp_db.ingest([cut, whole], workers=1)
    assert report.failed == ()
    assert [p for p, _ in report.notes] == [str(cut)]
    assert "no faces" in report.notes[0][1] and "point cloud" in report.notes[0][1]
    assert report.to_dict()["notes"][0]["path"] == str(cut)
    assert "v " in text


def test_off_counts_disagreeing_with_the_header_are_a_load_error(tmp_path: Path) -> None:
    good = tmp_path / "good.off"
    good.write_bytes(BOX.export(file_type="off").encode())
    assert len(load(good).faces) == len(BOX.faces)
    lines = good.read_text().splitlines()
    short = tmp_path / "short.off"
    short.write_text("\n".join(lines[:-3]) + "\n")  # three faces cut off
    with pytest.raises(LoadError, match="truncated: the header announces 8 vertices and 12 faces"):
        load(short)
    wrong = tmp_path / "wrong.off"
    wrong.write_text("\n".join([*lines[:-1], "3 0 1 99"]) + "\n")
    with pytest.raises(LoadError, match="face names vertices"):
        load(wrong)


def test_obj_faces_naming_missing_vertices_are_a_load_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.obj"
    bad.write_text(BOX.export(file_type="obj") + "f 1 2 40\n")
    with pytest.raises(LoadError, match="vertex 40 but the file has 8 vertices"):
        load(bad)
    neg = tmp_path / "neg.obj"
    neg.write_text("v 0 0 0\nv 1 0 0\nf -1 -2 -3\n")
    with pytest.raises(LoadError, match="vertex -3"):
        load(neg)


def test_caps_refuse_giant_files_as_failure_rows(tmp_db, tmp_path: Path) -> None:
    big = _write_obj(tmp_path / "big.obj", trimesh.creation.icosphere(subdivisions=3))
    small = _write_obj(tmp_path / "small.obj")
    report = tmp_db.ingest([big, small], workers=1, max_faces=100)
    assert len(report.ingested) == 1 and "max_faces=100" in report.failed[0][1]
    report = tmp_db.ingest([big], workers=1, max_bytes=1000)
    assert "max_bytes=1000" in report.failed[0][1]
    with pytest.raises(ConfigError, match="max_bytes"):
        tmp_db.ingest([big], max_bytes=0)


def test_ingest_into_a_folder_that_is_not_a_store_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "documents"
    folder.mkdir()
    (folder / "thesis.tex").write_text("precious")
    from shapedb.errors import StoreError

    with pytest.raises(StoreError, match="not empty"):
        database.connect(folder)
    assert [p.name for p in folder.iterdir()] == ["thesis.tex"]
    shutil.rmtree(folder)


def test_ingest_into_a_store_without_its_manifest_changes_nothing(tmp_db, tmp_path: Path) -> None:
    """rm manifest.json; ingest --db base."""
    from shapedb.errors import StoreError

    tmp_db.ingest([_write_obj(tmp_path / "a.obj")], workers=1)
    root = tmp_db.store.path
    files = sorted(root.rglob("*.parquet"))
    (root / "manifest.json").unlink()
    with pytest.raises(StoreError, match="manifest.json is missing.*shapedb repair"):
        database.connect(root).ingest(
            [_write_obj(tmp_path / "b.obj", trimesh.creation.icosphere())]
        )
    assert sorted(root.rglob("*.parquet")) == files


def test_a_dead_worker_under_a_users_script_names_the_likely_cause(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Workers import the caller's script: one that ingests at its top level kills them."""
    import sys
    import types
    from concurrent.futures.process import BrokenProcessPool

    from ingest.workers import result
    from shapedb.errors import ShapeDBError

    class Dead:
        def result(self) -> None:
            raise BrokenProcessPool("terminated abruptly")

    monkeypatch.setitem(sys.modules, "__main__", types.SimpleNamespace(__file__="/w/measure.py"))
    item = types.SimpleNamespace(source="/w/models/a.ply")
    with pytest.raises(ShapeDBError, match="measure.py.*if __name__ == '__main__'") as err:
        result(Dead(), item)
    assert "a.ply" in str(err.value) and "\n" not in str(err.value)
