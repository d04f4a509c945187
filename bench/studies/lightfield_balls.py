"""The light field descriptor computed from the balls, alone and fused with version 4.

For each set's split (meshes), from the cached decompositions (nothing is decomposed:
a decomposition missing under today's engine key is read under the keys of the
engines in :data:`bench.support.cached.ENGINE_COMMITS`, which differ only where the sets are unaffected):

* ``v4``: shapedb's default descriptor, L1 in version 4's calibrated units;
* ``lfb <config>``: :func:`shapedb.signature.lightfield.ball_light_field` of the balls under
  each configuration of ``--configs`` (``res/fields/depth weight``), distance
  :func:`shapedb.signature.lightfield.light_field_distance`;
* fusions of v4 with one light field configuration (``--fuse``):

  - ``sum w``: ``d4 + w * dl / typical`` (``typical``: the geometric mean over the sets
    of the median pairwise light field distance, measured on the split unless given);
  - ``rank w``: reciprocal rank fusion, ``1 / (60 + rank4) + w / (60 + rankl)``;
  - ``adapt w``: ``d4 + w * a_q^p * dl / typical`` with ``a_q`` the overlap of the
    query's ``--top`` nearest under v4 and under the light field (query-adaptive,
    ``p = --power``);
  - ``adrank w``: rank fusion with the light field's term gated the same way,
    ``1 / (60 + rank4) + w * a_q^p / (60 + rankl)``;
  - with ``--ceiling c`` the gate of ``adapt`` and ``adrank`` is also multiplied by
    ``clip((c - s_q) / --ramp, 0, 1)``, ``s_q`` the median of ``dl / typical`` over the
    median of ``d4`` among the query's 100 nearest by v4 (the candidates a re-ranking
    stage would see): the light field's spread relative to v4's, high where every
    silhouette looks alike (the people, the figures);

* with ``--queries pointcloud`` (or another cached variant): the queries are that
  variant's decompositions, compared with every model's mesh (its own mesh left out, as
  :func:`bench.common.retrieval_scores` leaves out the diagonal);
* with ``--baselines``: the mesh light field descriptor (``bench.support.lightfield``) and D2
  (``bench.support.baselines``) in the same run.

Per row NN / 1-T / DCG per set and the objective (mean over the sets of (NN + 1-T +
DCG) / 3). A fusion passes when no set's NN, 1-T or DCG is more than two queries below
v4. Usage::

    python -m bench.studies.lightfield_balls                    # validation, all six sets
    python -m bench.studies.lightfield_balls --split test --baselines --typical 17.2 \\
        --fuse 64/3/0 --configs 64/10/0 --sum 0.5 --rank --adapt 8 --adrank 2

``--cost N`` times the decomposition, version 4 and the light fields of N models per
set (CAPOD, generic, web) in one process, and the re-ranking of 100 candidates.
Light field distance matrices are cached under ``$SHAPEDB_BENCH_CACHE/lightfield_balls``
(keyed by the set's models, the configuration and the code of shapedb/signature/lightfield.py).
Results go to bench/results/studies/lightfield_balls_<split>.json.
"""

from __future__ import annotations

import argparse
import hashlib
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import (
    Balls,
    class_nn,
    format_table,
    retrieval_scores,
    write_json,
)
from bench.sets.datasets import CACHE_DIR, Dataset, capod, generic, mesh_arrays, web
from bench.support.cached import CHOICES, SETS, load
from bench.support.tuning import unit_of
from shapedb.config.core import Config, DescriptorConfig, LightFieldConfig
from shapedb.signature.descriptor import LAYOUTS
from shapedb.signature.lightfield import ball_light_field, light_field_distance

FloatArray = NDArray[np.float64]
OUT = Path(__file__).resolve().parents[1] / "results" / "studies"
TOP = 5


def fill_config(text: str, base: LightFieldConfig | None = None) -> LightFieldConfig:
    """``plain`` / ``edges`` / ``dilate<p>`` / ``close<p>`` joined by ``+`` -> config."""
    from dataclasses import replace

    cfg = base or LightFieldConfig(n_fields=3, resolution=64)
    for part in text.split("+"):
        if part == "plain":
            continue
        if part == "edges":
            cfg = replace(cfg, edges=True)
        elif part.startswith("dilate"):
            cfg = replace(cfg, dilate_px=float(part[6:]))
        elif part.startswith("close"):
            cfg = replace(cfg, close_px=int(part[5:]))
        else:
            raise ValueError(f"fill {part!r} is unknown")
    return cfg


