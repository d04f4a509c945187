"""The search bench's synthetic vectors: the default configuration's length and scale."""

from __future__ import annotations

import numpy as np
import pytest

from bench.query import run_size, synthetic_vectors
from shapedb.config.core import Config, KernelConfig


@pytest.mark.parametrize("config", [KernelConfig(), KernelConfig(method="paper", n_r=10)])
def test_synthetic_vectors_have_the_configured_length(config: KernelConfig) -> None:
    x = synthetic_vectors(500, config, seed=0)
    assert (
        x.shape == (500, Config(kernel=config).dim)
        and x.dtype == np.float32
        and np.isfinite(x).all()
    )


def test_synthetic_descriptors_are_calibrated_like_real_ones() -> None:
    # describe() scales unrelated shapes to about ln 10 apart; so do the synthetic ones
    x = synthetic_vectors(2000, KernelConfig(), seed=1).astype(np.float64)
    d = np.abs(x[:1000] - x[1000:]).sum(axis=1)
    assert 0.5 * np.log(10) < np.median(d) < 2 * np.log(10)


def test_a_small_run_finds_the_exact_neighbours() -> None:
    row = run_size(2000, n_queries=50, n_latency=5, n_baseline=5)
    assert row["dim"] == Config().dim
    assert row["recall_at_10"] == 1.0 and row["baseline_recall_at_10"] == 1.0
