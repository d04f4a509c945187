"""bench.retrieval's mesh-only baselines (D2, spherical harmonics, light fields)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.retrieval import cloud_classes, main, run_baselines
from bench.sets.datasets import web
from bench.support.baselines import D2Config


def test_baselines_only_rank_a_tiny_web_set(capsys: pytest.CaptureFixture[str]) -> None:
    ds = web(per_kind=3, kinds=["mug", "skyscraper"])
    out = run_baselines(ds, D2Config(n_pairs=2**14))
    names = [r["method"] for r in out["table"]]
    assert names == [
        "D2 shape distribution, meshes",
        "spherical harmonics, meshes",
        "light field descriptor, meshes",
    ]
    # a mug and a skyscraper are far apart for every descriptor
    assert all(r["NN"] == 1.0 for r in out["table"])
    assert "baselines only" in capsys.readouterr().out


def test_the_flag_is_on_the_command_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "--baselines-only" in capsys.readouterr().out


def test_cloud_classes_lists_the_clouds_largest_loss_first() -> None:
    """Two classes of two: mesh queries all find their class; cloud queries of class
    "b" find class "a" first, those of "a" still find "a"."""
    labels = np.array(["a", "a", "b", "b"])
    meshes = np.array(
        [[0, 0.9, 0.1, 0.1], [0.9, 0, 0.1, 0.1], [0.1, 0.1, 0, 0.9], [0.1, 0.1, 0.9, 0]]
    )
    clouds = meshes.copy()
    clouds[2:, :2] = 0.95  # b's clouds look like a's meshes
    assert cloud_classes(meshes, clouds, labels) == [("b", 1.0, 0.0), ("a", 1.0, 1.0)]
