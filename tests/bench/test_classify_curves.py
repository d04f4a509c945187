"""The heldout50 set of bench.classify_curves tests on the held-out set's test models."""

from __future__ import annotations

from collections import Counter

import numpy as np

from bench.classify import generated
from bench.classify_curves import heldout50
from query.learn.training_data import stratified_split


def test_heldout50_tests_on_the_heldout_test_models() -> None:
    ds, train, test = heldout50()
    small = generated(20, 20)
    _, te20 = stratified_split([m.label for m in small.models], (14 / 20, 6 / 20), seed=0)
    assert [ds.models[i].name for i in test] == [small.models[i].name for i in te20]
    assert len(np.intersect1d(train, test)) == 0
    assert set(Counter(ds.models[i].label for i in train).values()) == {50}
    assert set(Counter(ds.models[i].label for i in test).values()) == {6}


def test_the_budget_row_is_the_products_selection_within_its_budget() -> None:
    """Within a budget too small for any other candidate, 1-NN (always scored) is saved."""
    from bench.classify_curves import budget_row

    rng = np.random.default_rng(0)
    labels = np.repeat(["a", "b", "c"], 12)
    x = (
        rng.normal(size=(36, 8))
        + 4.0 * (labels[:, None] == np.array(["a", "b", "c"])).argmax(1)[:, None]
    )
    data = {"labels": labels, "mesh": [None] * 36, "x_mesh": x}
    train = np.concatenate([np.arange(k * 12, k * 12 + 9) for k in range(3)])
    test = np.setdiff1d(np.arange(36), train)
    row = budget_row(data, train, test, {"epochs": 1}, budget=1e-3)
    assert row["name"] == "1-nn" and row["test_mesh"] == 1.0
    assert row["statuses"]["1-nn"] == "scored"
    assert "skipped" in row["statuses"].values()
