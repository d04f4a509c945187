"""The bench's settings of the stage: flat settings sent to the config or the stage's numbers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.support.tuning import OverlapFusion, Setting, configure, parse_value, split_settings
from query.search.rerank_lightfield import LightFieldFusion
from query.search.tuning import PRODUCT
from shapedb.config.core import Config
from shapedb.errors import ConfigError


def test_flat_settings_go_to_the_config_or_the_stage_s_numbers() -> None:
    options, tuning = split_settings(
        {"fv_enabled": False, "lf_weight": 4.0, "rerank_candidates": 50, "lf_power": 3.0,
         "lf_resolution": 64, "lf_edges": True}
    )  # fmt: skip
    assert options == {"fv_enabled": False, "lf_resolution": 64, "lf_edges": True}
    assert tuning == {"weight": 4.0, "candidates": 50, "power": 3.0}
    got = configure(Config().with_options(rerank="lightfield"), {
        "fv_enabled": False, "lf_weight": 4.0, "lf_candidates": 50, "lf_edges": True})  # fmt: skip
    assert got.tuning == dataclasses.replace(PRODUCT, weight=4.0, candidates=50)
    assert got.config.light_field.edges and not got.config.stores_field_vectors
    assert got.power == 0.0 and type(got.scorer()) is LightFieldFusion
    assert Setting(Config().with_options(rerank="none")).scorer() is None
    with pytest.raises(ConfigError):
        configure(Config(), {"lf_ramp": 0.0})  # the stage's own checks


def test_values_read_as_numbers_bools_or_text() -> None:
    assert [parse_value(v) for v in ("8", "0.5", "-2", "true", "field")] == [
        8, 0.5, -2, True, "field"]  # fmt: skip


def test_the_overlap_gate_multiplies_the_product_s_and_is_off_at_power_0() -> None:
    rng = np.random.default_rng(3)
    d4, dl = np.sort(rng.random(30)), rng.random(30)
    own = np.zeros(30, bool)
    own[0] = True
    t = dataclasses.replace(PRODUCT, ceiling=0.0, contrast_floor=0.0)
    plain = LightFieldFusion(Config(), tuning=t).gate(d4, dl, own, None)
    assert OverlapFusion(Config(), tuning=t, power=0.0).gate(d4, dl, own, None) == plain == 1.0
    others = np.arange(1, 30)
    near_l = others[np.argsort(dl[others], kind="stable")[:5]]
    share = len(np.intersect1d(others[:5], near_l)) / 5
    got = OverlapFusion(Config(), tuning=t, power=2.0).gate(d4, dl, own, None)
    assert got == pytest.approx(share**2)
