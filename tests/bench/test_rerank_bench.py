"""bench.studies.rerank_stage: the product's stage scored on every store against version 4 alone."""

from __future__ import annotations

import numpy as np

from bench.studies.rerank_stage import baseline_rows
from bench.support.stores import STAGE_NOW, shared_rows
from query.search.tuning import PRODUCT


class _Split:
    """Two small sets whose stage distance knows the classes better than version 4."""

    def __init__(self, n: int = 40) -> None:
        rng = np.random.default_rng(5)
        cls = np.arange(n) % 4
        x = rng.random((n, 6)) + cls[:, None] * 0.2
        y = rng.random((n, 2)) * 0.2 + cls[:, None]
        self.split = "test"
        self.sets = np.array(["web"] * (n // 2) + ["generic"] * (n - n // 2))
        self.labels = np.array([f"{s}:{c}" for s, c in zip(self.sets, cls, strict=True)])
        self.d4 = np.abs(x[:, None] - x[None]).sum(-1)
        self.dl = np.abs(y[:, None] - y[None]).sum(-1) * 20.0
        self.light = self.dl

    def store(self, names: tuple[str, ...]) -> np.ndarray:
        return np.flatnonzero(np.isin(self.sets, list(names)))


def test_the_rows_compare_the_stage_with_version_4_on_every_store() -> None:
    split = _Split()
    stores, base, rows = baseline_rows(split, ("web", "generic"))  # type: ignore[arg-type]
    assert set(stores) == {"web", "generic"}  # no mix of these two in MIXES
    v4 = rows["v4 (no stage)"]
    assert v4["worst_queries"] == 0.0 and v4["passes"]
    assert v4["stores"] == base
    alone = rows["light fields alone (K = 100)"]
    assert alone["objective"] > v4["objective"]  # the stage's distance knows the classes
    rows.update(shared_rows(stores, split, PRODUCT, base))  # type: ignore[arg-type]
    assert STAGE_NOW in rows
