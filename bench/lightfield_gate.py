"""How much the ``"lightfield"`` stage's light field should count, per store and per query.

Usage (from the repository root)::

    python -m bench.lightfield_gate                      # validation: the grid, the choice
    python -m bench.lightfield_gate --split test         # test: the rows chosen on validation
    python -m bench.lightfield_gate --lf-source field    # the same on the field's light fields

Every bench set's split (meshes; the cached balls of :func:`bench.cached.load`, nothing
decomposed) is a store of its own, and so are the mixed stores of :data:`MIXES` (web +
figures, web + people, generic + parts, all six). In each store every shape queries the
others: its ``K = 100`` nearest by version 4's stored distance (ties by ascending id, the
query among them, as ``query.rerank.search`` hands them over) are re-ranked by the gated
reciprocal rank fusion of :class:`query.rerank_lightfield.LightFieldFusion`,
``1 / (o + rank_d) + w g(q) / (o + rank_l)``, and scored (NN / 1-T / DCG) per set inside
the store. Rows, in the same run: version 4 (no stage), the balls' light fields alone,
the gates before (:data:`LEGACY`, :data:`SPREAD_GATE`), the product's stage at its
defaults, on validation the grid's choices, and with ``--oracle`` the gate's headroom
(:func:`oracle_rows`: gates that know which sets are jointed); the statistics of each
store and the gate's margin (:func:`bench.gate_checks.margin`) are printed beside.

The selection (validation, ``--grid ratio``, the default): every setting of
:func:`bench.gate_checks.ratio_settings` that passes the rule (no set, alone or in a
mix, more than two queries below v4 on NN, 1-T or DCG), keeps the analytic chain in
poses shut through the product's scorer (:func:`bench.gate_checks.analytic_stores`) and
keeps both margins (:data:`bench.gate_checks.MIN_MARGIN`); the best objective among them
is chosen. ``--grid spread``: the grid of the spread gate (:data:`GRID`), by the rule
alone.

The light field distances (the store's float32 light fields,
:func:`shapedb.lightfield.record_light_field`, every pair of the split's six sets) are
cached under ``$SHAPEDB_BENCH_CACHE/lightfield_gate`` keyed by the models and the code of
``shapedb/lightfield.py`` and ``shapedb/lightfield_descriptor.py``, so a changed silhouette
re-computes them and the selection re-runs in one command. Written to
bench/results/lightfield_gate_<split>.json. A held-out set that :mod:`bench.cached` knows
(``webplus``) is run with ``--split test --no-grid --datasets webplus figures people`` (it
and its mixes with the figures and the people). ``--lf-n-balls N``: the light fields of
the packing continued to N balls (``LightFieldConfig.n_balls``, decomposed and cached by
:func:`bench.packings.longer`; ``--lf-within M``: the first N by radius of the packing
continued to M); version 4 stays that of the cached balls. ``--lf-source field``: the
light fields of the field's inside (``LightFieldConfig.source``, computed once per model
and cached by :mod:`bench.inside_fields`); ``--lf-set FIELD=VALUE``: other
``LightFieldConfig`` fields (e.g. ``resolution=128``).

The field vectors (:mod:`bench.field_vectors`): ``--field-vectors`` scores the stage whose
distance fuses the light field distance with the L1 distances of the field's depth
buffers and harmonics (fixed scales) and whose candidates are the union of version 4's
K and the field vectors' K2 nearest, everywhere the stage uses the light field distance
(ranks, the gate's statistics, the analytic stores); ``--fv-weights``, ``--fv-scales``,
``--fv-candidates`` replace the product's values (``LightFieldFusionConfig``'s, once it
has them), and ``--no-field-vectors`` keeps the light field alone. Such a run also
scores the stage before the field vectors (the light field distance, K alone) in the
same run. ``--mesh-lfd``: the peer's row, every shape of each store ranked by the mesh
light field descriptor (:func:`bench.rerank_select.lfd_split_matrix`, cached).
``--no-rigid-margin``: the ratio grid keeps the jointed margin alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench import cached, inside_fields
from bench.cached import load
from bench.common import format_table, write_json
from bench.datasets import CACHE_DIR
from bench.features import kernel_features
from bench.gate_checks import (
    JOINTED,
    JOINTED_SETS,
    MIN_MARGIN,
    analytic_gates,
    analytic_shapes,
    analytic_stores,
    margin,
    ratio_settings,
)
from bench.packings import light_field_balls
from query.lightfield_spread import pooled
from shapedb.config import Config
from shapedb.descriptor import LAYOUTS
from shapedb.lightfield import light_field_distance, record_light_field

FloatArray = NDArray[np.float64]
RESULTS = Path(__file__).resolve().parent / "results"
SETS = ("web", "generic", "capod", "figures", "parts", "people")
MIXES = {
    "web+figures": ("web", "figures"),
    "web+people": ("web", "people"),
    "generic+parts": ("generic", "parts"),
    "all six": SETS,
    "webplus+figures": ("webplus", "figures"),
    "webplus+people": ("webplus", "people"),
}
#: Sets a run may name: the six, and the held-out ones :mod:`bench.cached` knows (``webplus``).
CHOICES = tuple(getattr(cached, "CHOICES", SETS))
MEASURES = ("nn", "first_tier", "dcg")


class Split:
    """Every set of one split together: names, set and class labels, v4 vectors, distances.

    Attributes
    ----------
    sets : (n,) str
        The set of each shape.
    labels : (n,) str
        ``set:class`` of each shape.
    d4 : (n, n) float64
        Version 4's stored distance (pre-weighted L1 of float32 vectors, as the index
        holds them).
    dl : (n, n) float64
        The stage's distance: the light field distances of the float32 light fields, or
        their fusion with the field vectors (:func:`bench.field_vectors.fuse`).
    light : (n, n) float64
        The light field distances.
    dv : (n, n) float64 or None
        The scaled field vectors' L1 distances (a fused split's union candidates).
    stage : bench.field_vectors.FieldStage or None
        The field vectors' part of a fused split.
    """

    def __init__(
        self,
        split: str,
        names: Sequence[str] = SETS,
        lf_n_balls: int | None = None,
        lf_within: int = 0,
        lf_source: str | None = None,
        lf_set: Sequence[str] = (),
    ) -> None:
        sets, labels, x, fields, keys = [], [], [], [], []
        cfg = Config().with_options(rerank="lightfield")  # the product's light fields
        if lf_n_balls is not None:
            cfg = cfg.with_options(lf_n_balls=lf_n_balls)
        if lf_source is not None:
            cfg = cfg.with_options(lf_source=lf_source)
        for kv in lf_set:  # other light-field settings (the field's: bench.inside_fields.cut)
            k, v = kv.split("=", 1)
            cfg = cfg.with_options(**{f"lf_{k}": float(v) if "." in v else int(v)})
        lf_n_balls = cfg.light_field.n_balls
        for name in names:
            ds, balls = load(name, split)
            x.append(kernel_features(balls, Config()).astype(np.float32))
            if cfg.light_field_inside:  # the field's inside, cached by bench.inside_fields
                fields.append(inside_fields.light_fields(name, split, ds, cfg.light_field))
            else:
                seen = light_field_balls(name, split, ds, balls, cfg, within=lf_within)
                fields.append(np.stack(
                    [record_light_field(b.centers, b.radii, cfg.light_field) for b in seen]
                ))  # fmt: skip
            sets += [name] * len(balls)
            labels += [f"{name}:{lab}" for lab in ds.labels]
            tag = f"|n{lf_n_balls}w{lf_within}" if cfg.light_field_tail else ""
            tag += f"|inside-{inside_fields.VERSION}" if cfg.light_field_inside else ""
            tag += f"|{cfg.light_field}" if lf_set else ""
            keys += [m.name + m.source + tag for m in ds.models]
        self.split = split
        self.sets = np.asarray(sets)
        self.labels = np.asarray(labels)
        v = np.concatenate(x).astype(np.float64)
        self.d4 = np.empty((len(v), len(v)))
        for i in range(len(v)):
            self.d4[i] = np.abs(v - v[i]).sum(axis=1)
        self.d4 /= np.log(10.0) / sum(b[3] for b in LAYOUTS[4])  # calibrated units
        self.dl = _light_field_matrix(np.concatenate(fields), keys)
        self.light = self.dl  # the light field distance (dl: the stage's, bench.field_vectors)
        self.dv: FloatArray | None = None  # the scaled field vectors' L1 (the union candidates)
        self.stage: Any = None  # bench.field_vectors.FieldStage of a fused split

    def store(self, names: Sequence[str]) -> NDArray[np.int64]:
        """Row indices of a store made of these sets."""
        return np.flatnonzero(np.isin(self.sets, list(names)))


def _light_field_matrix(fields: NDArray[np.float32], keys: list[str]) -> FloatArray:
    core = Path(__file__).resolve().parents[1] / "shapedb"
    code = b"".join((core / f).read_bytes() for f in ("lightfield.py", "lightfield_descriptor.py"))
    key = hashlib.sha256(code + "\n".join(keys).encode()).hexdigest()[:16]
    path = CACHE_DIR / "lightfield_gate" / f"{key}.npy"
    if path.exists():
        return np.load(path)
    t = time.perf_counter()
    d = light_field_distance(fields.astype(np.float64))
    print(f"  light field distances {d.shape}: {time.perf_counter() - t:.0f} s", flush=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, d)
    return d


class Store:
    """One store's candidate lists and per-query statistics, for any gate at once.

    Parameters
    ----------
    split : Split
    rows : (n,) int
        The store's shapes (indices into ``split``); ids are their positions.
    candidates : int
        K, the candidates re-ranked per query.
    offset : float
        The rank fusion's offset.
    field_candidates : int
        K2: each query's candidates also take its ``K2`` nearest by ``split.dv`` (the
        scaled field vectors' L1, :mod:`bench.field_vectors`) that are not among the K,
        after them in the stored distance's order (the product's union). 0, or a split
        without ``dv``: the K alone.

    Attributes
    ----------
    cand : (n, C) int64
        Each query's candidates in list order (the stored distance, ties by id), itself
        among them; ``C`` the longest list, shorter lists padded past ``count``.
    count : (n,) int64
        Each query's candidates (K, plus its field vectors' extras).
    rank_l : (n, C) float64
        Rank of each candidate by the light field distance among the query's candidates
        (ties in list order); padding ranks last.
    """

    def __init__(self, split: Split, rows: NDArray[np.int64], candidates: int = 100,
                 offset: float = 60.0, field_candidates: int = 0) -> None:  # fmt: skip
        self.rows = rows
        self.labels = split.labels[rows]
        self.sets = split.sets[rows]
        d4 = split.d4[np.ix_(rows, rows)]
        dl = split.dl[np.ix_(rows, rows)]
        n = len(rows)
        k = min(candidates, n)
        self.order = np.argsort(d4, axis=1, kind="stable")  # whole list, ties by id
        self._d4, self._dl = d4, dl
        self.listing, self.count = self.order, np.full(n, k)
        dv = getattr(split, "dv", None)
        if field_candidates > 0 and dv is not None:
            from bench.field_vectors import union_order

            self.listing, self.count = union_order(
                self.order, dv[np.ix_(rows, rows)], k, min(field_candidates, n))  # fmt: skip
        c = int(self.count.max())
        self.cand = self.listing[:, :c]
        pad = np.arange(c)[None, :] >= self.count[:, None]
        self.D = np.where(pad, np.inf, np.take_along_axis(d4, self.cand, 1))
        self.L = np.where(pad, np.inf, np.take_along_axis(dl, self.cand, 1))
        self.own = self.cand == np.arange(n)[:, None]
        self.pad = pad
        self.rank_l = np.empty((n, c))
        np.put_along_axis(self.rank_l, np.argsort(self.L, axis=1, kind="stable"),
                          np.arange(c, dtype=np.float64)[None, :], 1)  # fmt: skip
        self.offset = offset
        self.same = self.labels[:, None] == self.labels[None, :]
        self.size = self.same.sum(axis=1) - 1  # relevant results per query

    def others(self, x: FloatArray) -> FloatArray:
        """(n, K - 1) ``x`` over each query's candidates without the query itself."""
        return x[~self.own].reshape(len(x), -1) if self.own.any(axis=1).all() else x[:, 1:]

    def nearest(self, c: int) -> tuple[FloatArray, FloatArray]:
        """(n, c) stored and light field distances of each shape's ``c`` nearest others.

        In the stored distance's order (ties by id), the shape left out, as the index
        hands them to :func:`query.lightfield_spread.local_spreads`.
        """
        n = len(self.rows)
        c = min(c, n - 1)
        head = self.order[:, : c + 1]
        keep = head != np.arange(n)[:, None]
        keep[keep.all(axis=1), -1] = False  # the shape not among them: its c first
        idx = head[keep].reshape(n, c)
        return np.take_along_axis(self._d4, idx, 1), np.take_along_axis(self._dl, idx, 1)

    def overlap(self, m: int) -> FloatArray:
        """(n,) share of the query's ``m`` nearest others common to both distances."""
        cand = self.others(self.cand.astype(np.float64)).astype(np.int64)
        ll = self.others(self.L)
        a = cand[:, :m]
        b = np.take_along_axis(cand, np.argsort(ll, axis=1, kind="stable")[:, :m], 1)
        return np.array([len(np.intersect1d(x, y)) / m for x, y in zip(a, b, strict=True)])

    def spread(self, typical: float = 18.03) -> FloatArray:
        """(n,) the product's ``s_q``: median light field over median stored distance."""
        return np.median(self.others(self.L), 1) / typical / np.median(self.others(self.D), 1)

    def spearman(self) -> FloatArray:
        """(n,) rank correlation of the two distances over the query's other candidates."""
        a = np.argsort(np.argsort(self.others(self.D), 1, kind="stable"), 1).astype(float)
        b = np.argsort(np.argsort(self.others(self.L), 1, kind="stable"), 1).astype(float)
        a -= a.mean(1, keepdims=True)
        b -= b.mean(1, keepdims=True)
        return (a * b).sum(1) / np.sqrt((a * a).sum(1) * (b * b).sum(1))

    def rankings(self, weight: FloatArray) -> NDArray[np.int64]:
        """(n, n) each query's whole list (store positions) at per-query weights ``weight``.

        ``weight`` (n,): the weight of the light field's rank term (``w g(q)``); inf
        ranks by the light field alone among the candidates. Past the K candidates the
        list keeps the stored-distance order.
        """
        n, k = self.cand.shape
        rank_d = np.arange(k, dtype=np.float64)[None, :]
        w = np.asarray(weight, np.float64)[:, None]
        alone = np.isinf(w[:, 0])
        fused = 1.0 / (self.offset + rank_d) + np.where(alone[:, None], 0.0,
                                                       w / (self.offset + self.rank_l))  # fmt: skip
        fused[alone] = 1.0 / (self.offset + self.rank_l[alone])
        ids = self.cand
        if not self.pad.any():
            head = np.take_along_axis(ids, np.lexsort((ids, -fused), axis=-1), 1)
        else:  # the padding keeps its list order after the candidates
            at = np.broadcast_to(np.arange(k, dtype=np.float64), ids.shape)
            keys = (
                np.where(self.pad, at, ids),
                np.where(self.pad, at, -fused),
                self.pad.astype(int),
            )
            head = np.take_along_axis(ids, np.lexsort(keys, axis=-1), 1)
        return np.concatenate([head, self.listing[:, k:]], axis=1)

    def measures(self, weight: FloatArray) -> FloatArray:
        """(n, 3) NN, 1-T, DCG of every query at per-query weights ``weight`` (:meth:`rankings`)."""
        n = len(self.cand)
        full = self.rankings(weight)
        hit = np.take_along_axis(self.same, full, 1)
        hit[full == np.arange(n)[:, None]] = False
        keep = full != np.arange(n)[:, None]
        hit = hit[keep].reshape(n, -1)
        c = np.maximum(self.size, 1)
        disc = np.ones(n - 1)
        disc[1:] = 1.0 / np.log2(np.arange(2, n))
        ideal = np.cumsum(disc)
        tier = np.array([hit[i, : c[i]].sum() for i in range(n)]) / c
        out = np.stack([hit[:, 0].astype(float), tier, (hit * disc).sum(1) / ideal[c - 1]], 1)
        out[self.size < 1] = np.nan
        return out

    def per_set(self, m: FloatArray) -> dict[str, dict[str, float]]:
        """Mean NN, 1-T, DCG per set of the store."""
        out = {}
        for s in dict.fromkeys(self.sets):
            rows = (self.sets == s) & np.isfinite(m[:, 0])
            out[str(s)] = {k: float(m[rows, j].mean()) for j, k in enumerate(MEASURES)}
        return out


