"""How much the ``"lightfield"`` stage's light field should count, per store and per query.

The selection of the stage's gate: its grids, the gates before it and their margins.
The product's stage at its defaults, measured per set, is :mod:`bench.studies.rerank_stage`, whose
rows (:func:`bench.studies.rerank_stage.baseline_rows`) every run here starts from.

Usage (from the repository root)::

    python -m bench.studies.lightfield_gate                      # validation: the grid, the choice
    python -m bench.studies.lightfield_gate --split test         # test: the rows chosen on validation
    python -m bench.studies.lightfield_gate --lf-source field    # the same on the field's light fields

Every bench set's split (meshes; the cached balls of :func:`bench.support.cached.load`, nothing
decomposed) is a store of its own, and so are the mixed stores of :data:`bench.support.stores.MIXES` (web +
figures, web + people, generic + parts, all six). In each store every shape queries the
others: its ``K = 100`` nearest by version 4's stored distance (ties by ascending id, the
query among them, as ``query.search.rerank.search`` hands them over) are re-ranked by the gated
reciprocal rank fusion of :class:`query.search.rerank_lightfield.LightFieldFusion`,
``1 / (o + rank_d) + w g(q) / (o + rank_l)``, and scored (NN / 1-T / DCG) per set inside
the store. Rows, in the same run: version 4 (no stage), the balls' light fields alone,
the gates before (:data:`LEGACY`, :data:`SPREAD_GATE`), the product's stage at its
defaults, on validation the grid's choices, and with ``--oracle`` the gate's headroom
(:func:`oracle_rows`: gates that know which sets are jointed); the statistics of each
store and the gate's margin (:func:`bench.studies.gate_checks.margin`) are printed beside.

The selection (validation, ``--grid ratio``, the default): every setting of
:func:`bench.studies.gate_checks.ratio_settings` that passes the rule (no set, alone or in a
mix, more than two queries below v4 on NN, 1-T or DCG), keeps the analytic chain in
poses shut through the product's scorer (:func:`bench.studies.gate_checks.analytic_stores`) and
keeps both margins (:data:`bench.studies.gate_checks.MIN_MARGIN`); the best objective among them
is chosen. ``--grid spread``: the grid of the spread gate (:data:`GRID`), by the rule
alone.

The light field distances (the store's float32 light fields,
:func:`shapedb.signature.lightfield.record_light_field`, every pair of the split's six sets) are
cached under ``$SHAPEDB_BENCH_CACHE/lightfield_gate`` keyed by the models and the code of
``shapedb/signature/lightfield.py`` and ``shapedb/signature/lightfield_descriptor.py``, so a changed silhouette
re-computes them and the selection re-runs in one command. Written to
bench/results/studies/lightfield_gate_<split>.json. A held-out set that :mod:`bench.support.cached` knows
(``webplus``) is measured by ``python -m bench.studies.rerank_stage --datasets webplus figures people``
(it and its mixes with the figures and the people). ``--lf-n-balls N``: the light fields of
the packing continued to N balls (``LightFieldConfig.n_balls``, decomposed and cached by
:func:`bench.support.packings.longer`; ``--lf-within M``: the first N by radius of the packing
continued to M); version 4 stays that of the cached balls. ``--lf-source field``: the
light fields of the field's inside (``LightFieldConfig.source``, computed once per model
and cached by :mod:`bench.support.inside_fields`); ``--lf-set FIELD=VALUE``: other
``LightFieldConfig`` fields (e.g. ``resolution=128``).

The field vectors (:mod:`bench.support.field_vectors`): ``--field-vectors`` scores the stage whose
distance fuses the light field distance with the L1 distances of the field's depth
buffers and harmonics (fixed scales) and whose candidates are the union of version 4's
K and the field vectors' K2 nearest, everywhere the stage uses the light field distance
(ranks, the gate's statistics, the analytic stores); ``--fv-weights``, ``--fv-scales``,
``--fv-candidates`` replace the product's values (:data:`query.search.tuning.PRODUCT`'s),
and ``--no-field-vectors`` keeps the light field alone. Such a run also scores the stage
before the field vectors (the light field distance, K alone) in the same run.
``--mesh-lfd``: the peer's row, every shape of each store ranked by the mesh
light field descriptor (:func:`bench.support.lightfield.lfd_split_matrix`, cached).
``--no-rigid-margin``: the ratio grid keeps the jointed margin alone.

The shared-neighbour term (:mod:`query.search.lightfield_neighbours`): "stage now" has the product's
(``--shared K BETA``: another), beside the stage without it; ``--shared-grid`` adds every
``k`` x ``beta`` of :data:`SHARED_GRID` (:func:`bench.support.stores.shared_rows`).
``--grid-term``: the selection's grid scored with the product's shared-neighbour term on
(the stage a store runs). ``--contrast-grid``: the stage now at every contrast floor x ramp
x depth of :data:`CONTRAST_GRID`, its term on, and the best of them by
the rule (:func:`contrast_rows`).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import format_table, write_json
from bench.studies.gate_checks import (
    JOINTED,
    JOINTED_SETS,
    MIN_MARGIN,
    analytic_gates,
    analytic_shapes,
    analytic_stores,
    gate_margin,
    ratio_settings,
)
from bench.studies.rerank_stage import baseline_rows
from bench.support.stores import (
    CHOICES,
    SETS,
    STAGE_NOW,
    Split,
    Store,
    gate_statistic,
    gate_weights,
    local_spreads,
    rows_table,
    score_row,
    shared_rows,
    shared_stores,
)
from bench.support.tuning import parse_value, unit_of
from query.search.tuning import PRODUCT

__all__ = [
    "GRID",
    "SHARED_GRID",
    "CONTRAST_GRID",
    "contrast_rows",
    "select",
    "oracle_rows",
    "statistics",
    "parser",
    "main",
]

FloatArray = NDArray[np.float64]
RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


def _short(setting: dict[str, Any]) -> str:
    """A grid setting in a few characters."""
    names = {"weight": "w", "spread_candidates": "m", "ratio_weight": "b",
             "ratio_candidates": "c", "pool": "pool", "pool_quantile": "q",
             "contrast_ramp": "cramp", "contrast_floor": "cfloor", "contrast_depth": "cdepth",
             "ceiling": "ceil", "ramp": "ramp"}  # fmt: skip
    return " ".join(f"{names.get(k, k)} {v:g}" for k, v in setting.items())


def _setting(label: str) -> dict[str, Any]:
    """The grid setting a row's label ends with."""
    import ast

    return dict(ast.literal_eval(label[label.index(": {") + 2 :]))


