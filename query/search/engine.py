"""Shape retrieval: ``db.search(query, k=10, where=None)`` and its batch form.

A query is turned into an Eq. 1 feature vector with the store's own configuration,
faiss proposes candidates (:mod:`query.search.index`) and the exact Eq. 2 distance decides
the order; the similarity reported is the Eq. 3 kernel ``exp(-lam * d)``.

Accepted queries, tried in this order:

* a stored shape id (``int``);
* a :class:`shapedb.mdbd.decomposition.Decomposition` (its configuration must be the store's; for the
  light field stage, decomposed with ``tail_balls=db.config.light_field_tail`` (and
  ``keep_inside=db.config.light_field_inside``) as ingest does, else its light fields
  see only its balls (without the inside: none, the stored order) and a warning is logged;
* a :class:`shapedb.geometry.base.Geometry` (decomposed with ``db.config.mdbd``);
* a :class:`shapedb.store.schema.ShapeRecord` (its stored feature);
* a raw feature vector (``(d,)`` array, list or tuple of floats);
* a path (``os.PathLike``, or a ``str`` naming an existing file): loaded with
  ``ingest.load``, decomposed and featurised with the store's configuration;
* a stored shape name (a ``str`` that is not an existing file).

A sparse point cloud (a sample every 2 grid cells or more) also has the feature of its
reconstruction (:mod:`shapedb.mdbd.reconstruct`), and in a store with sparse views
(``CloudConfig.view_cells > 0``, :mod:`shapedb.geometry.view`) every dense shape that of its
view. A pair of a sparse cloud and a dense shape is as far apart as the nearest of the
cloud's own feature and the dense shape's own feature or view, and the cloud's
reconstruction and the dense shape's own feature. A sparse geometry or file query
costs a Poisson reconstruction and its decomposition; a dense one in a store with
views and sparse clouds one more (point-cloud) decomposition. In a store of dense shapes
with the light field stage a point cloud that ranks as its proxy (below) needs no
reconstruction, and none is computed; one that keeps its own row (jointed subjects) has
its reconstruction computed then.

In a store of dense shapes only (the default store of meshes) a sparse cloud's candidate
list holds each shape at the nearer of its own feature's and its reconstruction's
distance, and the re-ranking stage orders it as any query's; a point cloud then ranks
the stored shapes as a search for its proxy does, the nearest of its first results by
its light fields drawn from its points (:mod:`query.search.cloud_proxy`), each hit at
its own distance to the cloud. A stored mesh that is not
closed packs its enclosed solid (:mod:`shapedb.geometry.enclosed`), a shell two cells
thick wherever a hole lets the flood in, while a cloud (and its closed reconstruction)
packs the solid its samples enclose, so their features can disagree where their light
fields (silhouettes) do not.

A store whose ``RerankConfig.scorer`` is not ``"none"`` (the default ``"lightfield"``)
re-ranks the first ``K`` results (:mod:`query.search.stage`) with that exact scorer
(:mod:`query.search.rerank`), except in stores with sparse clouds or ``view_cells``,
which rank by the stored distance. The hits are in
the scorer's order; their distance and similarity are the stored vector's, so a later
hit may be nearer by the stored distance than an earlier one.

A stored query is *not* excluded from its own results: it ranks first, with
similarity 1.0 (distance 0), unless another shape has an identical feature and a
smaller id. Ties are broken by ascending id everywhere.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.search.catalog import catalog as store_catalog
from shapedb.errors import ConfigError, NotFoundError, QueryError, ShapeDBError
from shapedb.results import Hit  # defined there, re-exported here

if TYPE_CHECKING:
    from shapedb.config.core import Config
    from shapedb.store.handle import StoreHandle

__all__ = ["Hit", "search", "search_batch", "query_features", "checked_k", "MAX_K"]

log = logging.getLogger(__name__)


def search(
    db: StoreHandle, query: Any, *, k: int = 10, where: str | None = None, metric: Any = None
) -> list[Hit]:
    """The k stored shapes most similar to ``query``, best first.

    Parameters
    ----------
    db : shapedb.Database
        The database (``db.store``, ``db.config``).
    query : int, str, os.PathLike, Geometry, Decomposition, ShapeRecord or (d,) array
        What to look for; see the module docstring.
    k : int
        Number of hits.
    where : str, optional
        SQL predicate over the ``shapes`` table (e.g. ``"label = 'Chair'"``); only
        shapes satisfying it are returned, and the search is then exhaustive (exact).
    metric : LearnedMetric or path, optional
        A similarity fitted on the store's labels (``db.fit_metric``,
        :mod:`query.learn.metric`) instead of the default; distances are then weighted
        by its block weights.

    Returns
    -------
    list of Hit
        At most k hits, by decreasing similarity (ties by ascending id).

    Raises
    ------
    NotFoundError
        Unknown shape id or name.
    QueryError
        Malformed query, k or ``where`` predicate.
    """
    return search_batch(db, [query], k=k, where=where, metric=metric)[0]


def search_batch(
    db: StoreHandle,
    queries: Sequence[Any],
    *,
    k: int = 10,
    where: str | None = None,
    metric: Any = None,
) -> list[list[Hit]]:
    """:func:`search` for many queries at once (one faiss call, one filter).

    Parameters
    ----------
    db : shapedb.Database
    queries : sequence
        Each as accepted by :func:`search`.
    k : int
    where : str, optional
    metric : LearnedMetric or path, optional

    Returns
    -------
    list of list of Hit
        One list per query, in the order of ``queries``.
    """
    from query.learn.metric import as_metric
    from query.search.index import open_index

    if isinstance(queries, (str, bytes, os.PathLike)) or not isinstance(queries, Sequence):
        if isinstance(queries, np.ndarray) and queries.ndim == 2:
            queries = list(queries)
        else:
            raise QueryError(
                "search_batch expects a sequence of queries", source=type(queries).__name__
            )
    k = checked_k(k)
    learned = as_metric(metric)
    if learned is not None:
        learned.check(db.config)
    if not len(queries):
        return []
    index = open_index(db, metric=learned)
    k = min(k, max(len(index.ids_), 1))  # never more rows than the store holds
    resolved = [_resolve(db, q, index) for q in queries]
    allowed = None
    if where is not None:
        from query.sql import allowed_ids

        allowed = allowed_ids(db, where)
    if db.config.cloud.view_cells or len(store_catalog(db, index.version_).sparse):
        ids, dist = _search_with_views(db, index, resolved, int(k), allowed, learned)
    else:
        from query.search.rerank import search as rerank_search
        from query.search.stage import scorer_for

        vectors = np.stack([r.feature for r in resolved])
        qids = np.array([r.sid for r in resolved], np.int64)
        arrays, query_arrays = _stored_arrays(db, resolved)
        scorer = scorer_for(db.config)
        wanted = max(int(k), int(scorer.tuning.candidates)) if scorer is not None else int(k)
        clouds = [
            r.sid < 0 and r.from_points for r in resolved
        ] if scorer is not None and scorer.tuning.proxy and arrays is not None else []  # fmt: skip
        first = wanted if any(clouds) else int(k)  # a cloud's proxy is among its first K
        ids, dist = rerank_search(
            index, vectors, first, config=db.config, query_ids=qids, allowed=allowed,
            scorer=scorer, arrays=arrays, query_arrays=query_arrays, stored_distances=True,
            candidates=_sparse_lists(index, resolved, vectors, wanted, allowed, clouds),
        )  # fmt: skip
        if any(clouds):
            ids, dist, own = _by_proxy(
                db, index, np.flatnonzero(clouds), resolved, (ids, dist), int(k), allowed,
                (scorer, arrays, query_arrays),
            )  # fmt: skip
            if len(own):  # clouds without a proxy: their own rows, reconstructions and all
                ids[own], dist[own] = rerank_search(
                    index, vectors[own], int(k), config=db.config, query_ids=qids[own],
                    allowed=allowed, scorer=scorer, arrays=arrays,
                    query_arrays={n: a[own] for n, a in query_arrays.items()},
                    stored_distances=True, candidates=_sparse_lists(
                        index, [resolved[i] for i in own], vectors[own], wanted, allowed),
                )  # fmt: skip
    catalog = store_catalog(db, index.version_)
    lam = float(db.config.kernel.lam)
    out: list[list[Hit]] = []
    for row_ids, row_d in zip(ids, dist, strict=True):
        keep = row_ids >= 0
        hits = []
        for i, d, entry in zip(
            row_ids[keep], row_d[keep], catalog.lookup(row_ids[keep]), strict=True
        ):
            if entry is None:  # deleted by a commit made while we searched
                continue
            hits.append(Hit(int(i), entry[0], entry[1], float(np.exp(-lam * d)), float(d)))
        out.append(hits)
    return out


MAX_K = 1_000_000_000
"""Largest ``k`` a search accepts (k above the store's size is capped at it)."""


def checked_k(k: Any) -> int:
    """``k`` as an int, or :class:`QueryError` when it is not an integer in [1, MAX_K].

    Callers then cap it at the number of stored shapes, so a large ``k`` never
    allocates more than the store's size.
    """
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise QueryError("k must be a positive integer", source=f"k={k!r}")
    if k > MAX_K:
        raise QueryError(
            f"k is too large: at most {MAX_K:,} (results are capped at the store's size anyway)",
            source=f"k={k!r}",
        )
    return int(k)


def query_features(db: StoreHandle, query: Any, *, index: Any = None) -> NDArray[np.float64]:
    """The feature vector of a query, computed with the store's configuration.

    Parameters
    ----------
    db : shapedb.Database
    query : see :func:`search`
    index : FeatureIndex, optional
        Used to read stored features without touching the store.

    Returns
    -------
    (d,) float64
    """
    return _resolve(db, query, index).feature


@dataclass
class _Query:
    """A resolved query: its feature, whether it is a sparse cloud, and its view.

    ``view`` is the query's other feature: a dense shape's sparse view
    (:mod:`shapedb.geometry.view`), a sparse cloud's reconstruction (:mod:`shapedb.mdbd.reconstruct`);
    or a function computing it (only called when the search needs it), or None when
    the query has none (a raw vector, a decomposition, a rejected reconstruction).
    ``sid`` is the stored shape's id when the query is one, else -1; ``decomposition``
    the query's own decomposition when it has one (a stored shape's is not read);
    ``light_field``, ``field_vector`` and ``surface_words`` an unstored record's own light
    fields, field vector and surface words, when it carries them (a geometry's words are
    computed from its surface); ``light_field`` also a point cloud's, drawn from its
    points (``from_points``).
    """

    feature: NDArray[np.float64]
    sparse: bool = False
    view: Any = None
    sid: int = -1
    decomposition: Any = None
    light_field: Any = None
    field_vector: Any = None
    surface_words: Any = None
    from_points: bool = False

    def view_feature(self) -> NDArray[np.float64] | None:
        if callable(self.view):
            self.view = self.view()
        return self.view


def _stored_arrays(db: StoreHandle, resolved: list[_Query]) -> tuple[Any, Any]:
    """The per-record array reader and the queries' own arrays a store's scorer reads.

    Only a store that keeps light fields (``Config.stores_light_fields``) has any: its
    records' ``light_field`` column, and each outside query's light fields computed from
    its decomposition (NaN for a stored query, read by id, or a raw vector), or drawn from
    a point cloud's points; in a store
    with field vectors (:mod:`query.search.field_fusion`) also their ``field_vector`` column and
    each outside query's own field vector, when its stage reads them (a field weight or
    extra candidates).
    """
    if not db.config.stores_light_fields:
        return None, None
    from query.search.field_fusion import FIELD, FieldFusion, query_field_vectors
    from query.search.rerank_lightfield import (
        COLUMN,
        query_light_fields,
        stored_arrays,
    )

    own = [r.decomposition if r.sid < 0 and r.light_field is None else None for r in resolved]
    fields = query_light_fields(db.config, own)
    for k, r in enumerate(resolved):
        if r.sid < 0 and r.light_field is not None:  # a record's own, or a cloud's from its points
            fields[k] = np.asarray(r.light_field, dtype=np.float64)
    out = {COLUMN: fields}
    fusion = FieldFusion.from_config(db.config)
    if fusion.active or fusion.proposes:
        own = [r.decomposition if r.sid < 0 and r.field_vector is None else None for r in resolved]
        vectors = query_field_vectors(db.config, own)
        for k, r in enumerate(resolved):
            if r.sid < 0 and r.field_vector is not None:  # a record's own
                vectors[k] = np.asarray(r.field_vector, dtype=np.float64)
        out[FIELD] = vectors
    if db.config.stores_surface_words:
        from query.search.word_fusion import WORDS_COLUMN, query_words

        out[WORDS_COLUMN] = query_words([r.surface_words if r.sid < 0 else None for r in resolved])
    return stored_arrays(db), out


def _resolve(db: StoreHandle, query: Any, index: Any) -> _Query:
    from shapedb.geometry.base import Geometry
    from shapedb.geometry.view import is_sparse
    from shapedb.mdbd.decomposition import Decomposition
    from shapedb.store.schema import ShapeRecord

    config = db.config
    dim = config.dim
    if isinstance(query, bool):
        raise QueryError("a boolean is not a query", source=repr(query))
    if isinstance(query, (int, np.integer)):
        return _stored(db, int(query), index)
    if isinstance(query, Decomposition):
        if query.config != config.mdbd:
            raise ConfigError(
                f"decomposition was computed with {query.config}, but the store uses {config.mdbd}",
                source="query decomposition",
            )
        if (
            config.stores_light_fields
            and config.light_field_tail
            and query.n_balls >= config.mdbd.n_balls
            and not len(query.tail_radii)
        ):
            log.warning(
                "query decomposition has no tail balls (decompose(..., tail_balls=%d) as "
                "ingest does): its light fields see only its %d balls",
                config.light_field_tail,
                query.n_balls,
            )
        if config.light_field_inside and query.inside is None:
            log.warning(
                "query decomposition has no inside (decompose(..., keep_inside=True) as "
                "ingest does for lf_source=field): it keeps the stored order, without the "
                "light field stage"
            )
        return _Query(
            _featurise(query, config), is_sparse(query.sampling, query.spacing),
            decomposition=query,
        )  # fmt: skip
    if isinstance(query, Geometry):
        return _from_geometry(db, query)
    if isinstance(query, ShapeRecord):
        if query.config != config:
            raise ConfigError("record was built with another configuration", source=query.name)
        d = query.decomposition
        view = None if query.view_feature is None else np.asarray(query.view_feature, np.float64)
        return _Query(
            _vector(query.feature, dim, source=query.name), is_sparse(d.sampling, d.spacing), view,
            decomposition=d, light_field=query.light_field,
            field_vector=getattr(query, "field_vector", None),
            surface_words=getattr(query, "surface_words", None),
        )  # fmt: skip
    if isinstance(query, os.PathLike) or (isinstance(query, str) and _is_file(query)):
        return _from_file(db, Path(query))
    if isinstance(query, str):
        try:
            sid = db.store.resolve(query)
        except NotFoundError:
            raise NotFoundError(
                "neither an existing file nor the name (or id) of a stored shape", source=query
            ) from None
        return _stored(db, sid, index)
    if isinstance(query, (np.ndarray, list, tuple)):
        return _Query(_vector(query, dim, source="query vector"))
    raise QueryError(
        "unsupported query type: expected a shape id or name, a path, a Geometry, "
        "a Decomposition or a feature vector",
        source=type(query).__name__,
    )


def _is_file(text: str) -> bool:
    try:
        return Path(text).is_file()
    except (OSError, ValueError):
        return False


def _vector(value: Any, dim: int, *, source: str) -> NDArray[np.float64]:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise QueryError(f"not a numeric feature vector: {exc}", source=source) from exc
    if v.shape != (dim,):
        raise QueryError(f"feature vector must have shape ({dim},), got {v.shape}", source=source)
    if not np.all(np.isfinite(v)):
        raise QueryError("feature vector has NaN or inf entries", source=source)
    return v


def _stored(db: StoreHandle, sid: int, index: Any) -> _Query:
    from query.search.index import open_index
    from shapedb.geometry.view import is_sparse

    v = index.features_of(sid) if index is not None else None
    if v is not None:  # sparseness and the view from memory too
        catalog = store_catalog(db, index.version_)
        pos = min(int(np.searchsorted(catalog.sparse, sid)), max(len(catalog.sparse) - 1, 0))
        sparse = bool(len(catalog.sparse) and catalog.sparse[pos] == sid)
        if not (sparse or db.config.cloud.view_cells):
            return _Query(v, sid=sid)  # a dense shape's second feature is a view: none here
        view = open_index(db, view=True).features_of(sid)  # own feature where none
        own = None if view is None or np.array_equal(view, v) else view
        return _Query(v, sparse, own, sid)
    columns = ["feature", "sampling", "spacing", "view_feature"]
    table = db.store.shapes(columns, ids=[sid])
    if table.num_rows == 0:
        raise NotFoundError("no shape with this id", source=sid)
    row = table.to_pylist()[0]
    feature = v if v is not None else np.asarray(row["feature"], dtype=np.float64)
    view = row.get("view_feature")
    return _Query(
        feature,
        is_sparse(float(row["sampling"] or 0.0), float(row["spacing"])),
        None if view is None else np.asarray(view, dtype=np.float64),
        sid,
    )


def _featurise(decomposition: Any, config: Any) -> NDArray[np.float64]:
    from shapedb.signature.kernel import features

    return np.asarray(features(decomposition, config), dtype=np.float64)


def _from_geometry(db: StoreHandle, geometry: Any) -> _Query:
    from shapedb.geometry.view import is_sparse, view_geometry
    from shapedb.mdbd.decomposition import decompose

    config = db.config
    d = decompose(
        geometry, config=config.mdbd, tail_balls=config.light_field_tail,
        keep_inside=config.light_field_inside,
    )  # fmt: skip
    sparse = is_sparse(d.sampling, d.spacing)
    if sparse:
        from shapedb.mdbd.reconstruct import reconstructed

        def recon() -> NDArray[np.float64] | None:
            found = reconstructed(geometry, d, config.mdbd, depth=config.cloud.reconstruct_depth)
            return None if found is None else _featurise(found, config)

        lf = _cloud_light_field(geometry, config)
        return _Query(
            _featurise(d, config), True, recon if config.cloud.reconstruct else None,
            decomposition=d, light_field=lf, from_points=lf is not None,
            surface_words=_surface_words(geometry, d.spacing, config),
        )  # fmt: skip

    def view() -> NDArray[np.float64] | None:
        try:
            g = view_geometry(geometry, d.spacing, config.cloud.view_cells)
            found = None if g is None else decompose(g, config=config.mdbd)
        except ShapeDBError as exc:  # compare by its own feature instead
            log.warning("query has no sparse view: %s", exc)
            return None
        return _featurise(found, config) if found is not None and found.n_balls else None

    lf = _cloud_light_field(geometry, config)
    return _Query(
        _featurise(d, config), False, view if config.cloud.view_cells else None, decomposition=d,
        light_field=lf, from_points=lf is not None,
        surface_words=_surface_words(geometry, d.spacing, config),
    )  # fmt: skip


def _surface_words(geometry: Any, spacing: float, config: Config) -> NDArray[np.float32] | None:
    """The geometry's surface words when the store keeps them, else None."""
    if not config.stores_surface_words:
        return None
    from shapedb.signature.surface_words import surface_points, surface_words

    return surface_words(surface_points(geometry, spacing))


def _cloud_light_field(geometry: Any, config: Any) -> NDArray[np.float32] | None:
    """A point cloud's light fields drawn from its points
    (:func:`shapedb.signature.lightfield.cloud_light_field`), in a store of the field's light
    fields; None for any other query or store (its light fields come from its
    decomposition). Measured: CAPOD validation clouds of 3,000 points find their class by
    the light fields alone 0.967 of the time drawn from their points, 0.833 from their
    decomposed inside (meshes 0.967)."""
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.signature.lightfield import cloud_light_field

    if not (isinstance(geometry, PointCloud) and config.light_field_inside):
        return None
    try:
        return cloud_light_field(geometry.points, config.light_field)
    except ValueError as exc:  # too few distinct points: its decomposition's instead
        log.warning("query cloud has no light fields of its own: %s", exc)
        return None


def _from_file(db: StoreHandle, path: Path) -> _Query:
    import ingest  # the public API only: ingest.load(path) -> Geometry

    geometry = ingest.load(path)
    log.debug("query %s: decomposing with %s", path, db.config.mdbd)
    return _from_geometry(db, geometry)


def _search_with_views(
    db: StoreHandle,
    index: Any,
    queries: list[_Query],
    k: int,
    allowed: NDArray[np.int64] | None,
    metric: Any = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Search with each shape's second feature (:mod:`shapedb.geometry.view`, :mod:`shapedb.mdbd.reconstruct`).

    Two dense shapes, and two sparse clouds, compare their own features. A pair of a
    sparse cloud and a dense shape is as far apart as the nearest of: the two own
    features; the cloud's own feature and the dense shape's view (stores with
    views); the cloud's reconstruction and the dense shape's own feature. Each
    comparison is one index search (the view index holds a dense shape's view and a
    sparse cloud's reconstruction, or the shape's own feature where it has none);
    the lists are merged keeping each shape's smallest distance (ties by ascending
    id). A raw vector compares with every shape's own feature.
    """
    from query.search.index import open_index

    out_ids = np.full((len(queries), k), -1, np.int64)
    out_d = np.full((len(queries), k), np.inf)
    sparse_ids = store_catalog(db, index.version_).sparse
    views = None
    with_views = bool(db.config.cloud.view_cells)
    for row, q in enumerate(queries):
        lists = [index.search(q.feature[None], k, allowed=allowed)]
        if q.sparse:  # against the dense shapes: everything but the sparse ids
            recon = q.view_feature()
            if recon is not None:
                lists.append(_among(index, recon, k, allowed, sparse_ids, inside=False))
            if with_views:
                views = views if views is not None else open_index(db, view=True, metric=metric)
                lists.append(_among(views, q.feature, k, allowed, sparse_ids, inside=False))
        elif len(sparse_ids):  # against the sparse shapes only
            views = views if views is not None else open_index(db, view=True, metric=metric)
            lists.append(_among(views, q.feature, k, allowed, sparse_ids, inside=True))
            own_view = q.view_feature() if with_views else None
            if own_view is not None:
                lists.append(_among(index, own_view, k, allowed, sparse_ids, inside=True))
        out_ids[row], out_d[row] = _nearest(lists, k)
    return out_ids, out_d


def _by_proxy(
    db: StoreHandle,
    index: Any,
    rows: NDArray[np.intp],
    resolved: list[_Query],
    found: tuple[NDArray[np.int64], NDArray[np.float64]],
    k: int,
    allowed: NDArray[np.int64] | None,
    stage: tuple[Any, Any, Any],
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.intp]]:
    """The first ``k`` results of each query, the point clouds' (``rows``) as their proxy's.

    A cloud whose light fields come from its points ranks the stored shapes as a search
    for its proxy does (:mod:`query.search.cloud_proxy`: the nearest of its first results
    by light field distance) where the proxy's own search opens the stage's spread gate
    (its nearest by stored distance are shapes whose silhouettes tell them apart: not
    jointed subjects, :meth:`LightFieldFusion.spread_gate`), each hit at its stored
    distance to the cloud's own feature; the other queries keep ``found``'s first ``k``.
    Also returns the clouds left without a proxy (their rows in ``found`` were ranked
    without their reconstructions: the caller ranks them again).
    """
    from query.search.cloud_proxy import proxies
    from query.search.rerank import search as rerank_search
    from query.search.rerank_lightfield import COLUMN, SPREAD

    scorer, arrays, query_arrays = stage
    ids, dist = found[0][:, :k].copy(), found[1][:, :k].copy()
    proxy = proxies(query_arrays[COLUMN][rows], found[0][rows], arrays)
    for n, x in enumerate(proxy):  # where the proxy's own gate is shut, the cloud's row stands
        if x < 0:
            continue
        pool, _ = index.search(index.features_of(int(x))[None], scorer.tuning.pool, allowed=allowed)
        listed = pool[0][pool[0] >= 0]
        spreads = arrays(SPREAD, listed) if len(listed) else None
        if spreads is None or scorer.spread_gate(np.asarray(spreads, np.float64)) <= 0:
            proxy[n] = -1
    own = rows[proxy < 0]
    rows, proxy = rows[proxy >= 0], proxy[proxy >= 0]
    if not len(rows):
        return ids, dist, own
    got, _ = rerank_search(
        index, np.stack([index.features_of(int(x)) for x in proxy]), k, config=db.config,
        query_ids=proxy, allowed=allowed, scorer=scorer, arrays=arrays,
    )  # fmt: skip
    for row, hits in zip(rows, got, strict=True):
        keep = hits[hits >= 0]
        ids[row], dist[row] = -1, np.inf
        near, d = index.search(resolved[row].feature, max(len(keep), 1), allowed=keep)
        by_id = dict(zip(near[0].tolist(), d[0].tolist(), strict=True))
        ids[row, : len(keep)] = keep
        dist[row, : len(keep)] = [by_id.get(int(i), np.inf) for i in keep]
    return ids, dist, own


def _sparse_lists(
    index: Any,
    queries: list[_Query],
    vectors: NDArray[np.float64],
    wanted: int,
    allowed: NDArray[np.int64] | None,
    proxied: Sequence[bool] = (),
) -> tuple[NDArray[np.int64], NDArray[np.float64]] | None:
    """Candidate lists (q, wanted) of a store of dense shapes; None when no query needs one.

    A sparse cloud's list keeps each shape at the nearer of its own feature's and its
    reconstruction's distance (the reconstruction's search merged, :func:`_nearest`),
    unless the cloud ranks as its proxy (``proxied[row]``, :func:`_by_proxy`: its
    reconstruction is never computed, it changed no validation query's results); every
    other query's is the index's search of its own feature.
    """
    recons = [
        q.sparse and not (row < len(proxied) and proxied[row]) for row, q in enumerate(queries)
    ]  # fmt: skip
    if not any(recons):
        return None
    ids, dist = index.search(vectors, wanted, allowed=allowed)
    ids, dist = np.array(ids, np.int64), np.array(dist, np.float64)
    for row, q in enumerate(queries):
        recon = q.view_feature() if recons[row] else None
        if recon is not None:
            own = (ids[row : row + 1], dist[row : row + 1])
            ids[row], dist[row] = _nearest(
                [own, index.search(recon[None], wanted, allowed=allowed)], wanted
            )
    return ids, dist


#: Up to this many ids, a search restricted to them scans them; beyond, the index is
#: searched unrestricted and the results filtered.
_SCAN_IDS = 4096


def _among(
    index: Any,
    vector: NDArray[np.float64],
    k: int,
    allowed: NDArray[np.int64] | None,
    ids: NDArray[np.int64],
    *,
    inside: bool,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The k nearest of ``vector`` (d,) among ``ids`` (sorted; or all but them), (1, k) each.

    Within ``allowed`` when given. A small set is scanned exactly; a large one (the
    dense shapes of a store, typically) is searched through the index without a
    restriction, dropping the other ids and asking for more until k remain.
    """
    scope = index.ids_[index.alive_] if allowed is None else np.asarray(allowed)
    if inside or allowed is not None or len(ids) == 0:
        subset = np.intersect1d(scope, ids) if inside else np.setdiff1d(scope, ids)
        if not inside and len(ids) == 0:
            subset = scope
        if len(subset) <= _SCAN_IDS or allowed is not None:
            if not len(subset):
                return np.full((1, k), -1, np.int64), np.full((1, k), np.inf)
            return index.search(vector[None], k, allowed=subset)  # type: ignore[no-any-return]
    want = k
    while True:  # all but ``ids``, which are few next to the rest
        got_ids, got_d = index.search(vector[None], want)
        member = np.isin(got_ids[0], ids)
        keep = (got_ids[0] >= 0) & (member == inside)
        if keep.sum() >= k or want >= len(scope):
            break
        want = min(2 * want + int(member.sum()), len(scope))
    out_i = np.full((1, k), -1, np.int64)
    out_d = np.full((1, k), np.inf)
    n = min(int(keep.sum()), k)
    out_i[0, :n], out_d[0, :n] = got_ids[0][keep][:n], got_d[0][keep][:n]
    return out_i, out_d


def _nearest(
    lists: list[tuple[NDArray[np.int64], NDArray[np.float64]]], k: int
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Result lists ((1, k) ids, (1, k) distances each) merged: each id once, nearest first.

    Each id keeps its smallest distance; sorted by distance, ties by ascending id;
    -1 ids pad. Top-k lists suffice: a shape among the k nearest by the smallest
    distance is among the k nearest of the list that gives it that distance.
    """
    i = np.concatenate([ids[0] for ids, _ in lists])
    d = np.concatenate([dist[0] for _, dist in lists])
    real = i >= 0
    i, d = i[real], d[real]
    order = np.lexsort((d, i))  # by id, the smaller distance first
    i, d = i[order], d[order]
    first = np.r_[True, i[1:] != i[:-1]]
    i, d = i[first], d[first]
    order = np.lexsort((i, d))[:k]
    out_i = np.full(k, -1, np.int64)
    out_d = np.full(k, np.inf)
    out_i[: len(order)], out_d[: len(order)] = i[order], d[order]
    return out_i, out_d
