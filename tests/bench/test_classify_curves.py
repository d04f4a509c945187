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
