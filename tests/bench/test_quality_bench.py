"""bench.quality: stores built through the product's ingest, cached, scored as searches rank."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench import quality
from bench.sets.datasets import generic, mesh_arrays
from bench.support import product_stores


def test_options_parse_numbers_booleans_and_words() -> None:
    got = quality.parse_options(
        ["resolution=64", "sheet_cells=1.5", "refine=false", "sheet_rule=enclosed"]
    )
    assert got == {"resolution": 64, "sheet_cells": 1.5, "refine": False, "sheet_rule": "enclosed"}
    with pytest.raises(SystemExit, match="key=value"):
        quality.parse_options(["resolution"])


def test_a_split_store_is_built_once_and_scored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(product_stores, "STORES_DIR", tmp_path)
    ds = generic().split("validation").head(per_class=2, classes=2)
    options = {"resolution": 32, "n_balls": 32}
    db = product_stores.split_store(ds, options, workers=1)
    assert len(db.store) == 4
    scores = product_stores.store_scores(db)
    assert scores["queries"] == 4 and 0.0 <= scores["nn"] <= 1.0
    assert set(scores["per_class_nn"]) == set(ds.labels)

    def no_ingest(model: object) -> None:
        raise AssertionError("a built store is ingested again")

    monkeypatch.setattr(product_stores, "mesh_arrays", no_ingest)
    again = product_stores.split_store(ds, options)
    assert again.path == db.path
    other = product_stores.store_key(ds, {**options, "n_balls": 16})
    assert other != product_stores.store_key(ds, options)


def test_a_half_built_store_is_completed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import shapedb
    from shapedb.geometry.mesh import TriangleMesh

    monkeypatch.setattr(product_stores, "STORES_DIR", tmp_path)
    ds = generic().split("validation").head(per_class=1, classes=2)
    options = {"resolution": 32, "n_balls": 32}
    half = shapedb.connect(
        tmp_path / f"{ds.name}_{product_stores.store_key(ds, options)}", **options
    )
    first = ds.models[0]
    half.ingest(
        [(first.name, first.label, TriangleMesh(*mesh_arrays(first)))], workers=1, progress=False
    )
    db = product_stores.split_store(ds, options, workers=1)
    assert sorted(db.shapes(["name"]).column("name").to_pylist()) == sorted(
        m.name for m in ds.models
    )


def test_scans_and_cropped_halves_query_the_meshes_store(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import json

    monkeypatch.setattr(product_stores, "STORES_DIR", tmp_path / "stores")
    ds = generic().split("validation").head(per_class=2, classes=2)
    monkeypatch.setattr(quality, "family_split", lambda name, split: ds)
    out = tmp_path / "queries.json"
    argv = ["--datasets", "generic", "--set", "resolution=32", "n_balls=32"]
    assert quality.main([*argv, "--queries", "one-sided", "cropped", "--out", str(out)]) == 0
    got = json.loads(out.read_text())
    assert got["queries"] == ["mesh", "one-sided", "cropped"]
    row = got["families"]["generic"]
    for kind in ("mesh", "one-sided", "cropped"):
        for measure in ("nn", "first_tier", "second_tier", "dcg"):
            assert 0.0 <= row[kind][measure] <= 1.0
    for kind in ("one-sided", "cropped"):
        # A one-sided scan of a thin shape may be refused at resolution 32: a scored miss.
        assert row[kind]["failed"] == len(row[kind]["errors"]) < len(ds)
        assert row[kind]["median_ms"] > 0
        assert set(row[kind]["top"]) | set(row[kind]["errors"]) == {m.name for m in ds.models}
        for name, hits in row[kind]["top"].items():
            assert name not in hits and len(hits) == len(ds) - 1


def test_partial_is_passed_only_to_a_search_that_takes_it() -> None:
    from bench.support.scan_queries import search_options

    class Old:
        def search(self, query: object, *, k: int = 10) -> list[object]:
            return []

    class New:
        def search(
            self, query: object, *, k: int = 10, partial: bool | None = None
        ) -> list[object]:
            return []

    assert search_options(Old(), None) == {}
    with pytest.raises(SystemExit, match="partial"):
        search_options(Old(), True)
    assert search_options(New(), None) == {"partial": None}
    assert search_options(New(), False) == {"partial": False}
