"""Cutting a configuration's light fields from the field bench's cached renderings."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.support.inside_fields import cut
from shapedb.config.core import LightFieldConfig, MDBDConfig
from shapedb.geometry.implicit import Box
from shapedb.geometry.inside import field_inside
from shapedb.mdbd.decomposition import prepare_field
from shapedb.signature.lightfield import inside_light_field


@pytest.fixture(scope="module")
def cached() -> dict[str, np.ndarray]:
    prep = prepare_field(Box((0, 0, 0), (2.0, 1.0, 0.3)), MDBDConfig(resolution=24))
    inside = field_inside(prep.F, prep.grid, prep.frame, prep.scale)
    base = LightFieldConfig(n_fields=10, resolution=64)
    return {
        "inside": inside,  # type: ignore[dict-item]
        "lf64": inside_light_field(inside, dataclasses.replace(base, depth_weight=1.0)),
        "lf128": inside_light_field(inside, dataclasses.replace(base, resolution=128)),
    }


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"n_fields": 10},
        {"resolution": 128},
        {"depth_weight": 2.0},
        {"n_fields": 1, "depth_weight": 0.5},
    ],
)
def test_a_cut_is_the_light_field_rendered_directly(cached: dict, options: dict) -> None:
    cfg = LightFieldConfig(**{"n_fields": 3, "resolution": 64, "source": "field", **options})
    got = cut(cached, cfg)
    want = inside_light_field(cached["inside"], cfg)
    assert got.shape == want.shape
    assert np.allclose(got, want, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize(
    "options", [{"resolution": 96}, {"zernike_order": 8}, {"seed": 1}, {"close_px": 1},
                {"resolution": 128, "depth_weight": 1.0}],
)  # fmt: skip
def test_what_is_not_cached_is_refused(cached: dict, options: dict) -> None:
    with pytest.raises(ValueError, match="not cached"):
        cut(cached, LightFieldConfig(source="field", **options))


def test_renderings_about_the_surface_centre_are_cut_for_that_centre_only(cached: dict) -> None:
    inside = cached["inside"]
    base = LightFieldConfig(n_fields=10, resolution=64, centre="surface")
    surface = {
        "lf64": inside_light_field(inside, dataclasses.replace(base, depth_weight=1.0)),
        "lf128": inside_light_field(inside, dataclasses.replace(base, resolution=128)),
        "centre": np.str_("surface"),
    }
    cfg = LightFieldConfig(n_fields=3, resolution=128, source="field", centre="surface")
    assert np.allclose(cut(surface, cfg), inside_light_field(inside, cfg), rtol=1e-6, atol=1e-7)
    # a rendering is never cut for the other centre (files without a centre: the volume's)
    with pytest.raises(ValueError, match="not cached"):
        cut(surface, dataclasses.replace(cfg, centre="volume"))
    with pytest.raises(ValueError, match="not cached"):
        cut(cached, cfg)
