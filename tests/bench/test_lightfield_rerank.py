"""bench.lightfield_rerank: the product's "lightfield" scorer ranks as the study's formula."""

from __future__ import annotations

import argparse
import os

import pytest

from bench.lightfield_rerank import measure


@pytest.mark.slow
@pytest.mark.skipif(
    not os.environ.get("SHAPEDB_BENCH_CACHE"), reason="needs the cached decompositions"
)
def test_with_every_shape_a_candidate_the_scorer_ranks_the_figures_as_the_study() -> None:
    args = argparse.Namespace(datasets=["figures"], split="validation", no_adaptive=True)
    got = measure(args)["study_check"]["figures"]
    for kind in ("float64", "float32"):
        assert got[kind]["queries"] > 0
        assert got[kind]["identical_rankings"] == got[kind]["queries"]
