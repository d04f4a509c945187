"""Light fields from a longer packing: what continuing the greedy packing costs at ingest.

The decomposition keeps its ``MDBDConfig.n_balls`` balls; with ``LightFieldConfig.n_balls``
above that, ingest continues the packing on the same field (no off-grid refinement for
the tail, :func:`shapedb.mdbd.decomposition.decompose`'s ``tail_balls``) and renders the light fields
of all the balls (:func:`shapedb.signature.lightfield.decomposition_light_field`).

``--cost K``: for K web validation models (one per class first), in one process, the
CPU seconds of what ingest does per model in a store that keeps light fields (load,
decompose, feature, light fields), with today's light fields (the decomposition's
balls: the baseline, measured in the same run, interleaved per model) and with each
``--n-balls``; medians of the per-model ratios. With the shared cache's refined
decompositions of ``--n-balls`` balls (``bench.common.cache_path``), also how far the
light fields of the unrefined tail are from those of the refined packing of as many
balls, against how far today's light fields are from them (``light_field_distance``).

Default: per set, the split decomposed with ``max(--n-balls)`` balls in all (cached
under ``$SHAPEDB_BENCH_CACHE/lightfield_pack``; the tail's first balls by radius stand
for the shorter lengths), the product's light fields (64 px, 3 fields) alone per
length, today's (the cached decompositions) and the mesh light field descriptor, in the
same run. Through the product's stage: ``python -m bench.studies.lightfield_gate --lf-n-balls N``.

Usage::

    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 nice -n 5 \\
        python -m bench.studies.lightfield_pack --cost 12 --n-balls 768 1024 1536
    nice -n 5 python -m bench.studies.lightfield_pack --split validation --refined

Results go to bench/results/studies/lightfield_pack_cost.json and
lightfield_pack_<split>.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import (
    Balls,
    cache_path,
    format_table,
    load_balls,
    retrieval_scores,
    variant_geometry,
    write_json,
)
from bench.sets.datasets import CACHE_DIR, Dataset, web
from bench.support.cached import CHOICES, SETS, load
from bench.support.packings import longer
from shapedb.config.core import Config, MDBDConfig, RerankConfig
from shapedb.config.lightfield import product_light_field

FloatArray = NDArray[np.float64]
OUT = Path(__file__).resolve().parents[1] / "results" / "studies"
#: The engine whose cache keys hold the refined N-ball decompositions (bench.support.cached).
REFINED_ENGINE = "2ba8d98"


def store_config(n_balls: int) -> Config:
    """A store that keeps light fields, from a packing of ``n_balls`` (0: today's)."""
    lf = dataclasses.replace(product_light_field(), n_balls=n_balls)
    return Config(rerank=RerankConfig(scorer="lightfield"), light_field=lf)


def ingest_cpu(model: Any, config: Config) -> tuple[float, dict[str, float], Any, Any]:
    """CPU seconds of one model's ingest work under ``config``, its stage timings,
    light fields and decomposition."""
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.kernel import features
    from shapedb.signature.lightfield import decomposition_light_field

    c0 = time.process_time()
    geometry = variant_geometry(model, "mesh", config.mdbd)
    d = decompose(geometry, config=config.mdbd, tail_balls=config.light_field_tail)
    features(d, config)
    t = time.process_time()
    lf = decomposition_light_field(d, config.light_field)
    timings = dict(d.timings)
    timings["light_field"] = time.process_time() - t
    return time.process_time() - c0, timings, lf, d


def _pick(k: int) -> list[Any]:
    ds = web().split("validation")
    labels = list(ds.labels)
    first = [i for i, lab in enumerate(labels) if labels.index(lab) == i]
    rest = [i for i in range(len(ds)) if i not in set(first)]
    return [ds.models[i] for i in (first + rest)[:k]]


def cost(k: int, n_balls: Sequence[int]) -> dict[str, Any]:
    """Per-model ingest CPU with longer packings against today's, and their light fields'
    distance to the refined packing's (where cached)."""
    from shapedb.signature.lightfield import light_field_distance, record_light_field

    models = _pick(k + 1)
    ingest_cpu(models[0], store_config(max(n_balls)))  # compile and warm caches, untimed
    models = models[1:]
    rows: list[dict[str, Any]] = []
    for m in models:
        row: dict[str, Any] = {"model": m.name}
        lfs = {}
        for n in (0, *n_balls):
            sec, timings, lf, d = ingest_cpu(m, store_config(n))
            row[str(n)] = {"cpu": sec, "timings": timings, "balls": d.n_balls,
                           "tail": int(len(d.tail_radii))}  # fmt: skip
            lfs[n] = lf
        for n in n_balls:
            path = cache_path(m, "mesh", MDBDConfig(n_balls=n), engine_commit=REFINED_ENGINE)
            if path.exists():
                b = load_balls(path)
                ref = record_light_field(b.centers, b.radii, product_light_field())
                dist = light_field_distance(np.stack([ref, lfs[n], lfs[0]]))
                row[str(n)]["to_refined"] = float(dist[0, 1])
                row[str(n)]["today_to_refined"] = float(dist[0, 2])
        rows.append(row)
        print(f"  {m.name}: " + ", ".join(f"{n}: {row[str(n)]['cpu']:.2f} s"
                                          for n in (0, *n_balls)), flush=True)  # fmt: skip
    summary: dict[str, Any] = {"0": {"cpu": float(np.median([r["0"]["cpu"] for r in rows]))}}
    table = [["today (decomposition's balls)", f"{summary['0']['cpu']:.2f}", "1.000", "", "", ""]]
    for n in n_balls:
        ratio = [r[str(n)]["cpu"] / r["0"]["cpu"] for r in rows]
        extra_dec = [
            r[str(n)]["timings"]["decompose"] - r["0"]["timings"]["decompose"] for r in rows
        ]
        extra_lf = [r[str(n)]["timings"]["light_field"] - r["0"]["timings"]["light_field"]
                    for r in rows]  # fmt: skip
        near = [r[str(n)]["to_refined"] / max(r[str(n)]["today_to_refined"], 1e-12)
                for r in rows if "to_refined" in r[str(n)]]  # fmt: skip
        s = {
            "cpu": float(np.median([r[str(n)]["cpu"] for r in rows])),
            "ratio_median": float(np.median(ratio)),
            "ratio_of_sums": float(
                sum(r[str(n)]["cpu"] for r in rows) / sum(r["0"]["cpu"] for r in rows)
            ),  # fmt: skip
            "extra_packing_s": float(np.median(extra_dec)),
            "extra_light_field_s": float(np.median(extra_lf)),
            "tail_balls": float(np.median([r[str(n)]["tail"] for r in rows])),
            "to_refined_over_today": float(np.median(near)) if near else None,
        }
        summary[str(n)] = s
        table.append([f"n_balls {n}", f"{s['cpu']:.2f}", f"{s['ratio_median']:.3f}",
                      f"{s['extra_packing_s']:.3f}", f"{s['extra_light_field_s']:.3f}",
                      "" if s["to_refined_over_today"] is None
                      else f"{s['to_refined_over_today']:.3f}"])  # fmt: skip
    print(format_table(
        f"ingest CPU per model, light-field store, {len(rows)} web validation models (medians)",
        ("light fields from", "CPU s", "x today", "+packing s", "+light fields s",
         "LF dist to refined / today's"), table,
    ))  # fmt: skip
    return {"models": len(rows), "summary": summary, "rows": rows}


def _prefix(b: Balls, main: int, n: int) -> Balls:
    """The decomposition's balls and the first ``n - main`` tail balls (by radius)."""
    k = max(n, main)
    return Balls(b.centers[:k], b.radii[:k], b.edges, b.spacing, 0.0)


def lf_matrix(name: str, split: str, ds: Dataset, balls: list[Balls], tag: str) -> FloatArray:
    """Light field distances (product light fields) of ``balls``, cached by ``tag``."""
    from shapedb.signature.lightfield import light_field_distance, record_light_field

    code = (
        Path(__file__).resolve().parents[2] / "shapedb" / "signature" / "lightfield.py"
    ).read_bytes()
    names = "\n".join(m.name + m.source for m in ds.models).encode()
    key = hashlib.sha256(code + names + tag.encode()).hexdigest()[:16]
    path = CACHE_DIR / "lightfield_pack" / f"d_{name}_{split}_{key}.npy"
    if path.exists():
        return np.load(path)
    cfg = product_light_field()
    lf = np.stack([record_light_field(b.centers, b.radii, cfg) for b in balls])
    d = np.asarray(light_field_distance(lf), np.float64)
    np.save(path, d)
    return d


def _fmt(s: dict[str, float]) -> str:
    return f"{s['nn']:.3f}/{s['first_tier']:.3f}/{s['dcg']:.3f}"


def retrieval(
    split: str, datasets: Sequence[str], n_balls: Sequence[int], workers: int, refined: bool
) -> dict[str, Any]:
    """The light fields alone of each packing length, today's (512, cached) and the mesh LFD."""
    from bench.support.lightfield import lfd_matrix

    tail = max(n_balls) - MDBDConfig().n_balls
    table: dict[str, dict[str, Any]] = {}

    def put(row: str, name: str, d: FloatArray, labels: Sequence[str]) -> None:
        table.setdefault(row, {})[name] = retrieval_scores(-d, np.asarray(labels))

    for name in datasets:
        t0 = time.perf_counter()
        ds, balls, main = longer(name, split, tail, workers=workers)
        today_ds, today = load(name, split)
        pos = {m.name: i for i, m in enumerate(today_ds.models)}
        today = [today[pos[m.name]] for m in ds.models]
        labels = list(ds.labels)
        d0 = lf_matrix(name, split, ds, today, "today")
        put("light fields, 512 (today)", name, d0, labels)
        mats = {}
        for n in n_balls:
            mats[n] = lf_matrix(name, split, ds, [_prefix(b, k, n) for b, k in
                                                 zip(balls, main, strict=True)], f"n{n}t{tail}")  # fmt: skip
            put(f"light fields, {n}", name, mats[n], labels)
        if refined:
            paths = [cache_path(m, "mesh", MDBDConfig(n_balls=1024), engine_commit=REFINED_ENGINE)
                     for m in ds.models]  # fmt: skip
            if all(p.exists() for p in paths):
                put("light fields, 1024 all refined", name,
                    lf_matrix(name, split, ds, [load_balls(p) for p in paths], "refined1024"),
                    labels)  # fmt: skip
        if name != "people":
            put("mesh LFD", name, lfd_matrix(ds), labels)
        print(f"  {name} {split}: {len(ds)} models ({time.perf_counter() - t0:.0f} s)", flush=True)
    rows = [[k, *(_fmt(v[n]) if n in v else "" for n in datasets)] for k, v in table.items()]
    print(format_table(f"light fields of longer packings, {split} (NN/1-T/DCG)",
                       ("row", *datasets), rows))  # fmt: skip
    return table


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.lightfield_pack")
    ap.add_argument("--cost", type=int, default=0, help="time N web validation models")
    ap.add_argument("--n-balls", type=int, nargs="+", default=[768, 1024, 1536, 2048])
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(SETS), choices=CHOICES)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--refined", action="store_true",
                    help="also the cached refined 1024-ball packings (where all cached)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None, help="JSON path")
    args = ap.parse_args(argv)
    if args.cost:
        got = cost(args.cost, args.n_balls)
        write_json(args.out or OUT / "lightfield_pack_cost.json", got)
    else:
        got = retrieval(args.split, args.datasets, args.n_balls, args.workers, args.refined)
        write_json(args.out or OUT / f"lightfield_pack_{args.split}.json", got)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
