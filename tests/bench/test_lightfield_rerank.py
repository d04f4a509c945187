"""The product's "lightfield" scorer ranks as the study's formula (bench.studies.lightfield_balls)."""

from __future__ import annotations

import os

import pytest

from bench.studies.lightfield_balls import check_product


@pytest.mark.slow
@pytest.mark.skipif(
    not os.environ.get("SHAPEDB_BENCH_CACHE"), reason="needs the cached decompositions"
)
def test_with_every_shape_a_candidate_the_scorer_ranks_the_figures_as_the_study() -> None:
    got = check_product(["figures"], "validation")["figures"]
    for kind in ("float64", "float32"):
        assert got[kind]["queries"] > 0
        assert got[kind]["identical_rankings"] == got[kind]["queries"]