def local_spreads(st: Store, candidates: int, typical: float, ratio_weight: float = 0.0,
                  ratio_candidates: int = 100) -> FloatArray:  # fmt: skip
    """(n,) each stored shape's local statistic (:func:`query.lightfield_spread.local_statistic`).

    The local spread over its ``candidates`` nearest others, times the ratio to the
    power ``ratio_weight`` (the spread's power ``1 - ratio_weight``).
    """
    reach = max(candidates, ratio_candidates) if ratio_weight > 0 else candidates
    d, ll = st.nearest(reach)
    near = np.median(ll[:, :candidates], 1)
    out = np.ones(len(d))
    if ratio_weight < 1:
        spread = near / typical / np.maximum(np.median(d[:, :candidates], 1), 1e-300)
        out *= spread ** (1.0 - ratio_weight)
    if ratio_weight > 0:
        best = np.median(np.sort(ll, 1)[:, :candidates], 1)
        out *= (near / np.maximum(best, 1e-300)) ** ratio_weight
    return out


def gate_statistic(st: Store, f: Any, memo: dict[Any, FloatArray] | None = None) -> FloatArray:
    """(n,) ``s_q`` of :class:`shapedb.config.LightFieldFusionConfig` ``f`` for every query.

    ``memo``: results kept by store and the fields they read (a grid reuses them).
    """
    key = (id(st), f.spread_candidates, f.typical, f.ratio_weight,
           f.ratio_candidates if f.ratio_weight > 0 else 0, f.pool, f.pool_quantile)  # fmt: skip
    if memo is not None and key in memo:
        return memo[key]
    s = local_spreads(st, f.spread_candidates, f.typical, f.ratio_weight, f.ratio_candidates)
    if f.pool > 0:
        s = pooled(s[st.cand[:, : f.pool]], f.pool_quantile)
    if memo is not None:
        memo[key] = s
    return s


