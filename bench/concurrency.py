"""Readers during writes: 8 readers search and run SQL while one writer ingests and a second waits.

A store of ``--base`` generated models (boxes, cylinders, spheres and tori of varied
proportions, written as OBJ files) is built first. Then, in separate processes:

``readers`` (``--readers``, default 8)
    loop over ``search(random stored shape, k=5)`` and ``SELECT count(*) FROM shapes``
    (alternately), timing each call, counting errors, and checking that the shape count
    a reader sees never decreases (a decrease would be rows lost to a reader);
``writer 1``
    ingests ``--files`` new models in commits of ``--batch`` (one worker);
``writer 2``
    starts while writer 1 holds the lock, waits for it (``lock_timeout``), then ingests
    its own ``--files`` models.

The same readers first run alone for ``--seconds`` (the baseline of the same run).
Reported: reader calls, errors, p50 / p99 latency alone and during the writes, the
second writer's wait, rows expected vs found at the end, and ``shapedb check``. The run
is bounded: readers stop when the writers finish or after ``--limit`` seconds.

Usage: ``python -m bench.concurrency [--readers 8] [--base 12] [--files 12] [--batch 2]
[--seconds 10] [--limit 300] [--out PATH]``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json

OUT = Path(__file__).resolve().parent / "results" / "concurrency.json"
OPTIONS: dict[str, Any] = {"resolution": 24, "n_balls": 32}


def _models(folder: Path, n: int, seed: int) -> list[Path]:
    """``n`` OBJ files of simple solids with random proportions."""
    import trimesh

    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k in range(n):
        kind = k % 4
        a, b, c = rng.uniform(0.3, 1.5, 3)
        if kind == 0:
            mesh = trimesh.creation.box(extents=(a, b, c))
        elif kind == 1:
            mesh = trimesh.creation.cylinder(radius=a / 2, height=b * 2)
        elif kind == 2:
            mesh = trimesh.creation.icosphere(subdivisions=2, radius=a)
            mesh.apply_scale((1.0, b / a, c / a))
        else:
            mesh = trimesh.creation.torus(major_radius=a, minor_radius=min(a, b) / 3)
        path = folder / f"m{seed}_{k:03d}.obj"
        path.write_text(mesh.export(file_type="obj"))
        out.append(path)
    return out


def _reader(path: str, stop: Any, start: Any, out: Any, seed: int) -> None:
    import query.database as database
    from query.search.engine import search
    from query.sql import sql

    rng = np.random.default_rng(seed)
    db = database.connect(path, create=False)
    samples: list[tuple[float, float, str]] = []  # (time, seconds, kind)
    errors: list[str] = []
    lost = 0
    seen = 0
    search(db, int(db.store.ids()[0]), k=5)  # warm up (imports, index) before timing
    sql(db, "SELECT 1")
    start.wait()
    k = 0
    while not stop.is_set():
        t0 = time.perf_counter()
        try:
            if k % 2 == 0:
                ids = db.store.ids()
                search(db, int(rng.choice(ids)), k=5)
                kind = "search"
            else:
                n = sql(db, "SELECT count(*) AS n FROM shapes").column("n")[0].as_py()
                lost += int(n < seen)
                seen = max(seen, n)
                kind = "sql"
            samples.append((time.time(), time.perf_counter() - t0, kind))
        except Exception as exc:  # counted and reported: the bench measures errors
            errors.append(f"{type(exc).__name__}: {exc}"[:200])
        k += 1
    out.put({"samples": samples, "errors": errors, "lost": lost})


def _writer(
    path: str, files: list[str], batch: int, timeout: float, out: Any, name: str, holding: Any
) -> None:
    import query.database as database

    db = database.connect(path, create=False, lock_timeout=timeout)
    t0 = time.time()

    locked: list[float] = []

    def progress(done: int, total: int) -> None:
        if not locked:  # called first with the lock held, before any work
            locked.append(time.time())
            holding.set()

    try:
        report = db.ingest(files, workers=1, batch_size=batch, progress=progress)
        out.put(
            {
                "name": name,
                "start": t0,
                "locked": locked[0] if locked else None,
                "end": time.time(),
                "ingested": len(report.ingested),
                "failed": len(report.failed),
                "error": None,
            }
        )
    except Exception as exc:  # reported, not raised: the bench counts it
        out.put({"name": name, "start": t0, "end": time.time(), "error": repr(exc)[:200]})


def _readers(path: str, n: int, stop: Any, seed: int) -> tuple[list[Any], Any, Any]:
    ctx = mp.get_context("spawn")
    start = ctx.Barrier(n + 1)
    out = ctx.Queue()
    procs = [ctx.Process(target=_reader, args=(path, stop, start, out, seed + i)) for i in range(n)]
    for p in procs:
        p.start()
    return procs, start, out


def _collect(procs: list[Any], out: Any) -> list[dict[str, Any]]:
    results = [out.get(timeout=120) for _ in procs]
    for p in procs:
        p.join(timeout=30)
    return results


def _stats(results: list[dict[str, Any]], t_from: float, t_to: float) -> dict[str, Any]:
    lat = [s for r in results for (t, s, _) in r["samples"] if t_from <= t <= t_to]
    ms = np.array(lat) * 1000.0 if lat else np.zeros(0)
    return {
        "calls": len(lat),
        "errors": sum(len(r["errors"]) for r in results),
        "rows_lost_to_readers": sum(r["lost"] for r in results),
        "p50_ms": float(np.percentile(ms, 50)) if len(ms) else None,
        "p99_ms": float(np.percentile(ms, 99)) if len(ms) else None,
        "first_errors": [e for r in results for e in r["errors"]][:3],
    }


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Build the store, run the baseline and the concurrent phase; return the figures."""
    import query.database as database
    from shapedb.store.integrity import check

    root = Path(tempfile.mkdtemp(prefix="shapedb-concurrency-"))
    path = str(root / "db")
    db = database.connect(path, **OPTIONS)
    base = db.ingest(_models(root / "base", args.base, 0), workers=1)
    first = [str(p) for p in _models(root / "w1", args.files, 1)]
    second = [str(p) for p in _models(root / "w2", args.files, 2)]
    ctx = mp.get_context("spawn")

    # baseline: the readers alone
    stop = ctx.Event()
    procs, start, out = _readers(path, args.readers, stop, 100)
    start.wait()
    t0 = time.time()
    time.sleep(args.seconds)
    stop.set()
    alone = _stats(_collect(procs, out), t0, time.time())

    # readers during two writers
    stop = ctx.Event()
    procs, start, out = _readers(path, args.readers, stop, 200)
    start.wait()
    wout = ctx.Queue()
    holding1, holding2 = ctx.Event(), ctx.Event()
    t_start = time.time()
    w1 = ctx.Process(
        target=_writer, args=(path, first, args.batch, args.limit, wout, "writer 1", holding1)
    )
    w1.start()
    holding1.wait(args.limit)  # writer 2 starts once writer 1 holds the lock
    w2 = ctx.Process(
        target=_writer, args=(path, second, args.batch, args.limit, wout, "writer 2", holding2)
    )
    w2.start()
    writers: list[dict[str, Any]] = []
    while len(writers) < 2 and time.time() - t_start < args.limit:
        try:
            writers.append(wout.get(timeout=1.0))
        except Exception:  # queue.Empty: keep waiting, bounded by --limit
            continue
    t_end = time.time()
    stop.set()
    during = _stats(_collect(procs, out), t_start, t_end)
    for w in (w1, w2):
        w.join(timeout=60)
        if w.is_alive():
            w.terminate()
    by_name = {w["name"]: w for w in writers}
    expected = len(base.ingested) + 2 * args.files
    found = len(database.connect(path, create=False).store)
    report = check(path)
    w2r = by_name.get("writer 2", {})
    return {
        "readers": args.readers,
        "base": len(base.ingested),
        "files_per_writer": args.files,
        "batch": args.batch,
        "alone": alone,
        "during_writes": during,
        "writers": writers,
        "writer2_waited_s": (
            w2r["locked"] - w2r["start"] if w2r.get("locked") and w2r.get("start") else None
        ),
        "rows_expected": expected,
        "rows_found": found,
        "rows_lost": expected - found,
        "check_ok": report.ok,
        "store": path,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--readers", type=int, default=8)
    parser.add_argument("--base", type=int, default=12)
    parser.add_argument("--files", type=int, default=12)
    parser.add_argument("--batch", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--limit", type=float, default=300.0)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    r = run(args)
    rows = []
    for phase in ("alone", "during_writes"):
        s = r[phase]
        rows.append(
            [phase, s["calls"], s["errors"], s["rows_lost_to_readers"], s["p50_ms"], s["p99_ms"]]
        )
    print(
        format_table(
            f"{r['readers']} readers (search k=5 + SQL count), store of {r['base']} shapes; "
            f"2 writers x {r['files_per_writer']} files, commits of {r['batch']}",
            ["phase", "calls", "errors", "rows lost", "p50 ms", "p99 ms"],
            rows,
        )
    )
    for w in r["writers"]:
        print(
            f"{w['name']}: {w.get('ingested', 0)} ingested, {w.get('failed', 0)} failed, "
            f"{w['end'] - w['start']:.1f} s, error {w['error']}"
        )
    print(
        f"writer 2 waited {r['writer2_waited_s'] or 0:.1f} s for the lock; rows expected "
        f"{r['rows_expected']}, found {r['rows_found']} (lost {r['rows_lost']}); "
        f"shapedb check: {'ok' if r['check_ok'] else 'DAMAGED'}"
    )
    if r["during_writes"]["p50_ms"] and r["alone"]["p50_ms"]:
        ratio = r["during_writes"]["p50_ms"] / r["alone"]["p50_ms"]
        print(f"reader p50 during writes / alone: {ratio:.2f}")
    write_json(args.out, r)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
