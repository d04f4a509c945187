"""The typed configuration: one section per concern, validation, JSON round trip, options."""

from __future__ import annotations

import dataclasses

import pytest

from shapedb.config.core import (
    OPTIONS,
    SPECIFICATION,
    CloudConfig,
    Config,
    DescriptorConfig,
    FieldVectorConfig,
    KernelConfig,
    LightFieldConfig,
    MDBDConfig,
    RerankConfig,
    parse_options,
    with_options,
)
from shapedb.config.part import PartConfig
from shapedb.config.surface_words import SurfaceWordsConfig
from shapedb.errors import ConfigError


def test_json_round_trip_and_fingerprint() -> None:
    cfg = Config().with_options(
        resolution=64, n_r=10, method="paper", descriptor=2, view_cells=4.0, reconstruct=False
    )
    again = Config.from_json(cfg.to_json())
    assert again == cfg and again.fingerprint == cfg.fingerprint
    assert Config().with_options(n_r=10).fingerprint == Config().fingerprint  # kernel only
    assert Config().with_options(view_cells=4.0).fingerprint == Config().fingerprint
    assert Config().with_options(resolution=64).fingerprint != Config().fingerprint


def test_each_concern_is_its_own_section() -> None:
    cfg = Config().with_options(
        tie_cells=0.0, lam=2.0, descriptor=1, view_cells=4.0, reconstruct_depth=6, rerank="none"
    )
    assert cfg.mdbd == MDBDConfig(tie_cells=0.0)
    assert cfg.kernel == KernelConfig(lam=2.0)
    assert cfg.descriptor == DescriptorConfig(version=1)
    assert cfg.cloud == CloudConfig(view_cells=4.0, reconstruct_depth=6)
    assert cfg.rerank == RerankConfig(scorer="none")
    assert set(cfg.to_dict()) == {
        "layout", "mdbd", "kernel", "descriptor", "cloud", "rerank", "light_field",
        "field_vector", "surface_words",
    }  # fmt: skip
    kernel_fields = {f.name for f in dataclasses.fields(KernelConfig)}
    assert kernel_fields == {"n_r", "t", "w", "la", "lb", "lam", "method"}


def test_every_flat_option_names_one_field() -> None:
    assert OPTIONS["descriptor"] == ("descriptor", "version")
    assert OPTIONS["view_cells"] == ("cloud", "view_cells")
    assert OPTIONS["tie_rule"] == ("mdbd", "tie_rule")
    assert OPTIONS["rerank"] == ("rerank", "scorer")
    assert parse_options(["rerank=none"]) == {"rerank": "none"}
    assert OPTIONS["lf_resolution"] == ("light_field", "resolution")
    for knob in ("lf_weight", "lf_field_candidates", "rerank_candidates", "rerank_ratio"):
        assert knob not in OPTIONS  # the stage's numbers are constants (query.search.tuning)
    assert OPTIONS["fv_enabled"] == ("field_vector", "enabled")
    assert "fv_harmonic_bands" not in OPTIONS and "lf_zernike_order" not in OPTIONS  # specs
    assert not any(k.startswith("sw_") or k == "enabled" for k in OPTIONS)  # words: no option
    assert parse_options(["fv_enabled=false", "lf_resolution=32"]) == {
        "fv_enabled": False, "lf_resolution": 32
    }  # fmt: skip
    sections = (MDBDConfig, KernelConfig, DescriptorConfig, CloudConfig, RerankConfig,
                LightFieldConfig, FieldVectorConfig, SurfaceWordsConfig)  # fmt: skip
    specs = sum(len(v) for v in SPECIFICATION.values())
    assert len(OPTIONS) == sum(len(dataclasses.fields(c)) for c in sections) - specs
    options = Config().options()
    assert set(options) == set(OPTIONS) and options["descriptor"] == 4
    assert Config().with_options(**options) == Config()
    with pytest.raises(ConfigError, match="unknown configuration option"):
        Config().with_options(version=3)


