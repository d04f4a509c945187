"""The sparse views' spacing (``CloudConfig.view_cells``), chosen on validation.

Usage (from the repository root)::

    python -m bench.studies.views [--cells 3 4 5] [--split validation] [--workers 2]

For each spacing (grid cells between view samples) the meshes of the split are
decomposed as sparse views (:func:`shapedb.geometry.view.view_geometry`, cached like every
bench decomposition) and the paper's 20 % point clouds are compared with them as a
store with views compares them. Reported per set: NN of cloud queries against the
mesh database, with the meshes' own features (no views) and with views; the mean
log margin ``log(d(nearest same class) / d(nearest other class))`` of those queries
(lower is better; far less noisy than NN); and NN of the even mixture. The mesh
retrieval the cloud queries are held against is in the first column. Results go to
bench/results/studies/views.json.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import (
    Balls,
    decompose_all,
    format_table,
    log_margin,
    retrieval_scores,
    write_json,
)
from bench.retrieval import build_sets
from bench.support.features import l1_matrix, mixture_mask, reconstructions
from shapedb.config.core import MDBDConfig
from shapedb.signature.descriptor import describe

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "views.json"


def _features(balls: Sequence[Balls]) -> NDArray[np.float64]:
    return np.stack([describe(b.decomposition().graph) for b in balls])


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.views", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--datasets", nargs="+", default=["capod", "articulated", "parts"])
    ap.add_argument("--cells", nargs="+", type=float, default=[3.0, 4.0, 5.0])
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    mdbd = MDBDConfig()
    rows: list[list[Any]] = []
    record: dict[str, Any] = {"split": args.split}
    for ds in build_sets(args.datasets, quick=False):
        sub = ds.split(args.split)
        m = decompose_all(sub.models, "mesh", mdbd, workers=args.workers, progress=None)
        p = decompose_all(sub.models, "pointcloud", mdbd, workers=args.workers, progress=None)
        r = reconstructions(sub.models, p, mdbd, workers=args.workers)
        views = {
            c: decompose_all(sub.models, f"view_{c:g}", mdbd, workers=args.workers, progress=None)
            for c in args.cells
        }
        keep = [
            i
            for i in range(len(sub))
            if m[i] is not None
            and p[i] is not None
            and all(v[i] is not None for v in views.values())
        ]
        labels = np.asarray([sub.models[i].label for i in keep])
        names = [sub.models[i].name for i in keep]
        fm = _features([m[i] for i in keep])  # type: ignore[misc]
        fp = _features([p[i] for i in keep])  # type: ignore[misc]
        fr = _features([r[i] for i in keep])  # type: ignore[misc]
        mix = mixture_mask(names)
        d_mm = l1_matrix(fm, fm)
        mesh_nn = retrieval_scores(-d_mm, labels)["nn"]
        settings: list[tuple[str, NDArray[np.float64]]] = [("none", fm)]
        settings += [(f"{c:g}", _features([views[c][i] for i in keep])) for c in args.cells]  # type: ignore[misc]
        for name, fv in settings:
            # the nearest of the store's comparisons (query.search.engine)
            d_pv = np.minimum(np.minimum(l1_matrix(fp, fv), l1_matrix(fp, fm)), l1_matrix(fr, fm))
            fx = np.where(mix[:, None], fp, fm)
            d_xy = l1_matrix(fx, np.where(mix[:, None], fp, fv))
            d_rx = l1_matrix(np.where(mix[:, None], fr, fm), fx)
            one = mix[:, None] != mix[None, :]
            near = np.minimum(np.minimum(d_xy, d_xy.T), np.minimum(d_rx, d_rx.T))
            d_mix = np.where(one, np.minimum(l1_matrix(fx, fx), near), l1_matrix(fx, fx))
            res = {
                "mesh_nn": mesh_nn,
                "cloud_nn": retrieval_scores(-d_pv, labels)["nn"],
                "cloud_log_margin": log_margin(d_pv, labels),
                "mixture_nn": retrieval_scores(-d_mix, labels)["nn"],
            }
            record[f"{ds.name}/{name}"] = res
            rows.append([ds.name, name, len(keep), *res.values()])
    print(
        format_table(
            f"Sparse views by spacing ({args.split} split; 'none': clouds against mesh features)",
            [
                "set",
                "view cells",
                "models",
                "mesh NN",
                "cloud NN",
                "cloud log margin",
                "mixture NN",
            ],
            rows,
        )
    )
    write_json(args.out, record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
