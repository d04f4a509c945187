"""A thickness block from the SDF: does a 20 % cloud's field keep what tells people apart?

Usage (from the repository root)::

    python -m bench.studies.thickness --split validation

For every model of the people set's split, the interior values of the field the
decomposition packs (:func:`shapedb.mdbd.decomposition.prepare_field`, default configuration) of its
mesh, of its paper cloud (20 % of the vertices) and of a second draw of that cloud (a
"twin", as a store could keep for each mesh) are reduced to 40 quantiles (2-98 %) of
``depth / volume^(1/3)`` (both in grid cells; ``deep`` variants keep depths over 0.5 or
1 cell, shifted by that much). Printed: mesh -> mesh NN; cloud -> mesh NN raw and after
a label-free mean shift learned from the other models' (mesh, cloud) pairs (leave one
out); cloud -> twin and twin -> twin NN; own-first; and the median distance of a cloud
to its own mesh (or twin) over the median distance between two subjects. Written to
bench/results/studies/thickness_<split>.json.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from bench.common import variant_geometry
from bench.sets.datasets import Model, people
from shapedb.config.core import MDBDConfig
from shapedb.mdbd.decomposition import prepare_field

OUT = Path(__file__).resolve().parents[1] / "results" / "studies"
VARIANTS = ("mesh", "pointcloud", "pointcloud_b")
KINDS = {"volume": 0.0, "deep0.5": 0.5, "deep1": 1.0}


def depths(model: Model, variant: str) -> NDArray[np.float64]:
    """Interior field values of ``model`` in ``variant``, in grid cells."""
    prep = prepare_field(variant_geometry(model, variant, MDBDConfig()), MDBDConfig())
    return np.asarray(prep.F[prep.F > 0], dtype=np.float64) / prep.grid.spacing


def block(x: NDArray[np.float64], deep: float, n: int = 40) -> NDArray[np.float64]:
    """40 quantiles of the depths over ``deep`` cells, shifted, / their volume^(1/3)."""
    y = x[x > deep] - deep
    return np.quantile(y / len(y) ** (1 / 3), np.linspace(0.02, 0.98, n)) / n


def _nn(d: NDArray[np.float64], labels: NDArray[np.str_]) -> float:
    d = d.copy()
    np.fill_diagonal(d, np.inf)  # a model itself, or a cloud's own mesh / twin
    return float(np.mean(labels[d.argmin(1)] == labels))


def _l1(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.abs(a[:, None] - b[None]).sum(-1)


def evaluate(
    values: dict[str, list[NDArray[np.float64]]], labels: NDArray[np.str_]
) -> dict[str, dict[str, float]]:
    """The rows of the study for one set of interior depths per variant."""
    out = {}
    same = labels[:, None] == labels[None]
    for kind, deep in KINDS.items():
        m, c, t = (np.stack([block(x, deep) for x in values[v]]) for v in VARIANTS)
        diff = c - m
        shifted = c - (diff.sum(0)[None] - diff) / (len(c) - 1)  # leave-one-out mean shift
        d_mm, d_cm, d_sm, d_ct, d_tt = (
            _l1(m, m), _l1(c, m), _l1(shifted, m), _l1(c, t), _l1(t, t)
        )  # fmt: skip
        between_m, between_t = np.median(d_mm[~same]), np.median(d_tt[~same])
        out[kind] = {
            "mesh_nn": _nn(d_mm, labels),
            "cloud_nn": _nn(d_cm, labels),
            "cloud_shifted_nn": _nn(d_sm, labels),
            "cloud_twin_nn": _nn(d_ct, labels),
            "twin_twin_nn": _nn(d_tt, labels),
            "own_first": float(np.mean(d_cm.argmin(1) == np.arange(len(c)))),
            "own_first_shifted": float(np.mean(d_sm.argmin(1) == np.arange(len(c)))),
            "shift_over_between": float(np.median(np.diag(d_cm)) / between_m),
            "shifted_over_between": float(np.median(np.diag(d_sm)) / between_m),
            "twin_over_between": float(np.median(np.diag(d_ct)) / between_t),
        }
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.thickness", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    args = ap.parse_args(argv)
    models = people().split(args.split).models
    values = {v: [depths(m, v) for m in models] for v in VARIANTS}
    labels = np.asarray([m.label for m in models])
    res = evaluate(values, labels)
    cols = list(next(iter(res.values())))
    print(f"thickness block, people {args.split} ({len(models)} models)")
    print("kind      " + " ".join(f"{c[:18]:>18s}" for c in cols))
    for kind, row in res.items():
        print(f"{kind:9s} " + " ".join(f"{row[c]:18.3f}" for c in cols))
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"thickness_{args.split}.json"
    path.write_text(json.dumps({"models": len(models), "rows": res}, indent=1) + "\n")
    print(f"written to {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