def parse_config(text: str) -> LightFieldConfig:
    """``res/fields/depth[/fill]`` -> :class:`LightFieldConfig`.

    ``fill`` as in :func:`fill_config` (e.g. ``edges+close1``).
    """
    res, fields, depth, *fill = text.split("/")
    cfg = LightFieldConfig(resolution=int(res), n_fields=int(fields), depth_weight=float(depth))
    return fill_config(fill[0], cfg) if fill else cfg


def _l1(x: FloatArray) -> FloatArray:
    out = np.empty((len(x), len(x)))
    for i in range(len(x)):
        out[i] = np.abs(x - x[i]).sum(axis=1)
    return out


def v4_distances(balls: list[Balls], queries: list[Balls] | None = None) -> FloatArray:
    """Version 4's L1 distances (queries x balls) in its calibrated units."""
    from bench.support.features import kernel_features

    cfg = Config(descriptor=DescriptorConfig(version=4))
    f = kernel_features(balls, cfg)
    cal = np.log(10.0) / sum(b[3] for b in LAYOUTS[4])
    if queries is None:
        return _l1(f) / cal
    q = kernel_features(queries, cfg)
    return np.abs(q[:, None, :] - f[None, :, :]).sum(axis=-1) / cal


def light_field_matrix(
    name: str,
    ds: Dataset,
    balls: list[Balls],
    text: str,
    queries: list[Balls] | None = None,
    variant: str = "mesh",
) -> tuple[FloatArray, float, float]:
    """Ball light field distances (queries x balls; cached), CPU s per model and of the distances."""
    code = (
        Path(__file__).resolve().parents[2] / "shapedb" / "signature" / "lightfield.py"
    ).read_bytes()
    key = hashlib.sha256(
        code
        + text.encode()
        + "\n".join(m.name + m.source for m in ds.models).encode()
        + (b"" if queries is None else variant.encode())
    ).hexdigest()[:16]
    path = CACHE_DIR / "lightfield_balls" / f"{name}_{key}.npz"
    if path.exists():
        z = np.load(path)
        return z["d"], float(z["per_model"]), float(z["dist_s"])
    cfg = parse_config(text)
    t = time.process_time()
    lf = np.stack([ball_light_field(b.centers, b.radii, cfg, edges=b.edges) for b in balls])
    per_model = (time.process_time() - t) / len(balls)
    t = time.process_time()
    if queries is None:
        d = light_field_distance(lf)
    else:
        lq = np.stack([ball_light_field(b.centers, b.radii, cfg, edges=b.edges) for b in queries])
        d = light_field_distance(lq, lf)
    dist_s = time.process_time() - t
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, d=d, per_model=per_model, dist_s=dist_s)
    return d, per_model, dist_s


def mesh_baselines(ds: Dataset) -> dict[str, FloatArray]:
    """Mesh light field descriptor and D2 distances of the split's models."""
    from bench.support.baselines import D2Config, d2_descriptor
    from bench.support.lightfield import LFDConfig, lfd_descriptor, lfd_distance

    arrays = [mesh_arrays(m) for m in ds.models]
    lfd = np.stack([lfd_descriptor(v, f, LFDConfig()) for v, f in arrays])
    d2 = np.stack([d2_descriptor(v, f, D2Config(n_pairs=262144)) for v, f in arrays])
    return {"LFD (mesh)": lfd_distance(lfd), "D2 (mesh)": _l1(d2)}


def _ranks(d: FloatArray) -> FloatArray:
    r = np.empty_like(d)
    order = np.argsort(d, axis=1, kind="stable")
    np.put_along_axis(r, order, np.arange(d.shape[1], dtype=np.float64)[None, :], axis=1)
    return r


def overlap(d4: FloatArray, dl: FloatArray, top: int = TOP) -> FloatArray:
    """(n,) share of each query's ``top`` nearest (itself left out) common to both distances."""
    n = len(d4)
    big = np.eye(n) * 1e300
    a = np.argsort(d4 + big, axis=1, kind="stable")[:, :top]
    b = np.argsort(dl + big, axis=1, kind="stable")[:, :top]
    return np.array([len(set(a[i]) & set(b[i])) / top for i in range(n)])


def spread(d4: FloatArray, dl: FloatArray, typical: float, candidates: int = 100) -> FloatArray:
    """(n,) median ``dl / typical`` over median ``d4`` among each query's nearest by ``d4``."""
    n = len(d4)
    near = np.argsort(d4 + np.eye(n) * 1e300, axis=1, kind="stable")[:, : min(candidates, n - 1)]
    num = np.median(np.take_along_axis(dl, near, axis=1), axis=1) / typical
    return num / np.maximum(np.median(np.take_along_axis(d4, near, axis=1), axis=1), 1e-300)


