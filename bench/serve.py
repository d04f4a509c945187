"""``shapedb serve`` over loopback HTTP, with the CLI and the library as baselines in the same run.

On a store of ``--shapes`` synthetic shapes (default 10^4: feature vectors shaped like
real ones, one ball each, committed in one go as ``bench.query`` does) this starts the
server in a child process bound to 127.0.0.1 and measures:

* **stored-id search**: ``GET /api/search?id=ID&k=10`` one request at a time on a
  keep-alive connection, p50 / p99; baselines: ``db.search(id)`` in this process (the
  library's floor) and ``python -m query.cli search ID`` (a new process per query);
* **file query**: ``POST /api/search`` with a model file against ``db.search(file)`` in
  this process (load, decomposition, descriptor and search: the floor), the load and
  decomposition alone, and the CLI with the file; medians of ``--file-repeats`` runs;
* **concurrency**: ``--clients`` threads (default 16), each on its own connection,
  searching random stored ids for ``--seconds`` (default 60): requests/s, errors,
  p50 / p99 under load;
* **memory**: the server's resident set after a warm-up, and after
  ``--memory-requests`` more requests (default 10,000: 70 % searches, 20 % pages of
  shapes, 10 % records with their balls, the info every hundredth).

The server's own share of each stored-id search is read from its ``Server-Timing``
header: on a loaded machine most of a loopback request's time is waiting for a core.

Everything is bounded: each phase has a fixed count or duration, and the server is
stopped at the end (or on error). Prints a table and writes ``bench/results/serve.json``
(with the load average at the start and the end). ``--quick`` shrinks every phase for a
smoke run. Run with ``nice -n 5 python -m bench.serve``.
"""

from __future__ import annotations

import argparse
import http.client
import logging
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json

log = logging.getLogger("bench.serve")

RESULTS = Path(__file__).parent / "results" / "serve.json"
CAPOD = Path("/work/shared/data/capod")


# ------------------------------------------------------------------ the store
def synthetic_store(root: Path, n: int) -> Any:
    """A store of ``n`` synthetic shapes (one ball each, realistic feature vectors)."""
    from bench.query import synthetic_records
    from query.database import connect
    from query.search.index import open_index
    from shapedb.config.core import Config

    config = Config()
    db = connect(root, config=config)
    db.commit(synthetic_records(n, config))
    open_index(db)  # built once here, loaded by the server
    return db


def default_model(folder: Path) -> Path:
    """A real mesh when the CAPOD set is there, else a generated one written to ``folder``."""
    if CAPOD.is_dir():
        found = sorted(CAPOD.glob("*/*.obj"))
        if found:
            return found[0]
    from shapedb.examples import part, to_mesh

    path = folder / "flange.obj"
    to_mesh(part("flange", 0), resolution=64).export(path)
    return path


# ------------------------------------------------------------------ the server
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Server:
    """``query.serve.server.serve`` in a child process on a loopback port."""

    def __init__(self, store: Path) -> None:
        self.port = _free_port()
        code = (
            "import logging, shapedb; from query.serve.server import serve; "
            "logging.basicConfig(level=logging.WARNING); "
            f"serve(shapedb.connect({str(store)!r}, create=False), port={self.port})"
        )
        self.proc = subprocess.Popen([sys.executable, "-c", code])
        deadline = time.monotonic() + 120
        while True:
            try:
                status, _ = get(self.connection(), "/api/server")
                if status == 200:
                    break
            except OSError:
                pass
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError("the server did not start")
            time.sleep(0.2)

    def connection(self) -> http.client.HTTPConnection:
        return http.client.HTTPConnection("127.0.0.1", self.port, timeout=120)

    def rss_mb(self) -> float:
        with open(f"/proc/{self.proc.pid}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
        return float("nan")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def get(conn: http.client.HTTPConnection, path: str) -> tuple[int, bytes]:
    return get_timed(conn, path)[:2]  # type: ignore[return-value]


def get_timed(conn: http.client.HTTPConnection, path: str) -> tuple[int, bytes, float]:
    """Status, body and the server's own milliseconds (its ``Server-Timing`` header)."""
    conn.request("GET", path)
    r = conn.getresponse()
    body = r.read()
    timing = r.getheader("server-timing", "app;dur=nan")
    return r.status, body, float(timing.split("dur=", 1)[1])


def post_file(conn: http.client.HTTPConnection, path: str, model: Path) -> tuple[int, bytes]:
    boundary = uuid.uuid4().hex
    body = (
        (
            f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="{model.name}"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n"
        ).encode()
        + model.read_bytes()
        + f"\r\n--{boundary}--\r\n".encode()
    )
    conn.request(
        "POST",
        path,
        body=body,
        headers={"Content-Type": f"multipart/form-data; boundary={boundary}"},
    )
    r = conn.getresponse()
    return r.status, r.read()


def _ms(seconds: list[float]) -> tuple[float, float]:
    a = np.asarray(seconds) * 1e3
    return float(np.percentile(a, 50)), float(np.percentile(a, 99))


def _cli(*argv: str) -> float:
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "query.cli", *argv], check=True, capture_output=True, text=True
    )
    return time.perf_counter() - t0


