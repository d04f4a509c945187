"""The ``"lightfield"`` re-ranking stage measured through the product path.

Usage (from the repository root)::

    python -m bench.studies.lightfield_rerank                       # validation, six sets
    python -m bench.studies.lightfield_rerank --split test
    python -m bench.studies.lightfield_rerank --split test --datasets webplus   # the held-out set
    python -m bench.studies.lightfield_rerank --cost                # per-query db.search time

For each set's split (meshes; the cached decompositions the light field study reads,
:func:`bench.support.cached.load`; nothing is decomposed), every shape queries a
flat :class:`query.search.index.FeatureIndex` through :func:`query.search.rerank.search` with ``k =
n`` (the product's search path), its own id given, as ``db.search(id)`` does. Rows, in
the same run:

* ``v4``: the default store (version 4's vector, no stage);
* ``adaptive (v7)``: version 7's vector with the adaptive views stage at its grid's
  choice (:class:`bench.studies.adaptive_rerank.AdaptiveFusion`);
* ``lightfield``: version 4's vector with ``rerank="lightfield"`` at the product's
  numbers (:data:`query.search.tuning.PRODUCT`, K = 100), the candidates' light
  fields read by id as a store keeps them (float32,
  :func:`shapedb.signature.lightfield.record_light_field` of the balls), and the stored local
  spreads computed over the set as a store computes them
  (:func:`query.search.lightfield_spread.local_spreads`); with the field's light fields and the
  field vectors on (the default), the field vectors too (:func:`field_vectors`, of the
  shells cached by :mod:`bench.support.field_shells`): the fused distance and the union
  candidates (:mod:`query.search.field_fusion`, :mod:`query.search.field_index`);
* ``lightfield (spread gate)``: the same with the gate before the ratio (the pooled
  local spread alone, :data:`SPREAD_GATE`), without the field vectors;
* ``lightfield (before)``: the same with the stage's settings before the pooled spread
  and the contrast floor (:data:`LEGACY`, its overlap gate
  :class:`bench.support.tuning.OverlapFusion`), without the field vectors.

With ``--baselines``, in the same run: the balls' light fields alone (``light fields
(balls)``, :func:`shapedb.signature.lightfield.light_field_distance` of the stored light fields),
and on the meshes the light field descriptor (:mod:`bench.support.lightfield`) and D2
(:mod:`bench.support.baselines`, 2^18 pairs). ``--per-kind`` adds every row's NN per class.

That the scorer ranks as the study's formula does is checked by the study
(``python -m bench.studies.lightfield_balls --check-product``).

``--cost`` builds six stores of the web validation shapes (v4 without a stage, v4 with
``rerank="lightfield"`` without the field vectors (:data:`NO_FIELD`), with them (the
fused distance and the union candidates at the defaults, or :data:`FIELD_STAGE`), the
same with the shared-neighbour term (the default's, or k 3, beta 0.8) and with
:data:`SPREAD_GATE`; each store committed and searched under its numbers,
:func:`query.search.tuning.tuned`), times computing the lightfield stores' local
statistics and shared-neighbour lists (the tables a commit writes), then ``db.search(id,
k=10)`` for every shape, interleaved, and prints medians and ratios to the plain store;
and the first search on a fresh copy of the stores with and without the term (cold: the
store as committed, its tables written). The adaptive stage is no store's any more: its
cost is :mod:`bench.studies.rerank_select`'s ``--cost``.
``--lf-source field`` (and ``--lf-set FIELD=VALUE``): the ``lightfield`` rows read the
light fields of the field's inside (cached by :mod:`bench.support.inside_fields`).
Written to bench/results/studies/lightfield_rerank_<split>.json (``lightfield_rerank_cost.json``).
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import class_nn, format_table, retrieval_scores, write_json
from bench.studies.adaptive_rerank import AdaptiveFusion
from bench.support import inside_fields
from bench.support.cached import CHOICES, load
from bench.support.features import kernel_features
from bench.support.field_vectors import SCALES, FieldStage
from bench.support.packings import light_field_balls
from bench.support.tuning import LEGACY_TYPICAL, Setting, configure, parse_value
from query.search import rerank
from query.search.field_fusion import FIELD, FieldFusion
from query.search.field_index import FieldIndex
from query.search.index import FeatureIndex
from query.search.lightfield_neighbours import NEIGHBOURS, stage_lists
from query.search.lightfield_spread import local_spreads
from query.search.rerank_lightfield import COLUMN, SPREAD, LightFieldFusion
from query.search.tuning import PRODUCT, StageTuning, tuned
from shapedb.config.core import Config
from shapedb.signature.lightfield import light_field_distance, record_light_field

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
SETS = ("web", "generic", "capod", "figures", "parts", "people")
_MEASURES = ("nn", "first_tier", "dcg")
_CHUNK = 32
#: The stage's gate before the ratio (the pooled spread and contrast floor): flat settings
#: (:func:`bench.support.tuning.configure`), the stage's numbers as ``lf_<field>`` (the
#: light field distance alone then, in the unit of that time: ``lf_typical``).
SPREAD_GATE = {"lf_weight": 4.0, "lf_ceiling": 0.11, "lf_ramp": 0.02, "lf_spread_candidates": 5,
               "lf_pool": 20, "lf_contrast_ramp": 0.05, "lf_ratio_weight": 0.0,
               "lf_pool_quantile": 0.5, "lf_typical": LEGACY_TYPICAL}  # fmt: skip
#: The stage without the field vectors (what a store written before them reads: no
#: shared-neighbour term either).
NO_FIELD = {"fv_enabled": False, "lf_field_depth_weight": 0.0, "lf_field_harmonic_weight": 0.0,
            "lf_field_candidates": 0, "lf_shared_neighbours": 0}  # fmt: skip
#: The field vectors' part of the stage where the defaults do not turn it on: the research's
#: weights 0.5 and 0.5 at its scales (:meth:`bench.support.field_vectors.FieldStage.at_scales`).
_FIELD = FieldStage.at_scales(0.5, 0.5, *SCALES, 100)
FIELD_STAGE = {"lf_field_depth_weight": _FIELD.depth_weight,
               "lf_field_harmonic_weight": _FIELD.harmonic_weight, "lf_scale": _FIELD.scale,
               "lf_field_candidates": 100}  # fmt: skip
#: The stage's settings before the pooled spread and the contrast floor (no shared neighbours).
LEGACY = {"lf_weight": 8.0, "lf_power": 3.0, "lf_ceiling": 0.09, "lf_spread_candidates": 100,
          "lf_pool": 0, "lf_contrast_floor": 0.0, "lf_ramp": 0.02, "lf_ratio_weight": 0.0,
          "lf_shared_neighbours": 0, "lf_typical": LEGACY_TYPICAL}  # fmt: skip


def index_of(x: np.ndarray) -> FeatureIndex:
    """A flat index over pre-weighted vectors (plain L1 is the stored distance)."""
    return FeatureIndex(kind="flat").fit(
        np.arange(len(x)), x.astype(np.float32), np.ones(x.shape[1])
    )


class Arrays:
    """A store's per-record arrays by id (ids 0..n-1): light fields, field vectors, the
    stored local spreads and shared-neighbour lists as a store computes them, and the
    field vector index."""

    def __init__(
        self,
        lf: np.ndarray,
        index: FeatureIndex,
        config: Config,
        fv: np.ndarray | None = None,
        tuning: StageTuning = PRODUCT,
    ) -> None:
        self.lf, self.index, self.config, self.fv = lf, index, config, fv
        self.tuning = tuning
        self._spreads: np.ndarray | None = None
        self._lists: np.ndarray | None = None
        self._field_index: FieldIndex | None = None

    def __call__(self, name: str, ids: np.ndarray) -> np.ndarray | None:
        if name == COLUMN:
            return np.asarray(self.lf[ids], np.float64)
        if name == FIELD and self.fv is not None:
            return np.asarray(self.fv[ids], np.float64)
        if name == SPREAD:
            if self._spreads is None:
                self._spreads = local_spreads(self.index, self, self.config, None, self.tuning)[1]
            return self._spreads[ids]
        if name == NEIGHBOURS and self.tuning.shares_neighbours:
            if self._lists is None:
                stage = LightFieldFusion(self.config, tuning=self.tuning)
                self._lists = stage_lists(self.index, self, self.config, stage)[1]
            return np.asarray(self._lists[ids], np.float64)
        return None

    def field_index(self) -> FieldIndex:
        """The field vector index of the store (empty without field vectors)."""
        if self._field_index is None:
            fusion = FieldFusion.from_config(self.config, self.tuning)
            fv = np.zeros((0, 1)) if self.fv is None else self.fv
            self._field_index = FieldIndex(np.arange(len(fv)), fusion.scaled(fv))
        return self._field_index


def field_vectors(ds: Any, config: Config) -> np.ndarray:
    """(n, d) float32 field vectors of ``ds``'s models as a store keeps them:
    :func:`shapedb.signature.field_vector.field_vector` of the field's inside cached by
    :func:`bench.support.field_shells.shells`."""
    from bench.support.field_shells import shells
    from shapedb.geometry.inside import Inside
    from shapedb.signature.field_vector import field_vector

    rows = []
    for z in shells(ds):
        inside = Inside(shell=np.asarray(z["shell"], np.float64), cell=float(z["cell"]),
                        centroid=np.asarray(z["centroid"], np.float64), count=int(z["count"]))  # fmt: skip
        rows.append(np.asarray(field_vector(inside, config.field_vector), np.float32))
    return np.stack(rows)


def rankings(
    index: FeatureIndex,
    config: Config | Setting,
    lf: np.ndarray | None = None,
    fv: np.ndarray | None = None,
    scorer: rerank.Scorer | None = None,
) -> np.ndarray:
    """(n, n) ids in the order the product returns them, every shape querying by its id.

    ``config``: the store's, at the product's numbers, or a :class:`Setting` (its
    numbers and gate). ``scorer``: the stage in place of the setting's (e.g. the adaptive
    stage); without light fields (``lf`` None) and ``scorer`` the index's order.
    """
    setting = config if isinstance(config, Setting) else Setting(config)
    x = np.asarray(index.features_, np.float64)
    n = len(x)
    out = np.empty((n, n), np.int64)
    arrays = None if lf is None else Arrays(lf, index, setting.config, fv, setting.tuning)
    if scorer is None and lf is not None:
        scorer = setting.scorer()
    for lo in range(0, n, _CHUNK):
        q = slice(lo, min(lo + _CHUNK, n))
        out[q], _ = rerank.search(
            index, x[q], n, config=setting.config, query_ids=np.arange(n)[q], arrays=arrays,
            scorer=scorer,
        )  # fmt: skip
    return out


def _ranks(order: np.ndarray) -> np.ndarray:
    """(n, n) rank of each shape in each query's list (0 first)."""
    ranks = np.empty(order.shape)
    np.put_along_axis(ranks, order, np.arange(order.shape[1], dtype=float)[None, :], 1)
    return ranks