#: The grid of the selection (:class:`query.search.tuning.StageTuning` fields; neighbours 5).
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
#: The gate before the pooled spread: the query's own spread over 100, times the overlap of
#: its nearest by either distance to the power :data:`LEGACY_POWER`.
LEGACY = {"weight": 8.0, "ceiling": 0.09, "spread_candidates": 100, "pool": 0,
          "contrast_floor": 0.0, "ramp": 0.02, "ratio_weight": 0.0}  # fmt: skip
LEGACY_POWER = 3.0


#: The shared-neighbour grid of ``--shared-grid``: ``k`` x ``beta``.
SHARED_GRID = ((2, 3, 4, 5), (0.4, 0.8, 1.6))
#: The contrast grid of ``--contrast-grid``: ``contrast_floor`` x ``contrast_ramp`` x
#: ``contrast_depth`` (floor 0, the contrast off, once).
CONTRAST_GRID = ((0.0, 0.1, 0.2, 0.25, 0.3, 0.35), (0.05, 0.1, 0.2), (20, 30, 50))


def contrast_rows(stores: dict[str, Store], split: Split, f: Any,
                  base: dict[str, dict[str, dict[str, float]]],
                  within: str = "store") -> dict[str, dict[str, Any]]:  # fmt: skip
    """The stage at the fusion ``f`` with its contrast at every setting of :data:`CONTRAST_GRID`.

    Every row keeps ``f``'s other gate fields and its shared-neighbour term (the gate is
    chosen for the stage the product runs); labelled ``"contrast: {...}"`` with the
    setting, and last ``"best of the contrast grid: {...}"``, the highest objective among
    the rows that pass the rule (no set more than two queries below version 4).
    """
    term = shared_stores(stores, split, f, within)
    rows: dict[str, dict[str, Any]] = {}
    for floor, ramp, depth in itertools.product(*CONTRAST_GRID):
        if floor == 0 and (ramp, depth) != (CONTRAST_GRID[1][0], CONTRAST_GRID[2][0]):
            continue  # the contrast off: ramp and depth unused
        s = {"contrast_floor": floor, "contrast_ramp": ramp, "contrast_depth": depth}
        g = dataclasses.replace(f, **s)
        rows[f"contrast: {s}"] = score_row(
            term, {k: gate_weights(st, g) for k, st in stores.items()}, base)  # fmt: skip
    passing = {k: r for k, r in rows.items() if r["passes"]}
    if passing:
        top = max(passing, key=lambda k: passing[k]["objective"])
        rows["best of the contrast grid: " + top.split(": ", 1)[1]] = passing[top]
    return rows


