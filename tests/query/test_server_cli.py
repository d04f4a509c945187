"""``shapedb serve`` from the command line: it serves the store, and refuses unsafe setups."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import urllib.request
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi", reason="the serve extra is not installed")
pytest.importorskip("uvicorn", reason="the serve extra is not installed")

from server_helpers import build_store  # noqa: E402

from query.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Any:
    return build_store(tmp_path_factory.mktemp("cli"))[0]


def test_serve_prints_its_url_and_answers(store: Any) -> None:
    argv = [sys.executable, "-m", "query.cli", "serve", "--db", str(store.path), "--port", "0"]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()  # printed once the index is loaded and the port bound
        assert line.startswith(f"serving {store.path} (6 shapes) at http://127.0.0.1:"), line
        url = line.split(" at ", 1)[1].split()[0]
        with urllib.request.urlopen(url + "api/info", timeout=30) as r:
            assert json.loads(r.read())["shapes"] == 6
        with urllib.request.urlopen(url, timeout=30) as r:
            assert b"<title>shapedb</title>" in r.read()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_serve_refuses_another_host_without_a_token(
    store: Any, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("SHAPEDB_TOKEN", raising=False)
    assert main(["serve", "--db", str(store.path), "--host", "0.0.0.0"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("shapedb: error: --host 0.0.0.0:") and "--token" in err


def test_serve_needs_a_store(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "--db", str(tmp_path / "nothing")]) == 1
    assert "no shapedb store" in capsys.readouterr().err
