"""Choosing the field vectors' part of the ``"lightfield"`` stage on validation.

Usage (from the repository root)::

    export SHAPEDB_BENCH_CACHE=/work/bench_cache
    nice -n 5 python -m bench.studies.field_choice --split validation     # the scales (medians)
    nice -n 5 python -m bench.studies.field_choice --choose               # the choice on validation

The scales ``m_l``, ``m_b``, ``m_h`` of :mod:`bench.support.field_vectors` are medians of each
distance over the split's off-diagonal pairs (:func:`medians`: pooled over the six sets,
per set, and the median of the per-set medians). ``--choose`` (:func:`choose`) scores
every scale rule x :data:`WEIGHTS` x :data:`K2` through the gate bench's stores (every
set and mix) at today's gate, with the two-queries rule against version 4, the analytic
chain on the fused distance and the gate's margins; the gate itself is re-chosen by
``python -m bench.studies.lightfield_gate --field-vectors ...`` (its grid) on the chosen
distance. Written to bench/results/studies/field_vectors_{medians,choice}_<split>.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import format_table, write_json
from bench.studies.gate_checks import (
    MIN_MARGIN,
    analytic_gates,
    analytic_shapes,
    analytic_stores,
    gate_margin,
)
from bench.support.field_vectors import FieldStage, analytic_distance, fuse, off_median, split_parts
from bench.support.stores import (
    MIXES,
    SETS,
    Split,
    Store,
    gate_weights,
    score_row,
)
from bench.support.tuning import parse_value
from query.search.tuning import PRODUCT

FloatArray = NDArray[np.float64]
RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


def medians(split: Split, names: Sequence[str]) -> dict[str, dict[str, float]]:
    """Median off-diagonal ``l``, ``b``, ``h``: pooled over the split, per set, and the
    median of the per-set medians."""
    b, h = split_parts(split, names)
    mats = {"l": split.light, "b": b, "h": h}
    out: dict[str, dict[str, float]] = {"pooled": {k: off_median(d) for k, d in mats.items()}}
    for n in names:
        idx = split.store((n,))
        out[n] = {k: off_median(d[np.ix_(idx, idx)]) for k, d in mats.items()}
    out["median of the sets"] = {k: float(np.median([out[n][k] for n in names])) for k in mats}
    return out


#: The choice's grid: the weights ``(a, c)`` and ``K2``.
WEIGHTS = ((0.5, 0.5), (0.25, 0.25), (0.25, 0.5), (0.5, 0.25), (0.75, 0.75), (0.125, 0.125))
K2 = (0, 50, 100, 200)


def choose(
    split_name: str = "validation", min_margin: float | None = None, gate: Any = None
) -> dict[str, Any]:
    """Every scale rule x :data:`WEIGHTS` x :data:`K2` at today's gate, on every set and mix.

    Per setting: the rows of the product's gate (:data:`query.search.tuning.PRODUCT`) on the
    fused distance with the union candidates, the two-queries rule against version 4,
    the analytic chain (shut) and rigid store (open) on the fused distance, and the
    jointed margin (:data:`bench.studies.gate_checks.MIN_MARGIN`; every rigid set's 95 % under the
    ceiling, which no setting keeps, nor today's product on the field's light fields, is
    reported, not required). Chosen: the best objective among
    the settings that keep all three; else the best by the rule and the chain.
    ``gate``: a :class:`query.search.tuning.StageTuning` in place of the product's.
    """
    import tempfile

    min_margin = MIN_MARGIN if min_margin is None else min_margin
    names = list(SETS)
    t0 = time.perf_counter()
    base_split = Split(split_name, names)
    meds = medians(base_split, names)
    print(format_table(f"median off-diagonal distances, {split_name}",
                       ("pairs", "l (light fields)", "b (depth)", "h (harmonics)"),
                       [[k, f"{v['l']:.4g}", f"{v['b']:.4g}", f"{v['h']:.4g}"]
                        for k, v in meds.items()]))  # fmt: skip
    rules = {"pooled": meds["pooled"], "median of the sets": meds["median of the sets"]}
    stores_of = {s: (s,) for s in names} | {k: v for k, v in MIXES.items() if set(v) <= set(names)}
    f = PRODUCT if gate is None else gate
    tmp = tempfile.TemporaryDirectory(prefix="field_vectors_")
    analytic = analytic_stores(Path(tmp.name))
    shapes = analytic_shapes()
    results: list[dict[str, Any]] = []
    base = None
    for rule, m in rules.items():
        for a, c in WEIGHTS:
            stage = FieldStage.at_scales(a, c, m["l"], m["b"], m["h"], 0)
            split = fuse(base_split, names, stage)
            amemo: dict[Any, Any] = {}
            dist = {k: analytic_distance(db, shapes[k], stage) for k, db in analytic.items()}
            g_chain, s_chain = analytic_gates(analytic["chain"], f, amemo, dist["chain"], stage)
            g_rigid, _ = analytic_gates(analytic["rigid"], f, amemo, dist["rigid"], stage)
            chain_ok = bool(np.all(g_chain == 0) and np.count_nonzero(g_rigid) >= 6)
            margin = None
            for k2 in K2:
                stores = {k: Store(split, split.store(v), field_candidates=k2)
                          for k, v in stores_of.items()}  # fmt: skip
                if base is None:
                    zero = {k: np.zeros(len(st.rows)) for k, st in stores.items()}
                    base = {k: st.per_set(st.measures(zero[k])) for k, st in stores.items()}
                    results.append({"setting": "v4 (no stage)",
                                    "row": score_row(stores, zero, base)})  # fmt: skip
                memo: dict[Any, FloatArray] = {}
                row = score_row(stores, {k: gate_weights(st, f, memo)
                                         for k, st in stores.items()}, base)  # fmt: skip
                if margin is None:  # the statistics read the K alone: one margin per distance
                    margin = gate_margin(stores, f, memo)
                wide = bool(margin["jointed_min"] >= min_margin * f.ceiling)
                got = {"setting": f"{rule}: " + dataclasses.replace(stage, candidates=k2).short(),
                       "rule": rule, "stage": dataclasses.asdict(
                           dataclasses.replace(stage, candidates=k2)),
                       "row": row, "margin": margin, "chain_shut": chain_ok,
                       "chain_min": float(np.nanmin(s_chain)), "wide": wide}  # fmt: skip
                results.append(got)
                print(f"  {got['setting']}: objective {row['objective']:.4f}, worst "
                      f"{row['worst_queries']:+.1f}, chain {'shut' if chain_ok else 'OPEN'}, "
                      f"margin {margin['jointed_min'] / f.ceiling:.2f} / rigid 95 % "
                      f"{margin['rigid_95']:.3f} ({time.perf_counter() - t0:.0f} s)", flush=True)  # fmt: skip
    tmp.cleanup()
    fv = [r for r in results if "stage" in r]
    keep = [r for r in fv if r["row"]["passes"] and r["chain_shut"] and r["wide"]]
    fallback = [r for r in fv if r["row"]["passes"] and r["chain_shut"]]
    best = (
        max(keep or fallback, key=lambda r: r["row"]["objective"]) if (keep or fallback) else None
    )
    _print(results, best)
    return {"split": split_name, "medians": meds, "gate": dataclasses.asdict(f),
            "min_margin": min_margin, "results": results,
            "chosen": None if best is None else best["setting"],
            "chosen_keeps_margin": bool(keep)}  # fmt: skip


def _print(results: list[dict[str, Any]], best: dict[str, Any] | None) -> None:
    cols = [(k, s) for k, v in results[0]["row"]["stores"].items() for s in v]
    table = []
    for r in results:
        e = r["row"]
        worst = f"{e['worst_queries']:+.1f} ({e['worst_at']})" if e["worst_at"] else "0"
        checks = "" if "stage" not in r else (
            ("chain shut" if r["chain_shut"] else "chain open") + ", "
            + ("margin kept" if r["wide"] else "margin lost"))  # fmt: skip
        mark = " *" if best is not None and r is best else ""
        table.append([r["setting"] + mark,
                      *("{nn:.3f} / {first_tier:.3f} / {dcg:.3f}".format(**e["stores"][k][s])
                        for k, s in cols), f"{e['objective']:.4f}", worst, checks])  # fmt: skip
    heads = [k if (k,) == (s,) else f"{s} in {k}" for k, s in cols]
    print(format_table("the stage on the fused distance at today's gate (NN / 1-T / DCG); * chosen",
                       ("setting", *heads, "objective", "worst", "checks"), table))  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.field_choice",
                                 description=__doc__.split("\n")[0])  # fmt: skip
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--choose", action="store_true",
                    help="the scales, weights and K2 at today's gate (validation)")  # fmt: skip
    ap.add_argument("--fusion", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="StageTuning fields of the gate (default: the product's)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.choose:
        pairs = dict(kv.split("=", 1) for kv in args.fusion)
        gate = dataclasses.replace(PRODUCT, **{k: parse_value(v) for k, v in pairs.items()})
        got = choose(args.split, gate=gate)
        out = args.out or RESULTS / f"field_vectors_choice_{args.split}.json"
    else:
        split = Split(args.split, SETS)
        meds = medians(split, SETS)
        print(format_table(f"median off-diagonal distances, {args.split}",
                           ("pairs", "l (light fields)", "b (depth)", "h (harmonics)"),
                           [[k, f"{v['l']:.4g}", f"{v['b']:.4g}", f"{v['h']:.4g}"]
                            for k, v in meds.items()]))  # fmt: skip
        got = {"split": args.split, "medians": meds}
        out = args.out or RESULTS / f"field_vectors_medians_{args.split}.json"
    write_json(out, got)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
