"""Tests of bench.representations' scoring: rows, own-first, mixture, D2 of points."""

from __future__ import annotations

import numpy as np

from bench.baselines import D2Config
from bench.representations import Distances, d2_points, score_rows


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
