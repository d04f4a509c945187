"""The store's local light field spreads: an index-time statistic of the ``"lightfield"`` stage.

A stored shape's *local spread* is the median light field distance (over its unit,
``StageTuning.scale`` when fused with the field vectors, else ``light_field_unit``) over
the median stored distance (in version 4's calibrated units, :func:`calibration`) among its ``spread_candidates`` nearest other
stored shapes by the stored distance (the index's exact order, ties by ascending id). It
is high where near neighbours by the stored vector look unlike each other: jointed
subjects in other poses, whose silhouettes change with the pose. The scorer
(:mod:`query.search.rerank_lightfield`) pools the spreads of a query's first candidates into
its gate (``StageTuning.pool``), so a query is judged by the region of the
store it falls in, not by itself alone, and a mixed store judges each region apart.

With ``StageTuning.ratio_weight`` ``b > 0`` the stored statistic is
``spread ** (1 - b) * ratio ** b`` (:func:`local_statistic`): the *ratio* is the median
light field distance of the shape's nearest others by the stored distance over that of
its nearest by the light field among its ``ratio_candidates`` nearest by the stored
distance. It is scale-free and high where the light field finds other shapes nearer
than the stored distance's neighbours (the same subject's other poses against other
subjects in the same pose). The pool takes the statistics' ``pool_quantile``.

The spreads depend on the whole store (a new shape changes its neighbours' lists). They
are computed on demand, for the shapes a search pools (a search costs the same whatever
the store's size), kept in process per store version, and written to
``<store>/index_lightfield/`` (a versioned table, :mod:`query.search.shape_table`) by the
commit hook (:func:`on_commit`): created at an ingest's end while the whole table costs at
most :data:`FULL_AT_COMMIT` light field distances (recomputed whole at each commit while
it does), or by :func:`refresh` at any size; once written, each commit *carries* it: the
shapes still alive keep their spreads (not recomputed when new neighbours arrive; the
table records the version each was computed at) and only the new shapes' are computed,
so a commit costs its new shapes, not the store. Read back while the parameters match. A
spread computed for one shape or for all at one version is the same number
(deterministic, from the stored vectors and light fields). Cost: ``spread_candidates``
light field distances per shape (``max(spread_candidates, ratio_candidates)`` with the
ratio).

In a store whose stage fuses the field vectors into the light field distance
(:mod:`query.search.field_fusion`), every light field distance above is the fused one, and the
fusion's weights are among the parameters a stored table must match (and the unit, always).
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.search.field_fusion import FieldFusion
from query.search.shape_table import ShapeTable, index_version, shared_table, update
from query.search.tuning import PRODUCT, StageTuning, active
from query.search.versioned import POINTER

if TYPE_CHECKING:
    from query.search.rerank import ArrayReader
    from shapedb.config.core import Config
    from shapedb.store.handle import StoreHandle

__all__ = [
    "forget",
    "SPREAD_DIR",
    "FULL_AT_COMMIT",
    "commit_distances",
    "SpreadTable",
    "calibration",
    "local_statistic",
    "pooled",
    "local_spreads",
    "spread_table",
    "store_spreads",
    "on_commit",
    "refresh",
]

log = logging.getLogger(__name__)

SPREAD_DIR = "index_lightfield"
_FORMAT = 2
_CHUNK = 256
#: The statistics are computed whole (the table created at an ingest's end, or recomputed
#: exactly at a commit) only while that costs at most this many light field distances
#: (:func:`commit_distances`; 2,000 shapes of the spread over 5, ~0.25 s): larger stores
#: keep no table until one is written (:func:`refresh`), then carry it.
FULL_AT_COMMIT = 10_000
_CACHE: dict[tuple[str, int], SpreadTable] = {}
_LOCK = threading.Lock()


def forget(path: str) -> None:
    """Drop the tables this process keeps for the store at ``path`` (as a new process)."""
    with _LOCK:
        for key in [k for k in _CACHE if k[0] == path]:
            _CACHE.pop(key, None)


def calibration(config: Config) -> float:
    """``c``: stored distances over ``c`` are in version 4's calibrated units."""
    if config.kernel.method != "mdbd":
        return 1.0
    from shapedb.signature.descriptor import LAYOUTS

    return float(np.log(10.0) / sum(b[3] for b in LAYOUTS[config.descriptor.version]))


