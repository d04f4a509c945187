"""The generic web-like set (bench.sets.generic_shapes, bench.sets.datasets.generic)."""

from __future__ import annotations

import numpy as np

from bench.sets.datasets import generic, mesh_arrays
from bench.sets.generic_shapes import KINDS, generic_mesh


def test_generation_is_deterministic_and_varied() -> None:
    assert len(KINDS) >= 20
    for kind in KINDS:
        v, f = generic_mesh(kind, 3)
        v2, f2 = generic_mesh(kind, 3)
        assert np.array_equal(v, v2) and np.array_equal(f, f2)
        assert f.min() >= 0 and f.max() < len(v) and np.isfinite(v).all()
        other, _ = generic_mesh(kind, 4)
        assert other.shape != v.shape or not np.allclose(other, v)


def test_most_models_are_not_watertight() -> None:
    import trimesh

    closed = sum(
        trimesh.Trimesh(*generic_mesh(k, i), process=True).is_watertight
        for k in KINDS
        for i in range(3)
    )
    assert closed < 0.5 * 3 * len(KINDS)


def test_dataset_split_and_meshes() -> None:
    ds = generic()
    assert len(ds) == 20 * len(KINDS) and len(set(ds.labels)) == len(KINDS)
    val = ds.split("validation")
    assert 0.3 < len(val) / len(ds) < 0.4
    assert {m.label for m in val.models} == set(KINDS)
    v, f = mesh_arrays(ds.models[0])
    assert np.array_equal(v, generic_mesh(KINDS[0], 0)[0])
