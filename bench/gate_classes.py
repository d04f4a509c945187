"""Where the ``"lightfield"`` stage loses to the mesh light field descriptor, class by class.

For one set of a split, each class's mean NN and first tier: the product's stage (its gate,
the field vectors and the shared-neighbour term), the same stage without the term, and the
mesh light field descriptor ranking every shape; with the share of the class's queries
whose gate is open (at all, and fully). Classes are listed by the descriptor's lead in
first tier. Run::

    nice -n 5 python -m bench.gate_classes --split validation --dataset generic
"""

from __future__ import annotations

import argparse
import copy
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

from bench.cached import CHOICES, load
from bench.common import format_table, write_json
from bench.field_vectors import fuse, stage_of
from bench.gate_stores import Split, Store, gate_weights, shared_stores
from bench.lightfield_gate import RESULTS
from bench.lightfield_gate import parser as gate_parser
from bench.rerank_select import lfd_split_matrix
from shapedb.config import Config

__all__ = ["per_class", "main"]


def per_class(split: str, name: str) -> list[dict[str, Any]]:
    """One row per class of ``name``'s ``split``, the descriptor's lead in 1-T first."""
    args = gate_parser().parse_args(["--split", split, "--no-grid", "--datasets", name])
    sp = fuse(Split(split, (name,)), (name,), stage_of(args))
    f = Config().lf_fusion
    st = Store(sp, sp.store((name,)), field_candidates=f.field_candidates)
    w = gate_weights(st, f)
    now = shared_stores({name: st}, sp, f)[name].measures(w)
    without = st.measures(w)
    peer = copy.copy(sp)
    peer.dl, peer.dv = lfd_split_matrix(load(name, split)[0].models), None
    ps = Store(peer, peer.store((name,)), candidates=len(peer.store((name,))))
    lfd = ps.measures(np.full(len(ps.rows), np.inf))
    labels = np.array([lab.split(":", 1)[1] for lab in st.labels])
    rows = []
    for c in sorted(set(labels)):
        m = labels == c
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
    ap = argparse.ArgumentParser(prog="python -m bench.gate_classes", description=__doc__)
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--dataset", default="generic", choices=CHOICES)
    args = ap.parse_args(argv)
    rows = per_class(args.split, args.dataset)
    keys = list(rows[0])
    title = (
        f"the stage against the mesh light field descriptor by class, {args.dataset} {args.split}"
    )
    print(format_table(title, keys, [[r[k] for k in keys] for r in rows]))
    out = RESULTS / f"gate_classes_{args.dataset}_{args.split}.json"
    write_json(out, {"split": args.split, "dataset": args.dataset, "rows": rows})
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