def gate_margin(stores: dict[str, Store], f: Any,
                memo: dict[Any, FloatArray] | None = None) -> dict[str, float]:  # fmt: skip
    """:func:`margin` of ``f``'s pooled statistic over every set in every store."""
    return margin({(k, str(s)): gate_statistic(st, f, memo)[st.sets == s]
                   for k, st in stores.items() for s in dict.fromkeys(st.sets)})  # fmt: skip


def _short(setting: dict[str, Any]) -> str:
    """A grid setting in a few characters."""
    names = {"weight": "w", "spread_candidates": "m", "ratio_weight": "b",
             "ratio_candidates": "c", "pool": "pool", "pool_quantile": "q",
             "contrast_ramp": "cramp", "ceiling": "ceil", "ramp": "ramp"}  # fmt: skip
    return " ".join(f"{names.get(k, k)} {v:g}" for k, v in setting.items())


def _setting(label: str) -> dict[str, Any]:
    """The grid setting a row's label ends with."""
    import ast

    return dict(ast.literal_eval(label[label.index(": {") + 2 :]))


def gate_weights(st: Store, f: Any, memo: dict[Any, FloatArray] | None = None) -> FloatArray:
    """(n,) ``weight * g(q)`` of :class:`shapedb.config.LightFieldFusionConfig` ``f``.

    ``memo``: the pooled statistics already computed, by store and the fields they read.
    """
    n = len(st.rows)
    g = np.ones(n)
    if f.power > 0:
        g *= st.overlap(f.neighbours) ** f.power
    if f.ceiling > 0:
        g *= np.clip((f.ceiling - gate_statistic(st, f, memo)) / f.ramp, 0.0, 1.0)
    if f.contrast_floor > 0:
        d = st.others(st.D)
        far = d[:, min(f.contrast_depth, d.shape[1]) - 1]
        t = np.median(d[:, : f.neighbours], 1) / np.maximum(far, 1e-300)
        g *= np.clip((t - f.contrast_floor) / f.contrast_ramp, 0.0, 1.0)
    return f.weight * g


