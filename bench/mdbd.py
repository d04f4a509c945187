"""Seconds per stage of the decomposition pipeline, against the naive reference loop.

For each model and grid resolution: the canonical frame's coarse passes ("frame"),
the SDF on the fine grid, the block-max decomposition loop without ("grid_loop") and
with ("refined_loop") off-grid refinement, the refinement's own share of the latter
("refine": precise queries + surrogate search) and its number of precise query
calls, the contact graph, the kernel features, and, as the baseline measured in the
same run, the naive loop (full-grid argmax and full-grid update per ball, plain numpy)
on the same field. "refine_x" is refined_loop / grid_loop. Peak memory is the
tracemalloc peak of one whole ``decompose`` call.

    python bench/mdbd.py            # 64, 96, 128, 192 cells; generated meshes + CAPOD
    python bench/mdbd.py --quick    # 64 and 128 cells, smaller models
    python bench/mdbd.py --profile 20   # CPU s per stage of the ingest job, 20 CAPOD models

``--profile N`` measures, at the default configuration, the CPU seconds
(``time.process_time``, robust to other load on the machine) of every stage of the
per-model ingest job on N CAPOD models spread over the classes: load, canonical
frame (cleaning, query structures and the two coarse passes), fine SDF, the grid
loop, refinement (refined loop minus grid loop), contact graph, features; medians
and means over the models. Its baseline is the previous run's JSON.

Writes ``bench/results/mdbd.json`` (``mdbd_profile.json`` with ``--profile``).
"""

from __future__ import annotations

import argparse
import json
import logging
import resource
import sys
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from shapedb import examples  # noqa: E402
from shapedb.config.core import MDBDConfig  # noqa: E402
from shapedb.geometry.base import Geometry  # noqa: E402
from shapedb.mdbd.decomposition import decompose, pack_balls, prepare_field  # noqa: E402
from shapedb.mdbd.graph import contact_edges  # noqa: E402
from shapedb.signature.kernel import features  # noqa: E402

logger = logging.getLogger("bench.mdbd")
CAPOD = Path("/work/shared/data/capod")
OUT = ROOT / "bench" / "results" / "mdbd.json"


def _mesh(vertices: np.ndarray, faces: np.ndarray, name: str) -> Geometry:
    from shapedb.geometry.mesh import TriangleMesh

    return TriangleMesh(vertices, faces, name=name)


def models(quick: bool) -> list[tuple[str, Geometry, int]]:
    """(name, geometry, face count) of the benchmark models."""
    import trimesh

    out: list[tuple[str, Geometry, int]] = []
    fig = examples.figure(0, 2)
    for res in (140,) if quick else (160, 310):  # ~50k and ~200k faces
        m = examples.to_mesh(fig, resolution=res)
        out.append((f"figure-mc{res}", _mesh(m.vertices, m.faces, f"figure-mc{res}"), len(m.faces)))
    out.append(("figure-implicit", fig, 0))
    for rel in ["class1/m1.obj"] if quick else ["class1/m1.obj", "class5/m3.obj", "class9/m7.obj"]:
        path = CAPOD / rel
        if path.exists():
            m = trimesh.load(path, force="mesh", process=False)
            out.append((f"capod/{rel}", _mesh(m.vertices, m.faces, rel), len(m.faces)))
    return out


