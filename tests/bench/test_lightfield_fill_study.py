"""The fill study's spellings of a light field configuration."""

from __future__ import annotations

import pytest

from bench.studies.lightfield_balls import fill_config, parse_config


def test_fills_are_spelled_as_the_config_fields() -> None:
    cfg = fill_config("edges+dilate0.5+close1")
    assert (cfg.edges, cfg.dilate_px, cfg.close_px) == (True, 0.5, 1)
    assert (cfg.n_fields, cfg.resolution) == (3, 64)
    plain = fill_config("plain")
    assert (plain.edges, plain.dilate_px, plain.close_px) == (False, 0.0, 0)
    got = parse_config("32/2/0/edges")
    assert (got.resolution, got.n_fields, got.edges) == (32, 2, True)
    assert parse_config("64/3/0").edges is False
    with pytest.raises(ValueError, match="unknown"):
        fill_config("blur2")


def test_per_query_scores_leave_the_query_out() -> None:
    import numpy as np

    from bench.common import per_query

    # points on a line: a a b b c; each query's nearest other model and its first tier
    x = np.array([0.0, 1.0, 1.6, 2.5, 10.0])
    d = np.abs(x[:, None] - x[None, :])
    nn, tier = per_query(d, ["a", "a", "b", "b", "c"])
    assert nn.tolist() == [True, False, False, True, False]
    assert tier.tolist() == [1.0, 0.0, 0.0, 1.0, 0.0]


def test_uncovered_cells_are_outside_every_ball() -> None:
    import numpy as np

    from bench.common import Balls
    from bench.studies.lightfield_fill import uncovered_cells

    b = Balls(np.array([[0.0, 0, 0], [3.0, 0, 0]]), np.array([1.0, 0.5]),
              np.zeros((0, 2), np.int64), 0.1, 0.0)  # fmt: skip
    cells = np.array([[0.0, 0, 0], [0.9, 0, 0], [1.1, 0, 0], [3.4, 0, 0], [3.6, 0, 0]])
    assert uncovered_cells(b, cells).tolist() == [False, False, True, False, True]
