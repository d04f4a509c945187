"""The light field stage's stores: every set of a split together, and one store's rankings.

:class:`Split` holds a split's shapes (sets, labels), version 4's stored distances and the
stage's distance (the light fields', or its fusion with the field vectors:
:func:`bench.support.field_vectors.fuse`); :class:`Store` one store's candidate lists
(version 4's K, and with the field vectors the union with their K2 nearest) and its
rankings at per-query weights; :func:`gate_weights` the product's own gate
(:meth:`query.search.rerank_lightfield.LightFieldFusion.gate`, at any
:class:`query.search.tuning.StageTuning`) on a store; :func:`score_row` a row
of scores against version 4 with the two-queries rule. Used by :mod:`bench.studies.rerank_stage` (the
product's stage at its defaults) and by the studies that tune it
(:mod:`bench.studies.lightfield_gate`, :mod:`bench.studies.field_choice`, ...).
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import format_table
from bench.sets.datasets import CACHE_DIR
from bench.support import cached, inside_fields
from bench.support.cached import load
from bench.support.features import kernel_features
from bench.support.packings import light_field_balls
from bench.support.tuning import OverlapFusion, at_unit, parse_value, unit_of, with_light_field
from query.search.lightfield_spread import local_statistic, pooled
from query.search.rerank_lightfield import LightFieldFusion
from query.search.tuning import PRODUCT
from shapedb.config.core import Config
from shapedb.signature import lightfield, lightfield_descriptor
from shapedb.signature.descriptor import LAYOUTS
from shapedb.signature.lightfield import light_field_distance, record_light_field

__all__ = [
    "SETS",
    "MIXES",
    "STAGE_NOW",
    "CHOICES",
    "MEASURES",
    "Split",
    "Store",
    "local_spreads",
    "shape_statistics",
    "gate_statistic",
    "gate_weights",
    "score_row",
    "shared_scale",
    "shared_stores",
    "shared_rows",
    "store_names",
    "product_split",
    "split_stores",
    "product_stores",
    "rows_table",
]

FloatArray = NDArray[np.float64]
SETS = ("web", "generic", "capod", "figures", "parts", "people")
MIXES = {
    "web+figures": ("web", "figures"),
    "web+people": ("web", "people"),
    "generic+parts": ("generic", "parts"),
    "all six": SETS,
    "webplus+figures": ("webplus", "figures"),
    "webplus+people": ("webplus", "people"),
}
#: Sets a run may name: the six, and the others :mod:`bench.support.cached` reads on request.
CHOICES = tuple(getattr(cached, "CHOICES", SETS))
MEASURES = ("nn", "first_tier", "dcg")
#: The row of the stage at the tuning a run scores (the product's unless a study says).
STAGE_NOW = "stage now (the product's StageTuning)"


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
        their fusion with the field vectors (:func:`bench.support.field_vectors.fuse`).
    light : (n, n) float64
        The light field distances.
    dv : (n, n) float64 or None
        The scaled field vectors' L1 distances (a fused split's union candidates).
    stage : bench.support.field_vectors.FieldStage or None
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
        for (
            kv
        ) in lf_set:  # other light-field settings (the field's: bench.support.inside_fields.cut)
            k, v = kv.split("=", 1)
            cfg = with_light_field(cfg, **{k: parse_value(v)})
        lf_n_balls = cfg.light_field.n_balls
        for name in names:
            ds, balls = load(name, split)
            x.append(kernel_features(balls, Config()).astype(np.float32))
            if cfg.light_field_inside:  # the field's inside, cached by bench.support.inside_fields
                fields.append(inside_fields.light_fields(name, split, ds, cfg.light_field))
            else:
                seen = light_field_balls(name, split, ds, balls, cfg, within=lf_within)
                fields.append(np.stack(
                    [record_light_field(b.centers, b.radii, cfg.light_field) for b in seen]
                ))  # fmt: skip
            sets += [name] * len(balls)
            labels += [f"{name}:{lab}" for lab in ds.labels]
            tag = f"|n{lf_n_balls}w{lf_within}" if cfg.light_field_tail else ""
            tag += (f"|inside-{inside_fields.VERSION}-{cfg.light_field.centre}"
                    if cfg.light_field_inside else "")  # fmt: skip
            tag += f"|{cfg.light_field}" if lf_set else ""
            keys += [cached.model_key(m) + tag for m in ds.models]
        self.split = split
        self.sets = np.asarray(sets)
        self.labels = np.asarray(labels)
        v = np.concatenate(x).astype(np.float64)
        self.d4 = np.empty((len(v), len(v)))
        for i in range(len(v)):
            self.d4[i] = np.abs(v - v[i]).sum(axis=1)
        self.d4 /= np.log(10.0) / sum(b[3] for b in LAYOUTS[4])  # calibrated units
        self.dl = _light_field_matrix(np.concatenate(fields), keys)
        self.light = (
            self.dl
        )  # the light field distance (dl: the stage's, bench.support.field_vectors)
        self.dv: FloatArray | None = None  # the scaled field vectors' L1 (the union candidates)
        self.stage: Any = None  # bench.support.field_vectors.FieldStage of a fused split

    def store(self, names: Sequence[str]) -> NDArray[np.int64]:
        """Row indices of a store made of these sets."""
        return np.flatnonzero(np.isin(self.sets, list(names)))


def _light_field_matrix(fields: NDArray[np.float32], keys: list[str]) -> FloatArray:
    code = b"".join(Path(m.__file__).read_bytes() for m in (lightfield, lightfield_descriptor))
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
        scaled field vectors' L1, :mod:`bench.support.field_vectors`) that are not among the K,
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
    stage : bench.support.field_vectors.FieldStage or None
        The split's (its distance's unit when it fuses the field vectors).
    """

    def __init__(self, split: Split, rows: NDArray[np.int64], candidates: int = 100,
                 offset: float = 60.0, field_candidates: int = 0) -> None:  # fmt: skip
        self.rows = rows
        self.stage: Any = getattr(split, "stage", None)  # the split's FieldStage, if fused
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
            from bench.support.field_vectors import union_order

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
        self.rank_s: FloatArray | None = None  # rank_l with the shared-neighbour term
        self.keep_first = True  # the term keeps each query's first other candidate

    def with_shared(self, k: int, beta: float, scale: float, within: str = "store") -> Store:
        """This store with the shared-neighbour term in the light field's rank (a copy).

        ``rank_l`` of the copy's fused rankings ranks by ``dl / scale - beta * S(q, x)``
        over each query's candidates (:mod:`query.search.lightfield_neighbours`: ``S = |({q} ∪
        N_k(q)) ∩ ({x} ∪ N_k(x))| / (k + 1)``, every query a stored shape), and the first
        result among the query's others stays the one without the term (:meth:`rankings`).

        Parameters
        ----------
        k, beta : int, float
            The term's ``k`` and ``beta``; ``k`` 0 or ``beta`` 0: this store unchanged.
        scale : float
            The unit of ``dl`` (:func:`shared_scale`: the stage's ``scale``).
        within : str
            Where ``N_k`` is taken: ``"store"``, each shape's ``k`` nearest others over the
            whole store (``split.dl`` restricted to the store's rows, ties by position);
            ``"candidates"``, among the shape's own candidates (its list as a query, ties
            in list order), as the product's table takes them.
        """
        import copy

        out = copy.copy(self)
        if k <= 0 or beta <= 0:
            return out
        n = len(self.rows)
        k = min(int(k), n - 1)
        if within == "store":
            d = np.array(self._dl, np.float64, copy=True)
            np.fill_diagonal(d, np.inf)
            nb = np.argsort(d, axis=1, kind="stable")[:, :k]
        elif within == "candidates":
            mine = np.where(self.own | self.pad, np.inf, self.L)
            nb = np.take_along_axis(self.cand, np.argsort(mine, axis=1, kind="stable")[:, :k], 1)
        else:
            raise ValueError(f"within={within!r}: expected 'store' or 'candidates'")
        member = np.zeros((n, n), np.float32)
        member[np.arange(n)[:, None], nb] = 1.0
        member[np.arange(n), np.arange(n)] = 1.0  # {x} ∪ N_k(x); a stored query is its id
        shared = np.take_along_axis(member @ member.T, self.cand, 1) / (k + 1.0)
        value = np.where(self.pad, np.inf, self.L / scale - beta * shared)
        out.rank_s = np.empty_like(self.rank_l)
        np.put_along_axis(out.rank_s, np.argsort(value, axis=1, kind="stable"),
                          np.arange(value.shape[1], dtype=np.float64)[None, :], 1)  # fmt: skip
        return out

    def others(self, x: FloatArray) -> FloatArray:
        """(n, K - 1) ``x`` over each query's candidates without the query itself."""
        return x[~self.own].reshape(len(x), -1) if self.own.any(axis=1).all() else x[:, 1:]

    def nearest(self, c: int) -> tuple[FloatArray, FloatArray]:
        """(n, c) stored and light field distances of each shape's ``c`` nearest others.

        In the stored distance's order (ties by id), the shape left out, as the index
        hands them to :func:`query.search.lightfield_spread.local_spreads`.
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

    def spread(self, unit: float = PRODUCT.scale) -> FloatArray:
        """(n,) median light field distance (over ``unit``) over median stored distance."""
        return np.median(self.others(self.L), 1) / unit / np.median(self.others(self.D), 1)

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
        list keeps the stored-distance order. With the shared-neighbour term
        (:meth:`with_shared`), a query whose weight is above 0 is ranked with the term,
        then (unless :attr:`keep_first` is False: a study's) the first of its other
        candidates without the term is moved back to the first place among them.
        """
        w = np.asarray(weight, np.float64)
        head = self._head(w, self.rank_l)
        if self.rank_s is not None and (w > 0).any():
            plain, term = head, self._head(w, self.rank_s)
            for q in np.flatnonzero(w > 0) if self.keep_first else ():
                first = plain[q][plain[q] != q][0]
                row = term[q]
                at = int(np.flatnonzero(row != q)[0])
                if row[at] != first:
                    rest = row[row != first]
                    term[q] = np.concatenate([rest[:at], [first], rest[at:]])
            head = term
        return np.concatenate([head, self.listing[:, head.shape[1] :]], axis=1)

    def _head(self, w: FloatArray, rank_l: FloatArray) -> NDArray[np.int64]:
        """(n, C) the candidates re-ranked at weights ``w`` with light field ranks ``rank_l``."""
        n, k = self.cand.shape
        rank_d = np.arange(k, dtype=np.float64)[None, :]
        alone = np.isinf(w)
        fused = 1.0 / (self.offset + rank_d) + np.where(alone[:, None], 0.0,
                                                       w[:, None] / (self.offset + rank_l))  # fmt: skip
        fused[alone] = 1.0 / (self.offset + rank_l[alone])
        ids = self.cand
        if not self.pad.any():
            return np.take_along_axis(ids, np.lexsort((ids, -fused), axis=-1), 1)
        # the padding keeps its list order after the candidates
        at = np.broadcast_to(np.arange(k, dtype=np.float64), ids.shape)
        keys = (np.where(self.pad, at, ids), np.where(self.pad, at, -fused), self.pad.astype(int))
        return np.take_along_axis(ids, np.lexsort(keys, axis=-1), 1)

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


