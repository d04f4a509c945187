"""The layout of the ``shapedb`` command line: one command table, short functions, one-line
errors."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import query.cli
import query.database
from query.cli import COMMANDS, build_parser, main
from shapedb.errors import StoreError

#: Subcommands that must stay (the table may add more).
COMMAND_NAMES = {
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


#: The longest function allowed in query/cli/ (lines, decorators and docstring included).
MAX_FUNCTION_LINES = 80


def test_the_command_table_names_every_subcommand_once_beside_its_handler() -> None:
    names = [c.name for c in COMMANDS]
    assert len(names) == len(set(names))
    assert COMMAND_NAMES <= set(names)
    for command in COMMANDS:
        assert command.help and command.help == " ".join(command.help.split()), command.name
        assert callable(command.arguments) and callable(command.handler), command.name
        assert command.handler.__module__.startswith("query.cli."), command.name


def test_the_parser_is_built_from_the_table() -> None:
    parser = build_parser()
    for command in COMMANDS:
        argv = [command.name, "--help"]
        with pytest.raises(SystemExit) as exc:
            parser.parse_args(argv)
        assert exc.value.code == 0, command.name
    args = parser.parse_args(["delete", "7", "--db", "x"])
    (delete,) = [c for c in COMMANDS if c.name == "delete"]
    assert args.handler is delete.handler and args.targets == ["7"]


def _function_lines(path: Path) -> dict[str, int]:
    """The length in lines of every function in ``path``, decorators included."""
    return {
        f"{path.name}:{node.name}:{node.lineno}": (node.end_lineno or node.lineno)
        - min([node.lineno, *(d.lineno for d in node.decorator_list)])
        + 1
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
    }


def test_no_function_in_the_cli_is_over_80_lines() -> None:
    package = Path(query.cli.__file__).parent
    lengths = {k: v for path in package.glob("*.py") for k, v in _function_lines(path).items()}
    assert lengths and not {k: v for k, v in lengths.items() if v > MAX_FUNCTION_LINES}


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
    for name in COMMAND_NAMES:
        assert name in out.stdout