def fuse(
    kind: str,
    w: float,
    d4: FloatArray,
    dl: FloatArray,
    typical: float,
    top: int = TOP,
    power: float = 3.0,
    ceiling: float = 0.0,
    ramp: float = 0.02,
) -> FloatArray:
    """A fused distance (rows are queries)."""
    if kind == "sum":
        return d4 + w * dl / typical
    if kind == "rank":
        return -(1.0 / (60.0 + _ranks(d4)) + w / (60.0 + _ranks(dl)))
    if kind in ("adapt", "adrank"):
        a = overlap(d4, dl, top) ** power
        if ceiling > 0:
            a = a * np.clip((ceiling - spread(d4, dl, typical)) / ramp, 0.0, 1.0)
    if kind == "adapt":
        return d4 + w * a[:, None] * dl / typical
    if kind == "adrank":
        return -(1.0 / (60.0 + _ranks(d4)) + w * a[:, None] / (60.0 + _ranks(dl)))
    raise ValueError(f"fusion {kind!r} is unknown")


def gate_stats(d4: FloatArray, dl: FloatArray, typical: float, top: int, power: float,
               ceiling: float, ramp: float) -> dict[str, float]:  # fmt: skip
    """How open the adaptive gate of ``adapt`` / ``adrank`` is over a set's queries.

    Returns the median spread ``s_q`` (:func:`spread`), the shares of queries whose
    ceiling factor is above 0 and equal to 1 (both 1 without a ceiling), the mean
    overlap term ``a_q^p`` and the mean gate (their product).
    """
    a = overlap(d4, dl, top) ** power
    s = spread(d4, dl, typical)
    c = np.clip((ceiling - s) / ramp, 0.0, 1.0) if ceiling > 0 else np.ones(len(s))
    return {"median_spread": float(np.median(s)), "ceiling_open": float(np.mean(c > 0)),
            "ceiling_full": float(np.mean(c >= 1)), "mean_overlap_term": float(np.mean(a)),
            "mean_gate": float(np.mean(a * c))}  # fmt: skip


def cost(per_set: int, text: str, candidates: int = 100) -> dict[str, dict[str, float]]:
    """Median CPU seconds per model: decomposition, v4, ball light fields; re-ranking K.

    Decomposes the first ``per_set`` validation models (one per class) of CAPOD,
    generic and web in this process; the re-ranking time is one query's
    :func:`light_field_distance` against ``candidates`` light fields.
    """
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.mdbd.decomposition import decompose
    from shapedb.mdbd.graph import ContactGraph
    from shapedb.signature.descriptor import describe
    from shapedb.signature.lightfield import light_field_dim

    cfg = parse_config(text)
    out = {}
    for ds in (capod().split("validation"), generic().split("validation"),
               web().split("validation")):  # fmt: skip
        rows, fields = [], []
        for m in ds.head(per_class=1).models[:per_set]:
            t = time.process_time()
            d = decompose(TriangleMesh(*mesh_arrays(m)))
            td = time.process_time() - t
            t = time.process_time()
            describe(ContactGraph(d.centers, d.radii, d.edges), 4)
            t4 = time.process_time() - t
            t = time.process_time()
            fields.append(ball_light_field(d.centers, d.radii, cfg, edges=d.edges))
            rows.append((td, t4, time.process_time() - t))
        td, t4, tl = np.median(np.asarray(rows), axis=0)
        bank = np.stack([fields[i % len(fields)] for i in range(candidates)])
        t = time.process_time()
        for q in fields:
            light_field_distance(q[None], bank)
        tq = (time.process_time() - t) / len(fields)
        out[ds.name] = {"decompose": td, "v4": t4, "light_field": tl, "extra": tl / (td + t4),
                        f"rerank_{candidates}": tq,
                        "bytes_float32": 4 * cfg.n_fields * 10 * light_field_dim(cfg)}  # fmt: skip
        print(f"{ds.name}: median CPU s decompose {td:.3f}, v4 {t4:.4f}, light fields {tl:.4f} "
              f"(+{tl / (td + t4):.1%}); re-rank {candidates} candidates {tq * 1e3:.1f} ms; "
              f"{out[ds.name]['bytes_float32']} bytes (float32)")  # fmt: skip
    return out


