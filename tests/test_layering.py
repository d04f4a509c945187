"""The architecture rules, checked: one-way data flow, no import cycles, no imports of
another module's private names, and a light ``import shapedb``."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("shapedb", "ingest", "query", "bench")


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


@pytest.mark.parametrize("heavy", ["faiss", "duckdb", "open3d", "torch", "dask", "matplotlib"])
def test_import_shapedb_stays_light(heavy: str) -> None:
    code = f"import sys, shapedb; sys.exit(1 if {heavy!r} in sys.modules else 0)"
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, f"'import shapedb' loaded {heavy}: {result.stderr}"


# --------------------------------------------------------------------------------------
# Import graph of the project's modules: cycles and private names
# --------------------------------------------------------------------------------------


def _module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _project_modules(root: Path, packages: tuple[str, ...]) -> dict[str, Path]:
    return {
        _module_name(root, path): path
        for package in packages
        for path in sorted((root / package).rglob("*.py"))
    }


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(path: Path, module: str) -> list[tuple[str, str | None, int, bool]]:
    """(imported module, imported name or None, line, only under TYPE_CHECKING) of a file.

    Imports inside functions count (a lazy import still closes a cycle at run time);
    relative imports are resolved against ``module``.
    """
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    found: list[tuple[str, str | None, int, bool]] = []

    def visit(node: ast.AST, typing_only: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for stmt in child.body:
                    visit_one(stmt, True)
                for stmt in child.orelse:
                    visit_one(stmt, typing_only)
            else:
                visit_one(child, typing_only)

    def visit_one(node: ast.AST, typing_only: bool) -> None:
        if isinstance(node, ast.Import):
            found.extend((a.name, None, node.lineno, typing_only) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package[: len(package) - node.level + 1]
                base = ".".join([*parent, base] if base else parent)
            found.extend((base, a.name, node.lineno, typing_only) for a in node.names)
        visit(node, typing_only)

    visit(ast.parse(path.read_text(), filename=str(path)), False)
    return found


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def import_graph(root: Path, packages: tuple[str, ...]) -> tuple[dict[str, set[str]], list[str]]:
    """The run-time import graph among the modules of ``packages``, and private-name imports.

    An edge ``a -> b`` is an import of project module ``b`` anywhere in ``a`` (also
    inside functions; not under ``if TYPE_CHECKING``). ``from p import name`` is an
    edge to ``p.name`` when that is a module, else to ``p``. Offences: importing a
    ``_name`` from another module, or a ``_module`` of another top-level package.
    """
    modules = _project_modules(root, packages)
    graph: dict[str, set[str]] = {}
    offences: list[str] = []
    for module, path in modules.items():
        edges: set[str] = set()
        where = f"{path.relative_to(root)}"
        for base, name, line, typing_only in _imports(path, module):
            if base.split(".")[0] not in packages:
                continue
            target = base
            if name is not None and f"{base}.{name}" in modules:
                target = f"{base}.{name}"
            elif name is not None and _is_private(name) and base != module:
                offences.append(f"{where}:{line} imports {name} from {base}")
            if target.split(".")[0] != module.split(".")[0] and any(
                _is_private(part) for part in target.split(".")[1:]
            ):
                offences.append(f"{where}:{line} imports the private module {target}")
            if not typing_only and target != module:
                edges.add(target)
        graph[module] = edges
    return graph, offences


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return sorted(cycles)


#: The floors of the house, lowest first: the data flows up, representation -> SDF -> MDBD
#: -> contact graph -> signatures -> store -> (ingest) -> index -> query, and a module
#: imports only from its own floor or below. A floor is a package, subpackage or module
#: (its longest prefix names it); packages' own ``__init__`` sit on the floor of their
#: subpackages' top (they re-export them).
FLOORS: tuple[tuple[str, ...], ...] = (
    ("shapedb.errors",),
    ("shapedb.config",),
    ("shapedb.geometry",),
    ("shapedb.mdbd",),
    ("shapedb.signature",),
    ("shapedb.store",),
    ("shapedb.results", "shapedb._parts", "shapedb.examples"),
    ("ingest",),
    ("query.learn",),
    ("query.sql",),
    ("query.search",),
    ("query.parts",),
    ("query.evaluate",),
    ("query.render", "query.thumbnails"),
    ("query.database", "query"),
    ("query.serve",),
    ("query.cli",),
)
#: The one import that runs down-up on purpose: ``shapedb.connect`` and
#: ``shapedb.Database`` are lazy re-exports of the facade, loaded on first use.
LAZY_FACADE = {("shapedb", "query.database")}


def floor_of(module: str) -> int:
    """The floor of a project module (bench/ sits above them all)."""
    if module == "shapedb":
        return len(FLOORS) - 1  # its __init__ re-exports every floor (lazily)
    best, level = -1, len(FLOORS)
    for i, names in enumerate(FLOORS):
        for name in names:
            if (module == name or module.startswith(name + ".")) and len(name) > best:
                best, level = len(name), i
    return level


def test_every_import_runs_down_the_floors() -> None:
    graph, _ = import_graph(ROOT, ("shapedb", "ingest", "query"))
    upward = sorted(
        f"{a} -> {b}"
        for a, targets in graph.items()
        for b in targets
        if floor_of(b) > floor_of(a) and (a, b) not in LAZY_FACADE
    )
    assert upward == []


def test_typing_imports_run_down_the_floors_too() -> None:
    """Even an ``if TYPE_CHECKING`` import runs down: a stage types the database it is given
    by a protocol (``shapedb.store.handle.StoreHandle``), not by the facade above it."""
    modules = _project_modules(ROOT, ("shapedb", "ingest", "query"))
    upward = []
    for module, path in modules.items():
        for base, name, line, typing_only in _imports(path, module):
            if not typing_only or base.split(".")[0] not in ("shapedb", "ingest", "query"):
                continue
            target = f"{base}.{name}" if name and f"{base}.{name}" in modules else base
            if floor_of(target) > floor_of(module):
                upward.append(f"{path.relative_to(ROOT)}:{line} {target}")
    assert sorted(upward) == []


def test_the_core_never_imports_a_downstream_package_but_for_the_facade() -> None:
    graph, _ = import_graph(ROOT, ("shapedb", "ingest", "query"))
    offenders = sorted(
        f"{a} -> {b}"
        for a, targets in graph.items()
        if a.split(".")[0] == "shapedb"
        for b in targets
        if b.split(".")[0] != "shapedb" and (a, b) not in LAZY_FACADE
    )
    assert offenders == []


def test_every_module_has_a_floor() -> None:
    graph, _ = import_graph(ROOT, ("shapedb", "ingest", "query"))
    assert sorted(m for m in graph if m != "shapedb" and floor_of(m) == len(FLOORS)) == []


def test_no_import_cycles() -> None:
    graph, _ = import_graph(ROOT, PACKAGES)
    assert import_cycles(graph) == []


def test_no_imports_of_private_names() -> None:
    _, offences = import_graph(ROOT, PACKAGES)
    assert offences == []


def test_the_checks_find_a_cycle_and_private_imports(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg.b import _helper\n")
    (pkg / "b.py").write_text("def f():\n    from . import a\n")
    (pkg / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import a\n"
    )
    (pkg / "sub" / "d.py").write_text("from ..c import x\nfrom other._priv import y\n")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "__init__.py").write_text("")
    (tmp_path / "other" / "_priv.py").write_text("")
    graph, offences = import_graph(tmp_path, ("pkg", "other"))
    assert import_cycles(graph) == [["pkg.a", "pkg.b"]]
    assert graph["pkg.c"] == set()  # typing-only imports make no run-time edge
    assert graph["pkg.sub.d"] == {"pkg.c", "other._priv"}
    assert offences == [
        "pkg/a.py:1 imports _helper from pkg.b",
        "pkg/sub/d.py:2 imports the private module other._priv",
    ]


def test_test_modules_have_unique_basenames() -> None:
    """pytest imports test files by basename (no packages under tests/): two alike break collection."""
    names = [p.name for p in (ROOT / "tests").rglob("test_*.py")]
    assert sorted({n for n in names if names.count(n) > 1}) == []
