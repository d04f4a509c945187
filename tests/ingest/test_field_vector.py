"""Ingest stores each record's field vector when the store keeps them (the product's default)."""

from __future__ import annotations

import numpy as np
from ingest_helpers import SMALL

import query.database as database
from shapedb.geometry.implicit import Box, Capsule, Sphere
from shapedb.mdbd.decomposition import decompose
from shapedb.signature.field_vector import decomposition_field_vector, field_vector_dim

SHAPES = {
    "ball": Sphere([0, 0, 0], 1.0),
    "brick": Box([0, 0, 0], [2.0, 1.0, 0.5]),
    "rod": Capsule([0, 0, 0], [3.0, 0, 0], 0.3),
}


def test_records_carry_the_field_vector_of_their_decomposition(tmp_path) -> None:  # type: ignore[no-untyped-def]
    db = database.connect(tmp_path / "db", **SMALL)
    assert db.config.stores_field_vectors  # a new store keeps them
    report = db.ingest(list(SHAPES.items()), workers=1)
    assert len(report.ingested) == 3
    again = database.connect(tmp_path / "db")
    for name, shape in SHAPES.items():
        rec = again.get(name)
        assert rec.field_vector is not None and rec.field_vector.dtype == np.float32
        assert rec.field_vector.shape == (field_vector_dim(again.config),)
        kept = decompose(shape, config=again.config.mdbd, keep_inside=True)
        np.testing.assert_array_equal(
            rec.field_vector, decomposition_field_vector(kept, again.config.field_vector)
        )
        assert rec.decomposition.timings["field_vector"] > 0
        assert rec.decomposition.inside is None  # the inside itself is never stored
    ball, brick = again.get("ball").field_vector, again.get("brick").field_vector
    assert ball is not None and brick is not None and not np.array_equal(ball, brick)


def test_a_store_without_field_vectors_carries_none(tmp_path) -> None:  # type: ignore[no-untyped-def]
    db = database.connect(tmp_path / "db", fv_enabled=False, **SMALL)
    assert not db.config.stores_field_vectors and db.config.light_field_inside
    db.ingest(list(SHAPES.items())[:2], workers=1)
    for name in ("ball", "brick"):
        rec = db.get(name)
        assert rec.field_vector is None and "field_vector" not in rec.decomposition.timings
        assert rec.light_field is not None  # today's store: the field's light fields
    column = db.store.shapes(["field_vector"]).column("field_vector").to_pylist()
    assert column == [None, None]
    # light fields of the balls: no inside to read a field vector from
    balls = database.connect(tmp_path / "balls", lf_source="balls", **SMALL)
    assert balls.config.field_vector.enabled and not balls.config.stores_field_vectors
    balls.ingest(list(SHAPES.items())[:1], workers=1)
    assert balls.get("ball").field_vector is None
