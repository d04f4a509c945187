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


def test_the_margin_is_the_least_jointed_over_the_largest_rigid() -> None:
    from bench.gate_checks import margin

    rigid = np.linspace(0.0, 1.0, 101)  # 95 %: 0.95
    people = np.linspace(2.0, 3.0, 101)  # 5 %: 2.05
    got = margin({("web+people", "web"): rigid, ("web+people", "people"): people,
                  ("figures", "figures"): people + 1.0})  # fmt: skip
    assert np.isclose(got["rigid_95"], 0.95) and np.isclose(got["jointed_5"], 2.05)
    assert np.isclose(got["ratio_5_95"], 2.05 / 0.95)
    assert (got["jointed_min"], got["rigid_max"]) == (2.0, 1.0)
    assert margin({("web", "web"): rigid}) == {}  # one kind only: no margin


def test_the_ratio_grid_scales_the_ceiling_with_the_ratio_weight() -> None:
    from bench.gate_checks import CEILINGS, ratio_settings

    settings = ratio_settings()
    keys = [tuple(sorted(s.items())) for s in settings]
    assert len(keys) == len(set(keys))  # no setting twice (b = 0 ignores the ratio's reach)
    for s in settings:
        assert s["ceiling"] in CEILINGS[s["ratio_weight"]]
        assert 0 < s["ramp"] < s["ceiling"]
    assert {s["ratio_candidates"] for s in settings if s["ratio_weight"] == 0} == {100}


def test_a_store_s_nearest_others_are_its_candidates_without_itself() -> None:
    from types import SimpleNamespace

    from bench.lightfield_gate import local_spreads

    rng = np.random.default_rng(3)
    x = rng.random((30, 4))
    d = np.abs(x[:, None] - x[None]).sum(-1)
    dl = d + rng.random((30, 30)) * 0.1
    dl = (dl + dl.T) / 2
    np.fill_diagonal(dl, 0.0)
    split = SimpleNamespace(labels=np.arange(30) % 3, sets=np.zeros(30), d4=d, dl=dl)
    st = Store(split, np.arange(30), candidates=12)  # type: ignore[arg-type]
    near_d, near_l = st.nearest(11)
    assert np.array_equal(near_d, st.others(st.D)) and np.array_equal(near_l, st.others(st.L))
    assert st.nearest(29)[0].shape == (30, 29)  # past the candidates: the whole store
    spread = np.median(near_l[:, :5], 1) / 2.0 / np.median(near_d[:, :5], 1)
    assert np.array_equal(local_spreads(st, 5, 2.0), spread)
    best = np.median(np.sort(st.nearest(20)[1], 1)[:, :5], 1)
    want = spread**0.5 * (np.median(near_l[:, :5], 1) / best) ** 0.5
    assert np.allclose(local_spreads(st, 5, 2.0, 0.5, 20), want)