#: The grid of the selection (``LightFieldFusionConfig`` fields; power 0, neighbours 5).
GRID = {
    "weight": (2.0, 4.0, 8.0),
    "ceiling": (0.11, 0.13, 0.15),
    "spread_candidates": (5, 10),
    "pool": (0, 5, 10, 20),
    "contrast_floor": (0.0, 0.2, 0.25, 0.3, 0.35),
    "contrast_ramp": (0.05, 0.1, 0.2),
    "contrast_depth": (20, 30),
}
#: ``--around``: values of one field each, the others at the defaults.
AROUND = {"weight": (2.0, 8.0), "ceiling": (0.09, 0.13, 0.15), "pool": (5, 10, 40),
          "spread_candidates": (10,), "contrast_floor": (0.0, 0.25, 0.35),
          "contrast_ramp": (0.1, 0.2), "contrast_depth": (20, 50)}  # fmt: skip
#: The gate before the ratio: the pooled median of the local spread over 5.
SPREAD_GATE = {"weight": 4.0, "ceiling": 0.11, "ramp": 0.02, "spread_candidates": 5, "pool": 20,
               "contrast_ramp": 0.05, "ratio_weight": 0.0, "pool_quantile": 0.5}  # fmt: skip
LEGACY = {"weight": 8.0, "power": 3.0, "ceiling": 0.09, "spread_candidates": 100, "pool": 0,
          "contrast_floor": 0.0, "ramp": 0.02, "ratio_weight": 0.0}  # fmt: skip


