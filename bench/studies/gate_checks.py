"""What a light field gate is checked against: jointed subjects, analytic stores, margins.

A library of the gate's studies (not a script), used by the gate's selection (:mod:`bench.studies.lightfield_gate`) and by the tests of the
``"lightfield"`` stage:

* :data:`JOINTED`: the bench sets whose subjects are jointed (figures, people), where the
  light field finds another pose and the gate must stay shut;
* :func:`analytic_stores` and :func:`analytic_gates`: two small analytic stores (rigid
  boxes and rods; one chain in eight poses) and the product scorer's gate on them, at
  any :class:`query.search.tuning.StageTuning`;
* :func:`margin`: how far apart a gate statistic puts the jointed sets and the rigid ones
  (:func:`gate_margin`: of a gate's statistic on the bench's stores);
* :data:`RATIO_GRID`, :data:`CEILINGS`, :func:`ratio_settings`: the ratio gate's grid.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.support.stores import Store, gate_statistic
from bench.support.tuning import at_unit
from query.search.lightfield_spread import pooled
from shapedb.config.core import Config
from shapedb.signature.lightfield import light_field_distance

__all__ = [
    "JOINTED",
    "JOINTED_SETS",
    "ANALYTIC",
    "RATIO_GRID",
    "CEILINGS",
    "MIN_MARGIN",
    "MARGIN",
    "chain",
    "analytic_shapes",
    "analytic_stores",
    "analytic_gates",
    "margin",
    "gate_margin",
    "ratio_settings",
]

FloatArray = NDArray[np.float64]
#: The stage's distance from the light field's: ``(query id, candidate ids, dl) -> (c,)``.
Distance = Callable[[int, NDArray[np.int64], NDArray[np.float64]], NDArray[np.float64]]

#: Sets whose subjects are jointed (the light field finds another pose): the oracle's "off".
JOINTED = ("figures", "people")
JOINTED_SETS = set(JOINTED)


#: ``--grid ratio`` (the default): the local statistic ``spread ** (1 - b) * ratio ** b``
#: pooled by a quantile; ``ceilings[b]``: the ceilings tried at ``b`` (the statistic's
#: scale moves with ``b``); ``ramp_share``: ``ramp = share * ceiling``; the contrast floor
#: 0.3 over depth 30.
RATIO_GRID: dict[str, tuple[Any, ...]] = {
    "weight": (4.0, 8.0),
    "spread_candidates": (3, 5),
    "ratio_weight": (0.0, 0.2, 0.33, 0.5, 1.0),
    "ratio_candidates": (30, 100),
    "pool": (20, 30),
    "pool_quantile": (0.25, 0.5),
    "ramp_share": (0.1, 0.2),
    "contrast_ramp": (0.05, 0.2),
}
CEILINGS = {
    0.0: (0.09, 0.10, 0.11, 0.13),
    0.2: (0.15, 0.16, 0.17, 0.18),
    0.33: (0.20, 0.21, 0.22, 0.23, 0.24),
    0.5: (0.28, 0.30, 0.32, 0.34),
    1.0: (1.5, 1.7, 1.9),
}
#: The selection's margins (``--grid ratio``): the least pooled statistic of a jointed set
#: (figures, people; alone and in every mix) at least this many times the ceiling (the
#: gate before this grid: 1.46), and the 95 % of every rigid set (alone and in every mix)
#: at most the ceiling: a gate that lets the rigid collections in, with a margin.
MIN_MARGIN = 1.4


def ratio_settings() -> list[dict[str, Any]]:
    """:data:`RATIO_GRID` x :data:`CEILINGS` as fields (no duplicate at ``b = 0``)."""
    import itertools

    out = []
    for c in itertools.product(*RATIO_GRID.values()):
        g = dict(zip(RATIO_GRID, c, strict=True))
        if g["ratio_weight"] == 0 and g["ratio_candidates"] != RATIO_GRID["ratio_candidates"][-1]:
            continue
        share = g.pop("ramp_share")
        for ceiling in CEILINGS[g["ratio_weight"]]:
            out.append({**g, "ceiling": ceiling, "ramp": float(np.round(share * ceiling, 4))})
    return out


def chain(angle: float, bend: float) -> Any:
    """Four balls joined by rods, its two joints bent by ``angle`` and ``bend`` (radians)."""
    from shapedb.geometry.implicit import Capsule, Sphere

    pts = [np.zeros(3)]
    heading = 0.0
    for turn in (0.0, angle, bend):
        heading += turn
        pts.append(pts[-1] + 1.6 * np.array([np.cos(heading), np.sin(heading), 0.0]))
    shape: Any = Sphere(tuple(pts[0]), 0.45)
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        shape = shape | Capsule(tuple(a), tuple(b), 0.25) | Sphere(tuple(b), 0.45)
    return shape


#: The analytic stores' configuration (small and fast): the stage's, coarser.
ANALYTIC = {"rerank": "lightfield", "resolution": 48, "n_balls": 128}


def analytic_shapes() -> dict[str, list[tuple[str, Any]]]:
    """The analytic stores' shapes by name: ``rigid`` (4 boxes, 4 rods), ``chain`` (8 poses)."""
    from shapedb.geometry.implicit import Box, Capsule

    poses = [(a, b) for a in (0.0, 0.5, 1.0, 1.5) for b in (-0.8, 0.8)]
    return {
        "rigid": [(f"box{k}", Box((0, 0, 0), (2.0 + 0.15 * k, 1.0, 0.6 + 0.05 * k)))
                  for k in range(4)] + [(f"rod{k}", Capsule((0, 0, 0), (3.0 + 0.2 * k, 0, 0), 0.4))
                                        for k in range(4)],
        "chain": [(f"pose{k}", chain(a, b)) for k, (a, b) in enumerate(poses)],
    }  # fmt: skip


