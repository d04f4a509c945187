"""One-sided scans completed by the balls they allow, searched as whole solids.

A depth camera proves two things about the space around its model: in front of the seen
surface nothing lies, and nothing lies along the rays that miss the model (outside its
silhouette). :func:`completed_scan` keeps, behind the seen surface, every ball that touches
that surface and is as large as that proven-empty space lets it be (seen orthographically
along the viewing direction); their union is the solid the search decomposes. A tube seen
side-on gets back its own radius; a plate seen face-on swells to a ball of half its width.

``python -m bench.studies.scan_completion --sets parts capod`` searches every validation
model's one-sided scan (:func:`bench.sets.scans.one_sided_scan`) against the store of the
split's meshes three ways, through ``db.search``: the scan itself (the product's view path),
its completion along the camera's true axis, and along the axis the product estimates
(:func:`shapedb.geometry.view.viewing_direction`, its side from the scan's rims). Not kept
(docs/studies.md): only solid machined parts gain, and only along the true axis.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import cKDTree

__all__ = ["completed_scan", "facing", "main"]

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "scan_completion.json"
#: Cells across the scan's wider side.
CELLS = 64
#: A ball touches the seen surface when its gap to it is at most this, in cells.
TOUCH_CELLS = 0.5


def facing(points: NDArray[np.float64], direction: NDArray[np.float64]) -> NDArray[np.float64]:
    """``direction`` (3,) or its opposite: the one along which the scan's rims lie farther
    than its middle (a camera looks at the near side of a solid)."""
    from shapedb.signature.lightfield_descriptor import image_axes

    u, w = image_axes(direction[None])
    xy = np.stack([points @ u[0].astype(float), points @ w[0].astype(float)], axis=1)
    r = np.linalg.norm(xy - xy.mean(axis=0), axis=1)
    z = points @ direction
    rim, middle = r > np.quantile(r, 0.8), r < np.quantile(r, 0.3)
    return direction if z[rim].mean() >= z[middle].mean() else -direction


def completed_scan(
    points: NDArray[np.float64], direction: NDArray[np.float64], *, cells: int = CELLS,
    name: str | None = None,
) -> object:  # fmt: skip
    """The union of the balls a one-sided scan allows, as a voxel solid in the view's frame.

    Parameters
    ----------
    points : (n, 3) float
        The scan, model units.
    direction : (3,) float
        The camera's viewing direction (from the camera into the scene).
    cells : int
        Cells across the scan's wider side in the image plane.

    Returns
    -------
    shapedb.VoxelGrid
        In the frame (image x, image y, depth): the search does not depend on the turn.
    """
    from shapedb.geometry.voxels import VoxelGrid
    from shapedb.signature.lightfield_descriptor import image_axes

    d = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    u, w = image_axes(d[None])
    q = np.asarray(points, np.float64) @ np.stack([u[0].astype(float), w[0].astype(float), d]).T
    lo, hi = q.min(axis=0), q.max(axis=0)
    h = float((hi[:2] - lo[:2]).max()) / cells
    pad = 3
    nx, ny = (np.ceil((hi[:2] - lo[:2]) / h).astype(int) + 2 * pad).tolist()
    nz = int(np.ceil((hi[2] - lo[2]) / h)) + cells // 2 + 2 * pad
    origin = lo - pad * h
    ij = np.floor((q[:, :2] - origin[:2]) / h).astype(int)
    # the front depth of every pixel, each sample splatted over the sample spacing
    spacing = float(np.median(cKDTree(q[:, :2]).query(q[:, :2], k=2)[0][:, 1]))
    rad = int(round(0.5 * spacing / h))
    front = np.full((nx, ny), np.inf)
    for dx in range(-rad, rad + 1):
        for dy in range(-rad, rad + 1):
            if dx * dx + dy * dy <= rad * rad + 0.5:
                a = np.clip(ij[:, 0] + dx, 0, nx - 1)
                b = np.clip(ij[:, 1] + dy, 0, ny - 1)
                np.minimum.at(front, (a, b), q[:, 2])
    seen = np.isfinite(front)
    silhouette = ndimage.binary_fill_holes(
        ndimage.binary_closing(np.pad(seen, 2), iterations=2)[2:-2, 2:-2]
    )
    nearest = ndimage.distance_transform_edt(~seen, return_distances=False, return_indices=True)
    depth = (front[nearest[0], nearest[1]] - origin[2]) / h
    z = np.arange(nz) + 0.5
    unknown = silhouette[:, :, None] & (z[None, None, :] >= depth[:, :, None])
    # distances between cell centres: the empty space begins half a cell before the
    # nearest empty cell's centre, the seen surface half a cell before the first unknown's
    radius = ndimage.distance_transform_edt(unknown) - 0.5
    surface = unknown & (z[None, None, :] - 1.0 < depth[:, :, None])
    gap = ndimage.distance_transform_edt(~surface) + 0.5 - radius
    touching = unknown & (gap <= TOUCH_CELLS)
    centres = np.argwhere(touching)
    size = np.floor(radius[touching]).astype(int)
    solid = np.zeros_like(unknown)
    for r in np.unique(size):
        mask = np.zeros_like(unknown)
        mask[tuple(centres[size == r].T)] = True
        solid |= mask if r <= 0 else ndimage.distance_transform_edt(~mask) <= r
    return VoxelGrid(solid, origin + 0.5 * h, h, surface="smooth", name=name)


def _family(name: str) -> dict[str, float]:
    """Class NN / 1-T / DCG of the family's validation scans, three ways."""
    from bench.common import retrieval_scores
    from bench.quality import family_split
    from bench.sets import scans
    from bench.sets.datasets import mesh_arrays, stable_seed
    from bench.support.product_stores import split_store
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.geometry.view import viewing_direction

    ds = family_split(name, "validation")
    db = split_store(ds, {})
    names = [m.name for m in ds.models]
    column = {n: j for j, n in enumerate(names)}
    ways = ("scan", "completed, true axis", "completed, estimated axis")
    sims = {way: np.full((len(names), len(names)), np.nan) for way in ways}
    for i, model in enumerate(ds.models):
        v, f = mesh_arrays(model)
        seed = stable_seed(model.name, "one-sided")
        points = scans.one_sided_scan(v, f, seed=seed)
        cloud = PointCloud(points, name=f"{model.name}~one-sided")
        centre, _ = scans.bounding_sphere(v)
        axis = centre - scans.viewpoint(v, seed=seed)
        estimated = viewing_direction(cloud)
        queries = {
            "scan": cloud,
            "completed, true axis": completed_scan(points, axis),
            "completed, estimated axis": cloud if estimated is None
            else completed_scan(points, facing(points, estimated)),
        }  # fmt: skip
        for way, query in queries.items():
            rank = 0
            for hit in db.search(query, k=len(names)):
                if hit.name != model.name and hit.name in column:
                    sims[way][i, column[hit.name]] = -float(rank)
                    rank += 1
    out = {}
    for way in ways:
        s = retrieval_scores(sims[way], np.asarray(ds.labels))
        out[way] = {k: round(float(s[k]), 4) for k in ("nn", "first_tier", "dcg")}
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench.studies.scan_completion",
        description="One-sided scans completed by the balls they allow, against the view path.",
    )
    parser.add_argument("--sets", nargs="+", default=["parts", "capod", "enclosures", "figures"])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    rows = {}
    for name in args.sets:
        rows[name] = _family(name)
        for way, s in rows[name].items():
            print(f"{name:12s} {way:28s} NN {s['nn']:.3f}  1-T {s['first_tier']:.3f}  "
                  f"DCG {s['dcg']:.3f}", flush=True)  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"split": "validation", "sets": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