def score_row(stores: dict[str, Store], weights: dict[str, FloatArray],
         base: dict[str, dict[str, dict[str, float]]]) -> dict[str, Any]:  # fmt: skip
    """Scores per store and set, the worst loss in queries against v4, the objective."""
    entry: dict[str, Any] = {"stores": {}, "worst_queries": 0.0, "worst_at": None}
    for name, st in stores.items():
        per = st.per_set(st.measures(weights[name]))
        entry["stores"][name] = per
        for s, v in per.items():
            n = int((st.sets == s).sum())
            loss = min((v[m] - base[name][s][m]) * n for m in MEASURES)
            if loss < entry["worst_queries"] - 1e-9:
                entry["worst_queries"], entry["worst_at"] = float(loss), f"{name}: {s}"
    entry["objective"] = float(np.mean(
        [np.mean([entry["stores"][s][s][m] for m in MEASURES]) for s in CHOICES if s in stores]
    ))  # fmt: skip
    entry["passes"] = entry["worst_queries"] >= -2.0 - 1e-9
    return entry


def select(args: argparse.Namespace, split: Split | None = None,
           analytic: dict[str, Any] | None = None) -> dict[str, Any]:  # fmt: skip
    """Rows of every store; on validation the grid and its choice; returns the JSON.

    ``split``: the shapes and distances to score (default: :class:`Split` of ``args``,
    fused with the field vectors of :func:`bench.field_vectors.stage_of` ``args``; a
    study passes its own distances this way; a split with a ``stage``
    (:func:`bench.field_vectors.fuse`) takes its union candidates and checks the
    analytic stores on its distance). ``analytic``: the analytic stores
    (:func:`bench.gate_checks.analytic_stores`), built here when None.
    """
    import itertools

    from bench.field_vectors import analytic_distance, fuse, stage_of

    t0 = time.perf_counter()
    if split is None:
        split = Split(
            args.split, args.datasets, args.lf_n_balls, args.lf_within, args.lf_source, args.lf_set
        )
        chosen = stage_of(args)
        if chosen is not None:
            split = fuse(split, args.datasets, chosen)
    stage = getattr(split, "stage", None)
    k2 = stage.candidates if stage is not None else 0
    names: dict[str, tuple[str, ...]] = {s: (s,) for s in args.datasets}
    names.update({k: v for k, v in MIXES.items() if set(v) <= set(args.datasets)})
    stores = {k: Store(split, split.store(v), field_candidates=k2) for k, v in names.items()}
    print(f"  {len(split.sets)} shapes, {len(stores)} stores ({time.perf_counter() - t0:.0f} s)")
    zero = {k: np.zeros(len(st.rows)) for k, st in stores.items()}
    v4 = stores  # version 4 alone: no union (its extras would come before the rest)
    if k2 > 0:
        v4 = {k: Store(split, split.store(v)) for k, v in names.items()}
    base = {k: st.per_set(st.measures(zero[k])) for k, st in v4.items()}
    default = Config().lf_fusion
    if args.fusion:  # the "stage now" row at other values (a setting chosen elsewhere)
        pairs = dict(kv.split("=", 1) for kv in args.fusion)
        default = dataclasses.replace(default, **{k: float(v) if "." in v else int(v)
                                                  for k, v in pairs.items()})  # type: ignore[arg-type]  # fmt: skip
    memo: dict[Any, FloatArray] = {}
    margins: dict[str, dict[str, float]] = {}
    rows: dict[str, dict[str, Any]] = {
        "v4 (no stage)": score_row(v4, zero, base),
        ("light fields alone (K = 100)" if stage is None else
         f"the stage's distance alone (K = 100, K2 = {k2})"): score_row(
            stores, {k: np.full(len(st.rows), np.inf) for k, st in stores.items()}, base),
        "rank fusion 0.5, ungated": score_row(
            stores, {k: np.full(len(st.rows), 0.5) for k, st in stores.items()}, base),
    }  # fmt: skip
    if stage is not None:  # the product before the field vectors, in the same run
        import copy

        before = copy.copy(split)
        before.dl, before.dv = split.light, None
        plain = {k: Store(before, before.store(v)) for k, v in names.items()}
        rows["the stage before the field vectors (light field distance, K = 100)"] = score_row(
            plain, {k: gate_weights(st, Config().lf_fusion) for k, st in plain.items()}, base
        )
    if getattr(args, "mesh_lfd", False):  # the peer: every shape ranked by the mesh LFD
        rows["mesh light field descriptor (every shape ranked)"] = mesh_lfd_row(
            split, args.datasets, names, base
        )
    legacy = dataclasses.replace(default, **LEGACY)  # type: ignore[arg-type]
    rows["stage before (overlap^3, own spread over 100)"] = score_row(
        stores, {k: gate_weights(st, legacy) for k, st in stores.items()}, base
    )
    spread_gate = dataclasses.replace(default, **SPREAD_GATE)  # type: ignore[arg-type]
    rows["spread gate (pooled median spread, the default before the ratio)"] = score_row(
        stores, {k: gate_weights(st, spread_gate, memo) for k, st in stores.items()}, base
    )
    margins["spread gate (pooled median spread, the default before the ratio)"] = gate_margin(
        stores, spread_gate, memo
    )
    if args.grid == "spread":
        settings = [dict(zip(GRID, c, strict=True)) for c in itertools.product(*GRID.values())]
        settings = [s for s in settings if s["contrast_floor"] > 0 or s["contrast_ramp"] == 0.05]
        subsets = (("own spread (pool 0)", lambda s: s["pool"] == 0),
                   ("no contrast floor", lambda s: s["contrast_floor"] == 0))  # fmt: skip
    else:
        settings = ratio_settings()
        subsets = (("the local spread alone (ratio weight 0)", lambda s: s["ratio_weight"] == 0),
                   ("the ratio alone (ratio weight 1)", lambda s: s["ratio_weight"] == 1))  # fmt: skip
    tmp = None
    if analytic is None:
        tmp = tempfile.TemporaryDirectory(prefix="lightfield_gate_")
        analytic = analytic_stores(Path(tmp.name))
    amemo: dict[Any, Any] = {}
    fused = {}  # the analytic stores on the stage's distance
    if stage is not None and stage.fuses:
        shapes = analytic_shapes()
        fused = {k: analytic_distance(db, shapes[k], stage) for k, db in analytic.items()}

    def gates(which: str, f: Any) -> tuple[FloatArray, FloatArray]:
        return analytic_gates(analytic[which], f, amemo, fused.get(which))

    def closed(f: Any) -> bool:
        """The chain in poses shut and the rigid analytic store open (some of it)."""
        g_rigid, _ = gates("rigid", f)
        g_chain, _ = gates("chain", f)
        return bool(np.all(g_chain == 0) and np.count_nonzero(g_rigid) >= 6)

    if args.split == "validation" and not args.no_grid:
        grid = []
        t0 = time.perf_counter()
        for s in settings:
            f = dataclasses.replace(default, power=0.0, **s)  # type: ignore[arg-type]
            grid.append((s, score_row(stores, {k: gate_weights(st, f, memo)
                                          for k, st in stores.items()}, base)))  # fmt: skip
        passing = [g for g in grid if g[1]["passes"]]
        n_rule = len(passing)
        passing = [g for g in passing if closed(dataclasses.replace(default, power=0.0, **g[0]))]  # type: ignore[arg-type]
        n_chain, chain_shut = len(passing), passing

        def wide(g: tuple[dict[str, Any], Any]) -> bool:
            """Both margins: the jointed sets well above the ceiling, the rigid ones below."""
            f = dataclasses.replace(default, power=0.0, **g[0])  # type: ignore[arg-type]
            m = gate_margin(stores, f, memo)
            rigid = m["rigid_95"] <= f.ceiling or not args.rigid_margin
            return bool(m["jointed_min"] >= args.min_margin * f.ceiling and rigid)

        if args.grid == "ratio" and len(set(stores) & JOINTED_SETS) == len(JOINTED_SETS):
            passing = [g for g in passing if wide(g)]
        best = max(passing, key=lambda g: g[1]["objective"]) if passing else None
        print(f"  grid: {len(grid)} settings, {n_rule} pass the rule, {n_chain} also keep the "
              f"chain in poses shut, {len(passing)} also keep the margin "
              f"({time.perf_counter() - t0:.0f} s); chosen {best and best[0]}")  # fmt: skip
        if chain_shut is not passing and chain_shut:
            top = max(chain_shut, key=lambda g: g[1]["objective"])
            label = f"best keeping the chain shut, any margin: {top[0]}"
            rows[label] = top[1]
            f = dataclasses.replace(default, power=0.0, **top[0])  # type: ignore[arg-type]
            margins[label] = gate_margin(stores, f, memo)
        for label, keep in subsets:
            sub = [g for g in passing if keep(g[0])]
            if sub:
                top = max(sub, key=lambda g: g[1]["objective"])
                rows[f"best with {label}: {top[0]}"] = top[1]
                f = dataclasses.replace(default, power=0.0, **top[0])  # type: ignore[arg-type]
                margins[f"best with {label}: {top[0]}"] = gate_margin(stores, f, memo)
        if best is not None:
            rows[f"best of the grid: {best[0]}"] = best[1]
            f = dataclasses.replace(default, power=0.0, **best[0])  # type: ignore[arg-type]
            margins[f"best of the grid: {best[0]}"] = gate_margin(stores, f, memo)
    rows["stage now (LightFieldFusionConfig defaults)"] = score_row(
        stores, {k: gate_weights(st, default) for k, st in stores.items()}, base
    )
    if args.oracle:
        rows.update(oracle_rows(stores, base, default))
    if args.around:  # one field of the defaults moved at a time
        for field, values in AROUND.items():
            for v in values:
                f = dataclasses.replace(default, **{field: v})  # type: ignore[arg-type]
                rows[f"defaults, {field} {v:g}"] = score_row(
                    stores, {k: gate_weights(st, f) for k, st in stores.items()}, base
                )
    margins["stage now (LightFieldFusionConfig defaults)"] = gate_margin(stores, default, memo)
    for label, m in margins.items():
        f = default if ": {" not in label else dataclasses.replace(
            default, power=0.0, **_setting(label))  # fmt: skip
        if label.startswith("spread gate"):
            f = spread_gate
        m["chain_min"] = float(np.nanmin(gates("chain", f)[1]))
        m["chain_open"] = float(np.count_nonzero(gates("chain", f)[0]))
        m["analytic_rigid_open"] = float(np.count_nonzero(gates("rigid", f)[0]))
        m["ceiling"] = float(f.ceiling)
    if tmp is not None:
        tmp.cleanup()
    _print(rows, stores, args.split)
    if margins and "jointed_5" in margins[next(iter(margins))]:
        print(format_table(
            "the gate's margin: s_q of the jointed sets and of the rigid ones (every store), "
            "of the analytic chain in poses; x: over the ceiling",
            ("row", "ceiling", "jointed min", "x", "jointed 5 %", "rigid 95 %", "rigid max",
             "5 % / 95 %", "chain", "x", "chain open", "analytic rigid open"),
            [[k if ": {" not in k else k[: k.index(": {")] + " " + _short(_setting(k)),
              f"{m['ceiling']:.3f}", f"{m['jointed_min']:.3f}",
              f"{m['jointed_min'] / m['ceiling']:.2f}", f"{m['jointed_5']:.3f}",
              f"{m['rigid_95']:.3f}", f"{m['rigid_max']:.3f}", f"{m['ratio_5_95']:.2f}",
              f"{m['chain_min']:.3f}", f"{m['chain_min'] / m['ceiling']:.2f}",
              f"{m['chain_open']:.0f} / 8", f"{m['analytic_rigid_open']:.0f} / 8"]
             for k, m in margins.items()],
        ))  # fmt: skip
    return {"split": args.split, "rows": rows, "defaults": dataclasses.asdict(default),
            "field_stage": None if stage is None else dataclasses.asdict(stage),
            "margins": margins,
            "statistics": statistics(stores, default),
            "sizes": {k: len(st.rows) for k, st in stores.items()}}  # fmt: skip


