"""The ingest report accounts for every input; labels matches; progress for a person waiting."""

from __future__ import annotations

import ast
import io
import logging
import shutil
from pathlib import Path

import pytest
import trimesh

import ingest.progress
import query.database as database
from ingest.progress import LOG_SECONDS, Progress
from shapedb.errors import ConfigError

INGEST = Path(__file__).resolve().parents[2] / "ingest"


@pytest.fixture()
def messy(tmp_path: Path, good_files: dict[str, Path]) -> Path:
    """A folder of good, identical, failing, hidden, companion and foreign files."""
    folder = tmp_path / "messy"
    (folder / "sub").mkdir(parents=True)
    (folder / ".git").mkdir()
    (folder / ".git" / "model.obj").write_bytes(good_files["box.obj"].read_bytes())
    shutil.copy(good_files["box.obj"], folder / "box.obj")
    shutil.copy(good_files["box.obj"], folder / "sub" / "box_copy.obj")  # same content
    shutil.copy(good_files["ico.off"], folder / "ico.off")
    broken = b"\0" * 80 + b"\x05\0\0\0" + b"\1"
    (folder / "broken1.stl").write_bytes(broken)
    (folder / "sub" / "broken2.stl").write_bytes(broken)  # same content, also broken
    shutil.copy(good_files["box.obj"], folder / "..obj")
    shutil.copy(good_files["cyl.stl"], folder / ".x.stl")
    (folder / "box.mtl").write_text("newmtl a\n")
    (folder / "scene.fbx").write_bytes(b"Kaydara FBX Binary  \0junk")
    return folder


def _outcomes(report) -> dict[str, tuple[str, str]]:  # type: ignore[no-untyped-def]
    names = [Path(p).name for p, _, _ in report.outcomes]
    assert len(names) == len(set(names)), names  # each path exactly once
    return {Path(p).name: (o, d) for p, o, d in report.outcomes}


def test_every_path_ends_in_exactly_one_outcome(tmp_db: database.Database, messy: Path) -> None:
    tmp_db.ingest([messy / "ico.off"], workers=1, progress=False)
    report = tmp_db.ingest(messy, workers=1, progress=False)
    got = _outcomes(report)
    assert {n: o for n, (o, _) in got.items()} == {
        "box.obj": "stored",
        "box_copy.obj": "unchanged",
        "ico.off": "unchanged",
        "broken1.stl": "failed",
        "broken2.stl": "failed",
        "..obj": "ignored",
        ".x.stl": "ignored",
        ".git": "ignored",
        "box.mtl": "ignored",
        "scene.fbx": "ignored",
    }
    # identical failing files are each parsed-or-judged and reported with the reason
    assert "truncated" in got["broken1.stl"][1] and got["broken2.stl"][1] == got["broken1.stl"][1]
    assert {Path(p).name for p, _ in report.failed} == {"broken1.stl", "broken2.stl"}
    assert {Path(f["path"]).name for f in tmp_db.info()["failures"]} == {
        "broken1.stl",
        "broken2.stl",
    }
    assert got["..obj"][1] == "hidden file" and got[".git"][1] == "hidden folder"
    assert "companion" in got["box.mtl"][1] and "unsupported" in got["scene.fbx"][1]
    assert got["box_copy.obj"][1].startswith("same content as") and got["box.obj"][1] == str(
        report.ingested[0]
    )
    # the older fields keep working and agree with the outcomes
    assert len(report.ingested) == 1 and set(report.skipped) == set(report.unchanged)
    assert {Path(p).name for p in report.skipped} == {"box_copy.obj", "ico.off"}
    assert report.counts() == {"stored": 1, "unchanged": 2, "failed": 2, "ignored": 5}
    assert "ignored=5" in repr(report)


