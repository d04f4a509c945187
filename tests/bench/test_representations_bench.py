"""Tests of bench.representations' scoring: rows, own-first, mixture, D2 of points."""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.representations import Distances, d2_points, score_rows
from bench.support.baselines import D2Config


def _toy() -> tuple[Distances, np.ndarray]:
    # two classes on a line: 0, 0.1, 0.2 and 10, 10.1, 10.2
    x = np.array([0.0, 0.1, 0.2, 10.0, 10.1, 10.2])
    d = np.abs(x[:, None] - x[None, :])
    labels = np.array(["a", "a", "a", "b", "b", "b"])
    cloud = d + 0.01  # a cloud sits a little off its mesh
    dist = Distances(
        mesh=d,
        cloud={"cloud": cloud},
        cloud_cloud=d,
        ingest=np.full(6, 2.0),
        query={"cloud": np.full(6, 3.0)},
    )
    return dist, labels


def test_rows_score_a_perfectly_separated_set_as_perfect() -> None:
    dist, labels = _toy()
    rows = score_rows("m", dist, labels)
    assert [r[1] for r in rows] == ["mesh->mesh", "cloud->mesh", "mixture"]
    for r in rows:
        assert r[2] == 1.0 and r[3] == 1.0  # NN and first tier
    assert rows[1][5] == 1.0  # every cloud's nearest mesh is its own
    assert rows[0][6] == 2.0 and rows[1][6] == 3.0  # median costs


def test_own_first_counts_clouds_nearer_another_mesh() -> None:
    dist, labels = _toy()
    swapped = dist.cloud["cloud"].copy()
    swapped[0, 0], swapped[0, 1] = swapped[0, 1], swapped[0, 0]  # cloud 0 nearer mesh 1
    dist.cloud["cloud"] = swapped
    rows = score_rows("m", dist, labels)
    assert rows[1][5] == 5 / 6
    assert rows[1][2] == 1.0  # still its class


def test_d2_of_points_is_a_pdf() -> None:
    pts = np.random.default_rng(0).normal(size=(500, 3))
    cfg = D2Config(n_pairs=2**14, bins=256, vertices=64)
    pdf = d2_points(pts, cfg)
    assert pdf.shape == (64,)
    assert np.isclose(pdf.sum(), 1.0)
    assert np.array_equal(pdf, d2_points(pts, cfg))


def _balls(radius: float, shift: float) -> Any:
    from bench.common import Balls

    centers = np.array([[shift, 0.0, 0.0], [shift + 1.5, 0.0, 0.0], [shift, 1.4, 0.0]])
    radii = np.array([radius, 0.5, 0.4])
    return Balls(centers, radii, np.array([[0, 1], [0, 2]]), 0.05, 1.0, {"sdf": 1.0}, 0.2)


def test_store_rule_mean_averages_a_cloud_and_its_reconstruction() -> None:
    """``combine="mean"`` compares the mean of the two features; a mask scales all three."""
    from bench.representations import SetData, pose_free_mask, store_rule
    from bench.sets.datasets import Dataset, Model
    from bench.support.features import kernel_features
    from shapedb.config.core import KernelConfig

    models = tuple(Model(f"m{i}", "a", f"toy:{i}") for i in range(2))
    mesh = [_balls(1.0, 0.0), _balls(0.8, 0.0)]
    cloud = [_balls(0.9, 0.0), _balls(0.7, 0.0)]
    recon = [_balls(1.1, 0.0), None]
    data = SetData(Dataset("toy", models), mesh, {"cloud": cloud}, {8: {"cloud": recon}})
    cfg = KernelConfig()
    mask = pose_free_mask(cfg)
    fm, fc = kernel_features(mesh, cfg) * mask, kernel_features(cloud, cfg) * mask
    fr = kernel_features([recon[0]], cfg) * mask
    got = store_rule(data, cfg, depth=8, combine="mean", mask=mask).cloud["cloud"]
    np.testing.assert_allclose(got[0], np.abs(fm - 0.5 * (fc[0] + fr[0])).sum(axis=1))
    np.testing.assert_allclose(got[1], np.abs(fm - fc[1]).sum(axis=1))  # no reconstruction
    nearest = store_rule(data, cfg, depth=8, mask=mask).cloud["cloud"]
    np.testing.assert_allclose(
        nearest[0], np.minimum(np.abs(fm - fc[0]).sum(1), np.abs(fm - fr[0]).sum(1))
    )
    assert mask.sum() == len(mask) - 33  # d2c_mean (30) and inertia (3) left out