def _scores(order: np.ndarray, labels: np.ndarray) -> dict[str, float]:
    return retrieval_scores(-_ranks(order), labels)


def mesh_baselines(ds: Any) -> dict[str, np.ndarray]:
    """(n, n) distances of the light field descriptor and D2 (2^18 pairs) on the meshes."""
    from bench.sets.datasets import mesh_arrays
    from bench.support.baselines import D2Config, d2_descriptor
    from bench.support.lightfield import LFDConfig, lfd_descriptor, lfd_distance

    arrays = [mesh_arrays(m) for m in ds.models]
    lfd = np.stack([lfd_descriptor(v, f, LFDConfig()) for v, f in arrays])
    d2 = np.stack([d2_descriptor(v, f, D2Config(n_pairs=262144)) for v, f in arrays])
    l1 = np.stack([np.abs(d2 - row).sum(axis=1) for row in d2])
    return {"LFD (mesh)": lfd_distance(lfd), "D2 (mesh)": l1}


def light_fields(balls: Sequence[Any], config: Config) -> np.ndarray:
    """(n, fields, 10, d) float32 light fields as a store keeps them, of ``balls`` as given
    (a longer packing's: :func:`bench.support.packings.light_field_balls`)."""
    cfg = config.light_field
    return np.stack([record_light_field(b.centers, b.radii, cfg, edges=b.edges) for b in balls])


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Rows per set, the study check, the table; returns the JSON written."""
    lf_cfg = Config().with_options(rerank="lightfield")
    if args.lf_source is not None:
        lf_cfg = lf_cfg.with_options(lf_source=args.lf_source)
    lf_set = {f"lf_{k}": parse_value(v) for k, v in (kv.split("=", 1) for kv in args.lf_set)}
    product = configure(lf_cfg, lf_set)  # the light fields' fields, or the stage's numbers
    lf_cfg = product.config
    adaptive = Config().with_options(descriptor=7, rerank="none")
    before = configure(lf_cfg, {**LEGACY, **NO_FIELD}, product.tuning)
    spread = configure(lf_cfg, {**SPREAD_GATE, **NO_FIELD}, product.tuning)
    table: dict[str, dict[str, Any]] = {
        "v4": {}, "adaptive (v7)": {}, "lightfield": {}, "lightfield (spread gate)": {},
        "lightfield (before)": {},
    }  # fmt: skip
    if args.baselines:
        table.update({"light fields (balls)": {}, "LFD (mesh)": {}, "D2 (mesh)": {}})
    per_kind: dict[str, dict[str, dict[str, float]]] = {}

    def add(row: str, name: str, d: np.ndarray, labels: np.ndarray) -> None:
        table[row][name] = retrieval_scores(-d, labels)
        if args.per_kind:
            per_kind.setdefault(name, {})[row] = class_nn(d, labels)

    for name in args.datasets:
        t0 = time.perf_counter()
        ds, balls = load(name, args.split)
        labels = np.asarray(ds.labels)
        v4 = kernel_features(balls, Config())
        if lf_cfg.light_field_inside:  # the field's inside, cached by bench.support.inside_fields
            lf = inside_fields.light_fields(name, args.split, ds, lf_cfg.light_field)
        else:
            lf = light_fields(
                light_field_balls(name, args.split, ds, balls, lf_cfg, within=args.lf_within),
                lf_cfg,
            )
        fv = field_vectors(ds, lf_cfg) if lf_cfg.stores_field_vectors else None
        i4 = index_of(v4)
        add("v4", name, _ranks(rankings(i4, Config())), labels)
        if not args.no_adaptive:
            v7 = kernel_features(balls, Config().with_options(descriptor=7))
            stage = AdaptiveFusion(adaptive)
            add(
                "adaptive (v7)",
                name,
                _ranks(rankings(index_of(v7), adaptive, scorer=stage)),
                labels,
            )
        add("lightfield", name, _ranks(rankings(i4, product, lf, fv)), labels)
        add("lightfield (spread gate)", name, _ranks(rankings(i4, spread, lf)), labels)
        add("lightfield (before)", name, _ranks(rankings(i4, before, lf)), labels)
        if args.baselines:
            add("light fields (balls)", name, light_field_distance(lf.astype(np.float64)), labels)
            for row, d in mesh_baselines(ds).items():
                add(row, name, d, labels)
        print(f"  {name}: {len(v4)} models ({time.perf_counter() - t0:.0f} s)", flush=True)
    sets = list(args.datasets)
    rows = []
    for row, per in table.items():
        if not per:
            continue
        obj = float(np.mean([sum(per[s][m] for m in _MEASURES) / 3 for s in sets]))
        per["objective"] = obj
        cells = [
            f"{per[s]['nn']:.3f} / {per[s]['first_tier']:.3f} / {per[s]['dcg']:.3f}" for s in sets
        ]
        rows.append([row, *cells, f"{obj:.4f}"])
    print()
    print(format_table(
        f"re-ranking stages through query.search.rerank.search, {args.split} splits (NN / 1-T / DCG)",
        ("row", *sets, "objective"), rows,
    ))  # fmt: skip
    for name, got in per_kind.items():
        kinds = list(dict.fromkeys(got[next(iter(got))]))
        print()
        print(format_table(f"{name}: NN per class", ("class", *got),
                           [[k, *(f"{got[r][k]:.2f}" for r in got)] for k in kinds]))  # fmt: skip
    return {"split": args.split, "table": table, "per_kind_nn": per_kind}


def _cost_store(root: Path, ds: Any, balls: Sequence[Any], setting: Setting) -> Any:
    """A store of ``ds``'s shapes at ``setting``, committed under its numbers (a commit
    writes the stage's tables), its index built."""
    import shapedb
    from query.search.index import open_index
    from shapedb.signature.kernel import features
    from shapedb.store.schema import ShapeRecord

    cfg = setting.config
    x = np.stack([features(b.decomposition(), cfg) for b in balls])
    lf = light_fields(balls, cfg) if cfg.stores_light_fields else None
    fv = field_vectors(ds, cfg) if cfg.stores_field_vectors else None
    db = shapedb.connect(root, config=cfg)
    with tuned(setting.tuning):
        db.commit([
            ShapeRecord(name=m.name, decomposition=b.decomposition(),
                        feature=x[j].astype(np.float32), config=cfg,
                        content_hash=hashlib.sha256(m.name.encode()).hexdigest(),
                        representation="mesh", label=m.label,
                        light_field=None if lf is None else lf[j],
                        field_vector=None if fv is None else fv[j])
            for j, (m, b) in enumerate(zip(ds.models, balls, strict=True))
        ])  # fmt: skip
        open_index(db)
    return db


