"""Mesh vs point-cloud agreement of the solid: IoU of inside cells and volume ratio.

For each CAPOD model (``--per-class`` models of every class), the mesh
(:class:`shapedb.geometry.mesh.TriangleMesh`) and its point-cloud version
(:func:`bench.sets.datasets.point_cloud`: a random 20 % of the vertices, or 2,000
area-weighted surface samples for coarse meshes) are evaluated with ``grid_sdf`` on
the same grid (``Grid.fit(mesh.bounds, resolution)``). Reported per model and per
class, plus the median:

``iou``
    |inside_mesh & inside_cloud| / |inside_mesh | inside_cloud|.
``vol``
    inside volume of the cloud / inside volume of the mesh.
``depth``
    median, over cells inside both, of cloud SDF / mesh SDF (the distance bias of
    the cloud: ball radii scale with it, ball volumes with its cube).

Usage: ``python -m bench.studies.agreement [--per-class 2] [--resolution 64] [--out PATH]``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from bench.sets.datasets import capod, mesh_arrays, point_cloud, stable_seed

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "agreement.json"


def _watertight(vertices: np.ndarray, faces: np.ndarray) -> bool:
    from shapedb.geometry.mesh import TriangleMesh

    return TriangleMesh(vertices, faces).closed


def measure(model, resolution: int) -> dict:
    """Agreement of one model's mesh and point cloud on a shared grid."""
    from shapedb.geometry.base import Grid
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.geometry.pointcloud import PointCloud

    v, f = mesh_arrays(model)
    mesh = TriangleMesh(v, f, name=model.name)
    pts = point_cloud(v, f, seed=stable_seed(model.name))
    cloud = PointCloud(pts, name=model.name)
    grid = Grid.fit(mesh.bounds, resolution=resolution)
    t0 = time.perf_counter()
    sm = mesh.grid_sdf(grid)
    t1 = time.perf_counter()
    sc = cloud.grid_sdf(grid)
    t2 = time.perf_counter()
    a, b = sm > 0, sc > 0
    both = a & b
    union = int((a | b).sum())
    depth = float(np.median(sc[both] / sm[both])) if both.any() else float("nan")
    return {
        "name": model.name,
        "label": model.label,
        "watertight": mesh.closed,
        "points": len(pts),
        "iou": float(both.sum() / union) if union else 1.0,
        "vol": float(b.sum() / max(int(a.sum()), 1)),
        "mesh_fill": float(a.mean()),
        "depth": depth,
        "mesh_s": t1 - t0,
        "cloud_s": t2 - t1,
    }


def summarise(rows: list[dict]) -> dict:
    """Per-class and overall medians (volume ratios also as |log| spread)."""

    def stats(rs: list[dict]) -> dict:
        vol = np.array([r["vol"] for r in rs])
        return {
            "n": len(rs),
            "iou": float(np.median([r["iou"] for r in rs])),
            "vol": float(np.median(vol)),
            "vol_within_1.5x": float(np.mean(np.abs(np.log(np.maximum(vol, 1e-9))) <= np.log(1.5))),
            "depth": float(np.nanmedian([r["depth"] for r in rs])),
        }

    out = {"all": stats(rows)}
    for wt in (True, False):
        sel = [r for r in rows if r["watertight"] == wt]
        if sel:
            out["watertight" if wt else "open"] = stats(sel)
    for label in sorted({r["label"] for r in rows}):
        out[label] = stats([r for r in rows if r["label"] == label])
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.agreement", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--per-class", type=int, default=2)
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    models = capod().head(per_class=args.per_class).models
    rows = []
    for m in models:
        r = measure(m, args.resolution)
        rows.append(r)
        print(
            f"{r['name']:>14} {r['label']:>10} wt={int(r['watertight'])} iou={r['iou']:.3f} "
            f"vol={r['vol']:.2f} depth={r['depth']:.2f} "
            f"t={r['mesh_s']:.2f}/{r['cloud_s']:.2f}s",
            flush=True,
        )
    summary = summarise(rows)
    print(f"\n{'group':>12} {'n':>3} {'iou':>6} {'vol':>6} {'<=1.5x':>7} {'depth':>6}")
    for k, s in summary.items():
        print(
            f"{k:>12} {s['n']:>3} {s['iou']:6.3f} {s['vol']:6.2f} "
            f"{s['vol_within_1.5x']:7.2f} {s['depth']:6.2f}"
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        json.dumps({"resolution": args.resolution, "rows": rows, "summary": summary}, indent=1)
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