def mesh_lfd_row(split: Split, sets: Sequence[str], names: dict[str, tuple[str, ...]],
                 base: dict[str, dict[str, dict[str, float]]]) -> dict[str, Any]:  # fmt: skip
    """The mesh light field descriptor's row (:func:`bench.rerank_select.lfd_split_matrix`):
    every shape of each store ranked by it alone, scored like the stage's rows."""
    import copy

    from bench.rerank_select import lfd_split_matrix

    models = [m for s in sets for m in load(s, split.split)[0].models]
    peer = copy.copy(split)
    peer.dl = lfd_split_matrix(models)
    peer.dv = None
    stores = {
        k: Store(peer, peer.store(v), candidates=len(peer.store(v))) for k, v in names.items()
    }
    return score_row(stores, {k: np.full(len(st.rows), np.inf) for k, st in stores.items()}, base)


def oracle_rows(stores: dict[str, Store], base: dict[str, dict[str, dict[str, float]]],
                f: Any) -> dict[str, dict[str, Any]]:  # fmt: skip
    """The headroom of the gate: rows whose gate knows each shape's set (not label-free).

    ``oracle``: ``g = 1`` for every shape of a rigid set, 0 for :data:`JOINTED`, at a few
    weights and rank offsets; ``oracle x contrast floor``: the oracle times the contrast
    factor of ``f`` (only the spread ceiling replaced by the labels); ``stage's gate, light
    fields alone where open``: the fusion with v4 replaced by the light field's order.
    """
    rigid = {k: ~np.isin(st.sets, JOINTED) for k, st in stores.items()}
    rows: dict[str, dict[str, Any]] = {}

    def add(label: str, weights: dict[str, FloatArray], offset: float = 60.0) -> None:
        kept = {k: st.offset for k, st in stores.items()}
        for st in stores.values():
            st.offset = offset
        try:
            rows[label] = score_row(stores, weights, base)
        finally:
            for k, st in stores.items():
                st.offset = kept[k]

    for w in (f.weight, 2 * f.weight, np.inf):
        add(f"oracle gate, weight {w:g}", {k: np.where(r, w, 0.0) for k, r in rigid.items()})
    add(f"oracle gate, weight {f.weight:g}, offset 20",
        {k: np.where(r, f.weight, 0.0) for k, r in rigid.items()}, offset=20.0)  # fmt: skip
    floor = dataclasses.replace(f, ceiling=0.0)  # the contrast factor alone
    add(f"oracle gate x contrast floor, weight {f.weight:g}",
        {k: np.where(rigid[k], gate_weights(st, floor), 0.0) for k, st in stores.items()})  # fmt: skip
    add("stage's gate, light fields alone where open",
        {k: np.where(gate_weights(st, f) > 0, np.inf, 0.0) for k, st in stores.items()})  # fmt: skip
    return rows


