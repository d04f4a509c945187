"""The typed configuration: validation, JSON round trip, overrides, older stores."""

from __future__ import annotations

import pytest

from shapedb.config import Config, KernelConfig, MDBDConfig, with_options
from shapedb.errors import ConfigError


def test_json_round_trip_and_fingerprint() -> None:
    cfg = Config().with_options(resolution=64, n_r=10, method="paper")
    again = Config.from_json(cfg.to_json())
    assert again == cfg and again.fingerprint == cfg.fingerprint
    assert Config().with_options(n_r=10).fingerprint == Config().fingerprint  # kernel only
    assert Config().with_options(resolution=64).fingerprint != Config().fingerprint


def test_a_stored_kernel_without_method_is_the_papers() -> None:
    old = {
        "mdbd": {"resolution": 64},
        "kernel": {"n_r": 32, "t": 10, "w": 0.9, "la": 0.75, "lb": 0.75, "lam": 1.0},
    }
    assert Config.from_dict(old).kernel.method == "paper"
    assert Config.from_dict({}).kernel.method == "mdbd"


def test_a_stored_kernel_without_descriptor_version_is_version_1() -> None:
    old = {"kernel": {"n_r": 32, "t": 10, "w": 0.9, "la": 0.75, "lb": 0.75, "lam": 1.0}}
    old["kernel"]["method"] = "mdbd"
    assert Config.from_dict(old).kernel.descriptor == 1
    assert Config.from_dict({}).kernel.descriptor == 4
    assert Config.from_json(Config().to_json()).kernel.descriptor == 4
    assert Config.from_dict({"kernel": {"method": "mdbd", "descriptor": 2}}).kernel.descriptor == 2


def test_a_stored_mdbd_config_without_tie_rule_took_the_first_cell() -> None:
    assert Config.from_dict({"mdbd": {"resolution": 64}}).mdbd.tie_rule == "first"
    assert Config.from_dict({}).mdbd.tie_rule == "middle"  # nothing stored: the defaults
    middle = Config().with_options(tie_rule="middle")
    assert Config.from_json(middle.to_json()).mdbd.tie_rule == "middle"


@pytest.mark.parametrize(
    ("cls", "options", "match"),
    [
        (MDBDConfig, {"resolution": 4}, "resolution"),
        (KernelConfig, {"method": "other"}, "method"),
        (KernelConfig, {"w": 0.0}, "w="),
        (KernelConfig, {"descriptor": 5}, "descriptor"),
        (MDBDConfig, {"tie_rule": "last"}, "tie_rule"),
        (MDBDConfig, {"colour": 1}, "unknown MDBDConfig option"),
    ],
)
def test_bad_values_are_refused(cls: type, options: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        with_options(cls, None, options)


def test_dimension_follows_the_method() -> None:
    from shapedb.descriptor import DIM, dim

    assert KernelConfig().dim == DIM == dim(3)
    assert KernelConfig(descriptor=1).dim == dim(1) == 247 and dim(2) == 257 and dim(3) == 335
    assert KernelConfig(method="paper", n_r=10).dim == 20


def test_options_parse_from_text_by_field_type() -> None:
    from shapedb.config import parse_options

    got = parse_options(["tie_cells=0", "descriptor=1", "refine=false", "method=paper"])
    assert got == {"tie_cells": 0.0, "descriptor": 1, "refine": False, "method": "paper"}
    assert isinstance(got["tie_cells"], float) and isinstance(got["descriptor"], int)
    for bad, match in [
        ("colour=red", "unknown configuration option 'colour'"),
        ("tie_cells", "KEY=VALUE"),
        ("n_balls=1.5", "expected int"),
        ("refine=maybe", "expected bool"),
    ]:
        with pytest.raises(ConfigError, match=match):
            parse_options([bad])