# ------------------------------------------------------------------ phases
def stored_search(server: Server, db: Any, n: int, requests: int, cli_runs: int) -> dict[str, Any]:
    rng = np.random.default_rng(0)
    ids = rng.integers(1, n + 1, requests).tolist()
    conn = server.connection()
    for sid in ids[:50]:  # warm-up
        get(conn, f"/api/search?id={sid}&k=10")
    http_s, app_s = [], []
    for sid in ids:
        t0 = time.perf_counter()
        status, _, app_ms = get_timed(conn, f"/api/search?id={sid}&k=10")
        http_s.append(time.perf_counter() - t0)
        app_s.append(app_ms / 1e3)
        assert status == 200, status
    lib_s = []
    for sid in ids[: min(requests, 500)]:
        t0 = time.perf_counter()
        db.search(int(sid), k=10)
        lib_s.append(time.perf_counter() - t0)
    cli_s = [_cli("search", str(sid), "--db", str(db.path), "-k", "10") for sid in ids[:cli_runs]]
    h50, h99 = _ms(http_s)
    a50, a99 = _ms(app_s)
    l50, l99 = _ms(lib_s)
    return {
        "requests": requests,
        "http_p50_ms": h50,
        "http_p99_ms": h99,
        "server_p50_ms": a50,
        "server_p99_ms": a99,
        "library_p50_ms": l50,
        "library_p99_ms": l99,
        "cli_median_ms": statistics.median(cli_s) * 1e3,
        "cli_runs": len(cli_s),
    }


def file_query(server: Server, db: Any, model: Path, repeats: int) -> dict[str, Any]:
    from shapedb.mdbd.decomposition import decompose

    dec_s, lib_s, http_s, cli_s = [], [], [], []
    db.search(model, k=10)  # warm-up of both processes (JIT, caches)
    post_file(server.connection(), "/api/search?k=10", model)
    for _ in range(repeats):
        t0 = time.perf_counter()
        decompose(db.load(model), config=db.config.mdbd)
        dec_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        db.search(model, k=10)  # load, decompose, describe, search: in this process
        lib_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        status, body = post_file(server.connection(), "/api/search?k=10", model)
        http_s.append(time.perf_counter() - t0)
        assert status == 200, body[:200]
        cli_s.append(_cli("search", str(model), "--db", str(db.path), "-k", "10"))
    dec, lib, web, cli = (statistics.median(x) * 1e3 for x in (dec_s, lib_s, http_s, cli_s))
    return {
        "model": str(model),
        "bytes": model.stat().st_size,
        "repeats": repeats,
        "decompose_ms": dec,
        "library_ms": lib,
        "http_ms": web,
        "http_over_library_ms": web - lib,
        "http_over_decomposition_ms": web - dec,
        "cli_ms": cli,
    }


def concurrent(server: Server, n: int, clients: int, seconds: float) -> dict[str, Any]:
    stop = time.monotonic() + seconds
    lat: list[list[float]] = [[] for _ in range(clients)]
    errors = [0] * clients

    def client(k: int) -> None:
        rng = np.random.default_rng(100 + k)
        conn = server.connection()
        while time.monotonic() < stop:
            t0 = time.perf_counter()
            try:
                status, _ = get(conn, f"/api/search?id={int(rng.integers(1, n + 1))}&k=10")
            except (OSError, http.client.HTTPException):
                errors[k] += 1
                conn = server.connection()
                continue
            lat[k].append(time.perf_counter() - t0)
            if status != 200:
                errors[k] += 1

    threads = [threading.Thread(target=client, args=(k,)) for k in range(clients)]
    t0 = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - t0
    flat = [x for per in lat for x in per]
    p50, p99 = _ms(flat)
    return {
        "clients": clients,
        "seconds": wall,
        "requests": len(flat),
        "errors": sum(errors),
        "requests_per_s": len(flat) / wall,
        "p50_ms": p50,
        "p99_ms": p99,
    }