def check_product(datasets: Sequence[str], split: str) -> dict[str, Any]:
    """Queries the product's ``"lightfield"`` scorer ranks exactly as :func:`fuse` does.

    With every shape a candidate (K = n), per set: light fields in float64 and in float32
    as a store keeps them; returns ``{set: {kind: {"identical_rankings", "queries"}}}``.
    """
    from bench.studies.lightfield_rerank import LEGACY, index_of, rankings
    from bench.support.features import kernel_features
    from bench.support.tuning import configure
    from shapedb.signature.lightfield import ball_light_field

    out: dict[str, Any] = {}
    for name in datasets:
        _, balls = load(name, split)
        v4 = kernel_features(balls, Config())
        whole = configure(
            Config().with_options(rerank="lightfield"), {"lf_candidates": len(v4), **LEGACY}
        )
        d4 = np.abs(v4[:, None, :] - v4[None, :, :]).sum(-1)
        d4 /= np.log(10.0) / sum(b[3] for b in LAYOUTS[4])
        f = whole.tuning
        spec = whole.config.light_field
        exact = np.stack([ball_light_field(b.centers, b.radii, spec, edges=b.edges)
                          for b in balls])  # fmt: skip
        for kind, fields in (("float64", exact), ("float32", exact.astype(np.float32))):
            fields = fields.astype(np.float64)
            study = np.argsort(
                fuse("adrank", f.weight, d4, light_field_distance(fields), unit_of(f),
                     f.neighbours, whole.power, f.ceiling, f.ramp), axis=1, kind="stable",
            )  # fmt: skip
            got = rankings(index_of(v4), whole, fields)
            same = int(np.all(got == study, axis=1).sum())
            out.setdefault(name, {})[kind] = {"identical_rankings": same, "queries": len(v4)}
        print(f"  {name}: {out[name]}", flush=True)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.lightfield_balls")
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(SETS), choices=CHOICES)
    ap.add_argument("--configs", nargs="+", default=["64/10/0", "64/10/1", "32/10/0", "64/3/0",
                                                      "64/1/0"])  # fmt: skip
    ap.add_argument("--fuse", default="64/10/0", help="configuration fused with v4")
    ap.add_argument("--sum", type=float, nargs="*", default=[0.5, 1, 2, 4, 8])
    ap.add_argument("--rank", type=float, nargs="*", default=[0.5, 1, 2])
    ap.add_argument("--adapt", type=float, nargs="*", default=[1, 2, 4, 8, 16])
    ap.add_argument("--adrank", type=float, nargs="*", default=[0.5, 1, 2, 4])
    ap.add_argument("--top", type=int, default=TOP, help="neighbours of the adaptive gate")
    ap.add_argument("--power", type=float, default=3.0, help="power of the adaptive gate")
    ap.add_argument("--ceiling", type=float, default=0.0, help="spread ceiling (0: none)")
    ap.add_argument("--ramp", type=float, default=0.02, help="width of the ceiling's fade")
    ap.add_argument("--typical", type=float, default=None)
    ap.add_argument("--baselines", action="store_true", help="mesh LFD and D2 in the same run")
    ap.add_argument(
        "--queries", default="mesh", help="variant of the queries (e.g. pointcloud) against meshes"
    )
    ap.add_argument("--per-kind", nargs="*", default=[], metavar="ROW",
                    help="rows (e.g. v4 'LFD (mesh)') whose NN is also given per class")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None, help="JSON path (default: by split)")
    ap.add_argument("--cost", type=int, default=0, help="only time N models per set (--fuse)")
    ap.add_argument("--check-product", action="store_true",
                    help="only check that rerank='lightfield' ranks as the chosen fusion")  # fmt: skip
    args = ap.parse_args(argv)
    if args.check_product:
        checks = check_product(args.datasets, args.split)
        write_json(args.out or OUT / f"lightfield_product_check_{args.split}.json", checks)
        return 0
    if args.cost:
        write_json(OUT / "lightfield_balls_cost.json", cost(args.cost, args.fuse))
        return 0

    sets: dict[str, dict[str, Any]] = {}
    cpu: dict[str, dict[str, float]] = {}
    for name in args.datasets:
        t0 = time.perf_counter()
        queries = None
        if args.queries == "mesh":
            ds, balls = load(name, args.split)
        else:
            ds, pairs = load(name, args.split, ("mesh", args.queries))
            balls, queries = [p[0] for p in pairs], [p[1] for p in pairs]
        mats: dict[str, FloatArray] = {"v4": v4_distances(balls, queries)}
        cpu[name] = {}
        for text in dict.fromkeys([*args.configs, args.fuse]):
            d, per_model, dist_s = light_field_matrix(name, ds, balls, text, queries, args.queries)
            mats[f"lfb {text}"] = d
            cpu[name][text] = per_model
            cpu[name][f"{text} distances s/pair"] = dist_s / max(len(d) * (len(d) - 1) / 2, 1)
        if args.baselines:
            mats.update(mesh_baselines(ds))
        sets[name] = {"labels": np.asarray(ds.labels), "mats": mats}
        print(f"  {name}: {len(ds)} models ({time.perf_counter() - t0:.0f} s)", flush=True)

    key = f"lfb {args.fuse}"
    medians = {
        n: float(np.median(s["mats"][key][np.triu_indices(len(s["labels"]), 1)]))
        for n, s in sets.items()
    }
    typical = args.typical or float(np.exp(np.mean(np.log(list(medians.values())))))
    gates = {n: gate_stats(s["mats"]["v4"], s["mats"][key], typical, args.top, args.power,
                           args.ceiling, args.ramp) for n, s in sets.items()}  # fmt: skip
    rows_spec: list[tuple[str, str, float]] = [("v4", "", 0.0)]
    rows_spec += [(f"lfb {c}", "", 0.0) for c in dict.fromkeys([*args.configs, args.fuse])]
    if args.baselines:
        rows_spec += [("LFD (mesh)", "", 0.0), ("D2 (mesh)", "", 0.0)]
    for kind in ("sum", "rank", "adapt", "adrank"):
        rows_spec += [(f"{kind} {w:g}", kind, w) for w in getattr(args, kind)]

    table, rows = [], []
    base: dict[str, dict[str, float]] = {}
    per_kind: dict[str, dict[str, dict[str, float]]] = {}
    for label, kind, w in rows_spec:
        entry: dict[str, Any] = {"row": label}
        obj = []
        for n, s in sets.items():
            m = s["mats"]
            d = (
                fuse(
                    kind, w, m["v4"], m[key], typical, args.top, args.power, args.ceiling, args.ramp
                )
                if kind
                else m[label]
            )
            sc = retrieval_scores(-d, s["labels"])
            entry[n] = sc
            if label in args.per_kind:
                per_kind.setdefault(n, {})[label] = class_nn(d, s["labels"])
            obj.append((sc["nn"] + sc["first_tier"] + sc["dcg"]) / 3)
        entry["objective"] = float(np.mean(obj))
        if label == "v4":
            base = {n: entry[n] for n in sets}
        entry["passes"] = all(
            entry[n][k] >= base[n][k] - 2.0 / len(sets[n]["labels"]) - 1e-12
            for n in sets
            for k in ("nn", "first_tier", "dcg")
        )
        table.append(entry)
        cells = [f"{entry[n]['nn']:.3f}/{entry[n]['first_tier']:.3f}/{entry[n]['dcg']:.3f}"
                 for n in sets]  # fmt: skip
        rows.append([label, *cells, f"{entry['objective']:.4f}", "yes" if entry["passes"] else ""])
    kinds = ("sum", "rank", "adapt", "adrank")
    fused = [e for e in table if e["passes"] and e["row"].split()[0] in kinds]
    chosen = max(fused, key=lambda e: e["objective"])["row"] if fused else None
    print()
    print(format_table(
        f"light fields from the balls, {args.split} splits, {args.queries} queries (NN/1-T/DCG), "
        f"fused: {args.fuse}, "
        f"typical {typical:.4g}, gate: top {args.top}, power {args.power:g}, "
        f"ceiling {args.ceiling:g}, ramp {args.ramp:g}",
        ("row", *sets, "objective", "passes"), rows,
    ))  # fmt: skip
    for n, got in per_kind.items():
        kinds_of = list(dict.fromkeys(sets[n]["labels"].tolist()))
        print()
        print(format_table(
            f"{n}: NN per class", ("class", *got),
            [[k, *(f"{got[r][k]:.2f}" for r in got)] for k in kinds_of],
        ))  # fmt: skip
    print(f"medians {medians}; chosen {chosen}")
    print(f"gates {gates}")
    print(f"CPU s per model / per pair: {cpu}")
    out = args.out or OUT / f"lightfield_balls_{args.split}.json"
    write_json(out, {"split": args.split, "queries": args.queries, "fuse": args.fuse,
                     "typical": typical,
                     "top": args.top, "power": args.power, "ceiling": args.ceiling,
                     "ramp": args.ramp,
                     "medians": medians, "table": table, "chosen": chosen, "cpu": cpu,
                     "per_kind_nn": per_kind, "gates": gates,
                     "sizes": {n: len(s["labels"]) for n, s in sets.items()}})  # fmt: skip
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
