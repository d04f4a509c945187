"""``shapedb check`` / ``repair`` and the CLI's guards on store input."""

from __future__ import annotations

from pathlib import Path

import pytest
import trimesh

from query.cli import main


@pytest.fixture()
def base(tmp_path: Path) -> Path:
    """A store of three small models, built through the CLI."""
    folder = tmp_path / "models"
    folder.mkdir()
    for k, ext in enumerate([(1, 1, 1), (1, 2, 1), (0.6, 0.6, 3)]):
        trimesh.creation.box(extents=ext).export(folder / f"m{k}.obj")
    db = tmp_path / "base"
    args = ["ingest", str(folder), "--db", str(db), "--resolution", "24", "--balls", "32"]
    assert main([*args, "--workers", "1", "--lock-timeout", "2"]) == 0
    return db


def _err(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


def test_check_and_repair_through_the_cli(base: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "--db", str(base)]) == 0
    assert ": ok" in capsys.readouterr().out
    seg = sorted((base / "data" / "balls").glob("*.parquet"))[0]
    seg.write_bytes(seg.read_bytes()[:-10])
    assert main(["check", "--db", str(base)]) == 1
    out = capsys.readouterr().out
    assert f"damaged: data/balls/{seg.name}" in out and "shapedb repair" in out
    assert main(["sql", "SELECT count(*) FROM balls", "--db", str(base)]) == 1
    assert f"segment data/balls/{seg.name}" in _err(capsys)
    assert main(["repair", "--db", str(base)]) == 1  # the shapes of that segment are lost
    out = capsys.readouterr().out
    assert "not recovered" in out and "lost+found" in out
    assert main(["check", "--db", str(base)]) == 0
    assert main(["repair", "--db", str(base)]) == 0
    assert "nothing to repair" in capsys.readouterr().out


def test_compact_through_the_cli(
    base: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trimesh.creation.box(extents=(2, 1, 1)).export(tmp_path / "later.obj")
    assert main(["ingest", str(tmp_path / "later.obj"), "--db", str(base), "--workers", "1"]) == 0
    capsys.readouterr()
    assert main(["compact", "--db", str(base)]) == 0
    assert "segments: shapes 2 -> 1" in capsys.readouterr().out
    assert main(["compact", "--db", str(base), "--json"]) == 0
    assert '"shapes": 1' in capsys.readouterr().out
    assert main(["sql", "SELECT count(*) FROM shapes", "--db", str(base)]) == 0
    assert main(["compact", "--db", str(base / "missing")]) == 1


def test_missing_manifest_is_one_line_and_repairable(
    base: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (base / "manifest.json").unlink()
    model = next(base.parent.joinpath("models").glob("*.obj"))
    assert main(["ingest", str(model), "--db", str(base)]) == 1
    assert "manifest.json is missing" in _err(capsys)
    assert main(["check", "--db", str(base)]) == 1
    assert "shapedb repair" in _err(capsys)
    assert main(["repair", "--db", str(base), "--json"]) == 0
    assert main(["info", "--db", str(base), "--json"]) == 0
    assert '"shapes": 3' in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv",
    [
        ["search", "m0", "-k", "99999999999999999999"],
        ["search", "m0", "-k", "3000000000"],
        ["search", "m0", "-k", "0"],
        ["sql", "COPY (SELECT 'x') TO 'manifest.json'"],
        ["sql", "SELECT * FROM read_csv('/etc/passwd')"],
        ["sql", "ATTACH 'x.duckdb'"],
        [
            "search",
            "m0",
            "--where",
            "true); COPY (SELECT 42) TO 'y.csv'; SELECT id FROM shapes WHERE (true",
        ],
    ],
)
def test_hostile_input_is_one_line_exit_1(
    base: Path, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    assert main([*argv, "--db", str(base)]) == 1
    err = _err(capsys)
    assert err.startswith("shapedb: error:") and err.count("\n") == 1
    assert main(["check", "--db", str(base)]) == 0


@pytest.mark.parametrize(
    "option",
    [["--workers", "0"], ["--workers", "-3"], ["--lock-timeout", "-1"], ["--max-bytes", "0"]],
)
def test_ingest_options_are_validated(
    base: Path, capsys: pytest.CaptureFixture[str], option: list[str]
) -> None:
    model = next(base.parent.joinpath("models").glob("*.obj"))
    with pytest.raises(SystemExit) as exc:
        main(["ingest", str(model), "--db", str(base), *option])
    assert exc.value.code == 2
    assert "invalid" in capsys.readouterr().err