def memory(server: Server, n: int, requests: int) -> dict[str, Any]:
    rng = np.random.default_rng(1)
    conn = server.connection()
    # mostly searches; a page of shapes, a record (with its balls) and the info now and then
    paths = ["/api/search?id={}&k=10"] * 7 + ["/api/shapes?offset={}&limit=20"] * 2
    paths += ["/api/shapes/{}"]
    for i in range(300):  # warm-up: every route's caches filled once
        get(conn, paths[i % 10].format(int(rng.integers(1, n + 1))))
    get(conn, "/api/info")
    start = server.rss_mb()
    bad = 0
    for i in range(requests):
        route = "/api/info" if i % 100 == 99 else paths[i % 10]
        status, _ = get(conn, route.format(int(rng.integers(1, n + 1))))
        bad += status != 200
    end = server.rss_mb()
    return {
        "requests": requests,
        "errors": bad,
        "rss_start_mb": start,
        "rss_end_mb": end,
        "growth": end / start - 1.0,
    }


# ------------------------------------------------------------------ main
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--shapes", type=int, default=10_000)
    parser.add_argument("--requests", type=int, default=2000, help="sequential stored searches")
    parser.add_argument("--cli-runs", type=int, default=5)
    parser.add_argument("--model", type=Path, help="model file of the file query")
    parser.add_argument("--file-repeats", type=int, default=3)
    parser.add_argument("--clients", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--memory-requests", type=int, default=10_000)
    parser.add_argument("--quick", action="store_true", help="a smoke run: every phase tiny")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    if args.quick:
        args.shapes, args.requests, args.cli_runs = min(args.shapes, 300), 100, 1
        args.file_repeats, args.seconds, args.memory_requests = 1, 2.0, 300
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    logging.getLogger("faiss.loader").setLevel(logging.WARNING)
    load_start = os.getloadavg()
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="shapedb-bench-serve-") as tmp:
        t0 = time.perf_counter()
        db = synthetic_store(Path(tmp) / "store", args.shapes)
        build_s = time.perf_counter() - t0
        model = args.model or default_model(Path(tmp))
        log.info("store of %d shapes in %.1f s; starting the server", args.shapes, build_s)
        server = Server(db.path)
        try:
            log.info("stored-id search")
            stored = stored_search(server, db, args.shapes, args.requests, args.cli_runs)
            log.info("file query: %s", model)
            files = file_query(server, db, model, args.file_repeats)
            log.info("%d clients for %.0f s", args.clients, args.seconds)
            load = concurrent(server, args.shapes, args.clients, args.seconds)
            log.info("memory over %d requests", args.memory_requests)
            mem = memory(server, args.shapes, args.memory_requests)
        finally:
            server.stop()
    result = {
        "machine": {
            "cpus": os.cpu_count(),
            "load_average_start": load_start,
            "load_average_end": os.getloadavg(),
        },
        "shapes": args.shapes,
        "store_build_s": build_s,
        "stored_search": stored,
        "file_query": files,
        "concurrency": load,
        "memory": mem,
        "total_seconds": time.perf_counter() - started,
    }
    write_json(args.out, result)
    print(_report(result))
    return 0


def _report(r: dict[str, Any]) -> str:
    s, f, c, m = r["stored_search"], r["file_query"], r["concurrency"], r["memory"]
    rows = [
        ["stored-id search p50 (ms)", s["http_p50_ms"], s["library_p50_ms"], s["cli_median_ms"]],
        ["stored-id search p99 (ms)", s["http_p99_ms"], s["library_p99_ms"], ""],
        ["  of which in the server p50 / p99 (ms)", s["server_p50_ms"], s["server_p99_ms"], ""],
        ["file query (ms)", f["http_ms"], f["library_ms"], f["cli_ms"]],
        ["  its load + decomposition alone (ms)", f["decompose_ms"], "", ""],
        ["  HTTP over the library's file search (ms)", f["http_over_library_ms"], "", ""],
        [f"{c['clients']} clients: requests/s", c["requests_per_s"], "", ""],
        [f"{c['clients']} clients: errors / p50 / p99 (ms)", c["errors"], c["p50_ms"], c["p99_ms"]],
        [f"RSS after {m['requests']} requests (MB)", m["rss_end_mb"], m["rss_start_mb"], ""],
        ["RSS growth", f"{100 * m['growth']:+.1f} %", "", ""],
    ]
    title = (
        f"shapedb serve on loopback, {r['shapes']:,} shapes (load {r['machine']['load_average_start'][0]:.1f})"
        " -- columns: HTTP, baseline (library in this process / start of the phase), CLI"
    )
    return format_table(title, ["measure", "http", "baseline", "cli"], rows)


if __name__ == "__main__":
    sys.exit(main())