def _table_times(db: Any, setting: Setting, label: str) -> dict[str, float]:
    """Seconds to compute ``db``'s local statistics and shared-neighbour lists at ``setting``
    (what its commit wrote), each timed alone."""
    from query.search.index import open_index
    from query.search.rerank_lightfield import stored_arrays

    out: dict[str, float] = {}
    index, reader, n = open_index(db), stored_arrays(db), len(db.store.features()[0])
    t = time.perf_counter()
    local_spreads(index, reader, setting.config, None, setting.tuning)
    out[f"spreads_s {label}"] = time.perf_counter() - t
    print(f"  local statistics of {n} shapes, {label}: {out[f'spreads_s {label}']:.2f} s")
    if setting.tuning.shares_neighbours:
        stage = LightFieldFusion(setting.config, tuning=setting.tuning)
        t = time.perf_counter()
        stage_lists(index, reader, setting.config, stage)
        out[f"lists_s {label}"] = time.perf_counter() - t
        print(f"  shared-neighbour lists of {n} shapes, {label}: {out[f'lists_s {label}']:.2f} s")
    return out


def cost(args: argparse.Namespace, repeats: int = 3, cold: int = 8) -> dict[str, Any]:
    """Median per-query ``db.search`` seconds of web validation stores, same run.

    Warm: every store's index, statistics and lists computed, ``repeats`` x n queries
    interleaved. Cold (the stage with and without the shared-neighbour term): the first
    ``db.search`` on a fresh copy of each store as committed (its index built, its tables
    written), for ``cold`` queries, paired.
    """
    import shutil

    import shapedb
    from query.search.lightfield_neighbours import neighbour_table
    from query.search.rerank_lightfield import stored_arrays

    ds, balls = load("web", "validation")
    product = Setting(Config().with_options(rerank="lightfield", fv_enabled=True))
    if not product.tuning.field_candidates:  # the stage's field numbers, if not the default
        product = configure(product.config, FIELD_STAGE, product.tuning)
    if not product.tuning.shares_neighbours:  # the term, if not the default
        product = configure(product.config, {"lf_shared_neighbours": 3, "lf_shared_weight": 0.8},
                            product.tuning)  # fmt: skip
    shared, fused = "lightfield + field vectors + shared (v4)", "lightfield + field vectors (v4)"
    plain = Config().with_options(rerank="lightfield")
    settings = {
        "none (v4)": Setting(Config().with_options(rerank="none")),
        "lightfield (v4)": configure(plain, NO_FIELD),
        fused: configure(product.config, {"lf_shared_neighbours": 0}, product.tuning),
        shared: product,
        "lightfield, spread gate (v4)": configure(plain, {**SPREAD_GATE, **NO_FIELD}),
    }
    out: dict[str, Any] = {"models": len(balls)}
    with tempfile.TemporaryDirectory() as tmp:
        dbs = {}
        for k, (label, st) in enumerate(settings.items()):
            dbs[label] = _cost_store(Path(tmp) / f"s{k}", ds, balls, st)
            if st.config.rerank.scorer == "lightfield":  # the index-time tables, timed alone
                if label in (shared, fused):  # the store as committed, for the cold queries
                    shutil.copytree(dbs[label].store.path, Path(tmp) / f"fresh{k}")
                out.update(_table_times(dbs[label], st, label))
            with tuned(st.tuning):
                got = dbs[label].evaluate()
            out[f"evaluate {label}"] = {m: float(getattr(got, m)) for m in _MEASURES}
            print(f"  db.evaluate {label}: {got.nn:.3f} / {got.first_tier:.3f} / {got.dcg:.3f}")
        ids = [int(i) for i in dbs["none (v4)"].store.features()[0]]
        for label, db in dbs.items():
            with tuned(settings[label].tuning):
                db.search(ids[0], k=10)  # warm: index built and loaded
        times: dict[str, list[float]] = {label: [] for label in dbs}
        for _ in range(repeats):
            for sid in ids:  # interleaved, so load changes hit every store alike
                for label, db in dbs.items():
                    with tuned(settings[label].tuning):
                        t = time.perf_counter()
                        db.search(sid, k=10)
                        times[label].append(time.perf_counter() - t)
        first: dict[str, list[float]] = {fused: [], shared: []}
        computed: list[int] = []  # lists the cold query read or computed
        sample = ids[:: max(1, len(ids) // cold)][:cold]
        for n, sid in enumerate(sample):  # cold: a fresh copy per query and store
            for label in (fused, shared) if n % 2 == 0 else (shared, fused):
                k = list(settings).index(label)
                root = Path(tmp) / f"cold{k}-{n}"
                shutil.copytree(Path(tmp) / f"fresh{k}", root)
                fresh = shapedb.connect(root)
                with tuned(settings[label].tuning):
                    t = time.perf_counter()
                    fresh.search(sid, k=10)
                    first[label].append(time.perf_counter() - t)
                if label == shared:
                    stage = LightFieldFusion(product.config, tuning=product.tuning)
                    table = neighbour_table(fresh, stored_arrays(fresh), stage)
                    computed.append(len(table.values))
            print(f"  cold query {sid}: {first[fused][-1]:.2f} s without the term, "
                  f"{first[shared][-1]:.2f} s with it ({computed[-1]} lists)", flush=True)  # fmt: skip
        out["cold_lists"] = computed
    med = {k: float(np.median(v)) for k, v in times.items()}
    base = med["none (v4)"]
    out["median_s"] = med
    out["ratio"] = {k: v / base for k, v in med.items()}

    def paired(a: list[float], b: list[float]) -> float:
        return float(np.median(np.asarray(a) / np.asarray(b)))

    # per query, against the same query without them (paired)
    out["field_vectors_paired_ratio"] = paired(times[fused], times["lightfield (v4)"])
    out["shared_paired_ratio"] = paired(times[shared], times[fused])
    out["cold_median_s"] = {k: float(np.median(v)) for k, v in first.items()}
    out["cold_shared_paired_ratio"] = paired(first[shared], first[fused])
    print(format_table(
        f"db.search per query, k = 10, {len(ids)} stored web shapes, {repeats} x {len(ids)} queries",
        ("stage", "median ms", "ratio"),
        [[k, f"{v * 1e3:.2f}", f"{v / base:.2f}"] for k, v in med.items()],
    ))  # fmt: skip
    print(f"field vectors (fused distance and union) against the lightfield stage alone: "
          f"median per-query ratio x{out['field_vectors_paired_ratio']:.2f}")  # fmt: skip
    print(f"shared-neighbour term against the same stage without it: warm x"
          f"{out['shared_paired_ratio']:.2f}; cold (first query on a fresh store, "
          f"{len(first[shared])} queries) {out['cold_median_s'][shared]:.2f} s against "
          f"{out['cold_median_s'][fused]:.2f} s, x{out['cold_shared_paired_ratio']:.2f}")  # fmt: skip
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.lightfield_rerank", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--datasets", nargs="+", default=list(SETS), choices=CHOICES)
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--no-adaptive", action="store_true", help="leave out the v7 adaptive row")
    ap.add_argument("--lf-within", type=int, default=0,
                    help="the light fields' balls: the first of the packing continued to this "
                         "many (as bench.studies.lightfield_gate --lf-within)")  # fmt: skip
    ap.add_argument("--baselines", action="store_true",
                    help="the balls' light fields alone, mesh LFD and D2 in the same run")  # fmt: skip
    ap.add_argument("--per-kind", action="store_true", help="every row's NN per class")
    ap.add_argument("--cost", action="store_true", help="only time db.search of the stores")
    ap.add_argument("--lf-source", default=None, choices=["balls", "field"],
                    help="what the light fields see (not with --cost)")  # fmt: skip
    ap.add_argument("--lf-set", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="other LightFieldConfig fields (e.g. resolution=128), or StageTuning's")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.cost:
        write_json(args.out or RESULTS / "lightfield_rerank_cost.json", cost(args))
        return 0
    result = measure(args)
    out = args.out or RESULTS / f"lightfield_rerank_{args.split}.json"
    write_json(out, result)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