def statistics(stores: dict[str, Store], f: Any) -> dict[str, dict[str, dict[str, list[float]]]]:
    """5 / 50 / 95 % of the gate's statistics per set in each store (printed as a table).

    ``spread 100``: the query's own spread over its 100 candidates (the gate before);
    ``local``: the local statistic (:func:`local_spreads` at ``f``); ``pooled``: ``s_q``,
    its ``f.pool_quantile`` over the first ``f.pool`` candidates; ``contrast``: the
    contrast of the floor.
    """
    out: dict[str, dict[str, dict[str, list[float]]]] = {}
    table = []
    for name, st in stores.items():
        d = st.others(st.D)
        far = d[:, min(f.contrast_depth, d.shape[1]) - 1]
        stats = {
            "spread 100": local_spreads(st, 100, f.typical),
            "local": local_spreads(
                st, f.spread_candidates, f.typical, f.ratio_weight, f.ratio_candidates
            ),
            "pooled": gate_statistic(st, f),
            "contrast": np.median(d[:, : f.neighbours], 1) / np.maximum(far, 1e-300),
        }
        for s in dict.fromkeys(st.sets):
            rows = st.sets == s
            q = {k: np.quantile(v[rows], [0.05, 0.5, 0.95]).tolist() for k, v in stats.items()}
            out.setdefault(name, {})[str(s)] = q
            table.append([s if (name,) == (s,) else f"{s} in {name}",
                          *("/".join(f"{x:.3f}" for x in q[k]) for k in stats)])  # fmt: skip
    print(format_table("the gate's statistics, 5 / 50 / 95 % of the queries",
                       ("set", "spread 100", "local", "pooled", "contrast"), table))  # fmt: skip
    return out


