"""What the field vector adds to a model's ingest (``FieldVectorConfig``, ``fv_enabled``).

Usage (from the repository root)::

    export SHAPEDB_BENCH_CACHE=/work/bench_cache
    nice -n 5 python -m bench.studies.field_vector_cost            # 20 web validation models
    nice -n 5 python -m bench.studies.field_vector_cost --models 40 --repeats 2

Per model (web validation, one model of each class first, then the rest in order): the
CPU seconds of this process for the ingest work of ``ingest.pipeline.build_record`` (load,
decomposition keeping the field's inside, descriptor, light fields and, when
``Config.stores_field_vectors``, the field vector) in a store of today's product without
field vectors (``fv_enabled=false``, the baseline) and in a new store (with them), the two
interleaved model by model and repeated (the minimum of the repeats). Printed: medians
and the median of the per-model ratios; also the field vector's own CPU over the
baseline's whole ingest. The first field vector of a process also builds the harmonics
on the angle grid (once per worker process); it is timed apart, in a warm-up on the first
model. Written to bench/results/studies/field_vector_cost.json.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, variant_geometry, write_json
from bench.support.cached import load
from shapedb.config.core import Config

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
STORES = {
    "today (fv_enabled=false)": Config().with_options(fv_enabled=False),
    "with the field vector": Config(),
}
BASE = "today (fv_enabled=false)"


def ingest_cpu(model: Any, config: Config) -> tuple[float, dict[str, float]]:
    """CPU seconds of one model's ingest work under ``config``, and each stage's."""
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.field_vector import decomposition_field_vector
    from shapedb.signature.kernel import features
    from shapedb.signature.lightfield import decomposition_light_field

    c0 = time.process_time()
    geometry = variant_geometry(model, "mesh", config.mdbd)
    d = decompose(
        geometry, config=config.mdbd, tail_balls=config.light_field_tail,
        keep_inside=config.light_field_inside,
    )  # fmt: skip
    features(d, config)
    timings = dict(d.timings)
    t = time.process_time()
    if config.stores_light_fields:
        decomposition_light_field(d, config.light_field)
    timings["light_field"] = time.process_time() - t
    t = time.process_time()
    if config.stores_field_vectors:
        decomposition_field_vector(d, config.field_vector)
    timings["field_vector"] = time.process_time() - t
    return time.process_time() - c0, timings


def models(k: int) -> list[Any]:
    """The first ``k + 1`` web validation models, one of each class first."""
    ds, _ = load("web", "validation")
    labels = list(ds.labels)
    first = [i for i, lab in enumerate(labels) if labels.index(lab) == i]
    order = first + [i for i in range(len(ds)) if i not in set(first)]
    return [ds.models[i] for i in order[: k + 1]]


def run(k: int, repeats: int) -> dict[str, Any]:
    """Per-model ingest CPU with and without the field vector; medians and ratios."""
    chosen = models(k)
    warm: dict[str, float] = {}
    for label, cfg in STORES.items():  # compile, load caches, build the harmonic table
        _, timings = ingest_cpu(chosen[0], cfg)
        warm[label] = timings["field_vector"]
    rows = []
    for m in chosen[1:]:
        row: dict[str, Any] = {"model": m.name}
        for _ in range(repeats):
            for label, cfg in STORES.items():
                sec, timings = ingest_cpu(m, cfg)
                if label not in row or sec < row[label]["cpu"]:
                    row[label] = {"cpu": sec, "timings": timings}
        rows.append(row)
        print(f"  {m.name}: " + ", ".join(f"{s}: {row[s]['cpu']:.3f} s" for s in STORES),
              flush=True)  # fmt: skip
    summary: dict[str, dict[str, float]] = {}
    for label in STORES:
        cpu = [r[label]["cpu"] for r in rows]
        fv = [r[label]["timings"]["field_vector"] for r in rows]
        summary[label] = {
            "cpu": float(np.median(cpu)),
            "ratio_median": float(
                np.median([c / r[BASE]["cpu"] for c, r in zip(cpu, rows, strict=True)])
            ),
            "ratio_of_sums": float(sum(cpu) / sum(r[BASE]["cpu"] for r in rows)),
            "field_vector": float(np.median(fv)),
            "field_vector_share": float(
                np.median([f / r[BASE]["cpu"] for f, r in zip(fv, rows, strict=True)])
            ),
            "light_field": float(np.median([r[label]["timings"]["light_field"] for r in rows])),
            "first_field_vector": warm[label],
        }
    table = [
        [label, f"{s['cpu']:.3f}", f"{s['ratio_median']:.3f}", f"{s['ratio_of_sums']:.3f}",
         f"{s['light_field']:.3f}", f"{s['field_vector']:.4f}", f"{s['field_vector_share']:.3f}",
         f"{s['first_field_vector']:.2f}"]
        for label, s in summary.items()
    ]  # fmt: skip
    print(format_table(
        f"ingest CPU per model, {len(rows)} web validation models (medians; min of {repeats})",
        ("store", "CPU s", "x today (median)", "x today (sums)", "light fields s",
         "field vector s", "fv / today", "first fv s"), table,
    ))  # fmt: skip
    return {"models": len(rows), "repeats": repeats, "summary": summary, "rows": rows}


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.field_vector_cost",
                                 description=__doc__.split("\n")[0])  # fmt: skip
    ap.add_argument("--models", type=int, default=20, help="web validation models timed")
    ap.add_argument("--repeats", type=int, default=1, help="runs per model and store (min)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    got = run(args.models, args.repeats)
    out = args.out or RESULTS / "field_vector_cost.json"
    write_json(out, got)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
