"""What the per-view framing adds to an ingest, and the stored distance's neighbours to a search.

Usage (from the repository root)::

    export SHAPEDB_BENCH_CACHE=/work/bench_cache
    nice -n 5 python -m bench.studies.stage_cost            # 20 web validation models
    nice -n 5 python -m bench.studies.stage_cost --models 40 --searches 3

Ingest: per model (web validation, one of each class first), the CPU seconds of this
process for the record's ingest work (:func:`bench.studies.field_vector_cost.ingest_cpu`)
with the light fields framed in the sphere's frame (``LightFieldConfig.framing="sphere"``,
the baseline) and per view (``"view"``, today's default), interleaved model by model.
Search: in the web validation store of :mod:`bench.quality`, every shape searched
(``db.search(id, k=10)``) with the product's stage and with the stored distance's
shared-neighbour term off (``descriptor_shared_weight=0``), interleaved shape by shape and
repeated (the minimum of the repeats). Printed: medians and the median of the paired
ratios. Written to bench/results/studies/stage_cost.json.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json
from bench.studies.field_vector_cost import ingest_cpu
from query.search.tuning import PRODUCT, tuned
from shapedb.config.core import Config

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


def _paired(base: list[float], other: list[float]) -> dict[str, float]:
    return {
        "baseline": float(np.median(base)),
        "measured": float(np.median(other)),
        "ratio_median": float(np.median(np.divide(other, base))),
    }


def models(k: int) -> list[Any]:
    """The first ``k + 1`` web validation models, one of each class first."""
    from bench.quality import family_split

    ds = family_split("web", "validation")
    labels = list(ds.labels)
    first = [i for i, lab in enumerate(labels) if labels.index(lab) == i]
    order = first + [i for i in range(len(ds)) if i not in set(first)]
    return [ds.models[i] for i in order[: k + 1]]


def ingest_rows(k: int) -> dict[str, Any]:
    """Ingest CPU per model, the sphere's frame against the per-view framing."""
    today = Config()
    sphere = replace(today, light_field=replace(today.light_field, framing="sphere"))
    chosen = models(k)
    for cfg in (sphere, today):  # compile the renderer
        ingest_cpu(chosen[0], cfg)
    base, other, lf_base, lf_other = [], [], [], []
    for m in chosen[1:]:
        sec, timings = ingest_cpu(m, sphere)
        base.append(sec)
        lf_base.append(timings["light_field"])
        sec, timings = ingest_cpu(m, today)
        other.append(sec)
        lf_other.append(timings["light_field"])
    out = _paired(base, other)
    out["light_field_baseline"] = float(np.median(lf_base))
    out["light_field_measured"] = float(np.median(lf_other))
    return out


def search_rows(repeats: int) -> dict[str, Any]:
    """Search wall seconds per stored shape, the term off against the product."""
    from bench.quality import family_split
    from bench.support.product_stores import split_store

    db = split_store(family_split("web", "validation"), {})
    ids = sorted(int(i) for i in db.sql("SELECT id FROM shapes").column("id").to_pylist())
    off = replace(PRODUCT, descriptor_shared_weight=0.0)
    for tuning in (off, PRODUCT):  # warm the store's tables and caches
        with tuned(tuning):
            db.search(ids[0], k=10)
    best: dict[str, list[float]] = {"off": [np.inf] * len(ids), "on": [np.inf] * len(ids)}
    for _ in range(repeats):
        for n, i in enumerate(ids):
            for name, tuning in (("off", off), ("on", PRODUCT)):
                with tuned(tuning):
                    t = time.perf_counter()
                    db.search(i, k=10)
                    best[name][n] = min(best[name][n], time.perf_counter() - t)
    return _paired(best["off"], best["on"])


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.stage_cost",
                                 description=__doc__.split("\n")[0])  # fmt: skip
    ap.add_argument("--models", type=int, default=20, help="web validation models timed")
    ap.add_argument("--searches", type=int, default=3, help="repeats of every search (min)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    got = {"ingest": ingest_rows(args.models), "search": search_rows(args.searches)}
    i, s = got["ingest"], got["search"]
    print(format_table("ingest CPU s per model and search wall s (medians)",
                       ("what", "baseline", "measured", "x (paired median)"), [
        ["ingest, per-view framing (sphere)", f"{i['baseline']:.3f}", f"{i['measured']:.3f}",
         f"{i['ratio_median']:.3f}"],
        ["  of which light fields", f"{i['light_field_baseline']:.3f}",
         f"{i['light_field_measured']:.3f}", ""],
        ["search, stored-distance neighbours (off)", f"{s['baseline'] * 1e3:.2f} ms",
         f"{s['measured'] * 1e3:.2f} ms", f"{s['ratio_median']:.3f}"],
    ]))  # fmt: skip
    out = args.out or RESULTS / "stage_cost.json"
    write_json(out, got)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
