"""The ``shapedb`` command line, called through ``main([...])``."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import pytest
import trimesh

from query.cli import main


def _boxes_and_rods(folder: Path) -> Path:
    """Six box meshes in ``folder``: three ``boxes`` and three ``rods``, a folder each."""
    for cls, shapes in {
        "boxes": [(1, 1, 1), (1, 2, 1), (1, 1, 3)],
        "rods": [(0.6, 0.6, 3), (0.7, 0.7, 4), (0.6, 0.8, 2.5)],
    }.items():
        (folder / cls).mkdir(parents=True)
        for k, ext in enumerate(shapes):
            trimesh.creation.box(extents=ext).export(folder / cls / f"{cls}{k}.obj")
    return folder


@pytest.fixture()
def models(tmp_path: Path) -> Path:
    folder = _boxes_and_rods(tmp_path / "models")
    (folder / "broken.stl").write_bytes(b"\0" * 80 + b"\x05\0\0\0" + b"\1")
    return folder


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A store of the six boxes and rods, labelled by folder, shared by the read-only tests."""
    root = tmp_path_factory.mktemp("store")
    assert _ingest(_boxes_and_rods(root / "models"), root / "db", "--quiet") == 0
    return root / "db"


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
    assert set(hits[0]) == {"id", "name", "label", "similarity", "distance", "path"}
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


# --------------------------------------------------------------------------------------
# Output for people
# --------------------------------------------------------------------------------------


