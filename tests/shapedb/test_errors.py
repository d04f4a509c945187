"""Missing dependencies: the message says what to install."""

from __future__ import annotations

import sys

import pytest

from shapedb.errors import MissingDependencyError, require


def test_a_missing_optional_dependency_names_its_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "gmsh", None)  # "import gmsh" fails
    with pytest.raises(MissingDependencyError, match=r"pip install 'shapedb\[cad\]'"):
        require("gmsh", extra="cad", feature="reading CAD files")


def test_a_missing_core_dependency_asks_for_a_reinstall(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "duckdb", None)
    with pytest.raises(MissingDependencyError, match="--force-reinstall shapedb") as err:
        require("duckdb", extra="sql", feature="SQL queries")  # no extra "sql" is declared
    assert "shapedb[sql]" not in str(err.value)


def test_a_present_module_is_returned() -> None:
    assert require("json", extra="cad", feature="x") is sys.modules["json"]
