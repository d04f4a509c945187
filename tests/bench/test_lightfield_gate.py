"""The selection bench of the lightfield stage's gate measures the product's rankings."""

from __future__ import annotations

import os

import numpy as np
import pytest

from bench.studies.lightfield_rerank import index_of, rankings
from bench.support.features import kernel_features
from bench.support.stores import Split, Store, gate_weights
from query.search.tuning import PRODUCT
from shapedb.config.core import Config


@pytest.mark.slow
@pytest.mark.skipif(
    not os.environ.get("SHAPEDB_BENCH_CACHE"), reason="needs the cached decompositions"
)
def test_the_gate_bench_ranks_the_parts_and_people_as_the_product() -> None:
    from bench.support import inside_fields
    from bench.support.cached import load
    from bench.support.stores import shared_stores

    # the product's light fields without the field vectors (the split fuses none), the
    # shared-neighbour term on; a shape's N_k among its candidates, as the product's table
    config = Config().with_options(rerank="lightfield", fv_enabled=False)
    assert PRODUCT.shares_neighbours
    split = Split("validation", ("parts", "people"))
    for name in ("parts", "people"):
        st = Store(split, split.store([name]))
        ds, balls = load(name, "validation")
        lf = inside_fields.light_fields(name, "validation", ds, config.light_field)
        got = rankings(index_of(kernel_features(balls, Config())), config, lf.astype(np.float64))
        weights = gate_weights(st, PRODUCT)
        want = shared_stores({name: st}, split, PRODUCT, "candidates")[name]
        assert np.array_equal(got, want.rankings(weights)), name
        # the term moves rigid parts; the people's gate is shut, so it moves none of them
        moved = not np.array_equal(want.rankings(weights), st.rankings(weights))
        assert moved == (name == "parts"), name


def test_the_margin_is_the_least_jointed_over_the_largest_rigid() -> None:
    from bench.studies.gate_checks import margin

    rigid = np.linspace(0.0, 1.0, 101)  # 95 %: 0.95
    people = np.linspace(2.0, 3.0, 101)  # 5 %: 2.05
    got = margin({("web+people", "web"): rigid, ("web+people", "people"): people,
                  ("figures", "figures"): people + 1.0})  # fmt: skip
    assert np.isclose(got["rigid_95"], 0.95) and np.isclose(got["jointed_5"], 2.05)
    assert np.isclose(got["ratio_5_95"], 2.05 / 0.95)
    assert (got["jointed_min"], got["rigid_max"]) == (2.0, 1.0)
    assert margin({("web", "web"): rigid}) == {}  # one kind only: no margin


def test_the_ratio_grid_scales_the_ceiling_with_the_ratio_weight() -> None:
    from bench.studies.gate_checks import CEILINGS, ratio_settings

    settings = ratio_settings()
    keys = [tuple(sorted(s.items())) for s in settings]
    assert len(keys) == len(set(keys))  # no setting twice (b = 0 ignores the ratio's reach)
    for s in settings:
        assert s["ceiling"] in CEILINGS[s["ratio_weight"]]
        assert 0 < s["ramp"] < s["ceiling"]
    assert {s["ratio_candidates"] for s in settings if s["ratio_weight"] == 0} == {100}


def test_a_store_s_nearest_others_are_its_candidates_without_itself() -> None:
    from types import SimpleNamespace

    from bench.support.stores import local_spreads

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


def test_the_bench_s_shared_term_ranks_as_the_product() -> None:
    import dataclasses
    from types import SimpleNamespace

    from bench.studies.lightfield_rerank import Arrays
    from bench.support.stores import shared_stores
    from query.search import rerank
    from query.search.index import FeatureIndex
    from query.search.lightfield_spread import calibration
    from query.search.rerank_lightfield import LightFieldFusion
    from shapedb.signature.kernel import weights
    from shapedb.signature.lightfield import light_field_distance

    rng = np.random.default_rng(5)
    n = 40
    lf = rng.random((4, 3, 10, 46))[np.arange(n) % 4] + 0.3 * rng.random((n, 3, 10, 46))
    dl = light_field_distance(lf)
    # every shape a candidate, the gate open: the light field's rank and the term decide
    config = Config().with_options(rerank="lightfield", fv_enabled=False)
    tuning = dataclasses.replace(
        PRODUCT, candidates=n, ceiling=0.0, contrast_floor=0.0, pool=0, shared_neighbours=3,
        shared_weight=0.8, light_field_unit=float(np.median(dl)), descriptor_shared_weight=0.0,
    )  # fmt: skip
    x = rng.random((n, config.dim)).astype(np.float32)
    index = FeatureIndex(kind="flat").fit(np.arange(n), x, weights(config))
    xs = np.asarray(index.features_, np.float64)
    d4 = np.abs(xs[:, None, :] - xs[None, :, :]) @ index.weights_ / calibration(config)
    split = SimpleNamespace(labels=np.arange(n) % 4, sets=np.zeros(n), d4=d4, dl=dl)
    st = Store(split, np.arange(n), candidates=n)  # type: ignore[arg-type]
    got, _ = rerank.search(index, xs, n, config=config, query_ids=np.arange(n),
                           scorer=LightFieldFusion(config, tuning=tuning),
                           arrays=Arrays(lf, index, config, tuning=tuning))  # fmt: skip
    w = gate_weights(st, tuning)
    want = shared_stores({"s": st}, split, tuning)["s"].rankings(w)  # type: ignore[arg-type]
    assert np.array_equal(got, want)
    assert not np.array_equal(want, st.rankings(w))  # the term moved some rankings
    assert np.array_equal(want[:, :2], st.rankings(w)[:, :2])  # never the first result


def test_the_contrast_grid_scores_every_setting_with_the_term() -> None:
    import dataclasses
    from types import SimpleNamespace

    from bench.studies.lightfield_gate import CONTRAST_GRID, contrast_rows
    from bench.support.stores import score_row, shared_stores

    rng = np.random.default_rng(7)
    n = 48
    x = rng.random((n, 5)) + (np.arange(n) % 4)[:, None] * 0.3
    d4 = np.abs(x[:, None] - x[None]).sum(-1)
    dl = np.abs(x[:, None, :2] - x[None, :, :2]).sum(-1) * 20.0 + rng.random((n, n))
    dl = (dl + dl.T) / 2
    np.fill_diagonal(dl, 0.0)
    split = SimpleNamespace(labels=np.arange(n) % 4, sets=np.array(["web"] * n), d4=d4, dl=dl)
    st = Store(split, np.arange(n), candidates=30)  # type: ignore[arg-type]
    stores = {"web": st}
    base = {"web": st.per_set(st.measures(np.zeros(n)))}
    f = dataclasses.replace(PRODUCT, ceiling=0.0, pool=0)
    rows = contrast_rows(stores, split, f, base)  # type: ignore[arg-type]
    floors, ramps, depths = CONTRAST_GRID
    assert len(rows) == 1 + (len(floors) - 1) * len(ramps) * len(depths) + 1
    off = dataclasses.replace(f, contrast_floor=0.0)
    term = shared_stores(stores, split, f)  # type: ignore[arg-type]
    want = score_row(term, {"web": gate_weights(st, off)}, base)
    key = f"contrast: {{'contrast_floor': 0.0, 'contrast_ramp': {ramps[0]}, 'contrast_depth': {depths[0]}}}"
    assert rows[key]["objective"] == want["objective"]
    best = [k for k in rows if k.startswith("best of the contrast grid")]
    assert len(best) == 1
    passing = [r["objective"] for k, r in rows.items() if r["passes"] and k not in best]
    assert rows[best[0]]["objective"] == max(passing)
