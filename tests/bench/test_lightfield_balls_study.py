"""The fusions of bench.studies.lightfield_balls on small distance matrices."""

from __future__ import annotations

import numpy as np

from bench.common import class_nn
from bench.studies.lightfield_balls import fuse, overlap, spread


def _points(seed: int, n: int = 12) -> np.ndarray:
    x = np.random.default_rng(seed).normal(size=(n, 3))
    return np.abs(x[:, None, :] - x[None, :, :]).sum(-1)


def test_the_overlap_gate_is_one_for_agreeing_distances_and_less_otherwise() -> None:
    d = _points(0)
    assert np.allclose(overlap(d, 3.0 * d, 5), 1.0)
    other = overlap(d, _points(1), 5)
    assert other.min() < 1.0 and np.all((other >= 0) & (other <= 1))


def test_the_spread_is_the_ratio_of_the_two_scales() -> None:
    d = _points(2)
    assert np.allclose(spread(d, 4.0 * d, 2.0), 2.0)


def test_a_closed_gate_ranks_by_v4_and_an_open_one_moves_the_order() -> None:
    d4, dl = _points(3), _points(4)
    order4 = np.argsort(d4 + np.eye(12) * 1e9, axis=1, kind="stable")
    # ceiling below every spread: the light field's term is 0 and v4's ranks decide
    closed = fuse("adrank", 8.0, d4, dl, 1.0, ceiling=1e-9)
    assert np.array_equal(np.argsort(closed + np.eye(12) * 1e9, axis=1, kind="stable"), order4)
    # the same light field as v4: the gate is open and the order is v4's too
    same = fuse("adrank", 8.0, d4, d4, 1.0, power=3.0)
    assert np.array_equal(np.argsort(same + np.eye(12) * 1e9, axis=1, kind="stable"), order4)
    # plain rank fusion with a heavy light field weight follows the light field
    heavy = fuse("rank", 100.0, d4, dl, 1.0)
    order_l = np.argsort(dl + np.eye(12) * 1e9, axis=1, kind="stable")
    assert np.array_equal(
        np.argsort(heavy + np.eye(12) * 1e9, axis=1, kind="stable")[:, :3], order_l[:, :3]
    )


def test_class_nn_is_the_per_class_share_of_right_nearest_neighbours() -> None:
    # points on a line: a a b b b; the b at 2.4 is nearer the a at 2.0 than the other b's
    x = np.array([0.0, 2.0, 2.4, 5.0, 6.0])
    labels = np.array(["a", "a", "b", "b", "b"])
    got = class_nn(np.abs(x[:, None] - x[None, :]), labels)
    assert got == {"a": 0.5, "b": 2 / 3}
