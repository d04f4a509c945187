"""The architecture rules, checked: one-way data flow and a light ``import shapedb``."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _imported_modules(package: str) -> dict[str, set[str]]:
    found: dict[str, set[str]] = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        names: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names.add(node.module.split(".")[0])
        found[str(path.relative_to(ROOT))] = names
    return found


def test_core_never_imports_downstream_packages() -> None:
    offenders = {
        path: sorted(names & {"ingest", "query"})
        for path, names in _imported_modules("shapedb").items()
        if names & {"ingest", "query"}
    }
    assert offenders == {}


def test_ingest_does_not_import_query() -> None:
    offenders = {p: n for p, n in _imported_modules("ingest").items() if "query" in n}
    assert offenders == {}


@pytest.mark.parametrize("heavy", ["faiss", "duckdb", "open3d", "torch", "dask", "matplotlib"])
def test_import_shapedb_stays_light(heavy: str) -> None:
    code = f"import sys, shapedb; sys.exit(1 if {heavy!r} in sys.modules else 0)"
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, f"'import shapedb' loaded {heavy}: {result.stderr}"