def local_spreads(st: Store, candidates: int, unit: float, ratio_weight: float = 0.0,
                  ratio_candidates: int = 100) -> FloatArray:  # fmt: skip
    """(n,) each stored shape's local statistic over its nearest others in the store.

    The product's :func:`query.search.lightfield_spread.local_statistic` at
    ``spread_candidates=candidates``, the unit ``unit``, ``ratio_weight`` and
    ``ratio_candidates``, of each shape's nearest others by the stored distance
    (:meth:`Store.nearest`).
    """
    f = dataclasses.replace(PRODUCT, spread_candidates=candidates,
                            ratio_weight=ratio_weight, ratio_candidates=ratio_candidates)  # fmt: skip
    d, ll = st.nearest(max(candidates, ratio_candidates) if ratio_weight > 0 else candidates)
    return np.array([local_statistic(d[i], ll[i], f, unit) for i in range(len(d))])


def shape_statistics(st: Store, f: Any, memo: dict[Any, FloatArray] | None = None) -> FloatArray:
    """(n,) every stored shape's local statistic under the fusion ``f`` (:func:`local_spreads`
    at the unit :func:`bench.support.tuning.unit_of` ``f`` and the store's stage), the
    spreads the product keeps with a store. ``memo``: kept by store and the fields read."""
    unit = unit_of(f, st.stage)
    key = ("local", id(st), f.spread_candidates, unit, f.ratio_weight,
           f.ratio_candidates if f.ratio_weight > 0 else 0)  # fmt: skip
    if memo is not None and key in memo:
        return memo[key]
    s = local_spreads(st, f.spread_candidates, unit, f.ratio_weight, f.ratio_candidates)
    if memo is not None:
        memo[key] = s
    return s


