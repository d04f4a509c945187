"""Where the ``"lightfield"`` stage loses to the mesh light field descriptor, class by class.

For one set of a split, each class's mean NN and first tier: the product's stage (its gate,
the field vectors and the shared-neighbour term), the same stage without the term, and the
mesh light field descriptor ranking every shape; with the share of the class's queries
whose gate is open (at all, and fully). Classes are listed by the descriptor's lead in
first tier. Run::

    nice -n 5 python -m bench.studies.gate_classes --split validation --dataset generic
    nice -n 5 python -m bench.studies.gate_classes --split validation --dataset generic \
        --store web generic capod figures parts people --out /tmp/classes.json
"""

from __future__ import annotations

import argparse
import copy
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json
from bench.studies.lightfield_gate import RESULTS
from bench.studies.lightfield_gate import parser as gate_parser
from bench.support.cached import CHOICES, load
from bench.support.field_vectors import fuse, stage_of
from bench.support.lightfield import lfd_split_matrix
from bench.support.stores import Split, Store, gate_weights, shared_stores
from query.search.tuning import PRODUCT

__all__ = ["per_class", "main"]


def per_class(split: str, name: str, store: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """One row per class of ``name``'s ``split``, the descriptor's lead in 1-T first.

    ``store``: the sets of the store its shapes query (``name`` among them); default
    ``name`` alone.
    """
    sets = tuple(store) if store else (name,)
    if name not in sets:
        raise ValueError(f"the store {sets} does not hold {name!r}")
    args = gate_parser().parse_args(["--split", split, "--no-grid", "--datasets", *sets])
    sp = fuse(Split(split, sets), sets, stage_of(args))
    f = PRODUCT
    st = Store(sp, sp.store(sets), field_candidates=f.field_candidates)
    w = gate_weights(st, f)
    now = shared_stores({name: st}, sp, f)[name].measures(w)
    without = st.measures(w)
    peer = copy.copy(sp)
    models = [m for s in sets for m in load(s, split)[0].models]
    peer.dl, peer.dv = lfd_split_matrix(models), None
    ps = Store(peer, peer.store(sets), candidates=len(peer.store(sets)))
    lfd = ps.measures(np.full(len(ps.rows), np.inf))
    mine = np.char.startswith(np.asarray(st.labels, dtype=str), f"{name}:")
    labels = np.array([lab.split(":", 1)[1] for lab in st.labels])
    rows = []
    for c in sorted(set(labels[mine])):
        m = mine & (labels == c)
        rows.append({
            "class": str(c), "n": int(m.sum()), "gate open": float((w[m] > 0).mean()),
            "gate full": float((w[m] >= f.weight - 1e-9).mean()),
            "1-T now": float(now[m, 1].mean()), "1-T without the term": float(without[m, 1].mean()),
            "1-T mesh LFD": float(lfd[m, 1].mean()), "NN now": float(now[m, 0].mean()),
            "NN mesh LFD": float(lfd[m, 0].mean()),
        })  # fmt: skip
    return sorted(rows, key=lambda r: r["1-T now"] - r["1-T mesh LFD"])


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.gate_classes", description=__doc__)
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--dataset", default="generic", choices=CHOICES)
    ap.add_argument(
        "--store", nargs="+", choices=CHOICES, default=None,
        help="the sets of the store the dataset's shapes query (default: the dataset alone)",
    )  # fmt: skip
    ap.add_argument("--out", default=None, help="the JSON written (default: bench/results/...)")
    args = ap.parse_args(argv)
    rows = per_class(args.split, args.dataset, args.store)
    keys = list(rows[0])
    where = f" in {' + '.join(args.store)}" if args.store else ""
    title = (
        f"the stage against the mesh light field descriptor by class, "
        f"{args.dataset}{where} {args.split}"
    )
    print(format_table(title, keys, [[r[k] for k in keys] for r in rows]))
    tag = "_in_" + "_".join(args.store) if args.store else ""
    out = Path(args.out) if args.out else (
        RESULTS / f"gate_classes_{args.dataset}{tag}_{args.split}.json"
    )  # fmt: skip
    write_json(out, {"split": args.split, "dataset": args.dataset, "store": args.store or
                     [args.dataset], "rows": rows})  # fmt: skip
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
