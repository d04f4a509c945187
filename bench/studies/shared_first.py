"""The shared-neighbour term with and without keeping each query's first result.

Usage (from the repository root)::

    python -m bench.studies.shared_first                       # validation, the product's k, beta
    python -m bench.studies.shared_first --split test --shared 4 1.6

The gate bench's stores (:mod:`bench.studies.lightfield_gate`: every set and mix of the split a
store, the product's stage with the field vectors, its gate) are scored three ways: the
stage without the shared-neighbour term, with it as the product ranks (the first result
among the query's others is the one without the term:
:meth:`query.search.rerank_lightfield.LightFieldFusion.fuse`), and with it unconstrained (the term
may change the first result too, :attr:`bench.support.stores.Store.keep_first` False). The
rows show what the contract costs or saves on NN. Written to
bench/results/studies/shared_first_<split>.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.common import write_json
from bench.support.stores import (
    MEASURES,
    gate_weights,
    product_stores,
    rows_table,
    score_row,
    shared_stores,
)
from query.search.tuning import PRODUCT

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


def rows(split_name: str, k: int | None = None, beta: float | None = None) -> dict[str, Any]:
    """The three rows on every store of the split (the product's k and beta unless given)."""
    f = PRODUCT
    if k is not None and beta is not None:
        f = dataclasses.replace(f, shared_neighbours=int(k), shared_weight=float(beta))
    split, stores, base = product_stores(split_name)
    gated = {n: gate_weights(st, f) for n, st in stores.items()}
    kept = shared_stores(stores, split, f)
    free = shared_stores(stores, split, f)
    for st in free.values():
        st.keep_first = False
    out = {
        "the stage without the term": score_row(stores, gated, base),
        f"the term (k {f.shared_neighbours}, beta {f.shared_weight:g}), first kept": score_row(
            kept, gated, base
        ),
        f"the term (k {f.shared_neighbours}, beta {f.shared_weight:g}), first free": score_row(
            free, gated, base
        ),
    }
    print(
        rows_table(f"the shared-neighbour term, {split_name} splits (NN / 1-T / DCG)", out, stores)
    )
    return {"split": split_name, "measures": MEASURES, "rows": out,
            "shared": [f.shared_neighbours, f.shared_weight]}  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.shared_first")
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--shared", nargs=2, default=None, metavar=("K", "BETA"))
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    k, beta = (None, None) if args.shared is None else (int(args.shared[0]), float(args.shared[1]))
    result = rows(args.split, k, beta)
    out = args.out or RESULTS / f"shared_first_{args.split}.json"
    write_json(out, result)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
