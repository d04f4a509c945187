"""``shapedb serve`` at its edges: null origins, upload names, out-of-range numbers, the
request log, and SQL statements interrupted when their client goes or the server stops."""

from __future__ import annotations

import logging
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi", reason="the serve extra is not installed")
pytest.importorskip("httpx", reason="TestClient needs httpx (dev extra)")

from server_helpers import OPTIONS, build_store, client, live_server, write_models  # noqa: E402

from query.serve.server import create_app  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
#: A statement that runs for minutes: only an interrupt ends it within the tests' time.
LONG_SQL = "SELECT count(*) FROM range(1000000000000) t(i) WHERE hash(i) % 7 = 3"
HUGE = "99999999999999999999"


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, dict[str, Path]]:
    return build_store(tmp_path_factory.mktemp("hardening"))


@pytest.fixture(scope="module")
def api(store: tuple[Any, dict[str, Path]]) -> Any:
    return client(create_app(store[0]), raise_server_exceptions=False)


def _wait(condition: Any, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


def test_a_null_origin_is_a_foreign_origin(api):
    null = {"Origin": "null"}
    r = api.post("/api/sql", json={"sql": "SELECT 1"}, headers=null)
    assert r.status_code == 403 and "cross-origin" in r.json()["error"]
    assert api.post("/api/ingest", files={"file": ("a.obj", b"x")}, headers=null).status_code == 403
    assert api.post("/api/search", files={"file": ("a.obj", b"x")}, headers=null).status_code == 403
    r = api.post("/api/match", json={"query": "box0", "node": 0}, headers=null)
    assert r.status_code == 403
    assert api.get("/api/info", headers=null).status_code == 200  # reads are not writes


@pytest.mark.parametrize(
    "path",
    [
        f"/api/shapes/{HUGE}",
        f"/api/shapes/{HUGE}/surface",
        f"/api/shapes/{HUGE}/thumbnail.png",
        f"/api/search?id={HUGE}",
        "/api/shapes/%C2%B2",  # a superscript two: a digit to str.isdigit, not to int()
        f"/api/shapes?offset={HUGE}",
        f"/api/search?id=1&k={HUGE}",
    ],
)
def test_out_of_range_numbers_are_4xx_json(api, path):
    r = api.get(path)
    assert 400 <= r.status_code < 500, (r.status_code, r.text)
    error = r.json()["error"]
    assert "\n" not in error and "Overflow" not in error and "internal" not in error


@pytest.mark.parametrize(
    "body",
    [
        {"query": int(HUGE), "node": 0},
        {"query": "box0", "node": 0, "targets": [int(HUGE)]},
        {"query": "box0", "node": int(HUGE)},
        {"query": "box0", "node": 0, "hops": int(HUGE)},
        {"query": "box0", "node": 0, "k": int(HUGE)},
    ],
)
def test_out_of_range_match_numbers_are_4xx_json(api, body):
    r = api.post("/api/match", json=body)
    assert 400 <= r.status_code < 500, (r.status_code, r.text)
    assert "internal" not in r.json()["error"]


def test_a_point_must_be_finite(api):
    r = api.post(
        "/api/match",
        content=b'{"query": "box0", "point": [1e999, 0, 0]}',
        headers={"Content-Type": "application/json"},
    )
    assert r.status_code == 400 and r.json()["error"].startswith("point.0:")


def test_an_ingested_upload_keeps_its_file_name(tmp_path, monkeypatch):
    import shapedb

    models = write_models(tmp_path / "models")
    db = shapedb.connect(tmp_path / "store", **OPTIONS)
    api = client(create_app(db))
    files = [
        ("file", ("box1.obj", models["box1"].read_bytes())),
        ("file", ("dir\\broken.obj", b"v 0 0 0\nf 1 2 3\n")),
    ]
    job = api.post("/api/ingest", files=files).json()["job"]
    assert _wait(lambda: api.get(f"/api/ingest/{job}").json()["state"] != "running", 120)
    state = api.get(f"/api/ingest/{job}").json()
    assert state["state"] == "done", state
    assert "shapedb-upload" not in str(state) and "/0/" not in str(state)
    (sid,) = state["report"]["ids"]
    shape = api.get(f"/api/shapes/{sid}")
    assert shape.json()["source"] == "box1.obj" and shape.json()["name"] == "box1"
    assert "shapedb-upload" not in shape.text
    assert [f["source"] for f in db.store.failures().to_pylist()] == ["broken.obj"]
    # a bare file name is never read from the server's working folder
    monkeypatch.chdir(models["box1"].parent)
    assert api.get(f"/api/shapes/{sid}/surface").json() == {"kind": "none"}


def test_every_request_is_logged(api, caplog):
    with caplog.at_level(logging.INFO, logger="query.serve"):
        api.get("/api/info")
        api.get("/api/shapes/no-such-shape")
        api.post("/api/sql", json={"sql": "SELECT 1"}, headers={"Origin": "http://evil.example"})
    lines = [r.getMessage() for r in caplog.records if r.name == "query.serve"]
    assert re.fullmatch(r"GET /api/info 200 \d+\.\d ms", lines[0]), lines
    assert lines[1].startswith("GET /api/shapes/no-such-shape 404 ")
    assert lines[2].startswith("POST /api/sql 403 ")


def _post_sql(url: str, statement: str) -> socket.socket:
    """Send ``POST /api/sql`` over a raw socket and return it (the answer unread)."""
    import json

    host, port = url.removeprefix("http://").split(":")
    body = json.dumps({"sql": statement}).encode()
    sock = socket.create_connection((host, int(port)), timeout=30)
    head = (
        f"POST /api/sql HTTP/1.1\r\nHost: {host}:{port}\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\n\r\n"
    )
    sock.sendall(head.encode() + body)
    return sock


def test_a_statement_is_interrupted_when_its_client_goes(store, caplog):
    import json
    import urllib.request

    app = create_app(store[0])
    running = app.state.service.statements
    with live_server(app) as url, caplog.at_level(logging.INFO, logger="query.serve"):
        sock = _post_sql(url, LONG_SQL)
        assert _wait(lambda: len(running) == 1, 30)
        time.sleep(0.5)  # the statement is under way
        sock.close()
        assert _wait(lambda: len(running) == 0, 5), "the statement still runs"
        assert _wait(lambda: "POST /api/sql 499" in caplog.text, 5)
        request = urllib.request.Request(
            url + "/api/sql",
            data=json.dumps({"sql": "SELECT 42 AS answer"}).encode(),
            headers={"Content-Type": "application/json"},
        )
        with urllib.request.urlopen(request, timeout=30) as r:
            assert json.loads(r.read())["rows"] == [[42]]


def test_ctrl_c_stops_the_server_during_a_statement(store):
    db = store[0]
    argv = [sys.executable, "-m", "query.cli", "serve", "--db", str(db.path), "--port", "0"]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )
    try:
        assert proc.stdout is not None and proc.stderr is not None
        url = proc.stdout.readline().split(" at ", 1)[1].split()[0].rstrip("/")
        sock = _post_sql(url, LONG_SQL)
        time.sleep(2)  # the statement is under way
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
        answer = sock.recv(65536)
        sock.close()
        assert answer.startswith(b"HTTP/1.1 503 ") and b"interrupted" in answer
        assert "INFO query.serve: POST /api/sql 503 " in proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_sql_over_a_damaged_segment_is_a_store_error(tmp_path):
    import shapedb

    models = write_models(tmp_path / "models")
    db = shapedb.connect(tmp_path / "store", **OPTIONS)
    db.ingest([models["box0"]], workers=1)
    segment = Path(db.store.files("balls")[0])
    segment.write_bytes(segment.read_bytes()[:100])  # no footer: DuckDB cannot read it
    api = client(create_app(db), raise_server_exceptions=False)
    r = api.post("/api/sql", json={"sql": "SELECT sum(r) FROM balls"})
    assert r.status_code == 500 and "segment" in r.json()["error"]
    assert segment.name in r.json()["error"]
