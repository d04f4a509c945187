"""Like with like: a cloud query against "twins" of the stored meshes.

A mesh's *twin* is another random 20 % of its vertices (the ``pointcloud_b`` variant,
never the query's own draw), decomposed as a point cloud at ingest; a sparse cloud
query is then compared with the twins as well as (or instead of) the meshes. From
the cached decompositions (decomposes what is missing), per weighting (descriptor
version 4, and version 4 without the pose blocks ``d2c_mean`` and ``inertia``), each
rule's cloud -> mesh NN / 1-T / DCG (the query's own model left out), own-first and
log margin (:func:`bench.common.log_margin`), and the cost of a twin against a mesh
decomposition (median seconds of the cached decompositions' own stages).

Rules (a cloud row against a stored shape):

``default``   nearer of the cloud's own feature and its kept reconstruction's, vs the mesh;
``own``       the cloud's own feature vs the mesh;
``query mean``  the mean of the cloud's own and its kept reconstruction's features (its
              own alone where none is kept) vs the mesh: averaging two packings of the
              query, at no extra cost (the store computes the reconstruction anyway);
``twin``      the cloud's own feature vs the twin;
``twin+default``  nearest of the three comparisons;
``twin+own``  nearer of cloud vs mesh and cloud vs twin (no reconstruction);
``mean``      the cloud's own feature vs the mean of the mesh's and the twin's features;
``both means``  the query mean vs the mean of the mesh's and the twin's.

``--query pointcloud_sphere`` takes the queries with the sphere-fit distance
(:mod:`shapedb.geometry.surface_fit`); their reconstructions are the paper cloud's (the same
points and normals), kept by the store's volume check against the new packing.

Usage: ``python -m bench.studies.cloud_twins --sets people --split validation
[--query pointcloud_sphere]``. Results go to
``bench/results/studies/cloud_twins_<sets>_<split>[_<query>][_no_twins].json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import bench.common as common
import bench.representations as representations
from bench.common import (
    Balls,
    decompose_all,
    format_table,
    log_margin,
    mdbd_config,
    retrieval_scores,
    write_json,
)
from bench.representations import build, load_set
from bench.support.features import kernel_features, l1_matrix
from shapedb.config.core import Config, MDBDConfig
from shapedb.signature.descriptor import LAYOUTS

OUT = Path(__file__).resolve().parents[1] / "results" / "studies"
FloatArray = NDArray[np.float64]
#: Engines whose cached decompositions are read where today's key has none: main
#: before the sphere-fit distance (only point clouds with ``distance="sphere"``
#: changed since), and the last commit before the sheet rule (the people set's
#: decompositions; see :mod:`bench.studies.people_blocks`).
FALLBACK_COMMITS = ("45ea7bf", "b95b2be", "f031e22")


def cached_path(model: Any, variant: str, config: MDBDConfig) -> Path:
    """Today's cache path of ``model``, else its key by an engine of :data:`FALLBACK_COMMITS`."""
    return common.existing_cache_path(model, variant, config, FALLBACK_COMMITS)


def weightings() -> dict[str, NDArray[np.float64]]:
    """Column masks of version 4's feature: all blocks, and without the pose blocks."""
    cols: list[float] = []
    for name, size, _t, _w in LAYOUTS[4]:
        cols += [0.0 if name in ("d2c_mean", "inertia") else 1.0] * size
    return {"v4": np.ones(len(cols)), "v4-pose": np.asarray(cols)}


def twins(models: Any, config: MDBDConfig, workers: int) -> list[Balls | None]:
    """Each model's twin decomposition (cached, else decomposed now)."""
    found = [cached_path(m, "pointcloud_b", config) for m in models]
    if all(p.exists() for p in found):
        return [common.load_balls(p, config.contact_tol_cells) for p in found]
    return decompose_all(models, "pointcloud_b", config, workers=workers)