def test_identical_good_files_are_stored_once(tmp_db: database.Database, messy: Path) -> None:
    files = [messy / "box.obj", messy / "sub" / "box_copy.obj", messy / "box.obj"]
    report = tmp_db.ingest(files, workers=1, progress=False)
    assert [o for _, o, _ in report.outcomes] == ["stored", "unchanged", "unchanged"]
    assert len(tmp_db) == 1


def _labelled(tmp_path: Path) -> Path:
    root = tmp_path / "models"
    root.mkdir()
    trimesh.creation.box().export(root / "a.obj")
    trimesh.creation.icosphere().export(root / "b.obj")
    return root


def test_labels_matching_none_of_the_files_is_an_error(
    tmp_db: database.Database, tmp_path: Path
) -> None:
    root = _labelled(tmp_path)
    csv = tmp_path / "labels.csv"
    csv.write_text("path,label\nother/x.obj,chair\nother/y.obj,table\n")
    with pytest.raises(ConfigError, match="match none of the 2 inputs") as info:
        tmp_db.ingest(root, labels=csv, workers=1, progress=False)
    assert str(csv) in str(info.value) and "\n" not in str(info.value)
    assert len(tmp_db) == 0


def test_labels_report_matches_and_warn_about_the_rest(
    tmp_db: database.Database, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    root = _labelled(tmp_path)
    csv = tmp_path / "labels.csv"
    csv.write_text("path,label\nmodels/a.obj,box\nmodels/typo.obj,ball\n")
    with caplog.at_level(logging.INFO, logger="ingest"):
        report = tmp_db.ingest(root, labels=csv, workers=1, progress=False)
    assert report.labels_matched == 1 and len(report.ingested) == 2
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any("models/typo.obj" in w and "matched no input" in w for w in warnings), warnings
    assert any("b.obj" in w and "not listed" in w for w in warnings), warnings
    assert any("1 of 2 inputs labelled" in r.getMessage() for r in caplog.records)
    assert tmp_db.ingest(root, workers=1, progress=False).labels_matched is None


def test_progress_bar_on_a_terminal() -> None:
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    out = Terminal()
    with Progress(4, done=1, stream=out) as bar:
        for k in (2, 3, 4):
            bar.update(k)
    text = out.getvalue()
    assert "4/4" in text and "file/s" in text  # count and rate; tqdm shows time left: <..
    assert "<" in text


def test_progress_log_lines_off_a_terminal(caplog: pytest.LogCaptureFixture) -> None:
    assert 2.0 <= LOG_SECONDS <= 10.0
    with caplog.at_level(logging.INFO, logger="ingest.progress"):
        with Progress(10, done=2, stream=io.StringIO(), seconds=0.05) as bar:
            bar.update(6)
            import time

            time.sleep(0.3)
    lines = [r.getMessage() for r in caplog.records if r.name == "ingest.progress"]
    assert lines and lines[-1].startswith("ingest: 6 / 10 files,") and "files/s" in lines[-1]
    assert "left" in lines[-1]


def test_ingest_logs_progress_unless_silenced(
    tmp_db: database.Database,
    good_files: dict[str, Path],
    caplog: pytest.LogCaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(ingest.progress, "LOG_SECONDS", 0.01)
    files = [good_files["box.obj"], good_files["ico.off"]]
    with caplog.at_level(logging.INFO, logger="ingest.progress"):
        tmp_db.ingest(files, workers=1, progress=False)
        assert not [r for r in caplog.records if r.name == "ingest.progress"]
        tmp_db.ingest(files, workers=1, force=True)
    assert [r for r in caplog.records if r.name == "ingest.progress"]
    calls: list[tuple[int, int]] = []
    tmp_db.ingest(files, workers=1, force=True, progress=lambda d, t: calls.append((d, t)))
    assert calls[0] == (0, 2) and calls[-1] == (2, 2)


def test_no_function_in_ingest_is_over_80_lines() -> None:
    long = []
    for path in sorted(INGEST.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > 80:
                    long.append(f"{path.name}:{node.name} ({n} lines)")
    assert not long, long