def local_statistic(
    d: NDArray[np.float64],
    dl: NDArray[np.float64],
    tuning: StageTuning = PRODUCT,
    unit: float | None = None,
) -> float:
    """One shape's local statistic from its nearest others by the stored distance.

    ``spread ** (1 - b) * ratio ** b`` of :class:`query.search.tuning.StageTuning`
    (``b = ratio_weight``; ``m = spread_candidates``): the spread is the median of ``dl``
    over the first ``m`` (over ``unit``) over the median of ``d`` over them; the ratio
    the median of ``dl`` over the first ``m`` over the median of the ``m`` smallest ``dl``
    among the first ``max(ratio_candidates, m)``.

    Parameters
    ----------
    d : (k,) float64
        Stored distances of the shape's nearest others, in version 4's calibrated units,
        in list order (non-decreasing; ties by ascending id), the shape left out.
    dl : (k,) float64
        Their light field distances to the shape.
    tuning : StageTuning
        The stage's numbers.
    unit : float, optional
        The unit of ``dl`` (:meth:`StageTuning.unit`); None: ``tuning.scale`` (fused).

    Returns
    -------
    float
        NaN when ``k`` is 0.
    """
    f = tuning
    if not len(d):
        return float("nan")
    m = int(f.spread_candidates)
    near = float(np.median(dl[:m]))
    b = float(f.ratio_weight)
    out = 1.0
    if b < 1.0:
        spread = near / (f.scale if unit is None else unit) / max(float(np.median(d[:m])), 1e-300)
        out *= spread ** (1.0 - b)
    if b > 0.0:
        c = max(int(f.ratio_candidates), m)
        best = float(np.median(np.sort(dl[:c])[:m]))
        out *= (near / max(best, 1e-300)) ** b
    return out


def pooled(values: NDArray[np.float64], quantile: float) -> NDArray[np.float64]:
    """The ``quantile`` of ``values`` (..., p) over the last axis, NaN left out.

    0.5 is the median (:func:`numpy.nanmedian`); NaN where every value is NaN.
    """
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows: NaN
        if quantile == 0.5:
            return np.asarray(np.nanmedian(values, axis=-1), np.float64)
        return np.asarray(np.nanquantile(values, quantile, axis=-1), np.float64)