def _print(rows: dict[str, dict[str, Any]], stores: dict[str, Store], split: str) -> None:
    cols = [(k, s) for k, st in stores.items() for s in dict.fromkeys(st.sets)]
    table = []
    for label, e in rows.items():
        cells = [
            "{nn:.3f} / {first_tier:.3f} / {dcg:.3f}".format(**e["stores"][k][s]) for k, s in cols
        ]
        worst = f"{e['worst_queries']:+.1f} ({e['worst_at']})" if e["worst_at"] else "0"
        short = label if ": {" not in label else label[: label.index(": {")] + ": " + _short(
            _setting(label))  # fmt: skip
        table.append([short, *cells, f"{e['objective']:.4f}", worst])
    heads = [k if (k,) == (s,) else f"{s} in {k}" for k, s in cols]
    print(format_table(
        f"the lightfield stage's gate, {split} splits, each set and mix a store (NN / 1-T / DCG)",
        ("row", *heads, "objective", "worst (queries)"), table,
    ))  # fmt: skip


def parser() -> argparse.ArgumentParser:
    """The command line of :func:`main` (and of the studies that score their own distances)."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.lightfield_gate", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(SETS), choices=CHOICES)
    ap.add_argument("--no-grid", action="store_true", help="only the fixed rows")
    ap.add_argument("--min-margin", type=float, default=MIN_MARGIN,
                    help="the ratio grid's least jointed statistic over the ceiling")  # fmt: skip
    ap.add_argument("--rigid-margin", action=argparse.BooleanOptionalAction, default=True,
                    help="the ratio grid's second margin: every rigid set's 95 %% at most the "
                         "ceiling (--no-rigid-margin: the jointed margin alone)")  # fmt: skip
    ap.add_argument("--grid", default="ratio", choices=["ratio", "spread"],
                    help="the selection's grid: the ratio gate's (default) or the spread gate's")  # fmt: skip
    ap.add_argument("--around", action="store_true", help="the defaults, one field moved")
    ap.add_argument("--oracle", action="store_true",
                    help="the headroom: gates that know which sets are jointed")  # fmt: skip
    ap.add_argument("--lf-n-balls", type=int, default=None,
                    help="light fields of the packing continued to N balls (default: the product's)")  # fmt: skip
    ap.add_argument("--lf-within", type=int, default=0,
                    help="take the --lf-n-balls prefix of the packing continued to this many")  # fmt: skip
    ap.add_argument("--lf-source", default=None, choices=["balls", "field"],
                    help="what the light fields see (LightFieldConfig.source; default the product's)")  # fmt: skip
    ap.add_argument("--lf-set", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="LightFieldConfig fields of the light fields (e.g. resolution=128)")  # fmt: skip
    ap.add_argument("--fusion", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="LightFieldFusionConfig fields of the 'stage now' row")  # fmt: skip
    ap.add_argument("--mesh-lfd", action="store_true",
                    help="the peer's row: every shape ranked by the mesh light field descriptor")  # fmt: skip
    ap.add_argument("--field-vectors", action=argparse.BooleanOptionalAction, default=None,
                    help="the stage with the field vectors (default: the product's; "
                         "--no-field-vectors: the light field alone, today's rows)")  # fmt: skip
    ap.add_argument("--fv-weights", type=float, nargs=2, default=None, metavar=("A", "C"),
                    help="weights of the depth and the harmonic distances")  # fmt: skip
    ap.add_argument("--fv-scales", type=float, nargs=3, default=None,
                    metavar=("M_L", "M_B", "M_H"), help="scales of l, b and h")  # fmt: skip
    ap.add_argument("--fv-candidates", type=int, default=None, metavar="K2",
                    help="the field vectors' nearest added to version 4's K")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    args = parser().parse_args(argv)
    result = select(args)
    tag = f"_n{args.lf_n_balls}" if args.lf_n_balls is not None else ""
    tag += f"_{args.lf_source}" if args.lf_source is not None else ""
    tag += "".join(f"_{kv.replace('=', '')}" for kv in args.lf_set)
    tag += "_fv" if result["field_stage"] is not None else ""
    out = args.out or RESULTS / f"lightfield_gate_{args.split}{tag}.json"
    write_json(out, result)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