def test_info_is_a_short_summary(store: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["info", "--db", str(store)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "labels:   2" in lines  # no stray colon
    assert "  boxes  3" in lines and "  rods   3" in lines
    size = next(line for line in lines if line.startswith("size:"))
    assert size.split()[2] in {"KB", "MB"} and "files" in size
    build = next(line for line in lines if line.startswith("build:"))
    assert "format 1" in build and "schema" in build and "created 20" in build
    assert not any("resolution" in line for line in lines)  # the configuration has its own flag
    assert len(lines) <= 12


def test_info_config_is_one_option_a_line_by_section(
    store: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from shapedb.config.core import OPTIONS

    capsys.readouterr()
    assert main(["info", "--db", str(store), "--config"]) == 0
    lines = capsys.readouterr().out.splitlines()
    sections = [line for line in lines if line.startswith("[")]
    assert "[mdbd]" in sections and len(sections) == len(set(sections)) >= 3
    options = [line.split() for line in lines if line.startswith("  ")]
    assert [o[0] for o in options] == list(OPTIONS) and all(o[1] == "=" for o in options)
    assert ["resolution", "=", "32"] in options
    assert main(["info", "--db", str(store), "--config", "--json"]) == 0
    assert _json(capsys)["mdbd"]["resolution"] == 32


def test_eval_prints_overall_scores_and_a_table_by_class(
    store: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert main(["eval", "--db", str(store), "--json"]) == 0
    scores = _json(capsys)
    keys = {"queries", "nn", "first_tier", "second_tier", "e_measure", "dcg", "per_class"}
    assert set(scores) == keys and set(scores["per_class"]) == {"boxes", "rods"}
    assert main(["eval", "--db", str(store)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "6 queries" in lines[0] and f"NN {scores['nn']:.3f}" in lines[1]
    at = next(i for i, line in enumerate(lines) if line.startswith("class"))
    header, rows = lines[at], lines[at + 1 :]
    assert header.split() == ["class", "queries", "NN", "1-T", "2-T", "DCG"]
    assert [r.split()[0] for r in rows] == ["boxes", "rods", "(all)"]
    for row in rows:  # aligned: every number ends where its column's name ends
        assert len(row) == len(header)
        ends = [m.end() for m in re.finditer(r"\S+", header)][1:]
        assert [m.end() for m in re.finditer(r"\S+", row)][1:] == ends
    boxes = scores["per_class"]["boxes"]
    assert rows[0].split()[1:] == [str(int(boxes["queries"]))] + [
        f"{boxes[k]:.3f}" for k in ("nn", "first_tier", "second_tier", "dcg")
    ]


def test_match_help_states_defaults_columns_and_ball_numbers(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["match", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    from query.cli import COMMANDS

    (command,) = [c for c in COMMANDS if c.name == "match"]
    parser = argparse.ArgumentParser()
    command.arguments(parser)
    for action in parser._actions:
        if action.option_strings and action.dest not in {"help", "verbose", "db"}:
            assert "default" in (action.help or ""), action.option_strings
    assert "(default 2)" in text  # --hops
    for column in ("similarity", "centre", "nodes"):
        assert re.search(rf"\b{column}\b", text.split("output columns:")[1]), column
    assert "shapedb show QUERY --balls" in text and "--out PNG" in text


def test_show_balls_lists_the_numbers_match_takes(
    store: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert main(["show", "rods1", "--balls", "--db", str(store)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["ball", "x", "y", "z", "radius", "contacts"]
    assert [int(line.split()[0]) for line in lines[1:]] == list(range(len(lines) - 1))
    assert main(["show", "rods1", "--db", str(store)]) == 1  # neither --out nor --balls
    assert "--balls" in capsys.readouterr().err


def test_sql_prints_an_aligned_table_with_readable_names(
    store: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    sql = "select label, count(*) from shapes group by label order by label"
    assert main(["sql", sql, "--db", str(store)]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "label  count",
        "boxes      3",
        "rods       3",
        "(2 rows)",
    ]
    assert main(["sql", sql, "--db", str(store), "--json"]) == 0  # the Arrow names, untouched
    assert _json(capsys) == [
        {"label": "boxes", "count_star()": 3},
        {"label": "rods", "count_star()": 3},
    ]


@pytest.mark.parametrize(
    "argv",
    [
        ["search", "100000000000000000000"],
        ["search", "rods1", "-k", "100000000000000000000"],
        ["delete", "100000000000000000000"],
        ["show", "100000000000000000000", "--balls"],
        ["match", "100000000000000000000", "--node", "0"],
        ["match", "rods1", "-k", "100000000000000000000"],
    ],
)
def test_numbers_out_of_range_are_one_line_errors(
    store: Path, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    capsys.readouterr()
    assert main([*argv, "--db", str(store)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("shapedb: error: ") and err.count("\n") == 1
    assert "100000000000000000000" in err and "internal" not in err


def test_ingest_quiet_asks_for_no_progress(
    models: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import query.database
    from shapedb.errors import QueryError

    seen: list[object] = []

    def ingest(self: object, paths: object, **options: object) -> None:
        seen.append(options["progress"])
        raise QueryError("stop here")

    monkeypatch.setattr(query.database.Database, "ingest", ingest)
    assert _ingest(models, tmp_path / "db", "--quiet") == 1
    assert _ingest(models, tmp_path / "db") == 1
    assert seen[0] is False and callable(seen[1])


def test_demo_ends_saying_where_its_store_is(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("faiss")
    import tempfile

    import query.cli.demo
    import shapedb.examples

    few = [s for s in shapedb.examples.catalogue() if s[1] in {"figure-s0", "figure-s1"}][::2]
    monkeypatch.setattr(shapedb.examples, "catalogue", lambda: few)
    monkeypatch.setattr(query.cli.demo, "DEMO_STORE", {"resolution": 24, "n_balls": 32})
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert main(["demo", "--workers", "1"]) == 0
    (made,) = tmp_path.glob("shapedb-demo-*")
    last = capsys.readouterr().out.splitlines()[-2:]
    assert str(made) in last[0] and last[1].startswith(f"remove it with:  rm -r {made}")
    assert main(["demo", "--workers", "1", "--clean"]) == 0
    last_line = capsys.readouterr().out.splitlines()[-1]
    assert last_line.startswith("removed the demo store")
    assert set(tmp_path.glob("shapedb-demo-*")) == {made}  # the second demo's store is gone
