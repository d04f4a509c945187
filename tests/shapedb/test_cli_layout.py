"""The layout of the ``shapedb`` command line: subcommands beside their handlers, one-line errors."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

import query.database
from query.cli import GROUPS, build_parser, main
from shapedb.errors import StoreError

#: Subcommands that must stay (groups may add more).
COMMANDS = {
    "ingest",
    "info",
    "delete",
    "search",
    "sql",
    "show",
    "match",
    "eval",
    "fit-metric",
    "train",
    "classify",
    "demo",
}


class _Recorder:
    """Stands in for ``add_subparsers()``: records the parser of each subcommand."""

    def __init__(self) -> None:
        self.parsers: dict[str, argparse.ArgumentParser] = {}

    def add_parser(self, name: str, **kwargs: object) -> argparse.ArgumentParser:
        self.parsers[name] = argparse.ArgumentParser(prog=name)
        return self.parsers[name]


def test_every_subcommand_is_registered_beside_its_handler() -> None:
    seen: set[str] = set()
    for group in GROUPS:
        recorder = _Recorder()
        group.register(recorder)
        for name, parser in recorder.parsers.items():
            handler = parser.get_default("handler")
            assert callable(handler), name
            assert handler.__module__ == group.__name__, (name, handler.__module__)
        assert not seen & set(recorder.parsers)
        seen |= set(recorder.parsers)
    assert COMMANDS <= seen


def test_the_parser_dispatches_to_the_handlers() -> None:
    args = build_parser().parse_args(["info", "--db", "x"])
    assert args.handler.__name__ == "info" and args.command == "info"


def _fail_on_connect(monkeypatch: pytest.MonkeyPatch, exc: Exception) -> None:
    def connect(*args: object, **kwargs: object) -> None:
        raise exc

    monkeypatch.setattr(query.database, "connect", connect)


def test_unexpected_error_is_one_line_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _fail_on_connect(monkeypatch, RuntimeError("disk\non fire"))
    assert main(["info", "--db", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("shapedb: internal error: RuntimeError: disk on fire")
    assert "Traceback" not in err


def test_verbose_shows_the_traceback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _fail_on_connect(monkeypatch, RuntimeError("disk on fire"))
    assert main(["-v", "info", "--db", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "in connect" in err
    assert err.splitlines()[-1] == "shapedb: internal error: RuntimeError: disk on fire"
    _fail_on_connect(monkeypatch, StoreError("no shapedb store at x"))
    assert main(["-v", "info", "--db", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err
    assert err.splitlines()[-1] == "shapedb: error: no shapedb store at x"
    assert main(["info", "--db", str(tmp_path)]) == 1
    assert capsys.readouterr().err == "shapedb: error: no shapedb store at x\n"
    assert main(["info", "--db", str(tmp_path), "-v"]) == 1  # -v after the subcommand too
    assert "Traceback" in capsys.readouterr().err


def test_console_script_is_main() -> None:
    from importlib.metadata import entry_points

    (script,) = entry_points(group="console_scripts", name="shapedb")
    assert script.load() is main


def test_help_lists_every_subcommand() -> None:
    code = "import sys; from query.cli import main; sys.exit(main(['--help']))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    for name in COMMANDS:
        assert name in out.stdout
