"""The gate's contrast opened where the light field is surer of its nearest than the stored distance.

Usage (from the repository root)::

    python -m bench.studies.contrast_surer                  # validation
    python -m bench.studies.contrast_surer --split test

The contrast (:class:`query.search.tuning.StageTuning`) keeps the light field out of
a query whose stored distance sets its nearest apart: ``t_v``, the median stored distance
of its ``neighbours`` nearest others over that of its ``contrast_depth``-th, below the floor.
The light field's own contrast ``t_l`` (the same over the query's candidates ranked by the
stage's light field distance) says how sure the light field is. This study opens the
contrast wherever ``t_l < rho * t_v`` (the other factors of the gate unchanged), on the gate
bench's stores (:mod:`bench.studies.lightfield_gate`: every set and mix of the split, the product's
stage with the field vectors and its shared-neighbour term), beside the product's gate and
the contrast off. Written to bench/results/studies/contrast_surer_<split>.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json
from bench.support.stores import (
    MEASURES,
    FloatArray,
    Store,
    gate_weights,
    product_stores,
    rows_table,
    score_row,
    shared_stores,
)
from query.search.tuning import PRODUCT

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
#: The ratios ``rho`` tried.
RHOS = (0.5, 0.7, 0.9, 1.0)


def contrasts(st: Store, f: Any) -> tuple[FloatArray, FloatArray]:
    """(n,) ``t_v`` and ``t_l`` of every query of ``st`` under the fusion ``f``."""
    d = st.others(st.D)
    ll = np.sort(st.others(st.L), 1)
    far = min(f.contrast_depth, d.shape[1]) - 1
    tv = np.median(d[:, : f.neighbours], 1) / np.maximum(d[:, far], 1e-300)
    tl = np.median(ll[:, : f.neighbours], 1) / np.maximum(ll[:, far], 1e-300)
    return tv, tl


def rows(split_name: str) -> dict[str, Any]:
    """The product's gate, the contrast off and the contrast opened at every ``rho``."""
    f = PRODUCT
    split, stores, base = product_stores(split_name)
    term = shared_stores(stores, split, f)
    now = {n: gate_weights(st, f) for n, st in stores.items()}
    off = {
        n: gate_weights(st, dataclasses.replace(f, contrast_floor=0.0)) for n, st in stores.items()
    }
    stats = {n: contrasts(st, f) for n, st in stores.items()}
    out = {"the product's gate": score_row(term, now, base),
           "the contrast off": score_row(term, off, base)}  # fmt: skip
    opened = {}
    for rho in RHOS:
        w = {n: np.where(stats[n][1] < rho * stats[n][0], off[n], now[n]) for n in stores}
        opened[rho] = int(sum(np.count_nonzero(w[n] != now[n]) for n in stores))
        out[f"opened where t_l < {rho:g} t_v"] = score_row(term, w, base)
    title = (
        f"the contrast opened where the light field is surer, {split_name} splits (NN / 1-T / DCG)"
    )
    print(rows_table(title, out, stores))
    quant = {n: {"t_v": np.quantile(tv, [0.1, 0.5, 0.9]).tolist(),
                 "t_l": np.quantile(tl, [0.1, 0.5, 0.9]).tolist()}
             for n, (tv, tl) in stats.items()}  # fmt: skip
    print(format_table(
        "the contrasts, 10 / 50 / 90 % of the queries", ("store", "t_v", "t_l"),
        [[n, "/".join(f"{x:.3f}" for x in q["t_v"]), "/".join(f"{x:.3f}" for x in q["t_l"])]
         for n, q in quant.items()],
    ))  # fmt: skip
    print("gates changed by each rho (every store):", opened)
    return {"split": split_name, "measures": MEASURES, "rows": out, "contrasts": quant,
            "changed": {str(k): v for k, v in opened.items()}}  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.contrast_surer")
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    result = rows(args.split)
    out = args.out or RESULTS / f"contrast_surer_{args.split}.json"
    write_json(out, result)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
