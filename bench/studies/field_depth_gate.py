"""The light field stage with the field's depth buffers and harmonics fused into its distance.

Usage (from the repository root)::

    python -m bench.studies.field_depth_gate                  # validation, every set and mix
    python -m bench.studies.field_depth_gate --split test
    python -m bench.studies.field_depth_gate --grid         # the gate re-chosen on validation
    python -m bench.studies.field_depth_gate --split test --candidates   # where the cut loses

The gate bench (:mod:`bench.studies.lightfield_gate`, its fixed rows: version 4, the light fields
alone, the product's stage) scores a split whose light field distance ``l`` (the product's:
the field's inside, :mod:`bench.support.inside_fields`) is replaced by

    ``m_l * (l / m_l + a * b / m_b + c * h / m_h) / (1 + a + c)``

with ``b`` and ``h`` the L1 distances of the depth buffer descriptor and of the
spherical-harmonic energies of the same field's inside (:mod:`bench.studies.field_depth`,
its cached shells), ``m`` each distance's median over the split's off-diagonal pairs and
``a``, ``c`` the weights chosen on web validation there (0.5, 0.5). The division keeps the
fused distance's scale near the light field's, so the gate's spread keeps its units.
Every set's shapes are scored in every store they belong to, as in the gate bench; the
rule is the same (no set more than two queries below version 4). Written to
bench/results/studies/field_depth_gate_<split>.json.
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
from bench.studies.field_depth import descriptor_matrix, shells
from bench.studies.lightfield_gate import parser, select
from bench.support.cached import load
from bench.support.stores import SETS, Split

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
DBD = "DBD 64 px, k 8"
SHD = "SHD 32 x 16, grid"


def _median(d: NDArray[np.float64]) -> float:
    return float(np.median(d[~np.eye(len(d), dtype=bool)]))


def field_matrices(
    split: str, names: Sequence[str]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(n, n) L1 distances of the depth buffers and of the harmonics over the sets' models."""
    all_shells, keys = [], []
    for name in names:
        ds, _ = load(name, split)
        all_shells += shells(ds)
        keys += [f"{name}:{m.name}{m.source}" for m in ds.models]
    b, _ = descriptor_matrix(DBD, all_shells, keys)
    h, _ = descriptor_matrix(SHD, all_shells, keys)
    return b, h


def fused_split(split: str, names: Sequence[str], dbd: float, shd: float) -> Split:
    """The gate bench's :class:`Split` with its light field distance fused as above."""
    out = Split(split, names)
    b, h = field_matrices(split, names)
    if b.shape != out.dl.shape:
        raise ValueError(f"{b.shape[0]} shells for {out.dl.shape[0]} light fields")
    m = _median(out.dl)
    fused = out.dl / m + dbd * b / _median(b) + shd * h / _median(h)
    out.dl = m * fused / (1.0 + dbd + shd)
    return out


def candidates(split: str, names: Sequence[str], dbd: float, shd: float) -> dict[str, Any]:
    """Where the stage's candidates lose the fused distance's gain: per set and store, NN and
    1-T of the fused distance over the whole store, over version 4's 100 or 300 nearest, over
    the 100 nearest of an L1 index of the two field vectors (``b / m_b + h / m_h``), and over
    the union of version 4's 100 and that index's 100."""
    base = Split(split, names)
    fused = fused_split(split, names, dbd, shd).dl
    b, h = field_matrices(split, names)
    vec = b / _median(b) + h / _median(h)
    rules = {
        "whole store": lambda d4, v, i: np.arange(len(d4)),
        "v4's 100": lambda d4, v, i: np.argsort(d4[i], kind="stable")[:101],
        "v4's 300": lambda d4, v, i: np.argsort(d4[i], kind="stable")[:301],
        "field vectors' 100": lambda d4, v, i: np.argsort(v[i], kind="stable")[:101],
        "union of both 100": lambda d4, v, i: np.union1d(
            np.argsort(d4[i], kind="stable")[:101], np.argsort(v[i], kind="stable")[:101]
        ),
    }
    out: dict[str, Any] = {}
    stores = {n: (n,) for n in names} | {"all six": tuple(names)}
    for store, members in stores.items():
        idx = base.store(members)
        labs = base.labels[idx]
        sub = np.ix_(idx, idx)
        f, d4, v = fused[sub], base.d4[sub], vec[sub]
        for name in members:
            queries = np.flatnonzero(base.sets[idx] == name)
            for rule, pick in rules.items():
                nn, tier = [], []
                for i in queries:
                    c = pick(d4, v, i)
                    c = c[c != i]
                    o = c[np.argsort(f[i, c], kind="stable")]
                    k = int((labs == labs[i]).sum()) - 1
                    nn.append(labs[o[0]] == labs[i])
                    tier.append(float((labs[o[:k]] == labs[i]).mean()) if k else 0.0)
                out.setdefault(f"{name} in {store}", {})[rule] = (
                    float(np.mean(nn)), float(np.mean(tier)))  # fmt: skip
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.field_depth_gate", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(SETS))
    ap.add_argument("--dbd", type=float, default=0.5, help="weight of the depth buffers")
    ap.add_argument("--shd", type=float, default=0.5, help="weight of the harmonics")
    ap.add_argument("--grid", action="store_true",
                    help="validation: also the gate bench's selection grid on these distances")  # fmt: skip
    ap.add_argument("--fusion", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="StageTuning fields of the 'stage now' row")  # fmt: skip
    ap.add_argument("--candidates", action="store_true",
                    help="the fused distance over other candidate sets (NN / 1-T), no gate")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.candidates:
        got = candidates(args.split, args.datasets, args.dbd, args.shd)
        rules = list(next(iter(got.values())))
        print(format_table(f"the fused distance by candidates, {args.split} (NN / 1-T)",
                           ("queries", *rules),
                           [[k, *(f"{a:.3f} / {b:.3f}" for a, b in v.values())]
                            for k, v in got.items()]))  # fmt: skip
        out = args.out or RESULTS / f"field_depth_candidates_{args.split}.json"
        write_json(out, got)
        print(f"written {out}")
        return 0
    flags = ["--split", args.split, "--datasets", *args.datasets, "--fusion", *args.fusion]
    gate_args = parser().parse_args(flags + ([] if args.grid else ["--no-grid"]))
    split = fused_split(args.split, args.datasets, args.dbd, args.shd)
    result = select(gate_args, split=split)
    result["fusion"] = {"dbd": args.dbd, "shd": args.shd, "dbd_name": DBD, "shd_name": SHD}
    out = args.out or RESULTS / f"field_depth_gate_{args.split}.json"
    write_json(out, result)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
