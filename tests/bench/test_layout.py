"""bench/ holds the product benchmarks; finished research in bench/studies/ still runs."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
STUDIES = sorted(p.stem for p in (BENCH / "studies").glob("*.py") if p.stem != "__init__")
#: Study modules that are libraries of the others.
NOT_SCRIPTS = {"adaptive_rerank", "descriptors", "gate_checks"}


@pytest.mark.parametrize("name", sorted(set(STUDIES) - NOT_SCRIPTS))
def test_every_study_is_still_runnable(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    module = importlib.import_module(f"bench.studies.{name}")
    with pytest.raises(SystemExit) as exit_:
        module.main(["--help"])
    assert exit_.value.code == 0
    assert f"bench.studies.{name}" in capsys.readouterr().out


def test_studies_write_their_results_apart() -> None:
    for name in STUDIES:
        source = (BENCH / "studies" / f"{name}.py").read_text()
        if '"results"' in source:
            assert '"results" / "studies"' in source, name


def test_nothing_in_bench_is_named_after_a_work_item() -> None:
    names = [p.stem for p in BENCH.rglob("*.py")]
    assert not [n for n in names if n.startswith("issue")]


PRODUCT = sorted(
    p.stem for p in BENCH.glob("*.py") if "def main(" in p.read_text() and p.stem != "__init__"
)


@pytest.mark.parametrize("name", PRODUCT)
def test_every_product_bench_answers_help(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    module = importlib.import_module(f"bench.{name}")
    with pytest.raises(SystemExit) as exit_:
        module.main(["--help"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.startswith("usage:")


def test_no_product_bench_imports_a_study() -> None:
    """Research depends on the product benches, never the other way."""
    for name in PRODUCT:
        source = (BENCH / f"{name}.py").read_text()
        assert "from bench.studies" not in source, name
        assert "import bench.studies" not in source, name


def test_the_top_level_holds_the_benchmarks_and_their_helpers_only() -> None:
    """Data sets live in bench/sets/, shared code in bench/support/, research in studies."""
    names = {p.stem for p in BENCH.glob("*.py")} - {"__init__"}
    assert names - set(PRODUCT) == {"common"}
    assert len(names) <= 16  # 15 benchmarks (bench.scale the newest) and common
