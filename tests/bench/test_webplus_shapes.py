"""The held-out web-like set (bench.sets.webplus_shapes, bench.sets.datasets.webplus)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.sets.datasets import families, mesh_arrays, webplus
from bench.sets.generic_shapes import KINDS as GENERIC_KINDS
from bench.sets.web_shapes import KINDS as WEB_KINDS
from bench.sets.webplus_shapes import FAMILIES, KINDS, webplus_mesh, webplus_version


def test_kinds_are_new_and_come_in_families() -> None:
    assert len(KINDS) >= 25
    assert not set(KINDS) & (set(WEB_KINDS) | set(GENERIC_KINDS))
    members = [k for family in FAMILIES.values() for k in family]
    assert sorted(members) == sorted(KINDS)  # each kind in exactly one family
    assert sum(len(f) >= 3 for f in FAMILIES.values()) >= 6


def test_every_kind_builds_deterministic_finite_varied_meshes() -> None:
    for kind in KINDS:
        shapes = set()
        for seed in range(4):
            v, f = webplus_mesh(kind, seed)
            v2, f2 = webplus_mesh(kind, seed)
            assert np.array_equal(v, v2) and np.array_equal(f, f2), kind
            assert len(v) > 0 and len(f) > 0, kind
            assert f.min() >= 0 and f.max() < len(v), kind
            assert np.isfinite(v).all(), kind
            assert np.ptp(v, axis=0).max() > 0, kind
            shapes.add(np.round(np.sort(np.ptp(v, axis=0)), 6).tobytes())
        assert len(shapes) == 4, kind  # proportions or scale differ between seeds


def test_poses_vary_within_an_organic_kind() -> None:
    # extents normalised by size: a pose changes the proportions of the bounding box
    def shape(kind: str, seed: int) -> np.ndarray:
        e = np.sort(np.ptp(webplus_mesh(kind, seed)[0], axis=0))
        return e / e[-1]

    organic = ("dinosaur", "kangaroo", "ape", "ostrich", "elephant", "rhinoceros", "giraffe")
    for kind in (*organic, "spider", "snake", "penguin"):
        ratios = np.stack([shape(kind, s) for s in range(12)])
        assert np.ptp(ratios[:, 0]) > 0.05, kind


def test_orientation_is_not_canonical() -> None:
    ups = [np.ptp(webplus_mesh("lighthouse", i)[0], axis=0).argmax() == 2 for i in range(20)]
    assert 10 <= sum(ups) < 20


def test_most_models_are_not_watertight() -> None:
    trimesh = pytest.importorskip("trimesh")
    closed = sum(
        trimesh.Trimesh(*webplus_mesh(k, i), process=True).is_watertight
        for k in KINDS
        for i in range(2)
    )
    assert closed < 0.3 * 2 * len(KINDS)


def test_dataset_is_a_test_split_with_versioned_sources() -> None:
    ds = webplus()
    assert len(ds) == 16 * len(KINDS) and len(set(ds.labels)) == len(KINDS)
    assert len(ds.split("test")) == len(ds) and len(ds.split("validation")) == 0
    assert all(m.source.endswith(":" + webplus_version()) for m in ds.models)
    v, _ = mesh_arrays(ds.models[0])
    assert np.array_equal(v, webplus_mesh(KINDS[0], 0)[0])
    assert len(set(families(ds.models))) == len(ds)


def test_a_stale_source_is_refused() -> None:
    m = webplus().models[0]
    with pytest.raises(ValueError, match="webplus generator"):
        mesh_arrays(replace(m, source=m.source.rsplit(":", 1)[0] + ":00000000"))
