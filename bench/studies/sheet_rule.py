"""What the local sheet rule (``MDBDConfig.sheet_rule="local"``) changes, and what it costs.

Usage (from the repository root)::

    export SHAPEDB_BENCH_CACHE=/work/bench_cache
    nice -n 5 python -m bench.studies.sheet_rule --split validation --models 12
    nice -n 5 python -m bench.studies.sheet_rule --sets generic --models 8   # quicker

For each set of the split: how many models the local rule thickens locally (their field
and decomposition change; the others are bit-identical). Then the CPU seconds of the
whole ingest work (:func:`bench.studies.field_vector_cost.ingest_cpu`: load, decomposition with
the field's inside, descriptor, light fields, field vector) under ``sheet_rule="whole"``
(the baseline) and ``"local"``, interleaved model by model, on ``--models`` models the
rule changes and as many it leaves alone, from generic and web: medians and the median
of the per-model ratios. Written to bench/results/studies/sheet_rule_<split>.json.
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
from bench.sets.datasets import articulated as figures
from bench.sets.datasets import capod, generic, parts, web
from bench.studies.field_vector_cost import ingest_cpu
from bench.support.cached import SETS
from shapedb.config.core import Config, MDBDConfig
from shapedb.geometry.sheet import LocallyThickened
from shapedb.mdbd.decomposition import prepare_field

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
STORES = {"whole": Config().with_options(sheet_rule="whole"), "local": Config()}


def _models(name: str, split: str) -> list[Any]:
    if name == "people":
        from bench.representations import build

        (ds,) = build(["people"], split)
        return list(ds.models)
    sets = {"generic": generic, "web": web, "capod": capod, "figures": figures, "parts": parts}
    return list(sets[name]().split(split).models)


def changed(model: Any) -> bool:
    """Whether the local rule thickens ``model`` locally (its field changes)."""
    cfg = MDBDConfig()
    prep = prepare_field(variant_geometry(model, "mesh", cfg), cfg)
    return isinstance(prep.local, LocallyThickened)


def run(split: str, k: int, sets: Sequence[str] = SETS) -> dict[str, Any]:
    """Counts per set, then paired ingest CPU on ``k`` changed and ``k`` unchanged models."""
    from concurrent.futures import ProcessPoolExecutor

    counts: dict[str, Any] = {}
    pools: dict[bool, list[Any]] = {True: [], False: []}
    for name in sets:
        ms = _models(name, split)
        with ProcessPoolExecutor(2) as ex:
            flags = list(ex.map(changed, ms, chunksize=2))
        counts[name] = {"models": len(ms), "changed": int(sum(flags))}
        print(f"  {name} {split}: {sum(flags)} of {len(ms)} thickened locally", flush=True)
        if name in ("generic", "web"):
            for m, f in zip(ms, flags, strict=True):
                pools[f].append(m)
    rng = np.random.default_rng(0)
    rows = []
    for kind, ms in pools.items():
        pick = [ms[i] for i in sorted(rng.choice(len(ms), min(k, len(ms)), replace=False))]
        ingest_cpu(pick[0], STORES["local"])  # compile and warm the caches
        for m in pick:
            sec = {label: ingest_cpu(m, cfg)[0] for label, cfg in STORES.items()}
            rows.append({"model": m.name, "changed": kind, **sec})
            print(f"  {m.name} ({'changed' if kind else 'unchanged'}): "
                  f"{sec['whole']:.2f} s / {sec['local']:.2f} s", flush=True)  # fmt: skip
    table = []
    for kind in (True, False):
        rs = [r for r in rows if r["changed"] == kind]
        table.append([
            "changed" if kind else "unchanged", len(rs),
            f"{np.median([r['whole'] for r in rs]):.2f}",
            f"{np.median([r['local'] for r in rs]):.2f}",
            f"{np.median([r['local'] / r['whole'] for r in rs]):.3f}",
        ])  # fmt: skip
    print(format_table(f"sheet rule, {split}: models thickened locally",
                       ("set", "models", "changed"),
                       [[n, c["models"], c["changed"]] for n, c in counts.items()]))  # fmt: skip
    print(format_table("ingest CPU per model (generic and web), medians",
                       ("models", "n", "whole s", "local s", "local / whole"), table))  # fmt: skip
    return {"split": split, "counts": counts, "rows": rows, "time": time.strftime("%Y-%m-%d")}


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.sheet_rule",
                                 description=__doc__.split("\n")[0])  # fmt: skip
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--models", type=int, default=12, help="models timed of each kind")
    ap.add_argument("--sets", nargs="+", default=list(SETS), choices=SETS)
    args = ap.parse_args(argv)
    got = run(args.split, args.models, args.sets)
    out = RESULTS / f"sheet_rule_{args.split}.json"
    write_json(out, got)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
