"""Does visibility orient a point cloud's sheets the way its mesh's inside needs?

Usage (from the repository root)::

    nice -n 5 python -m bench.studies.cloud_orientation --per-class 3
    nice -n 5 python -m bench.studies.cloud_orientation --classes sink bookshelf --per-class 7

A point cloud's normals are oriented towards the nearest exterior cell of an adaptive
shell (:class:`shapedb.geometry.pointcloud.PointCloud`). On a single sheet that the exterior
reaches from both sides (a sink's basin, a house's walls of quads, a shelf) that vote is
a coin toss, and the cloud's winding number finds less inside than the mesh's, whose
sheets keep the orientation they were built with. This study re-orients the points
that are *two-sided* (the shell's exterior on both sides, at the wall's radius plus 1.5
cells along the normal) and *single-layer* (no neighbour with a parallel normal farther
than ``layer`` times the spacing off the tangent plane) towards the side from which
more rays escape through the shell's wall (``rays`` cosine-distributed rays per side;
a side must win by ``margin``), then compares each cloud's inside with its mesh's on a
64-cell grid (intersection over union), today's orientation and the re-oriented one.

Written to bench/results/studies/cloud_orientation_<split>.json.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import format_table, write_json
from bench.sets.datasets import generic, mesh_arrays, min_cloud_points, point_cloud, stable_seed
from shapedb.geometry.base import Grid
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
#: The kinds whose clouds find their meshes least often (docs/results.md, "Across
#: representations"), and three that lose nothing.
CLASSES = ("sink", "two_story_house", "bookshelf", "table", "desk", "wheel", "human", "car")


def hemisphere(k: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """(k, 3) cosine-distributed unit directions about +z."""
    u, v = rng.random(k), rng.random(k)
    r, theta = np.sqrt(u), 2 * np.pi * v
    return np.stack([r * np.cos(theta), r * np.sin(theta), np.sqrt(1 - u)], axis=1)


def tangents(n: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two unit tangents (m, 3) each, orthogonal to the unit normals n (m, 3)."""
    a = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t = np.cross(n, a)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(n, t)


