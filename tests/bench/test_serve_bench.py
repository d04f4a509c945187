"""The serve bench end to end on a tiny store (a child server, the CLI baseline): no errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("fastapi", reason="the serve extra is not installed")


@pytest.mark.slow
def test_a_tiny_run_answers_every_request(tmp_path: Path) -> None:
    import trimesh

    from bench.serve import main

    model = tmp_path / "box.obj"
    trimesh.creation.box((2, 1, 1)).export(model)
    out = tmp_path / "serve.json"
    argv = ["--shapes", "200", "--requests", "30", "--cli-runs", "1", "--model", str(model)]
    argv += ["--file-repeats", "1", "--seconds", "1", "--memory-requests", "60", "--out", str(out)]
    assert main(argv) == 0
    r = json.loads(out.read_text())
    assert r["shapes"] == 200
    assert r["concurrency"]["errors"] == 0 and r["concurrency"]["requests"] > 0
    assert r["memory"]["errors"] == 0 and r["memory"]["requests"] == 60
    assert r["stored_search"]["cli_runs"] == 1
    assert r["file_query"]["http_ms"] > 0
