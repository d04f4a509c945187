"""The ``shapedb`` command line, called through ``main([...])``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import trimesh

from query.cli import main


@pytest.fixture()
def models(tmp_path: Path) -> Path:
    folder = tmp_path / "models"
    for cls, shapes in {
        "boxes": [(1, 1, 1), (1, 2, 1), (1, 1, 3)],
        "rods": [(0.6, 0.6, 3), (0.7, 0.7, 4), (0.6, 0.8, 2.5)],
    }.items():
        (folder / cls).mkdir(parents=True)
        for k, ext in enumerate(shapes):
            trimesh.creation.box(extents=ext).export(folder / cls / f"{cls}{k}.obj")
    (folder / "broken.stl").write_bytes(b"\0" * 80 + b"\x05\0\0\0" + b"\1")
    return folder


def _json(capsys: pytest.CaptureFixture[str]) -> object:
    return json.loads(capsys.readouterr().out)


def _ingest(models: Path, db: Path, *extra: str) -> int:
    return main(
        [
            "ingest",
            str(models),
            "--db",
            str(db),
            "--resolution",
            "32",
            "--balls",
            "64",
            "--workers",
            "1",
            "--label-from-folder",
            *extra,
        ]
    )


def test_ingest_info_delete(
    tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "db"
    assert _ingest(models, db, "--json") == 1  # one input failed
    report = _json(capsys)
    assert report["ingested"] == 6 and report["skipped"] == 0
    assert [Path(f["path"]).name for f in report["failed"]] == ["broken.stl"]
    assert "truncated" in report["failed"][0]["error"]
    assert set(report) == {"ingested", "skipped", "failed", "notes"}

    assert main(["info", "--db", str(db), "--json"]) == 0
    info = _json(capsys)
    assert set(info) == {"shapes", "labels", "failures", "config"}
    assert info["shapes"] == 6 and info["labels"] == {"boxes": 3, "rods": 3}
    assert info["config"]["mdbd"]["resolution"] == 32
    assert [Path(f["path"]).name for f in info["failures"]] == ["broken.stl"]

    (models / "broken.stl").unlink()
    assert _ingest(models, db, "--json") == 0  # idempotent
    assert _json(capsys) == {"ingested": 0, "skipped": 6, "failed": [], "notes": []}

    assert main(["delete", "boxes0", "2", "--db", str(db)]) == 0
    assert "deleted 2" in capsys.readouterr().out
    assert main(["info", "--db", str(db)]) == 0
    text = capsys.readouterr().out
    assert "shapes:   4" in text and "rods" in text


def test_ingest_sets_any_option_of_a_new_store(
    tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "db"
    (models / "broken.stl").unlink()
    assert _ingest(models, db, "--set", "tie_cells=0", "--set", "descriptor=1", "--json") == 0
    capsys.readouterr()
    assert main(["info", "--db", str(db), "--json"]) == 0
    config = _json(capsys)["config"]
    assert config["mdbd"]["tie_cells"] == 0.0 and config["descriptor"]["version"] == 1
    assert main(["ingest", str(models), "--db", str(db), "--set", "colour=red"]) == 1
    assert "unknown configuration option 'colour'" in capsys.readouterr().err


def test_fv_enabled_false_makes_the_store_of_before_the_field_vectors(
    tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (models / "broken.stl").unlink()
    plain, kept = tmp_path / "plain", tmp_path / "kept"
    assert _ingest(models / "rods", plain, "--set", "fv_enabled=false") == 0
    assert _ingest(models / "rods", kept) == 0
    capsys.readouterr()
    query = "SELECT count(field_vector) AS n FROM shapes"
    for db, n in ((plain, 0), (kept, 3)):
        assert main(["sql", query, "--db", str(db), "--json"]) == 0
        assert _json(capsys) == [{"n": n}]
    assert main(["info", "--db", str(plain), "--json"]) == 0
    assert _json(capsys)["config"]["field_vector"]["enabled"] is False


def test_plain_output(tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _ingest(models, tmp_path / "db") == 1
    out = capsys.readouterr().out
    assert out.startswith("ingested 6, skipped 0, failed 1")
    assert "broken.stl" in out


def test_errors_are_one_line(
    tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["info", "--db", str(tmp_path / "missing")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("shapedb: error: ") and err.count("\n") == 1
    assert "no shapedb store" in err
    assert not (tmp_path / "missing").exists()
    db = tmp_path / "db"
    _ingest(models, db)
    capsys.readouterr()
    assert main(["ingest", str(models), "--db", str(db), "--resolution", "64"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("shapedb: error: ") and "resolution" in err
    assert main(["delete", "nope", "--db", str(db)]) == 1
    assert "nope" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["ingest", "--db", str(db)])  # argparse: PATH is required
    assert exit_info.value.code == 2


def test_search_sql_eval(tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("faiss")
    db = tmp_path / "db"
    _ingest(models, db)
    capsys.readouterr()
    assert main(["search", "rods1", "--db", str(db), "-k", "3", "--json"]) == 0
    hits = _json(capsys)
    assert len(hits) == 3
    assert set(hits[0]) == {"id", "name", "label", "similarity", "distance"}
    assert hits[0]["name"] == "rods1" and hits[0]["similarity"] == pytest.approx(1.0)
    query = models / "boxes" / "boxes2.obj"
    assert (
        main(
            [
                "search",
                str(query),
                "--db",
                str(db),
                "-k",
                "2",
                "--where",
                "label = 'boxes'",
                "--json",
            ]
        )
        == 0
    )
    assert {h["label"] for h in _json(capsys)} == {"boxes"}

    sql = "SELECT label, count(*) AS n FROM shapes GROUP BY label ORDER BY label"
    assert main(["sql", sql, "--db", str(db), "--json"]) == 0
    assert _json(capsys) == [{"label": "boxes", "n": 3}, {"label": "rods", "n": 3}]
    assert main(["sql", sql, "--db", str(db), "--csv"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].replace('"', "") == "label,n" and len(lines) == 3
    assert main(["sql", sql, "--db", str(db)]) == 0
    assert "boxes" in capsys.readouterr().out
    assert main(["sql", "SELEC nonsense", "--db", str(db)]) == 1
    assert capsys.readouterr().err.startswith("shapedb: error: ")

    assert main(["eval", "--db", str(db), "--json", "--plot", str(tmp_path / "pr.png")]) == 0
    scores = _json(capsys)
    assert scores["queries"] == 6 and 0.0 <= scores["nn"] <= 1.0
    assert (tmp_path / "pr.png").stat().st_size > 0

    metric = tmp_path / "metric.json"
    assert main(["fit-metric", "--db", str(db), "--out", str(metric)]) == 0
    assert f"saved to {metric}" in capsys.readouterr().out
    assert main(["fit-metric", "--db", str(db), "--out", str(metric), "--json"]) == 0
    fitted = _json(capsys)
    assert fitted["n_shapes"] == 6 and fitted["n_classes"] == 2 and metric.exists()
    assert main(["eval", "--db", str(db), "--metric", str(metric), "--json"]) == 0
    assert _json(capsys)["queries"] == 6
    assert main(["search", "rods1", "--db", str(db), "--metric", str(metric), "--json"]) == 0
    assert _json(capsys)[0]["name"] == "rods1"
    weighted = "SELECT mdbd_kernel(feature, feature) AS k FROM shapes LIMIT 1"
    assert main(["sql", weighted, "--db", str(db), "--metric", str(metric), "--json"]) == 0
    assert _json(capsys) == [{"k": 1.0}]
    assert main(["search", "rods1", "--db", str(db), "--metric", str(tmp_path / "no.json")]) == 1
    assert "no.json" in capsys.readouterr().err


@pytest.mark.slow
def test_demo(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("faiss")
    assert main(["demo", "--db", str(tmp_path / "demo"), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "ingested 20" in out and "shapes most like" in out
    assert f"shapedb serve --db {tmp_path / 'demo'}" in out


def test_show_and_match(tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("faiss")
    db = tmp_path / "db"
    _ingest(models, db)
    capsys.readouterr()
    png = tmp_path / "rod.png"
    assert main(["show", "rods1", "--db", str(db), "--out", str(png)]) == 0
    assert png.stat().st_size > 10_000  # a real picture, not an empty canvas
    file_png = tmp_path / "file.png"
    assert main(["show", str(models / "boxes" / "boxes0.obj"), "--out", str(file_png)]) == 0
    assert file_png.stat().st_size > 10_000
    assert capsys.readouterr().out.split() == [str(png), str(file_png)]

    out = tmp_path / "match.png"
    argv = ["match", "rods1", "--db", str(db), "--node", "0", "-k", "3", "--json"]
    assert main([*argv, "--out", str(out)]) == 0
    matches = _json(capsys)
    assert 1 <= len(matches) <= 3
    assert set(matches[0]) == {"id", "name", "label", "similarity", "nodes"}
    assert matches[0]["name"] == "rods1" and matches[0]["similarity"] == pytest.approx(1.0)
    assert all(isinstance(n, int) for n in matches[0]["nodes"])
    assert out.stat().st_size > 10_000
    assert main(["match", "no-such-shape", "--db", str(db), "--node", "0"]) == 1
    assert capsys.readouterr().err.startswith("shapedb: error: ")


def test_train_and_classify(
    tmp_path: Path, models: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from query.learn.gnn import import_torch

    try:
        import_torch()
    except ImportError:
        pytest.skip("needs the learn extra: pip install 'shapedb[learn]'")
    db = tmp_path / "db"
    _ingest(models, db)
    capsys.readouterr()
    model = tmp_path / "m.pt"
    argv = ["train", "--db", str(db), "--epochs", "2", "--out", str(model), "--json"]
    argv += ["--methods", "1-nn", "linear", "tag", "--test", "0"]
    assert main(argv) == 0
    trained = _json(capsys)
    assert trained["classes"] == ["boxes", "rods"] and model.exists()
    scores = trained["selection"]["scores"]
    assert [s["name"] for s in scores] == ["1-nn", "linear", "tag"]
    chosen = max(scores, key=lambda s: s["correct"])  # the first of ties: the simplest
    assert trained["kind"] == trained["selection"]["chosen"] == chosen["name"]
    query = str(models / "rods" / "rods0.obj")
    assert main(["classify", query, "--db", str(db), "--model", str(model), "--json"]) == 0
    result = _json(capsys)
    assert result["label"] in {"boxes", "rods"}
    assert sum(result["probabilities"].values()) == pytest.approx(1.0)
    # many models, one process and one load: one JSON line each, in order
    argv = ["classify", query, "boxes0", "rods1", "--db", str(db), "--model", str(model)]
    assert main([*argv, "--json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["source"] for r in lines] == [query, "boxes0", "rods1"]
    assert all(r["label"] in {"boxes", "rods"} for r in lines)
    assert main(["classify", query, "--db", str(db), "--model", str(tmp_path / "none.pt")]) == 1
    assert capsys.readouterr().err.startswith("shapedb: error: ")


def test_ingest_voxels_as_smooth_solids(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import numpy as np

    folder = tmp_path / "vox"
    folder.mkdir()
    occ = np.zeros((16, 16, 16), dtype=bool)
    occ[3:13, 3:13, 4:10] = True
    np.save(folder / "slab.npy", occ)
    db = tmp_path / "db"
    assert main(["ingest", str(folder), "--db", str(db), "--resolution", "24", "--balls", "16",
                 "--workers", "1", "--json"]) == 0  # fmt: skip
    assert _json(capsys)["ingested"] == 1
    # the same file read as a smooth solid is another shape (another solid)
    assert main(["ingest", str(folder), "--db", str(db), "--as", "smooth_voxels",
                 "--workers", "1", "--json"]) == 0  # fmt: skip
    assert _json(capsys) == {"ingested": 1, "skipped": 0, "failed": [], "notes": []}
