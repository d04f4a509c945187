"""Validation at the test's class sizes: does the stage's neighbour size fit the classes?

Usage (from the repository root)::

    python -m bench.studies.class_size --variants k3 k6

Each family's validation split holds a third of each class (CAPOD 4 a class, the
generated sets 3-7), its test split two thirds (8-13): a term that reads a query's ``k``
nearest neighbours (the stage's shared neighbours, :class:`query.search.tuning.StageTuning`'s
``shared_neighbours``) is chosen on classes half the size of those it is reported on. This
study adds models of new seeds to the validation split of every generated family, so that
its classes are as large as the test's (:func:`large_validation`; the test split is
untouched), ingests them through the product (:func:`bench.support.product_stores.split_store`,
cached) and scores stage variants on both validations. CAPOD has no further models (4 a
class either way). Written to ``bench/results/studies/class_size.json``.
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
from bench.quality import FAMILIES, family_split
from bench.sets.datasets import Dataset, Model, load_dataset
from query.search.tuning import PRODUCT, tuned

__all__ = ["VARIANTS", "EXTRA", "large_validation", "main"]

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"

#: The stage variants this study can score (fields of ``StageTuning``).
VARIANTS: dict[str, dict[str, Any]] = {
    f"k{k}": {"shared_neighbours": k} for k in (3, 4, 5, 6, 7, 8)
}

#: Models added to each class of a family's validation split: enough to reach its test
#: split's class size (generated sets: 20 a kind, 7 in validation, 13 in test; parts 12 a
#: kind, 4 and 8; people 10 poses a subject, 3 and 7).
EXTRA = {"generic": 6, "web": 6, "enclosures": 6, "figures": 6, "parts": 4, "people": 4}


def _grid(classes: Sequence[Any], seeds: range, name: str, label: str, source: str) -> list[Model]:
    """Validation models of every class and seed; ``name``, ``label`` and ``source`` are
    format strings of ``c`` (the class) and ``i`` (the seed)."""
    return [
        Model(name.format(c=c, i=i), label.format(c=c), source.format(c=c, i=i), split="validation")
        for c in classes
        for i in seeds
    ]


def _extra_models(name: str, extra: int) -> list[Model]:
    """``extra`` new models of each class of family ``name`` (seeds past the set's own)."""
    if name == "generic":
        from bench.sets.generic_shapes import KINDS

        return _grid(KINDS, range(20, 20 + extra), "{c}_{i:02d}", "{c}", "generic:{c}:{i}")
    if name == "web":
        from bench.sets.web_shapes import KINDS, web_version

        source = "web:{c}:{i}:" + web_version()
        return _grid(KINDS, range(20, 20 + extra), "{c}_{i:02d}", "{c}", source)
    if name == "enclosures":
        from bench.sets.enclosures import KINDS as ENCLOSURE_KINDS
        from bench.sets.enclosures import enclosure_version

        source = "enclosure:{c}:{i}:" + enclosure_version()
        return _grid(ENCLOSURE_KINDS, range(20, 20 + extra), "{c}_{i:02d}", "{c}", source)
    if name == "figures":
        seeds = range(20, 20 + extra)
        return _grid(range(15), seeds, "s{c:02d}_p{i:02d}", "subject{c:02d}", "figure:{c}:{i}")
    if name == "parts":
        from bench.sets.datasets import part_kinds

        return _grid(part_kinds(), range(12, 12 + extra), "{c}_{i:02d}", "{c}", "part:{c}:{i}")
    if name == "people":
        seeds = range(10, 10 + extra)
        return _grid(range(12), seeds, "h{c:02d}_p{i:02d}", "person{c:02d}", "person:{c}:{i}")
    return []


def large_validation(name: str) -> Dataset:
    """Family ``name``'s validation split with :data:`EXTRA` new models in each class."""
    ds = family_split(name, "validation")
    known = {m.source for m in load_dataset(ds.name).models}
    extra = [m for m in _extra_models(name, EXTRA.get(name, 0)) if m.source not in known]
    return Dataset(ds.name, ds.models + tuple(extra))


def _class_size(ds: Dataset) -> float:
    _, counts = np.unique(ds.labels, return_counts=True)
    return float(np.median(counts))


def run(stores: dict[str, Any], variants: Sequence[str]) -> dict[str, Any]:
    """Each variant's scores on ``stores`` (family -> open Database) and macro objective."""
    from bench.support.product_stores import store_scores

    out: dict[str, Any] = {}
    for v in variants:
        with tuned(replace(PRODUCT, **VARIANTS[v])):
            scores = {f: store_scores(db) for f, db in stores.items()}
        macro = float(
            np.mean([(s["nn"] + s["first_tier"] + s["dcg"]) / 3 for s in scores.values()])
        )
        out[v] = {"families": scores, "macro": macro}
        print(f"  {v}: macro {macro:.4f}", flush=True)
    return out


def table(results: dict[str, Any], title: str) -> str:
    """NN / 1-T per family, macro and worst NN loss against the first variant."""
    first = next(iter(results.values()))["families"]
    body = []
    for v, r in results.items():
        loss = {f: first[f]["nn"] - s["nn"] for f, s in r["families"].items()}
        worst = max(loss, key=loss.__getitem__)
        cells = [f"{s['nn']:.3f}/{s['first_tier']:.3f}" for s in r["families"].values()]
        body.append([v, *cells, f"{r['macro']:.4f}", f"{worst} {loss[worst]:+.3f}"])
    return format_table(title, ["variant", *first, "macro", "worst NN loss"], body)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.class_size", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--datasets", nargs="+", default=list(FAMILIES), choices=FAMILIES)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "class_size.json")
    args = ap.parse_args(argv)
    from bench.support.product_stores import split_store

    report: dict[str, Any] = {}
    for which in ("validation", "large validation"):
        stores, sizes = {}, {}
        for name in args.datasets:
            ds = (
                family_split(name, "validation")
                if which == "validation"
                else large_validation(name)
            )
            sizes[name] = _class_size(ds)
            stores[name] = split_store(ds, {}, workers=args.workers)
        print(f"{which}: median class size {sizes}", flush=True)
        results = run(stores, args.variants)
        print(table(results, f"NN/1-T per family ({which})"))
        report[which] = {"class_size": sizes, "variants": results}
    write_json(args.out, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