def gate_statistic(st: Store, f: Any, memo: dict[Any, FloatArray] | None = None) -> FloatArray:
    """(n,) ``s_q`` of every query under the stage's numbers ``f`` (a ``StageTuning``).

    The shape's own local statistic (:func:`shape_statistics`), or with ``f.pool`` its
    ``pool_quantile`` over the first ``pool`` candidates (the product's
    :func:`query.search.lightfield_spread.pooled`). ``memo``: results kept by store and
    the fields they read (a grid reuses them).
    """
    key = (id(st), f.spread_candidates, unit_of(f, st.stage), f.ratio_weight,
           f.ratio_candidates if f.ratio_weight > 0 else 0, f.pool, f.pool_quantile)  # fmt: skip
    if memo is not None and key in memo:
        return memo[key]
    s = shape_statistics(st, f, memo)
    if f.pool > 0:
        s = pooled(s[st.cand[:, : f.pool]], f.pool_quantile)
    if memo is not None:
        memo[key] = s
    return s


def gate_weights(
    st: Store, f: Any, memo: dict[Any, FloatArray] | None = None, power: float = 0.0
) -> FloatArray:
    """(n,) ``weight * g(q)`` under the stage's numbers ``f`` (a ``StageTuning``).

    ``g(q)`` is the product's gate (:meth:`query.search.rerank_lightfield.LightFieldFusion.gate`)
    on each query's candidates, reading the stored shapes' :func:`shape_statistics`.
    ``memo``: the pooled statistics already computed, by store and the fields they read.
    ``power`` > 0: times the overlap gate of the stage before the spread ceiling
    (:class:`bench.support.tuning.OverlapFusion`). The scorer's unit is
    :func:`bench.support.tuning.unit_of` ``f`` and the store's stage.
    """
    unit = at_unit(f, st.stage)
    scorer = (
        OverlapFusion(Config(), tuning=unit, power=power)
        if power > 0
        else LightFieldFusion(Config(), tuning=unit)
    )
    spreads = shape_statistics(st, f, memo) if f.ceiling > 0 and f.pool > 0 else None
    g = np.empty(len(st.rows))
    for q in range(len(g)):
        keep = ~st.pad[q]
        cand = st.cand[q][keep]
        g[q] = scorer.gate(st.D[q][keep], st.L[q][keep], st.own[q][keep],
                           None if spreads is None else spreads[cand])  # fmt: skip
    return f.weight * g


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


