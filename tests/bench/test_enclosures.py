"""The thin-walled set (bench.sets.enclosures, bench.sets.datasets.enclosures)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.sets.datasets import build_sets, enclosures, families, load_dataset, mesh_arrays
from bench.sets.enclosures import FAMILIES, KINDS, enclosure_mesh, enclosure_version


def _misoriented_edges(v: np.ndarray, f: np.ndarray) -> int:
    """Edges that two faces traverse in the same direction, once equal positions are merged."""
    _, ids = np.unique(np.round(v, 9), axis=0, return_inverse=True)
    g = ids.ravel()[f]
    directed = np.concatenate([g[:, [0, 1]], g[:, [1, 2]], g[:, [2, 0]]])
    directed = directed[directed[:, 0] != directed[:, 1]]
    _, counts = np.unique(directed, axis=0, return_counts=True)
    return int((counts > 1).sum())


def test_kinds_come_in_close_pairs() -> None:
    assert len(KINDS) >= 10
    members = [k for family in FAMILIES.values() for k in family]
    assert sorted(members) == sorted(KINDS)  # each kind in exactly one family


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_builds_deterministic_finite_varied_meshes(kind: str) -> None:
    meshes = [enclosure_mesh(kind, s) for s in range(4)]
    again = [enclosure_mesh(kind, s) for s in range(4)]
    for (v, f), (v2, f2) in zip(meshes, again, strict=True):
        assert np.array_equal(v, v2) and np.array_equal(f, f2)
        assert len(f) > 0 and f.min() >= 0 and f.max() < len(v) and np.isfinite(v).all()
        assert np.ptp(v[np.unique(f)], axis=0).min() > 0  # every kind is 3-D
    extents = {np.round(np.sort(np.ptp(v, axis=0)), 6).tobytes() for v, _ in meshes}
    assert len(extents) == 4  # proportions or scale differ between seeds


def test_meshes_are_built_as_web_and_cad_models_are() -> None:
    models = [(k, s) for k in KINDS for s in range(6)]
    meshes = [enclosure_mesh(k, s) for k, s in models]
    misoriented = [_misoriented_edges(v, f) > 0 for v, f in meshes]
    assert sum(misoriented) > 0.3 * len(models)
    strays = [len(np.setdiff1d(np.arange(len(v)), f)) > 0 for v, f in meshes]
    assert 0 < sum(strays) < len(models)
    y_up = [np.ptp(enclosure_mesh("bookcase", s)[0], axis=0).argmax() == 1 for s in range(20)]
    z_up = [np.ptp(enclosure_mesh("bookcase", s)[0], axis=0).argmax() == 2 for s in range(20)]
    assert sum(y_up) > 3 and sum(z_up) > 3  # a bookcase is tallest along its builder's up
    sizes = [np.ptp(enclosure_mesh("house", s)[0], axis=0).max() for s in range(20)]
    assert max(sizes) / min(sizes) > 3


def test_an_unknown_kind_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown enclosures kind"):
        enclosure_mesh("castle", 0)


def test_dataset_splits_sources_and_families() -> None:
    ds = enclosures()
    assert len(ds) == 20 * len(KINDS) and len(set(ds.labels)) == len(KINDS)
    val, test = ds.split("validation"), ds.split("test")
    assert len(val) > 0 and len(test) > 0 and len(val) + len(test) == len(ds)
    assert not {m.name for m in val.models} & {m.name for m in test.models}
    assert {m.label for m in val.models} == set(KINDS) == {m.label for m in test.models}
    assert all(m.source.endswith(":" + enclosure_version()) for m in ds.models)
    v, _ = mesh_arrays(ds.models[0])
    assert np.array_equal(v, enclosure_mesh(KINDS[0], 0)[0])
    assert len(set(families(ds.models))) == len(ds)
    assert load_dataset("enclosures") == ds
    (quick,) = build_sets(["enclosures"], quick=True)
    assert len(quick) == 6 * len(KINDS)


def test_sources_change_with_the_code(monkeypatch: pytest.MonkeyPatch) -> None:
    import inspect

    from bench.sets import enclosure_shapes

    before = enclosure_version()
    original = inspect.getsource

    def edited(obj: object) -> str:  # the builders' module with one more line of code
        extra = "\nEDITED = 1\n" if obj is enclosure_shapes else ""
        return original(obj) + extra  # type: ignore[arg-type]

    monkeypatch.setattr(inspect, "getsource", edited)
    enclosure_version.cache_clear()
    try:
        assert enclosure_version() != before
        assert enclosures(per_kind=1).models[0].source.endswith(":" + enclosure_version())
    finally:
        monkeypatch.undo()
        enclosure_version.cache_clear()
    assert enclosure_version() == before


def test_a_stale_source_is_refused() -> None:
    m = enclosures().models[0]
    with pytest.raises(ValueError, match="enclosures generator"):
        mesh_arrays(replace(m, source=m.source.rsplit(":", 1)[0] + ":00000000"))