def escaping(
    grid: Grid, wall: NDArray[np.bool_], starts: NDArray[np.float64], dirs: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Fraction (m,) of the rays dirs (m, k, 3) from starts (m, 3) that leave the grid
    without entering a wall cell (steps of 0.7 cells)."""
    shape = np.asarray(grid.shape)
    alive = np.ones(dirs.shape[:2], dtype=bool)
    out = np.zeros(dirs.shape[:2], dtype=bool)
    steps = int(np.ceil(np.linalg.norm(shape) / 0.7)) + 2
    for s in range(1, steps):
        p = starts[:, None, :] + dirs * (s * 0.7 * grid.spacing)
        ijk = np.rint((p - grid.origin) / grid.spacing).astype(np.int64)
        off = np.any((ijk < 0) | (ijk >= shape), axis=2)
        out |= alive & off
        alive &= ~off
        ijk = np.clip(ijk, 0, shape - 1)
        alive &= ~wall[ijk[..., 0], ijk[..., 1], ijk[..., 2]]
        if not alive.any():
            break
    return np.asarray(out.mean(axis=1), dtype=np.float64)


def visible_normals(
    cloud: PointCloud, *, rays: int = 32, margin: float = 0.15, layer: float = 0.15, seed: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
    """The cloud's normals (n, 3), its two-sided single-layer points turned to the side
    more rays escape from; and which points (n,) are two-sided and which were turned."""
    grid, wall, exterior = cloud._shell
    n = cloud._pca
    normals = np.array(cloud.normals)
    h = grid.spacing
    radius = np.maximum(
        cloud.shell * np.minimum(cloud.spacing, 4 * np.median(cloud.spacing)) / h, 1.5
    )
    reach = (radius + 1.5) * h
    p = np.asarray(cloud.points)

    def outside(q: NDArray[np.float64]) -> NDArray[np.bool_]:
        ijk = grid.to_index(q)
        return np.asarray(exterior[ijk[:, 0], ijk[:, 1], ijk[:, 2]])

    two = outside(p + reach[:, None] * n) & outside(p - reach[:, None] * n)
    nb = cloud._neighbours
    d = p[nb] - p[:, None, :]
    off_plane = np.abs(np.einsum("nkj,nj->nk", d, n))
    parallel = np.abs(np.einsum("nkj,nj->nk", n[nb], n)) > 0.9
    two &= ~np.any(parallel & (off_plane > layer * cloud.spacing[:, None]), axis=1)
    idx = np.flatnonzero(two)
    turned = np.zeros(len(p), dtype=bool)
    if len(idx) == 0:
        return normals, two, turned
    h_dirs = hemisphere(rays, np.random.default_rng(seed))
    t, b = tangents(n[idx])
    side = []
    for s in (1.0, -1.0):
        m = s * n[idx]
        dirs = (
            h_dirs[None, :, 0:1] * t[:, None, :]
            + h_dirs[None, :, 1:2] * (s * b)[:, None, :]
            + h_dirs[None, :, 2:3] * m[:, None, :]
        )
        side.append(escaping(grid, wall, p[idx] + reach[idx, None] * m, dirs))
    diff = side[0] - side[1]
    turn = np.where(diff > margin, 1.0, np.where(diff < -margin, -1.0, 0.0))
    chosen = turn != 0
    normals[idx[chosen]] = n[idx[chosen]] * turn[chosen, None]
    turned[idx[chosen]] = True
    return normals, two, turned


def iou(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> float:
    """Intersection over union of two masks; 1.0 when both are empty."""
    union = int((a | b).sum())
    return float((a & b).sum() / union) if union else 1.0


def measure(model: Any, resolution: int = 64) -> dict[str, Any]:
    """IoU of the model's cloud's inside with its mesh's, today's normals and visibility's."""
    v, f = mesh_arrays(model)
    mesh = TriangleMesh(v, f, name=model.name)
    points = point_cloud(
        v, f, seed=stable_seed(model.name, "pointcloud"), min_points=min_cloud_points(model)
    )
    cloud = PointCloud(points, name=model.name)
    normals, two, turned = visible_normals(cloud)
    turned_cloud = PointCloud(cloud.points, normals, name=model.name)
    grid = Grid.fit(mesh.bounds, resolution=resolution, padding=2)
    cells = grid.points()
    inside = mesh.contains(cells)
    return {
        "model": model.name,
        "label": model.label,
        "two_sided": float(two.mean()),
        "turned": float(turned.mean()),
        "iou_today": iou(inside, cloud.contains(cells)),
        "iou_visible": iou(inside, turned_cloud.contains(cells)),
    }


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.cloud_orientation", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--split", default="validation", choices=("validation", "test"))
    ap.add_argument("--classes", nargs="+", default=list(CLASSES))
    ap.add_argument("--per-class", type=int, default=3)
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    models = generic().split(args.split).models
    rows, per_model = [], []
    for label in args.classes:
        chosen = [m for m in models if m.label == label][: args.per_class]
        got = [measure(m) for m in chosen]
        per_model += got
        if got:
            rows.append([
                label, len(got),
                float(np.median([g["two_sided"] for g in got])),
                float(np.median([g["iou_today"] for g in got])),
                float(np.median([g["iou_visible"] for g in got])),
            ])  # fmt: skip
            print(f"  {label}: {rows[-1][3]:.3f} -> {rows[-1][4]:.3f}", flush=True)
    columns = ["kind", "models", "two-sided (median)", "IoU today", "IoU visibility"]
    title = "a cloud's inside against its mesh's (IoU, medians; generic " + args.split + ")"
    print(format_table(title, columns, rows))
    out = Path(args.out) if args.out else RESULTS / f"cloud_orientation_{args.split}.json"
    write_json(out, {"rows": rows, "models": per_model})
    print(f"written: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
