"""One-sided scans against the views of the stored light fields.

A depth camera's scan bounds another solid than its model's, so its packing, descriptor
and light fields resemble no stored shape's (the whole path finds a CAPOD scan's class a
quarter of the time). Its silhouette from the camera is the model's own, though, and
every stored shape keeps the silhouettes of its field's inside from 30 directions (its
light fields, the ``light_field`` column). :func:`view_search` compares the scan's
silhouette (:func:`shapedb.signature.scan_view.scan_view_features`, seen along the
cloud's viewing direction) with every view of every stored shape and ranks the shapes
by their nearest view: an exact scan of the memory-mapped light fields, linear in the
store (faiss's brute force L1: about 4 ms a query at 10^4 shapes and 50 ms at 10^5 on one
loaded core; at 10^6 half a second, where an index over the views would be the next step).

In a store that also keeps view words (``Config.stores_view_words``), the silhouette is
joined by the scan's surface words: the scan's words against each shape's words seen from
fixed directions (:mod:`query.search.scan_words`). The silhouette tells the outline, the
words the surface inside it (a plate's holes, a bracket's bends); the shapes are ordered
by their ranks by silhouette and by words fused (:func:`fused_scores`,
:data:`WORD_OFFSET`, :data:`WORDS_WEIGHT`), over the :data:`WORD_CANDIDATES` nearest by
words (the rest rank after them).

``db.search`` takes this path by itself for a point cloud it calls one-sided
(:func:`query.parts.partial.is_one_sided_cloud`: its geometry,
:func:`shapedb.geometry.view.viewing_direction`, and in a store with view words its
words), in a store that keeps light fields; each hit's ``path`` is ``"view"``.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from query.search.array_cache import open_column
from query.search.catalog import catalog
from query.search.feature_index import faiss_pairwise_l1
from query.search.rerank_lightfield import COLUMN
from query.search.scan_words import nearest_by_view_words
from shapedb.results import Hit
from shapedb.signature.lightfield_descriptor import light_field_dim, silhouette_dim
from shapedb.signature.scan_view import scan_view_features
from shapedb.signature.view_words import scan_words

if TYPE_CHECKING:
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.store.handle import StoreHandle

__all__ = [
    "VIEW_UNIT",
    "WORD_CANDIDATES",
    "WORD_OFFSET",
    "WORDS_WEIGHT",
    "view_search",
    "view_distances",
    "nearest_view",
    "fused_scores",
]

log = logging.getLogger(__name__)

#: Distances over this unit give a hit's similarity ``exp(-distance / VIEW_UNIT)``: the
#: median distance of CAPOD validation scans to shapes of other classes (3.0) over ln 10,
#: so that, as on the whole path, an unrelated shape scores about 0.1.
VIEW_UNIT = 1.3
#: Shapes ranked by their view words (``k`` more when k is larger); the rest rank after.
WORD_CANDIDATES = 64
#: The reciprocal ranks' offset and the words' weight against the silhouette's (1): the
#: best NN + 1-T summed over CAPOD and parts validation scans of offsets 2-32 and weights
#: 0.25-4 (``python -m bench.studies.view_words``): CAPOD 0.817, parts 0.750 NN, against
#: the words alone 0.700, 0.667 and the view path before (silhouettes) 0.617, 0.271.
WORD_OFFSET = 16.0
WORDS_WEIGHT = 2.0
#: Stored shapes compared at once (bounds memory: ``BLOCK * 30 * 46 * 4`` bytes).
BLOCK = 4096


def view_distances(
    db: StoreHandle, features: NDArray[np.float32]
) -> tuple[NDArray[np.int64], NDArray[np.float64]] | None:
    """Every stored shape's distance to a silhouette: the smallest L1 distance between
    ``features`` and one of its light fields' views.

    Parameters
    ----------
    db : shapedb.Database
    features : (silhouette_dim,) float32
        :func:`~shapedb.signature.scan_view.scan_view_features` under the store's
        light field configuration.

    Returns
    -------
    ((n,) int64, (n,) float64) or None
        Alive ids ascending and their distances (inf for a shape stored without light
        fields); None when the store keeps no light fields.
    """
    cfg = db.config.light_field
    views, full, part = cfg.n_fields * 10, light_field_dim(cfg), silhouette_dim(cfg)
    cache = open_column(db, COLUMN)
    q = np.asarray(features, np.float32).reshape(1, 1, part)
    if cache is not None:
        if not cache.chunks or cache.width != views * full:
            return None
        per_row = np.full(cache.n_rows, np.inf)
        start = 0
        for chunk in cache.chunks:
            for s in range(0, len(chunk), BLOCK):
                block = np.asarray(chunk[s : s + BLOCK], np.float32)
                per_row[start + s : start + s + len(block)] = nearest_view(block, q, views, full)
            start += len(chunk)
        rows = cache.rows
        return cache.ids, np.where(rows >= 0, per_row[np.maximum(rows, 0)], np.inf)
    # a store the cache cannot be written beside (read-only): read the column
    table = db.store.shapes([COLUMN])
    ids = db.store.ids()
    out = np.full(len(ids), np.inf)
    values = table.column(COLUMN).to_pylist()
    if not any(v is not None for v in values):
        return None
    for i, v in enumerate(values):
        if v is not None and len(v) == views * full:
            out[i] = float(
                nearest_view(np.asarray(v, np.float32).reshape(1, -1), q, views, full)[0]
            )
    return ids, out


def nearest_view(
    rows: NDArray[np.float32], q: NDArray[np.float32], views: int, full: int
) -> NDArray[np.float64]:
    """(r,) each row's (r, views * full) least L1 distance between a view's silhouette part
    and ``q`` (1, 1, part): faiss's brute force over the views when they hold nothing
    else (ten times numpy's speed), numpy over the leading part otherwise."""
    part = q.shape[-1]
    if part == full and rows.flags.c_contiguous:
        d = faiss_pairwise_l1(q.reshape(1, part), rows.reshape(-1, part))
        return np.asarray(d.reshape(-1, views).min(axis=1), np.float64)
    block = rows.reshape(-1, views, full)[:, :, :part]
    return np.asarray(np.abs(block - q).sum(-1).min(-1), np.float64)


def view_search(
    db: StoreHandle,
    cloud: PointCloud,
    direction: NDArray[np.float64] | None,
    *,
    k: int,
    allowed: NDArray[np.int64] | None = None,
) -> list[Hit] | None:
    """The k stored shapes whose views look most like the scan's silhouette, best first.

    Parameters
    ----------
    db : shapedb.Database
    cloud : PointCloud
        A one-sided scan.
    direction : (3,) float or None
        Its viewing direction (:func:`shapedb.geometry.view.viewing_direction`); None
        when unknown (a cloud only its words call one-sided): ranked by its words alone.
    k : int
        Hits wanted (checked by the caller).
    allowed : (m,) int64, optional
        Only these ids (a ``where`` predicate's).

    Returns
    -------
    list of Hit or None
        ``path="view"``, ties by ascending id. In a store with view words, ``similarity``
        is the fused score over its largest value (1: first by silhouette and by words)
        and ``distance`` its ``-log``; in a store without, ``distance`` is the nearest
        view's L1 distance and ``similarity`` ``exp(-distance / VIEW_UNIT)``. None when
        the store keeps no light fields or the scan has no silhouette to draw (the caller
        searches the whole path instead).

        Ranked by its words alone, ``distance`` is the least chi-square distance to a
        view's words (in [0, 1]) and ``similarity`` ``1 - distance``; None when the store
        keeps no view words or the scan has no words.
    """
    if direction is None:
        return _by_words_alone(db, cloud, k, allowed)
    try:
        features = scan_view_features(cloud.points, direction, db.config.light_field)
    except ValueError as exc:  # no silhouette to draw (points on a line along the view)
        log.info("view path: %s; the whole path instead", exc)
        return None
    found = view_distances(db, features)
    if found is None:
        return None
    ids, dist = found
    keep = np.isfinite(dist)
    if allowed is not None:
        keep &= np.isin(ids, allowed)
    ids, dist = ids[keep], dist[keep]
    similarity = np.exp(-dist / VIEW_UNIT)
    if db.config.stores_view_words and len(ids):
        fused = _fused_with_words(db, cloud, ids, dist, k, allowed)
        if fused is not None:
            similarity = fused
            dist = -np.log(np.maximum(fused, np.finfo(np.float64).tiny))
    order = np.lexsort((ids, dist))[:k]
    names = catalog(db, db.store.version).lookup(ids[order])
    hits = []
    for sid, d, sim, found_name in zip(
        ids[order], dist[order], similarity[order], names, strict=True
    ):
        if found_name is None:  # deleted by a commit made while we searched
            continue
        hits.append(Hit(int(sid), found_name[0], found_name[1], float(sim), float(d), "view"))
    return hits


def fused_scores(
    silhouette_ranks: NDArray[np.float64],
    word_ranks: NDArray[np.float64],
    offset: float = WORD_OFFSET,
    weight: float = WORDS_WEIGHT,
) -> NDArray[np.float64]:
    """(n,) ``(1 / (offset + r_s) + weight / (offset + r_w)) / ((1 + weight) / offset)``:
    the fused reciprocal ranks (0 first) of n shapes, over the largest possible score
    (1: first by both)."""
    s = np.asarray(silhouette_ranks, np.float64)
    w = np.asarray(word_ranks, np.float64)
    return (1.0 / (offset + s) + weight / (offset + w)) * offset / (1.0 + weight)


def _by_words_alone(
    db: StoreHandle, cloud: PointCloud, k: int, allowed: NDArray[np.int64] | None
) -> list[Hit] | None:
    """The k shapes nearest the scan by its view words, as hits; None without any."""
    words = scan_words(cloud.points)
    if not words.any():
        return None
    ids, dist = nearest_by_view_words(db, words, k, allowed)
    if not len(ids):
        return None
    names = catalog(db, db.store.version).lookup(ids)
    return [
        Hit(int(sid), name[0], name[1], float(1.0 - d), float(d), "view")
        for sid, d, name in zip(ids, dist, names, strict=True)
        if name is not None  # deleted by a commit made while we searched
    ]


def _fused_with_words(
    db: StoreHandle,
    cloud: PointCloud,
    ids: NDArray[np.int64],
    dist: NDArray[np.float64],
    k: int,
    allowed: NDArray[np.int64] | None,
) -> NDArray[np.float64] | None:
    """(n,) the fused score of each of ``ids`` (ascending, their silhouette distances
    ``dist``); None when no shape has view words or the scan has none."""
    words = scan_words(cloud.points)
    if not words.any():
        return None
    near, _ = nearest_by_view_words(db, words, max(WORD_CANDIDATES, k), allowed)
    if not len(near):
        return None
    silhouette = np.empty(len(ids))
    silhouette[np.lexsort((ids, dist))] = np.arange(len(ids))
    by_words = np.full(len(ids), float(len(near)))
    at = np.searchsorted(ids, near)
    found = (at < len(ids)) & (ids[np.minimum(at, len(ids) - 1)] == near)
    by_words[at[found]] = np.flatnonzero(found)
    return fused_scores(silhouette, by_words)
