"""bench.concurrency end to end on a tiny store (slow: it spawns reader and writer processes)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest


@pytest.mark.slow
def test_concurrency_bench_runs_and_loses_nothing(tmp_path: Path) -> None:
    from bench.concurrency import main

    out = tmp_path / "c.json"
    argv = ["--readers", "2", "--base", "3", "--files", "2", "--batch", "1", "--seconds", "1"]
    assert main([*argv, "--limit", "240", "--out", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["rows_lost"] == 0 and r["check_ok"]
    assert r["during_writes"]["errors"] == 0 and r["alone"]["errors"] == 0
    assert all(w["error"] is None for w in r["writers"])
