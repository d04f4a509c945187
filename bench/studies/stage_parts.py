"""Which parts of the re-ranking stage earn their numbers: each switched off, on every family.

Usage (from the repository root)::

    python -m bench.studies.stage_parts --split validation --set sheet_rule=enclosed

The stores are :mod:`bench.quality`'s (each family's split ingested through the product,
cached; built here when missing). Every variant is the product's stage
(:data:`query.search.tuning.PRODUCT`) with some of its parts switched off, run through
:func:`query.search.tuning.tuned` so that every store's searches rank with it, scored with
:meth:`Database.evaluate`. Rows: the variant's macro objective over the families (mean of
``(NN + 1-T + DCG) / 3``), its worst family's NN loss against the product's stage, and the
tuned numbers it leaves. Written to ``bench/results/studies/stage_parts_<split>.json``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json
from bench.quality import FAMILIES, parse_options
from query.search.tuning import PRODUCT, StageTuning, tuned

__all__ = ["VARIANTS", "numbers_left", "run", "table", "main"]

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"

#: Each variant: the stage's fields it sets, and the fields that then no longer matter.
VARIANTS: dict[str, tuple[dict[str, Any], tuple[str, ...]]] = {
    "product": ({}, ()),
    "no shared neighbours": ({"shared_weight": 0.0}, ("shared_weight",)),
    "no stored-distance neighbours": (
        {"descriptor_shared_weight": 0.0},
        ("descriptor_shared_weight",),
    ),
    "no contrast floor": (
        {"contrast_floor": 0.0},
        ("contrast_floor", "contrast_ramp", "contrast_depth", "neighbours"),
    ),
    "no ratio": ({"ratio_weight": 0.0}, ("ratio_weight", "ratio_candidates")),
    "own statistic (no pool)": ({"pool": 0}, ("pool", "pool_quantile")),
    "no field candidates": ({"field_candidates": 0}, ("field_candidates",)),
}


def numbers_left(dropped: Sequence[str]) -> int:
    """The stage's tuned numbers left when the fields ``dropped`` no longer matter."""
    from dataclasses import fields

    return len([f for f in fields(StageTuning) if f.name not in set(dropped)])


def _combined(names: Sequence[str]) -> tuple[dict[str, Any], tuple[str, ...]]:
    sets: dict[str, Any] = {}
    dropped: tuple[str, ...] = ()
    for name in names:
        s, d = VARIANTS[name]
        sets.update(s)
        dropped += d
    return sets, dropped


def _scores(stores: dict[str, Any], tuning: StageTuning) -> dict[str, dict[str, float]]:
    from bench.support.product_stores import store_scores

    with tuned(tuning):
        return {name: store_scores(db) for name, db in stores.items()}


def run(stores: dict[str, Any], combine: Sequence[str] = ()) -> dict[str, Any]:
    """Every variant (and ``combine``'s together) on ``stores`` (family -> open Database):
    per variant its families' scores, macro objective, worst family and numbers left."""
    runs = dict(VARIANTS)
    if combine:
        runs[" + ".join(combine)] = _combined(combine)
    results: dict[str, Any] = {}
    for name, (sets, dropped) in runs.items():
        scores = _scores(stores, replace(PRODUCT, **sets))
        macro = float(
            np.mean([(s["nn"] + s["first_tier"] + s["dcg"]) / 3 for s in scores.values()])
        )
        results[name] = {"families": scores, "macro": macro, "numbers": numbers_left(dropped)}
        print(f"  {name}: macro {macro:.4f}", flush=True)
    base = results["product"]["families"]
    for r in results.values():
        loss = {f: base[f]["nn"] - s["nn"] for f, s in r["families"].items()}
        worst = max(loss, key=loss.__getitem__)
        r["worst"] = {"family": worst, "nn_loss": loss[worst]}
    return results


def table(results: dict[str, Any], split: str) -> str:
    """:func:`run`'s results as a table: NN / 1-T per family, macro, worst loss, numbers."""
    families = list(next(iter(results.values()))["families"])
    body = []
    for name, r in results.items():
        cells = [f"{s['nn']:.3f}/{s['first_tier']:.3f}" for s in r["families"].values()]
        w = r["worst"]
        body.append(
            [name, *cells, f"{r['macro']:.4f}", f"{w['family']} {w['nn_loss']:+.3f}", r["numbers"]]
        )
    return format_table(f"NN/1-T per family ({split})",
                        ["variant", *families, "macro", "worst NN loss", "numbers"], body)  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.stage_parts", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(FAMILIES), choices=FAMILIES)
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    ap.add_argument(
        "--combine",
        nargs="*",
        default=[],
        metavar="VARIANT",
        help="also run these variants together (names as in the table)",
    )
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)  # fmt: skip
    from bench.quality import family_split
    from bench.support.product_stores import split_store

    options = parse_options(args.set)
    stores = {n: split_store(family_split(n, args.split), options) for n in args.datasets}
    results = run(stores, args.combine)
    print(table(results, args.split))
    write_json(
        args.out or RESULTS / f"stage_parts_{args.split}.json",
        {"options": options, "variants": results},
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
