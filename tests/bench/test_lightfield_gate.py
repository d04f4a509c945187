"""The selection bench of the lightfield stage's gate measures the product's rankings."""

from __future__ import annotations

import os

import numpy as np
import pytest

from bench.features import kernel_features
from bench.lightfield_gate import Split, Store, gate_weights
from bench.lightfield_rerank import index_of, light_fields, rankings
from bench.packings import light_field_balls
from shapedb.config import Config


@pytest.mark.slow
@pytest.mark.skipif(
    not os.environ.get("SHAPEDB_BENCH_CACHE"), reason="needs the cached decompositions"
)
def test_the_gate_bench_ranks_the_parts_and_people_as_the_product() -> None:
    from bench.cached import load

    config = Config().with_options(rerank="lightfield")
    split = Split("validation", ("parts", "people"))
    for name in ("parts", "people"):
        st = Store(split, split.store([name]))
        ds, balls = load(name, "validation")
        seen = light_field_balls(name, "validation", ds, balls, config)  # the product's packing
        got = rankings(index_of(kernel_features(balls, Config())), config,
                       light_fields(seen, config).astype(np.float64))  # fmt: skip
        want = st.rankings(gate_weights(st, config.lf_fusion))
        assert np.array_equal(got, want), name
