"""Ingest throughput: models per minute on CAPOD, serial vs. processes vs. Dask.

Ingests the CAPOD models (real, non-watertight OBJ meshes) into a fresh store at
the default configuration, once per executor setting, and reports models per
minute. The baseline is one worker in this process, measured in the same run.

    python -m bench.ingest [--data ../shared/data/capod] [--limit N] [--workers 1 2]
                           [--no-dask] [--resolution N] [--balls N] [--views CELLS]

Prints a table and writes bench/results/ingest.json. ``--views CELLS`` adds a run
into a store that keeps sparse views (``CloudConfig.view_cells``): its CPU seconds per
model against the runs without are the views' cost.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
if not __package__:  # run as a file: bench/ingest.py would shadow the ingest package
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]
    sys.path.insert(0, str(HERE.parent))
DEFAULT_DATA = HERE.parent.parent / "shared" / "data" / "capod"


def _files(data: Path, limit: int | None) -> list[Path]:
    files = sorted(data.rglob("*.obj"))
    if limit:
        # spread the subset over the classes rather than taking the first folders
        step = max(len(files) // limit, 1)
        files = files[::step][:limit]
    return files


def _run(
    files: list[Path], options: dict[str, Any], *, workers: int | None = None, scheduler: Any = None
) -> dict[str, Any]:
    import query.database as database

    root = Path(tempfile.mkdtemp(prefix="shapedb-bench-"))
    try:
        db = database.connect(root / "db", **options)
        t0 = time.perf_counter()
        report = db.ingest(files, workers=workers, scheduler=scheduler, batch_size=32)
        seconds = time.perf_counter() - t0
        t = db.shapes(["build_seconds", "timings"])
        builds = t.column("build_seconds").to_pylist()
        cpu = [dict(x).get("cpu", float("nan")) for x in t.column("timings").to_pylist()]
        load = os.getloadavg()[0]
        return {
            "models": len(files),
            "ingested": len(report.ingested),
            "failed": len(report.failed),
            "failures": [{"path": p, "error": e} for p, e in report.failed],
            "seconds": seconds,
            "models_per_minute": 60.0 * len(files) / seconds,
            "mean_build_seconds": sum(builds) / max(len(builds), 1),
            # CPU seconds per model in its worker: robust to other load on the machine
            "mean_cpu_seconds": sum(cpu) / max(len(cpu), 1),
            "load_average_1min": load,
        }
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DEFAULT_DATA)
    p.add_argument("--limit", type=int, default=None, help="use a subset of N models")
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--no-dask", action="store_true")
    p.add_argument("--resolution", type=int, default=None, help="default: the Config default")
    p.add_argument("--balls", type=int, default=None)
    p.add_argument(
        "--views",
        type=float,
        default=0.0,
        help="also ingest into a store with sparse views every VIEWS grid cells (view_cells)",
    )
    p.add_argument("--out", type=Path, default=HERE / "results" / "ingest.json")
    return p


def _dask_row(files: list[Path], options: dict[str, Any], n: int) -> dict[str, Any]:
    """The ingest of ``files`` on a Dask LocalCluster of ``n`` single-threaded processes."""
    from shapedb.errors import require

    distributed = require(
        "distributed", extra="distributed", feature="the Dask rows (--no-dask to skip them)"
    )
    Client, LocalCluster = distributed.Client, distributed.LocalCluster
    print(
        f"ingesting {len(files)} models on a Dask LocalCluster ({n} processes)...",
        file=sys.stderr,
    )
    with (
        LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        Client(cluster) as client,
    ):
        return {
            "setting": f"dask LocalCluster {n}x1",
            "workers": n,
            **_run(files, options, scheduler=client),
        }


def _print_table(rows: list[dict[str, Any]]) -> None:
    """The rows, with speed-ups against the first, and the CPU-bound ceiling of 2 cores."""
    base = rows[0]["models_per_minute"]
    cpu = rows[0]["mean_cpu_seconds"]
    print()
    print(
        f"{'setting':28s} {'models':>6s} {'failed':>6s} {'seconds':>8s} {'models/min':>10s} "
        f"{'speed-up':>8s} {'build s':>8s} {'cpu s':>6s} {'load':>5s}"
    )
    for r in rows:
        print(
            f"{r['setting']:28s} {r['models']:6d} {r['failed']:6d} {r['seconds']:8.1f} "
            f"{r['models_per_minute']:10.1f} {r['models_per_minute'] / base:8.2f} "
            f"{r['mean_build_seconds']:8.2f} {r['mean_cpu_seconds']:6.2f} "
            f"{r['load_average_1min']:5.1f}"
        )
    ceiling = 2 * 60.0 / cpu if cpu > 0 else float("nan")
    print(
        f"CPU-bound ceiling on 2 idle cores: {ceiling:.1f} models/min "
        f"({cpu:.2f} CPU s per model; target 120)"
    )


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)

    from shapedb.config.core import Config

    options: dict[str, Any] = {}
    if args.resolution:
        options["resolution"] = args.resolution
    if args.balls:
        options["n_balls"] = args.balls
    config = Config().with_options(**options)
    files = _files(args.data, args.limit)
    if not files:
        print(f"no OBJ files under {args.data}", file=sys.stderr)
        return 1

    rows: list[dict[str, Any]] = []
    for w in args.workers:
        print(f"ingesting {len(files)} models with {w} worker(s)...", file=sys.stderr)
        rows.append(
            {
                "setting": f"{w} worker" + ("s" if w > 1 else ""),
                "workers": w,
                **_run(files, options, workers=w),
            }
        )
    if args.views:
        w = max(args.workers)
        print(f"ingesting {len(files)} models with views, {w} worker(s)...", file=sys.stderr)
        rows.append(
            {
                "setting": f"{w} workers, views {args.views:g}",
                "workers": w,
                **_run(files, {**options, "view_cells": args.views}, workers=w),
            }
        )
    if not args.no_dask:
        rows.append(_dask_row(files, options, max(args.workers)))

    _print_table(rows)
    cpu = rows[0]["mean_cpu_seconds"]
    out = {
        "benchmark": "ingest",
        "data": str(args.data),
        "config": config.to_dict(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "baseline": rows[0]["setting"],
        "target_models_per_minute_2_cores": 120,
        "cpu_bound_models_per_minute_2_cores": 2 * 60.0 / cpu if cpu > 0 else None,
        "results": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=2))
    print(f"\nwrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