def test_the_part_kernel_is_embedded() -> None:
    part = PartConfig()
    assert part.kernel == KernelConfig(n_r=10, method="paper") and part.dim == 20
    assert part.with_options(n_r=5, hops=1) == PartConfig(
        hops=1, kernel=KernelConfig(n_r=5, method="paper")
    )
    assert {f.name for f in dataclasses.fields(PartConfig)} == {
        "hops",
        "kernel",
        "size",
        "centre",
        "contact_tol_cells",
    }
    with pytest.raises(ConfigError, match="kernel"):
        PartConfig(kernel=KernelConfig())  # a part is compared by the paper's kernel
    with pytest.raises(ConfigError, match="unknown part option"):
        part.with_options(method="mdbd")
    assert PartConfig.from_dict(part.to_dict()) == part


def test_part_fingerprints_keep_their_values() -> None:
    # part indexes on disk are named by these (computed before the kernel was embedded)
    assert PartConfig().fingerprint == "a2a4535f18e7"
    paper = PartConfig(size=0.0, centre=0.0, contact_tol_cells=0.0)
    assert paper.fingerprint == "871693aac500"
    assert PartConfig().with_options(hops=1, n_r=5).fingerprint == "1beca3d68d7e"


@pytest.mark.parametrize(
    ("cls", "options", "match"),
    [
        (MDBDConfig, {"resolution": 4}, "resolution"),
        (KernelConfig, {"method": "other"}, "method"),
        (KernelConfig, {"w": 0.0}, "w="),
        (DescriptorConfig, {"version": 99}, "descriptor"),
        (DescriptorConfig, {"version": True}, "descriptor"),
        (CloudConfig, {"reconstruct_depth": 20}, "reconstruct_depth"),
        (CloudConfig, {"reconstruct": 1}, "reconstruct"),
        (MDBDConfig, {"tie_rule": "last"}, "tie_rule"),
        (MDBDConfig, {"colour": 1}, "unknown MDBDConfig option"),
        (KernelConfig, {"descriptor": 1}, "unknown KernelConfig option"),
    ],
)
def test_bad_values_are_refused(cls: type, options: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        with_options(cls, None, options)


def test_dimension_follows_the_method_and_the_descriptor() -> None:
    from shapedb.signature.descriptor import DIM, dim

    assert Config().dim == DIM == dim(4)
    assert Config().with_options(descriptor=1).dim == dim(1) == 247
    assert dim(2) == 257 and dim(3) == 335
    assert Config().with_options(method="paper", n_r=10).dim == 20
    assert Config().with_options(method="paper", n_r=10, descriptor=1).dim == 20


def test_options_parse_from_text_by_field_type() -> None:
    from shapedb.config.core import parse_options

    got = parse_options(
        ["tie_cells=0", "descriptor=1", "refine=false", "method=paper", "view_cells=4"]
    )
    assert got == {
        "tie_cells": 0.0,
        "descriptor": 1,
        "refine": False,
        "method": "paper",
        "view_cells": 4.0,
    }
    assert isinstance(got["tie_cells"], float) and isinstance(got["descriptor"], int)
    assert isinstance(got["view_cells"], float)
    cfg = Config().with_options(**got)
    assert cfg.descriptor.version == 1 and cfg.cloud.view_cells == 4.0
    for bad, match in [
        ("colour=red", "unknown configuration option 'colour'"),
        ("tie_cells", "KEY=VALUE"),
        ("n_balls=1.5", "expected int"),
        ("refine=maybe", "expected bool"),
        ("descriptor=two", "expected int"),
    ]:
        with pytest.raises(ConfigError, match=match):
            parse_options([bad])


def test_the_configuration_stays_small_and_rejects_retired_scorers() -> None:
    """About forty fields in all (the stage's numbers are not options), and no string
    names a scorer the code does not have."""
    assert len(OPTIONS) <= 30
    with pytest.raises(ConfigError, match="rerank"):
        Config().with_options(rerank="adaptive")
