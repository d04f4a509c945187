"""The hard web-like set (bench.sets.web_shapes, bench.sets.datasets.web)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.sets.datasets import families, mesh_arrays, web
from bench.sets.web_shapes import FAMILIES, KINDS, web_mesh, web_version


def test_kinds_come_in_close_families() -> None:
    assert len(KINDS) >= 40
    members = [k for family in FAMILIES.values() for k in family]
    assert sorted(members) == sorted(KINDS)  # each kind in exactly one family
    assert sum(len(f) >= 3 for f in FAMILIES.values()) >= 8


def test_generation_is_deterministic_and_varied() -> None:
    for kind in KINDS:
        v, f = web_mesh(kind, 3)
        v2, f2 = web_mesh(kind, 3)
        assert np.array_equal(v, v2) and np.array_equal(f, f2)
        assert f.min() >= 0 and f.max() < len(v) and np.isfinite(v).all()
        other, _ = web_mesh(kind, 4)
        assert other.shape != v.shape or not np.allclose(other, v)


def test_orientation_is_not_canonical() -> None:
    # a skyscraper standing upright is longest along z; some are turned arbitrarily
    ups = [np.ptp(web_mesh("skyscraper", i)[0], axis=0).argmax() == 2 for i in range(20)]
    assert 10 <= sum(ups) < 20


def test_most_models_are_not_watertight() -> None:
    trimesh = pytest.importorskip("trimesh")
    closed = sum(
        trimesh.Trimesh(*web_mesh(k, i), process=True).is_watertight
        for k in KINDS
        for i in range(2)
    )
    assert closed < 0.3 * 2 * len(KINDS)


def test_dataset_split_sources_and_families() -> None:
    ds = web()
    assert len(ds) == 20 * len(KINDS) and len(set(ds.labels)) == len(KINDS)
    val = ds.split("validation")
    assert 0.3 < len(val) / len(ds) < 0.4
    assert {m.label for m in val.models} == set(KINDS)
    assert all(m.source.endswith(":" + web_version()) for m in ds.models)
    v, f = mesh_arrays(ds.models[0])
    assert np.array_equal(v, web_mesh(KINDS[0], 0)[0])
    assert len(set(families(ds.models))) == len(ds)


def test_a_stale_source_is_refused() -> None:
    from dataclasses import replace

    m = web().models[0]
    with pytest.raises(ValueError, match="web generator"):
        mesh_arrays(replace(m, source=m.source.rsplit(":", 1)[0] + ":00000000"))