def shared_scale(split: Split, f: Any) -> float:
    """The unit of the shared-neighbour term on ``split`` under the fusion ``f``
    (:func:`bench.support.tuning.unit_of`: the split's stage's ``scale`` when it fuses the
    field vectors, else ``f``'s ``light_field_unit``; as
    :attr:`query.search.rerank_lightfield.LightFieldFusion.scale`)."""
    return unit_of(f, getattr(split, "stage", None))


def shared_stores(stores: dict[str, Store], split: Split, f: Any,
                  within: str = "store") -> dict[str, Store]:  # fmt: skip
    """``stores`` with the shared-neighbour term of the fusion ``f`` (:meth:`Store.with_shared`;
    unchanged where ``f`` has it off)."""
    k, beta = int(f.shared_neighbours), float(f.shared_weight)
    scale = shared_scale(split, f)
    return {name: st.with_shared(k, beta, scale, within) for name, st in stores.items()}


def shared_rows(stores: dict[str, Store], split: Split, f: Any,
                base: dict[str, dict[str, dict[str, float]]],
                grid: Sequence[tuple[int, float]] = (),
                within: str = "store") -> dict[str, dict[str, Any]]:  # fmt: skip
    """The "stage now" rows of the gate bench at the fusion ``f`` (its gate in every row).

    With ``f``'s shared-neighbour term on, first the same stage without it; then the stage
    at every ``(k, beta)`` of ``grid`` (a study's); last the stage at ``f``
    (:data:`STAGE_NOW`). ``within``: where ``N_k`` is taken
    (:meth:`Store.with_shared`).
    """
    gated = {k: gate_weights(st, f) for k, st in stores.items()}
    rows: dict[str, dict[str, Any]] = {}
    if f.shared_neighbours > 0 and f.shared_weight > 0:
        rows["stage now without the shared neighbours (k 0)"] = score_row(stores, gated, base)
    for k, beta in grid:
        g = dataclasses.replace(f, shared_neighbours=k, shared_weight=beta)
        rows[f"stage now, shared k {k} beta {beta:g}"] = score_row(
            shared_stores(stores, split, g, within), gated, base)  # fmt: skip
    rows[STAGE_NOW] = score_row(shared_stores(stores, split, f, within), gated, base)
    return rows


