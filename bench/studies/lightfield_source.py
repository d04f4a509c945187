"""What the light fields see (``LightFieldConfig.source``): the balls or the field's inside.

Usage (from the repository root)::

    python -m bench.studies.lightfield_source                         # validation, every set, alone
    python -m bench.studies.lightfield_source --variants              # web validation: fields, px, depth
    python -m bench.studies.lightfield_source --variants "field, 3 x 128 px"   # every set
    python -m bench.studies.lightfield_source --split test --datasets web webplus
    python -m bench.studies.lightfield_source --cost 40               # ingest CPU per model

Default: per set of the split, the light fields alone (every shape queries the rest of
its set by the light field distance; NN / 1-T / DCG) of the mesh (the light field
descriptor of ``bench/lightfield.py``, 10 light fields; not on the people, whose
meshes are made on the fly), of the balls (:data:`BALLS`, the product's before the field's: the packing continued to
2048 balls, :func:`bench.support.packings.light_field_balls`) and of the
field's inside at 3 light fields of 64 px (``source="field"``, cached by
:mod:`bench.support.inside_fields`), in the same run. ``--variants``: the field's inside at 3
and 10 light fields, 64 and 128 px, and with depth images (``depth_weight``); named,
only those (on every set unless ``--datasets``). ``--classes``: also each row's NN and
first tier on the named classes.

``--cost N``: per-model ingest CPU (this process: load, decompose, descriptor and light
fields, as ``ingest.pipeline.build_record`` does them) of N web validation models in a
store of the product's balls (baseline, measured in the same run, interleaved model by
model) and of ``source="field"``; medians and the median of the per-model ratios.

Distance matrices are cached under ``$SHAPEDB_BENCH_CACHE/lightfield_source``. Results go
to bench/results/studies/lightfield_source_<split>.json (``_variants``, ``_cost``).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import format_table, per_query, retrieval_scores, write_json
from bench.sets.datasets import CACHE_DIR, Dataset
from bench.studies.field_vector_cost import ingest_cpu
from bench.studies.field_vector_cost import models as first_models
from bench.support import inside_fields
from bench.support.cached import CHOICES, SETS, load, model_key
from bench.support.packings import light_field_balls
from shapedb.config.core import Config, LightFieldConfig
from shapedb.signature.lightfield import light_field_distance, record_light_field

FloatArray = NDArray[np.float64]
#: The product's balls are the first by radius of the packing continued to this many
#: (:func:`bench.support.packings.longer`'s ``within``, as the gate's product rows were measured).
WITHIN = 4096
RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
#: The balls' light fields the product kept before the field's (``lf_source=balls``): 3
#: light fields of 64 px of the packing continued to 2048 balls; the baseline of every run.
BALLS = LightFieldConfig(n_fields=3, resolution=64, n_balls=2048, source="balls")
#: ``--variants``: the field's inside at other light-field settings (over 3 x 64 px).
VARIANTS: dict[str, dict[str, Any]] = {
    "field, 3 x 64 px": {},
    "field, 10 x 64 px": {"n_fields": 10},
    "field, 3 x 128 px": {"resolution": 128},
    "field, 10 x 128 px": {"n_fields": 10, "resolution": 128},
    "field, 3 x 64 px, depth 0.5": {"depth_weight": 0.5},
    "field, 3 x 64 px, depth 1": {"depth_weight": 1.0},
    "field, 3 x 64 px, depth 2": {"depth_weight": 2.0},
}


def _cached(tag: str, keys: Sequence[str], compute: Any) -> FloatArray:
    code = (
        Path(__file__).resolve().parents[2] / "shapedb" / "signature" / "lightfield.py"
    ).read_bytes()
    key = hashlib.sha256(code + tag.encode() + "\n".join(keys).encode()).hexdigest()[:16]
    path = CACHE_DIR / "lightfield_source" / f"{key}.npy"
    if path.exists():
        return np.load(path)
    d = np.asarray(light_field_distance(np.asarray(compute(), np.float64)))
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, d)
    return d


def matrices(
    name: str, split: str, configs: dict[str, LightFieldConfig], mesh: bool = True
) -> tuple[Dataset, dict[str, FloatArray]]:
    """A split's light field distance matrices, (n, n) each: the mesh's, then per config."""
    from bench.support.lightfield import lfd_matrix

    ds, balls = load(name, split)
    keys = [model_key(m) for m in ds.models]
    out: dict[str, FloatArray] = {}
    if mesh and name != "people":
        out["mesh LFD (10 fields)"] = lfd_matrix(ds)
    for label, lf in configs.items():
        cfg = Config().with_options(rerank="lightfield")
        cfg = dataclasses.replace(cfg, light_field=lf)
        if cfg.light_field_inside:
            tag = f"{name}|{split}|{lf}|inside-{inside_fields.VERSION}"
            out[label] = _cached(
                tag, keys, lambda cfg=cfg: inside_fields.light_fields(name, split, ds, cfg.light_field)
            )  # fmt: skip
        else:

            def balls_lf(cfg: Config = cfg) -> NDArray[np.float32]:
                seen = light_field_balls(name, split, ds, balls, cfg, within=WITHIN)
                return np.stack(
                    [record_light_field(b.centers, b.radii, cfg.light_field) for b in seen]
                )

            out[label] = _cached(f"{name}|{split}|{lf}|balls|w{WITHIN}", keys, balls_lf)
    return ds, out


def alone(
    split: str,
    datasets: Sequence[str],
    variants: Sequence[str] | None,
    classes: Sequence[str] = (),
) -> dict[str, Any]:
    """Light fields alone per set: the mesh's, the product's balls, the field's inside
    (at the product's settings, or at each of ``variants``, keys of :data:`VARIANTS`);
    with ``classes``, also each row's NN and first tier on those classes."""
    product = BALLS
    base = dataclasses.replace(BALLS, source="field")  # 3 x 64 px; VARIANTS move from here
    configs = {f"balls (product, {product.n_balls} balls)": product}
    if variants is not None:
        pick = variants or list(VARIANTS)
        configs.update({k: dataclasses.replace(base, **VARIANTS[k]) for k in pick})
    else:
        configs["field's inside"] = base
    table: dict[str, dict[str, dict[str, float]]] = {}
    sizes = {}
    per_class: dict[str, dict[str, dict[str, float]]] = {}
    for name in datasets:
        t0 = time.perf_counter()
        ds, mats = matrices(name, split, configs)
        sizes[name] = len(ds)
        for label, d in mats.items():
            table.setdefault(label, {})[name] = retrieval_scores(-d, np.asarray(ds.labels))
        print(f"  {name}: {len(ds)} models ({time.perf_counter() - t0:.0f} s)", flush=True)
        if classes:
            got = {label: per_query(d, ds.labels) for label, d in mats.items()}
            lab = np.asarray(ds.labels)
            for c in classes:
                if (lab == c).any():
                    per_class.setdefault(f"{name}: {c}", {}).update({
                        label: {"nn": float(nn[lab == c].mean()),
                                "first_tier": float(t[lab == c].mean())}
                        for label, (nn, t) in got.items()})  # fmt: skip
    if per_class:
        labels = list(next(iter(per_class.values())))
        print(format_table(f"per class, {split} (NN / 1-T)", ("class", *labels),
                           [[c, *(f"{v[k]['nn']:.2f} / {v[k]['first_tier']:.2f}" for k in labels)]
                            for c, v in per_class.items()]))  # fmt: skip
    rows = [[label, *(f"{v[n]['nn']:.3f} / {v[n]['first_tier']:.3f} / {v[n]['dcg']:.3f}"
                      if n in v else "" for n in datasets)] for label, v in table.items()]  # fmt: skip
    print(format_table(f"light fields alone, {split} (NN / 1-T / DCG)",
                       ("source", *(f"{n} ({sizes[n]})" for n in datasets)), rows))  # fmt: skip
    return {"split": split, "sizes": sizes, "table": table, "per_class": per_class,
            "configs": {k: dataclasses.asdict(v) for k, v in configs.items()}}  # fmt: skip


def cost(k: int) -> dict[str, Any]:
    """Per-model ingest CPU of a store of the field's inside against the product's balls."""
    models = first_models(k)
    plain = Config().with_options(rerank="lightfield", fv_enabled=False)  # light fields only
    stores = {
        "balls (product)": plain.with_options(lf_source="balls", lf_resolution=64),
        "field's inside": plain.with_options(lf_source="field", lf_resolution=64),
        "field's inside, 128 px": plain.with_options(lf_source="field", lf_resolution=128),
    }
    for cfg in stores.values():  # compile and warm caches, untimed
        ingest_cpu(models[0], cfg)
    rows = []
    for m in models[1:]:
        row: dict[str, Any] = {"model": m.name}
        for label, cfg in stores.items():
            sec, timings = ingest_cpu(m, cfg)
            row[label] = {"cpu": sec, "timings": timings}
        rows.append(row)
        print(f"  {m.name}: " + ", ".join(f"{k}: {row[k]['cpu']:.2f} s" for k in stores),
              flush=True)  # fmt: skip
    base = "balls (product)"
    summary: dict[str, dict[str, float]] = {}
    table = []
    for label in stores:
        ratio = [r[label]["cpu"] / r[base]["cpu"] for r in rows]
        parts = {p: float(np.median([r[label]["timings"].get(p, 0.0) for r in rows]))
                 for p in ("sdf", "decompose", "inside", "light_field")}  # fmt: skip
        summary[label] = {"cpu": float(np.median([r[label]["cpu"] for r in rows])),
                          "ratio_median": float(np.median(ratio)),
                          "ratio_of_sums": float(sum(r[label]["cpu"] for r in rows)
                                                 / sum(r[base]["cpu"] for r in rows)),
                          **parts}  # fmt: skip
        s = summary[label]
        table.append([label, f"{s['cpu']:.3f}", f"{s['ratio_median']:.3f}",
                      f"{s['ratio_of_sums']:.3f}", f"{s['decompose']:.3f}", f"{s['inside']:.3f}",
                      f"{s['light_field']:.3f}"])  # fmt: skip
    print(format_table(
        f"ingest CPU per model, light-field store, {len(rows)} web validation models (medians)",
        ("light fields of", "CPU s", "x balls (median)", "x balls (sums)", "packing s",
         "inside s", "light fields s"), table,
    ))  # fmt: skip
    return {"models": len(rows), "summary": summary, "rows": rows}


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.lightfield_source",
                                 description=__doc__.split("\n")[0])  # fmt: skip
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=None, choices=CHOICES)
    ap.add_argument("--variants", nargs="*", default=None, choices=list(VARIANTS),
                    help="the field at these settings (none named: all; default sets: web)")  # fmt: skip
    ap.add_argument("--classes", nargs="+", default=[], help="also NN / 1-T on these classes")
    ap.add_argument("--cost", type=int, default=0, help="time N web validation models")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.cost:
        got = cost(args.cost)
        out = args.out or RESULTS / "lightfield_source_cost.json"
    else:
        names = args.datasets or (["web"] if args.variants == [] else list(SETS))
        got = alone(args.split, names, args.variants, args.classes)
        tag = "_variants" if args.variants is not None else ""
        out = args.out or RESULTS / f"lightfield_source_{args.split}{tag}.json"
    write_json(out, got)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