def local_spreads(
    index: Any,
    fields: ArrayReader,
    config: Config,
    ids: NDArray[np.int64] | None = None,
    tuning: StageTuning = PRODUCT,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Indexed shapes' local spreads (every alive shape's by default).

    Parameters
    ----------
    index : FeatureIndex
        Fitted (:mod:`query.search.index`) over the stored vectors; its alive ids are the shapes.
    fields : ArrayReader
        Reads the ``"light_field"`` column by ids, (m, fields, 10, d), NaN rows for
        records without; and, when ``config``'s stage fuses the field vectors, the
        ``"field_vector"`` column (a shape whose row cannot be fused keeps ``l``).
    config : Config
        The descriptor (calibration) and what the store keeps.
    ids : (k,) int64, optional
        The shapes wanted; ids not alive in the index are left out.

    Returns
    -------
    ids : (n,) int64
        Ascending, alive.
    spreads : (n,) float64
        NaN for a shape with no light fields or no neighbour with them.
    """
    from query.search.field_fusion import FIELD
    from shapedb.signature.lightfield import light_field_distance

    f = tuning
    fusion = FieldFusion.from_config(config, tuning)
    alive = np.sort(np.asarray(index.ids_, np.int64)[np.asarray(index.alive_, bool)])
    ids = alive if ids is None else np.intersect1d(alive, np.asarray(ids, np.int64))
    out = np.full(len(ids), np.nan)
    if len(alive) < 2 or len(ids) == 0:
        return ids, out
    m = min(_reach(f), len(alive) - 1)
    cal = calibration(config)
    unit = f.unit(fusion.active)
    x = np.asarray(index.features_, np.float64)[index.lookup(ids)]
    for lo in range(0, len(ids), _CHUNK):
        q = ids[lo : lo + _CHUNK]
        near, dist = index.search(x[lo : lo + _CHUNK], m + 1)
        wanted = np.unique(np.concatenate([q, near[near >= 0]]))
        got = fields("light_field", wanted)
        if got is None:
            continue
        fv = fields(FIELD, wanted) if fusion.active else None
        pos = {int(i): k for k, i in enumerate(wanted)}
        for row, sid in enumerate(q):
            keep = (near[row] >= 0) & (near[row] != sid)
            nb, d = near[row][keep][:m], dist[row][keep][:m]
            lq = got[pos[int(sid)]]
            lc = got[[pos[int(i)] for i in nb]]
            ok = np.all(np.isfinite(lc.reshape(len(nb), -1)), axis=1)
            if not np.all(np.isfinite(lq)) or not ok.any():
                continue
            dl = light_field_distance(lq[None], lc[ok])[0]
            if fusion.active:
                fc = None if fv is None else fv[[pos[int(i)] for i in nb]][ok]
                dl = fusion.distance(dl, None if fv is None else fv[pos[int(sid)]], fc)
            out[lo + row] = local_statistic(d[ok] / cal, dl, tuning, unit)
    return ids, out


def commit_distances(n: int, tuning: StageTuning = PRODUCT) -> int:
    """Light field distances the statistics of a store of ``n`` shapes cost."""
    return int(n) * _reach(tuning)


def _reach(f: Any) -> int:
    """Nearest others the local statistic reads."""
    reach = int(f.spread_candidates)
    if f.ratio_weight > 0:
        reach = max(reach, int(f.ratio_candidates))
    return reach


def _meta(config: Config, version: int, tuning: StageTuning) -> dict[str, Any]:
    f, lf = tuning, config.light_field
    return {
        "format": _FORMAT,
        "version": version,
        "spread_candidates": int(f.spread_candidates),
        "unit": f.unit(FieldFusion.from_config(config, tuning).active),
        "ratio_weight": float(f.ratio_weight),
        "ratio_candidates": int(f.ratio_candidates),
        "light_field": repr(lf),
        "descriptor": int(config.descriptor.version),
        "method": config.kernel.method,
        "field_fusion": FieldFusion.from_config(config, tuning).key(),
    }


class SpreadTable(ShapeTable):
    """The local spreads of one store version, filled as they are asked for.

    Parameters
    ----------
    db : shapedb.Database
    fields : ArrayReader
        The store's light fields by id (:func:`query.search.rerank_lightfield.stored_arrays`).
    meta : dict, optional
        The parameters (:func:`_meta` at the index's version by default).
    """

    directory = SPREAD_DIR
    file = "spreads.npy"
    what = "light field spreads"

    def __init__(
        self,
        db: StoreHandle,
        fields: ArrayReader,
        meta: dict[str, Any] | None = None,
        tuning: StageTuning = PRODUCT,
    ) -> None:
        self.fields, self.tuning = fields, tuning
        if meta is None:
            meta = _meta(db.config, index_version(db), tuning)
        super().__init__(db, meta)

    def compute(self, ids: NDArray[np.int64] | None) -> tuple[NDArray[np.int64], Any]:
        return local_spreads(self.index, self.fields, self.db.config, ids, self.tuning)

    def get(self, ids: NDArray[np.int64] | None = None) -> NDArray[np.float64]:
        """(k,) spreads of ``ids`` (every alive shape's when None); NaN for ids without.

        Computes the ids not known yet, in this process (a read writes nothing).
        """
        _, values = self.known(ids)
        return np.array([np.nan if v is None else float(v) for v in values], np.float64)


def spread_table(
    db: StoreHandle, fields: ArrayReader, tuning: StageTuning = PRODUCT
) -> SpreadTable:
    """The shared :class:`SpreadTable` of ``db``'s store at its index's current version."""
    return shared_table(  # type: ignore[no-any-return]
        _CACHE, _LOCK, db, lambda v: _meta(db.config, v, tuning),
        lambda m: SpreadTable(db, fields, m, tuning),
    )  # fmt: skip


def store_spreads(
    db: StoreHandle, fields: ArrayReader, tuning: StageTuning = PRODUCT
) -> dict[int, float]:
    """Every stored shape's local spread at the store's current version, by id.

    Read from ``<store>/index_lightfield/`` under the stage's parameters (carried: values of an
    earlier version kept, :mod:`query.search.shape_table`); the missing ones computed
    (:func:`local_spreads`), not written. :func:`refresh` gives the exact table.
    """
    table = spread_table(db, fields, tuning)
    table.get(None)
    return dict(table.values)


def on_commit(db: StoreHandle, fields: ArrayReader, *, create: bool = False) -> None:
    """Bring the spreads up to date after a commit, for a store whose stage pools them.

    Only a store with the ``"lightfield"`` scorer and a table written before, or, with
    ``create`` (the end of an ingest), a store whose whole table costs at most
    :data:`FULL_AT_COMMIT` light field distances (:func:`commit_distances`): the one place
    that writes the table (:func:`query.search.shape_table.update`: the new shapes'
    spreads computed, the others carried; a table within the limit recomputed whole).
    Other stores' searches compute the spreads they pool, in memory.
    """
    tuning = active()
    if db.config.rerank.scorer != "lightfield" or tuning.pool <= 0:
        return
    written = (Path(db.store.path) / SPREAD_DIR / POINTER).exists()
    if not written and not create:  # nothing to keep: no index opened, nothing computed
        return
    n = len(db.store)
    if written or commit_distances(n, tuning) <= FULL_AT_COMMIT:
        update(spread_table(db, fields, tuning), commit_distances(n, tuning), FULL_AT_COMMIT)


def refresh(db: StoreHandle, fields: ArrayReader, tuning: StageTuning = PRODUCT) -> SpreadTable:
    """Recompute every stored shape's spread at the store's version and save the table.

    The exact table (nothing carried, ``exact`` in its pointer), whatever the store's
    size (``commit_distances`` light field distances); a store the process cannot
    write keeps it in memory. Returns the shared table.
    """
    table = spread_table(db, fields, tuning)
    table.refresh()
    table.keep()
    return table