def select(args: argparse.Namespace, split: Split | None = None,
           analytic: dict[str, Any] | None = None) -> dict[str, Any]:  # fmt: skip
    """Rows of every store; on validation the grid and its choice; returns the JSON.

    ``split``: the shapes and distances to score (default: :class:`Split` of ``args``,
    fused with the field vectors of :func:`bench.support.field_vectors.stage_of` ``args``; a
    study passes its own distances this way; a split with a ``stage``
    (:func:`bench.support.field_vectors.fuse`) takes its union candidates and checks the
    analytic stores on its distance). ``analytic``: the analytic stores
    (:func:`bench.studies.gate_checks.analytic_stores`), built here when None.
    """
    from bench.support.field_vectors import analytic_distance, fuse, stage_of

    t0 = time.perf_counter()
    if split is None:
        split = Split(
            args.split, args.datasets, args.lf_n_balls, args.lf_within, args.lf_source, args.lf_set
        )
        chosen = stage_of(args)
        if chosen is not None:
            split = fuse(split, args.datasets, chosen)
    stage = getattr(split, "stage", None)
    stores, base, rows = baseline_rows(split, args.datasets,
                                       mesh_lfd=getattr(args, "mesh_lfd", False))  # fmt: skip
    print(f"  {len(split.sets)} shapes, {len(stores)} stores ({time.perf_counter() - t0:.0f} s)")
    default = PRODUCT
    if args.fusion:  # the "stage now" row at other values (a setting chosen elsewhere)
        pairs = dict(kv.split("=", 1) for kv in args.fusion)
        default = dataclasses.replace(default, **{k: parse_value(v) for k, v in pairs.items()})
    if getattr(args, "shared", None):  # the term of the "stage now" row, not the product's
        default = dataclasses.replace(default, shared_neighbours=int(args.shared[0]),
                                      shared_weight=float(args.shared[1]))  # fmt: skip
    memo: dict[Any, FloatArray] = {}
    margins: dict[str, dict[str, float]] = {}
    legacy = dataclasses.replace(default, **LEGACY)  # type: ignore[arg-type]
    rows["stage before (overlap^3, own spread over 100)"] = score_row(
        stores, {k: gate_weights(st, legacy, power=LEGACY_POWER) for k, st in stores.items()}, base
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
        return analytic_gates(analytic[which], f, amemo, fused.get(which), stage)

    def closed(f: Any) -> bool:
        """The chain in poses shut and the rigid analytic store open (some of it)."""
        g_rigid, _ = gates("rigid", f)
        g_chain, _ = gates("chain", f)
        return bool(np.all(g_chain == 0) and np.count_nonzero(g_rigid) >= 6)

    if args.split == "validation" and not args.no_grid:
        grid = []
        t0 = time.perf_counter()
        # --grid-term: each setting scored with the product's shared-neighbour term on
        scored = (
            shared_stores(stores, split, default) if getattr(args, "grid_term", False) else stores
        )
        for s in settings:
            f = dataclasses.replace(default, **s)  # type: ignore[arg-type]
            grid.append((s, score_row(scored, {k: gate_weights(st, f, memo)
                                          for k, st in stores.items()}, base)))  # fmt: skip
        passing = [g for g in grid if g[1]["passes"]]
        n_rule = len(passing)
        passing = [g for g in passing if closed(dataclasses.replace(default, **g[0]))]  # type: ignore[arg-type]
        n_chain, chain_shut = len(passing), passing

        def wide(g: tuple[dict[str, Any], Any]) -> bool:
            """Both margins: the jointed sets well above the ceiling, the rigid ones below."""
            f = dataclasses.replace(default, **g[0])  # type: ignore[arg-type]
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
            f = dataclasses.replace(default, **top[0])  # type: ignore[arg-type]
            margins[label] = gate_margin(stores, f, memo)
        for label, keep in subsets:
            sub = [g for g in passing if keep(g[0])]
            if sub:
                top = max(sub, key=lambda g: g[1]["objective"])
                rows[f"best with {label}: {top[0]}"] = top[1]
                f = dataclasses.replace(default, **top[0])  # type: ignore[arg-type]
                margins[f"best with {label}: {top[0]}"] = gate_margin(stores, f, memo)
        if best is not None:
            rows[f"best of the grid: {best[0]}"] = best[1]
            f = dataclasses.replace(default, **best[0])  # type: ignore[arg-type]
            margins[f"best of the grid: {best[0]}"] = gate_margin(stores, f, memo)
    shared = list(itertools.product(*SHARED_GRID)) if getattr(args, "shared_grid", False) else []
    rows.update(shared_rows(stores, split, default, base, shared,
                            getattr(args, "shared_within", "store")))  # fmt: skip
    if getattr(args, "contrast_grid", False):
        rows.update(contrast_rows(stores, split, default, base,
                                  getattr(args, "shared_within", "store")))  # fmt: skip
    if args.oracle:
        rows.update(oracle_rows(stores, base, default))
    if args.around:  # one field of the defaults moved at a time
        for field, values in AROUND.items():
            for v in values:
                f = dataclasses.replace(default, **{field: v})  # type: ignore[arg-type]
                rows[f"defaults, {field} {v:g}"] = score_row(
                    stores, {k: gate_weights(st, f) for k, st in stores.items()}, base
                )
    margins[STAGE_NOW] = gate_margin(stores, default, memo)
    for label, m in margins.items():
        f = default if ": {" not in label else dataclasses.replace(
            default, **_setting(label))  # fmt: skip
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
            "spread 100": local_spreads(st, 100, unit_of(f, st.stage)),
            "local": local_spreads(
                st, f.spread_candidates, unit_of(f, st.stage), f.ratio_weight, f.ratio_candidates
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
    def short(label: str) -> str:
        return label if ": {" not in label else label[: label.index(": {")] + ": " + _short(
            _setting(label))  # fmt: skip

    print(rows_table(
        f"the lightfield stage's gate, {split} splits, each set and mix a store (NN / 1-T / DCG)",
        rows, stores, short,
    ))  # fmt: skip


def parser() -> argparse.ArgumentParser:
    """The command line of :func:`main` (and of the studies that score their own distances)."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.lightfield_gate", description=__doc__.split("\n")[0]
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
                    help="StageTuning fields of the 'stage now' row")  # fmt: skip
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
    ap.add_argument("--shared", nargs=2, default=None, metavar=("K", "BETA"),
                    help="the shared-neighbour term of the 'stage now' row (default: the product's)")  # fmt: skip
    ap.add_argument("--shared-grid", action="store_true",
                    help="the 'stage now' row at every k x beta of SHARED_GRID")  # fmt: skip
    ap.add_argument("--grid-term", action="store_true",
                    help="score the selection's grid with the product's shared-neighbour term on")  # fmt: skip
    ap.add_argument("--contrast-grid", action="store_true",
                    help="the 'stage now' row at every contrast of CONTRAST_GRID, with its term")  # fmt: skip
    ap.add_argument("--shared-within", default="store", choices=["store", "candidates"],
                    help="where a shape's N_k is taken: the whole store, or its own candidates")  # fmt: skip
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