def seconds(balls: list[Balls]) -> float:
    """Median seconds of the decompositions' own stages."""
    return float(np.median([representations.cost(b) for b in balls]))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m bench.studies.cloud_twins")
    ap.add_argument("--sets", nargs="+", default=["people"])
    ap.add_argument("--split", default="validation")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--query",
        default="pointcloud",
        choices=("pointcloud", "pointcloud_sphere"),
        help="the queries' cloud variant (their reconstructions are the paper cloud's)",
    )
    ap.add_argument(
        "--no-twins", action="store_true", help="rules without twins only (decomposes none)"
    )
    args = ap.parse_args(argv)
    representations.KINDS["cloud"] = (args.query, "pointcloud_recon")
    representations.ENGINE_COMMITS[:] = FALLBACK_COMMITS
    cfg = mdbd_config()
    out: dict[str, Any] = {}
    for ds in build(args.sets, args.split):
        data = load_set(ds, cfg, ["cloud"], workers=args.workers, cached=True)
        if args.no_twins:
            tw: list[Balls | None] = [None] * len(data.ds)
        else:
            tw = twins(data.ds.models, cfg, args.workers)
        keep = [i for i, t in enumerate(tw) if t is not None]
        if len(keep) < len(tw) and not args.no_twins:
            print(f"  {ds.name}: {len(tw) - len(keep)} twin(s) failed; kept as meshes only")
        labels = np.asarray(data.labels)
        n = len(labels)
        conf = Config()
        fm_all = kernel_features(data.mesh, conf)
        fc_all = kernel_features(data.clouds["cloud"], conf)
        ft_all = fm_all.copy()
        if keep:
            ft_all[keep] = kernel_features([tw[i] for i in keep], conf)  # type: ignore[misc]
        rec = data.recons["cloud"]
        ridx = [i for i, r in enumerate(rec) if r is not None]
        fr_all = kernel_features([rec[i] for i in ridx], conf) if ridx else None  # type: ignore[misc]
        rows: list[list[Any]] = []
        table: dict[str, Any] = {}
        for wname, mask in weightings().items():
            fm, fc, ft = fm_all * mask, fc_all * mask, ft_all * mask
            own = l1_matrix(fc, fm)
            default = own.copy()
            if fr_all is not None:
                default[ridx] = np.minimum(default[ridx], l1_matrix(fr_all * mask, fm))
            # the query's mean feature: of its own and its kept reconstruction's
            fq = fc.copy()
            if fr_all is not None:
                fq[ridx] = 0.5 * (fc[ridx] + fr_all * mask)
            rules = {
                "mesh->mesh": l1_matrix(fm, fm),
                "default": default,
                "own": own,
                "query mean": l1_matrix(fq, fm),
            }
            if keep:
                twin = l1_matrix(fc, ft)
                rules |= {
                    "twin": twin,
                    "twin+default": np.minimum(default, twin),
                    "twin+own": np.minimum(own, twin),
                    "mean": l1_matrix(fc, 0.5 * (fm + ft)),
                    "both means": l1_matrix(fq, 0.5 * (fm + ft)),
                }
            for rname, d in rules.items():
                s = retrieval_scores(-d, labels)
                first = float(np.mean(np.argmin(d, axis=1) == np.arange(n)))
                row = [
                    wname,
                    rname,
                    s["nn"],
                    s["first_tier"],
                    s["dcg"],
                    first,
                    log_margin(d, labels),
                ]
                rows.append(row)
                table[f"{wname} {rname}"] = row[2:]
        mesh_s = seconds(data.mesh)
        twin_s = seconds([tw[i] for i in keep]) if keep else float("nan")  # type: ignore[misc]
        cloud_s = seconds(data.clouds["cloud"])
        print(
            format_table(
                f"{ds.name} {args.split} ({n} models): {args.query} queries against meshes "
                "and twins",
                ("weights", "rule", "NN", "1-T", "DCG", "own-first", "margin"),
                rows,
            )
        )
        print(
            f"cost (median s, own stages): mesh {mesh_s:.2f}, twin {twin_s:.2f} "
            f"(ingest x{(mesh_s + twin_s) / mesh_s:.2f}), query cloud {cloud_s:.2f}"
        )
        out[ds.name] = {
            "n": n,
            "table": table,
            "seconds": {"mesh": mesh_s, "twin": twin_s, "cloud": cloud_s},
        }
    suffix = ("" if args.query == "pointcloud" else f"_{args.query}") + (
        "_no_twins" if args.no_twins else ""
    )
    write_json(
        OUT / f"cloud_twins_{'_'.join(args.sets)}_{args.split}{suffix}.json",
        {"split": args.split, "query": args.query, "sets": out},
    )


if __name__ == "__main__":
    main()