def analytic_stores(root: Path) -> dict[str, Any]:
    """Two stores under ``root``: ``rigid`` (4 boxes, 4 rods) and ``chain`` (8 poses of one).

    A gate must open on the first and stay shut on the second (a jointed subject alone
    in a store, none of the people's other subjects in the same pose to betray it).
    The shapes are :func:`analytic_shapes`'.
    """
    from query.database import connect

    # no stored field vectors: the stage sees the light field alone, and a field-vector
    # run passes its fused distance to analytic_gates (bench.support.field_vectors.analytic_distance)
    config = Config().with_options(**ANALYTIC, fv_enabled=False)
    out = {}
    for name, shapes in analytic_shapes().items():
        out[name] = connect(root / name, config=config)
        out[name].ingest(shapes, workers=1)
    return out


def analytic_gates(
    db: Any,
    f: Any,
    memo: dict[Any, Any] | None = None,
    distance: Distance | None = None,
    stage: Any = None,
) -> tuple[FloatArray, FloatArray]:
    """(n,) ``g(q)`` and (n,) ``s_q`` of every shape of ``db`` querying it, at ``f``.

    The product's scorer (:class:`query.search.rerank_lightfield.LightFieldFusion`); ``s_q``
    NaN with ``f.pool`` 0.

    ``f``: the stage's numbers, a :class:`query.search.tuning.StageTuning` (the store's own
    light fields and descriptor); the local statistics computed by
    :func:`query.search.lightfield_spread.local_spreads` under ``f``, every shape a candidate.
    ``distance``: the stage's distance in place of the light field's,
    ``distance(query id, candidate ids, light field distances)`` (the field vectors'
    fusion, :func:`bench.support.field_vectors.analytic_distance`), in the statistics and the
    gate alike; ``memo`` keys it by its identity. ``stage``: the
    :class:`bench.support.field_vectors.FieldStage` of that distance, whose ``scale`` is the
    unit (:func:`bench.support.tuning.at_unit`; without it, ``f``'s).
    """
    from query.search.index import open_index
    from query.search.lightfield_spread import calibration, local_spreads
    from query.search.rerank_lightfield import COLUMN, LightFieldFusion, stored_arrays

    f = at_unit(f, stage)
    config = db.config
    index, reader = open_index(db), stored_arrays(db)
    key = (str(db.store.path), f.spread_candidates, f.scale, f.ratio_weight,
           f.ratio_candidates if f.ratio_weight > 0 else 0, id(distance))  # fmt: skip
    if (memo is None or key not in memo) and distance is not None:
        got = _fused_spreads(index, reader, config, f, distance)
        if memo is None:
            memo = {}
        memo[key] = dict(zip(got[0].tolist(), got[1].tolist(), strict=True))
    elif memo is None or key not in memo:
        got = local_spreads(index, reader, config, None, f)
        if memo is None:
            memo = {}
        memo[key] = dict(zip(got[0].tolist(), got[1].tolist(), strict=True))
    stat = memo[key]
    scorer = LightFieldFusion(config, tuning=f)
    ids = np.sort(np.asarray(index.ids_, np.int64)[np.asarray(index.alive_, bool)])
    gates, pooled_s = [], []
    for sid in ids:
        feature = index.features_of(int(sid))
        assert feature is not None, "every stored shape is indexed"
        cand, dist = index.search(feature[None], len(ids))
        c = cand[0]
        fields = reader(COLUMN, np.append(c, sid))
        assert fields is not None, "the analytic stores keep light fields"
        dl = light_field_distance(fields[-1][None], fields[:-1])[0]
        if distance is not None:
            dl = distance(int(sid), c, dl)
        spreads = np.array([stat.get(int(i), np.nan) for i in c])
        gates.append(scorer.gate(dist[0] / calibration(config), dl, c == sid, spreads))
        pooled_s.append(pooled(spreads[: f.pool], f.pool_quantile) if f.pool > 0 else np.nan)
    return np.asarray(gates), np.asarray(pooled_s, np.float64)