def run_one(name: str, g: Geometry, res: int, n_balls: int, naive_limit: int) -> dict[str, Any]:
    cfg = MDBDConfig(resolution=res, n_balls=n_balls)
    prep = prepare_field(g, cfg)
    grid, F = prep.grid, prep.F
    row: dict[str, Any] = {"model": name, "resolution": res, "cells": grid.size}
    row["frame"] = prep.timings.get("frame", 0.0)
    row["sdf"] = prep.timings["sdf"]
    for label, refine in (("grid_loop", False), ("refined_loop", True)):
        stats: dict[str, float] = {}
        t0 = time.perf_counter()
        c, r = pack_balls(
            prep.local,
            grid,
            F.copy(),
            MDBDConfig(resolution=res, n_balls=n_balls, refine=refine),
            naive=False,
            stats=stats,
        )
        row[label] = time.perf_counter() - t0
    row["refine"] = stats["refine"]
    row["queries"] = int(stats["queries"])
    row["refine_x"] = row["refined_loop"] / max(row["grid_loop"], 1e-9)
    row["n_balls"] = len(r)
    order = np.argsort(-r, kind="stable")
    t0 = time.perf_counter()
    edges = contact_edges(c[order], r[order], cfg.contact_tol_cells * grid.spacing)
    row["graph"] = time.perf_counter() - t0
    from shapedb.mdbd.graph import ContactGraph

    graph = ContactGraph(c[order], r[order], edges)
    t0 = time.perf_counter()
    features(graph)
    row["features"] = time.perf_counter() - t0
    if res <= naive_limit:
        t0 = time.perf_counter()
        pack_balls(
            prep.local,
            grid,
            F.copy(),
            MDBDConfig(resolution=res, n_balls=n_balls, refine=False),
            naive=True,
        )
        row["naive_loop"] = time.perf_counter() - t0
    else:
        row["naive_loop"] = None
    tracemalloc.start()
    decompose(g, config=cfg)
    row["peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return row


STAGES = ["load", "frame", "sdf", "grid_loop", "refine", "graph", "features", "total"]


def profile_one(path: Path) -> dict[str, Any]:
    """CPU seconds per stage of the per-model ingest job on one file (default config)."""
    from ingest.loaders import load
    from shapedb.mdbd.frame import canonical_frame, frame_grid
    from shapedb.mdbd.graph import ContactGraph

    cfg = MDBDConfig()
    cpu = time.process_time
    row: dict[str, Any] = {"model": f"{path.parent.name}/{path.name}"}
    c0 = cpu()
    g = load(path)
    row["load"] = cpu() - c0
    row["faces"] = int(len(getattr(g, "faces", ())))
    c0 = cpu()
    V, c, lo, hi, hc = canonical_frame(g, cfg)  # type: ignore[misc]
    local = g.transformed(V.T, -V.T @ c)
    grid = frame_grid(lo, hi, 0.5 * hc, cfg)
    row["frame"] = cpu() - c0
    c0 = cpu()
    F = np.ascontiguousarray(local.grid_sdf(grid), dtype=np.float32)
    row["sdf"] = cpu() - c0
    c0 = cpu()
    pack_balls(local, grid, F.copy(), MDBDConfig(refine=False), naive=False)
    row["grid_loop"] = cpu() - c0
    c0 = cpu()
    centers, radii = pack_balls(local, grid, F, cfg, naive=False)
    row["refine"] = max(cpu() - c0 - row["grid_loop"], 0.0)
    order = np.argsort(-radii, kind="stable")
    centers, radii = centers[order], radii[order]
    c0 = cpu()
    edges = contact_edges(centers, radii, cfg.contact_tol_cells * grid.spacing)
    row["graph"] = cpu() - c0
    c0 = cpu()
    features(ContactGraph(centers, radii, edges))
    row["features"] = cpu() - c0
    row["total"] = sum(row[k] for k in STAGES[:-1])
    return row


def profile(n: int, out: Path) -> int:
    """Print and save the CPU-seconds-per-stage table over n CAPOD models."""
    files = sorted(CAPOD.rglob("*.obj"))
    files = files[:: max(len(files) // n, 1)][:n]
    if not files:
        print(f"no CAPOD models under {CAPOD}", file=sys.stderr)
        return 1
    previous = json.loads(out.read_text()) if out.exists() else None
    profile_one(files[0])  # warm-up: numba kernels, lazy imports
    rows = []
    for f in files:
        rows.append(profile_one(f))
        logger.info(
            "%s", {k: round(v, 3) if isinstance(v, float) else v for k, v in rows[-1].items()}
        )
    median = {k: float(np.median([r[k] for r in rows])) for k in STAGES}
    mean = {k: float(np.mean([r[k] for r in rows])) for k in STAGES}
    print(f"CPU seconds per stage over {len(rows)} CAPOD models (default config)")
    print(f"{'':8s}" + "".join(f"{k:>10s}" for k in STAGES))
    print(f"{'median':8s}" + "".join(f"{median[k]:10.3f}" for k in STAGES))
    print(f"{'mean':8s}" + "".join(f"{mean[k]:10.3f}" for k in STAGES))
    if previous and previous.get("models") == [r["model"] for r in rows]:
        base = previous["median"]
        print(f"{'prev med':8s}" + "".join(f"{base[k]:10.3f}" for k in STAGES))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        json.dumps(
            {"models": [r["model"] for r in rows], "median": median, "mean": mean, "rows": rows},
            indent=1,
        )
        + "\n"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer models and resolutions")
    ap.add_argument("--n-balls", type=int, default=512)
    ap.add_argument("--profile", type=int, default=0, metavar="N", help="CPU per stage, N models")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if args.profile:
        return profile(args.profile, args.out or OUT.with_name("mdbd_profile.json"))
    args.out = args.out or OUT
    resolutions = (64, 128) if args.quick else (64, 96, 128, 192)
    naive_limit = 128 if args.quick else 192
    # compile (or load) the numba kernels outside the timings
    decompose(examples.part("plate", 0), resolution=32, n_balls=8)
    rows = []
    for name, g, faces in models(args.quick):
        for res in resolutions:
            row = run_one(name, g, res, args.n_balls, naive_limit)
            row["faces"] = faces
            rows.append(row)
            logger.info(
                "%s @%d: %s",
                name,
                res,
                {
                    k: round(v, 3) if isinstance(v, float) else v
                    for k, v in row.items()
                    if k not in ("model",)
                },
            )
    cols = [
        "model",
        "faces",
        "resolution",
        "n_balls",
        "frame",
        "sdf",
        "grid_loop",
        "refined_loop",
        "refine",
        "queries",
        "refine_x",
        "graph",
        "features",
        "naive_loop",
        "peak_mb",
    ]
    width = {c: max(len(c), *(len(_fmt(r.get(c))) for r in rows)) for c in cols}
    print("seconds per stage (naive_loop: reference, full argmax + full update per ball)")
    print("  ".join(c.rjust(width[c]) for c in cols))
    for r in rows:
        print("  ".join(_fmt(r.get(c)).rjust(width[c]) for c in cols))
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"process peak RSS: {maxrss:.0f} MB")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        json.dumps({"n_balls": args.n_balls, "rows": rows, "peak_rss_mb": maxrss}, indent=1) + "\n"
    )
    return 0


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3f}"
    return str(v)


if __name__ == "__main__":
    raise SystemExit(main())