def store_names(datasets: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """The stores of a run over ``datasets``: each set alone, and each mix of :data:`MIXES`
    whose sets are all among them."""
    names: dict[str, tuple[str, ...]] = {s: (s,) for s in datasets}
    names.update({n: v for n, v in MIXES.items() if set(v) <= set(datasets)})
    return names


def product_split(split_name: str, datasets: Sequence[str] = SETS) -> Split:
    """:class:`Split` of ``datasets`` at the product's stage: fused with the product's field
    vectors (:func:`bench.support.field_vectors.fuse`) when its stage has them."""
    import argparse

    from bench.support.field_vectors import fuse, stage_of

    split = Split(split_name, datasets)
    stage = stage_of(argparse.Namespace())
    return split if stage is None else fuse(split, datasets, stage)


def split_stores(split: Split, datasets: Sequence[str]) -> tuple[
    dict[str, tuple[str, ...]], dict[str, Store], dict[str, Store], dict[str, Any]
]:  # fmt: skip
    """The stores of ``split`` over ``datasets`` (:func:`store_names`).

    Returns the names, the stage's stores (a fused split's candidates are the union of
    version 4's K and the field vectors' K2), version 4's stores (its K alone) and the
    rule's base: version 4's scores per store and set.
    """
    stage = getattr(split, "stage", None)
    k2 = stage.candidates if stage is not None else 0
    names = store_names(datasets)
    stores = {n: Store(split, split.store(v), field_candidates=k2) for n, v in names.items()}
    v4 = {n: Store(split, split.store(v)) for n, v in names.items()} if k2 > 0 else stores
    base = {n: st.per_set(st.measures(np.zeros(len(st.rows)))) for n, st in v4.items()}
    return names, stores, v4, base


def product_stores(split_name: str) -> tuple[Split, dict[str, Store], dict[str, Any]]:
    """The stores of a split of every set of :data:`SETS` at the product's stage
    (:func:`product_split`, :func:`split_stores`), and the rule's base."""
    split = product_split(split_name)
    _, stores, _, base = split_stores(split, SETS)
    return split, stores, base


def rows_table(title: str, rows: dict[str, dict[str, Any]], stores: dict[str, Store],
               label: Callable[[str], str] = str) -> str:  # fmt: skip
    """The gate bench's table of ``rows`` (:func:`score_row` entries): NN / 1-T / DCG of
    every set in every store, the objective and the worst loss; ``label`` shortens a row's
    name."""
    cols = [(k, s) for k, st in stores.items() for s in dict.fromkeys(st.sets)]
    table = []
    for name, e in rows.items():
        cells = [
            "{nn:.3f} / {first_tier:.3f} / {dcg:.3f}".format(**e["stores"][k][s]) for k, s in cols
        ]
        worst = f"{e['worst_queries']:+.1f} ({e['worst_at']})" if e["worst_at"] else "0"
        table.append([label(name), *cells, f"{e['objective']:.4f}", worst])
    heads = [k if (k,) == (s,) else f"{s} in {k}" for k, s in cols]
    return format_table(title, ("row", *heads, "objective", "worst (queries)"), table)
