"""The store's local light field spreads: an index-time statistic of the ``"lightfield"`` stage.

A stored shape's *local spread* is the median light field distance (over
``LightFieldFusionConfig.typical``) over the median stored distance (in version 4's
calibrated units, :func:`calibration`) among its ``spread_candidates`` nearest other
stored shapes by the stored distance (the index's exact order, ties by ascending id). It
is high where near neighbours by the stored vector look unlike each other: jointed
subjects in other poses, whose silhouettes change with the pose. The scorer
(:mod:`query.rerank_lightfield`) pools the spreads of a query's first candidates into
its gate (``LightFieldFusionConfig.pool``), so a query is judged by the region of the
store it falls in, not by itself alone, and a mixed store judges each region apart.

The spreads depend on the whole store (a new shape changes its neighbours' lists), so
they are computed for every stored shape when the store's index is brought up to date
(the commit hook :func:`on_commit`, or the first search of a store version), kept in
``<store>/index_lightfield/`` (a versioned directory like the index's: ``ids.npy``,
``spreads.npy``, and the store version and the parameters they were computed with in
``current.json``), read back while they match, and recomputed (deterministically, from
the stored vectors and light fields) when they do not. Cost: ``spread_candidates`` light
field distances per stored shape.
"""

from __future__ import annotations

import logging
import os
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query._versioned import POINTER, current, save_version

if TYPE_CHECKING:
    from query.rerank import ArrayReader
    from shapedb.config import Config
    from shapedb.database import Database

__all__ = ["SPREAD_DIR", "calibration", "local_spreads", "store_spreads", "on_commit"]

log = logging.getLogger(__name__)

SPREAD_DIR = "index_lightfield"
_FORMAT = 1
_CHUNK = 256
_CACHE: dict[tuple[str, int], dict[int, float]] = {}
_LOCK = threading.Lock()


def calibration(config: Config) -> float:
    """``c``: stored distances over ``c`` are in version 4's calibrated units."""
    if config.kernel.method != "mdbd":
        return 1.0
    from shapedb.descriptor import LAYOUTS

    return float(np.log(10.0) / sum(b[3] for b in LAYOUTS[config.descriptor.version]))


def local_spreads(
    index: Any, fields: ArrayReader, config: Config
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Every indexed shape's local spread.

    Parameters
    ----------
    index : FeatureIndex
        Fitted (:mod:`query.index`) over the stored vectors; its alive ids are the shapes.
    fields : ArrayReader
        Reads the ``"light_field"`` column by ids, (m, fields, 10, d), NaN rows for
        records without.
    config : Config
        ``lf_fusion.spread_candidates`` and ``typical``, and the descriptor (calibration).

    Returns
    -------
    ids : (n,) int64
        Ascending.
    spreads : (n,) float64
        NaN for a shape with no light fields or no neighbour with them.
    """
    from shapedb.lightfield import light_field_distance

    f = config.lf_fusion
    ids = np.sort(np.asarray(index.ids_, np.int64)[np.asarray(index.alive_, bool)])
    out = np.full(len(ids), np.nan)
    if len(ids) < 2:
        return ids, out
    m = min(int(f.spread_candidates), len(ids) - 1)
    cal = calibration(config)
    x = np.asarray(index.features_, np.float64)[index.lookup(ids)]
    for lo in range(0, len(ids), _CHUNK):
        q = ids[lo : lo + _CHUNK]
        near, dist = index.search(x[lo : lo + _CHUNK], m + 1)
        wanted = np.unique(np.concatenate([q, near[near >= 0]]))
        got = fields("light_field", wanted)
        if got is None:
            continue
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
            denom = max(float(np.median(d[ok])) / cal, 1e-300)
            out[lo + row] = float(np.median(dl)) / f.typical / denom
    return ids, out


def _meta(config: Config, version: int) -> dict[str, Any]:
    f, lf = config.lf_fusion, config.light_field
    return {
        "format": _FORMAT,
        "version": version,
        "spread_candidates": int(f.spread_candidates),
        "typical": float(f.typical),
        "light_field": repr(lf),
        "descriptor": int(config.descriptor.version),
        "method": config.kernel.method,
    }


def store_spreads(db: Database, fields: ArrayReader) -> dict[int, float]:
    """The local spreads of the store's shapes at its current version, by id.

    Read from ``<store>/index_lightfield/`` when it holds this version's spreads under
    the store's parameters; else computed (:func:`local_spreads` over the store's
    index, :func:`query.index.open_index`) and written there. Kept in-process per store
    version.

    Parameters
    ----------
    db : shapedb.Database
    fields : ArrayReader
        The store's light fields by id (:func:`query.rerank_lightfield.stored_arrays`).
    """
    from query.index import open_index

    index = open_index(db)
    version = int(index.version_ if index.version_ is not None else db.store.version)
    key = (os.fspath(db.store.path), version)
    with _LOCK:
        got = _CACHE.get(key)
    if got is not None:
        return got
    root = Path(db.store.path) / SPREAD_DIR
    meta = _meta(db.config, version)
    ids = spreads = None
    if (root / POINTER).exists():
        try:
            stored, sub = current(root)
            if all(stored.get(k) == v for k, v in meta.items()):
                ids, spreads = np.load(sub / "ids.npy"), np.load(sub / "spreads.npy")
        except (OSError, ValueError, KeyError) as exc:
            log.warning("recomputing the light field spreads: %s", exc)
    if ids is None or spreads is None:
        ids, spreads = local_spreads(index, fields, db.config)
        a, b = ids, spreads

        def write(sub: Path) -> None:
            np.save(sub / "ids.npy", a)
            np.save(sub / "spreads.npy", b)

        save_version(root, write, meta, version=version)
        log.info("light field spreads of %d shapes at store version %s", len(ids), version)
    out = {int(i): float(s) for i, s in zip(ids, spreads, strict=True)}
    with _LOCK:
        _CACHE[key] = out
        for old in [k for k in _CACHE if k[0] == key[0] and k[1] != version]:
            _CACHE.pop(old, None)
    return out


def on_commit(db: Database, fields: ArrayReader) -> None:
    """Bring the spreads up to date after a commit, for a store whose stage pools them.

    Only a store with the ``"lightfield"`` scorer, ``pool > 0`` and light fields stored,
    and whose spreads were computed before (a store never searched gets them at its
    first search).
    """
    cfg = db.config
    if cfg.rerank.scorer != "lightfield" or cfg.lf_fusion.pool <= 0:
        return
    if (Path(db.store.path) / SPREAD_DIR / POINTER).exists():
        store_spreads(db, fields)