def _fused_spreads(index: Any, reader: Any, config: Any, f: Any,
                   distance: Distance) -> tuple[NDArray[np.int64], FloatArray]:  # fmt: skip
    """:func:`query.search.lightfield_spread.local_spreads` of every alive shape on ``distance``."""
    from query.search.lightfield_spread import calibration, local_statistic
    from query.search.rerank_lightfield import COLUMN

    ids = np.sort(np.asarray(index.ids_, np.int64)[np.asarray(index.alive_, bool)])
    reach = max(f.spread_candidates, f.ratio_candidates if f.ratio_weight > 0 else 0)
    m = min(reach, len(ids) - 1)
    out = np.full(len(ids), np.nan)
    for k, sid in enumerate(ids):
        feature = index.features_of(int(sid))
        near, dist = index.search(feature[None], m + 1)
        keep = (near[0] >= 0) & (near[0] != sid)
        nb, d = near[0][keep][:m], dist[0][keep][:m]
        fields = reader(COLUMN, np.append(nb, sid))
        dl = light_field_distance(fields[-1][None], fields[:-1])[0]
        out[k] = local_statistic(d / calibration(config), distance(int(sid), nb, dl), f)
    return ids, out


#: The keys of :func:`margin`.
MARGIN = ("jointed_5", "rigid_95", "jointed_min", "rigid_max", "ratio_5_95", "ratio_min_max")


def margin(pooled_by: dict[tuple[str, str], FloatArray]) -> dict[str, float]:
    """The gate's separation: the pooled statistic's lowest jointed over highest rigid.

    ``pooled_by[(store, set)]``: the set's queries' ``s_q`` in that store. Over every set
    in every store: ``ratio_5_95`` the least 5 % of a :data:`JOINTED` set over the largest
    95 % of a rigid one (> 1: one ceiling between them shuts 95 % of every jointed set and
    opens 95 % of every rigid one), ``ratio_min_max`` the same of the least and the
    largest; empty when the stores hold only one kind.
    """
    jointed = [v for (_, s), v in pooled_by.items() if s in JOINTED]
    rigid = [v for (_, s), v in pooled_by.items() if s not in JOINTED]
    if not jointed or not rigid:
        return {}
    out = {
        "jointed_5": min(float(np.quantile(v, 0.05)) for v in jointed),
        "rigid_95": max(float(np.quantile(v, 0.95)) for v in rigid),
        "jointed_min": min(float(v.min()) for v in jointed),
        "rigid_max": max(float(v.max()) for v in rigid),
    }
    out["ratio_5_95"] = out["jointed_5"] / out["rigid_95"]
    out["ratio_min_max"] = out["jointed_min"] / out["rigid_max"]
    return out


def gate_margin(stores: dict[str, Store], f: Any,
                memo: dict[Any, FloatArray] | None = None) -> dict[str, float]:  # fmt: skip
    """:func:`margin` of ``f``'s pooled statistic over every set in every store."""
    return margin({(k, str(s)): gate_statistic(st, f, memo)[st.sets == s]
                   for k, st in stores.items() for s in dict.fromkeys(st.sets)})  # fmt: skip
