"""Shape retrieval: ``db.search(query, k=10, where=None)`` and its batch form.

A query is turned into an Eq. 1 feature vector with the store's own configuration,
faiss proposes candidates (:mod:`query.index`) and the exact Eq. 2 distance decides
the order; the similarity reported is the Eq. 3 kernel ``exp(-lam * d)``.

Accepted queries, tried in this order:

* a stored shape id (``int``);
* a :class:`shapedb.mdbd.Decomposition` (its configuration must be the store's);
* a :class:`shapedb.geometry.Geometry` (decomposed with ``db.config.mdbd``);
* a :class:`shapedb.schema.ShapeRecord` (its stored feature);
* a raw feature vector (``(d,)`` array, list or tuple of floats);
* a path (``os.PathLike``, or a ``str`` naming an existing file): loaded with
  ``ingest.load``, decomposed and featurised with the store's configuration;
* a stored shape name (a ``str`` that is not an existing file).

A stored query is *not* excluded from its own results: it ranks first, with
similarity 1.0 (distance 0), unless another shape has an identical feature and a
smaller id. Ties are broken by ascending id everywhere.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import ConfigError, NotFoundError, QueryError

__all__ = ["Hit", "search", "search_batch", "query_features"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Hit:
    """One search result.

    Attributes
    ----------
    id : int
        Stored shape id.
    name : str
        Stored shape name.
    label : str or None
        Class label, if any.
    similarity : float
        Eq. 3 kernel value ``exp(-lam * distance)``, in (0, 1].
    distance : float
        Eq. 2 weighted L1 distance between the query's and the shape's features.
    """

    id: int
    name: str
    label: str | None
    similarity: float
    distance: float

    def to_dict(self) -> dict[str, Any]:
        """``{"id", "name", "label", "similarity", "distance"}``, JSON-ready."""
        return asdict(self)


def search(db: Any, query: Any, *, k: int = 10, where: str | None = None) -> list[Hit]:
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
    return search_batch(db, [query], k=k, where=where)[0]


def search_batch(
    db: Any, queries: Sequence[Any], *, k: int = 10, where: str | None = None
) -> list[list[Hit]]:
    """:func:`search` for many queries at once (one faiss call, one filter).

    Parameters
    ----------
    db : shapedb.Database
    queries : sequence
        Each as accepted by :func:`search`.
    k : int
    where : str, optional

    Returns
    -------
    list of list of Hit
        One list per query, in the order of ``queries``.
    """
    from query.index import open_index

    if isinstance(queries, (str, bytes, os.PathLike)) or not isinstance(queries, Sequence):
        if isinstance(queries, np.ndarray) and queries.ndim == 2:
            queries = list(queries)
        else:
            raise QueryError(
                "search_batch expects a sequence of queries", source=type(queries).__name__
            )
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise QueryError("k must be a positive integer", source=f"k={k!r}")
    if not len(queries):
        return []
    index = open_index(db)
    vectors = np.stack([query_features(db, q, index=index) for q in queries])
    allowed = None
    if where is not None:
        from query.sql import allowed_ids

        allowed = allowed_ids(db, where)
    ids, dist = index.search(vectors, int(k), allowed=allowed)
    catalog = _catalog(db, index.version_)
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


def query_features(db: Any, query: Any, *, index: Any = None) -> NDArray[np.float64]:
    """The Eq. 1 feature vector of a query, computed with the store's configuration.

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
    from shapedb.geometry import Geometry
    from shapedb.mdbd import Decomposition
    from shapedb.schema import ShapeRecord

    config = db.config
    dim = config.kernel.dim
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
        return _featurise(query, config)
    if isinstance(query, Geometry):
        from shapedb.mdbd import decompose

        return _featurise(decompose(query, config=config.mdbd), config)
    if isinstance(query, ShapeRecord):
        if query.config != config:
            raise ConfigError("record was built with another configuration", source=query.name)
        return _vector(query.feature, dim, source=query.name)
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
        return _vector(query, dim, source="query vector")
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


def _stored(db: Any, sid: int, index: Any) -> NDArray[np.float64]:
    if index is not None:
        v = index.features_of(sid)
        if v is not None:
            return v
    table = db.store.shapes(["feature"], ids=[sid])
    if table.num_rows == 0:
        raise NotFoundError("no shape with this id", source=sid)
    return np.asarray(table.column("feature")[0].as_py(), dtype=np.float64)


def _featurise(decomposition: Any, config: Any) -> NDArray[np.float64]:
    from shapedb.kernel import features

    return np.asarray(features(decomposition, config.kernel), dtype=np.float64)


def _from_file(db: Any, path: Path) -> NDArray[np.float64]:
    import ingest  # the public API only: ingest.load(path) -> Geometry
    from shapedb.mdbd import decompose

    geometry = ingest.load(path)
    log.debug("query %s: decomposing with %s", path, db.config.mdbd)
    return _featurise(decompose(geometry, config=db.config.mdbd), db.config)


class _Catalog:
    """id -> (name, label) for one store version, sorted by id for searchsorted."""

    def __init__(self, ids: NDArray[np.int64], names: list[str], labels: list[str | None]):
        self.ids = ids
        self.names = names
        self.labels = labels

    def lookup(self, ids: NDArray[np.int64]) -> list[tuple[str, str | None] | None]:
        """(name, label) of each id; None for an id this catalog does not hold."""
        pos = np.minimum(np.searchsorted(self.ids, ids), max(len(self.ids) - 1, 0))
        found = (self.ids[pos] == ids) if len(self.ids) else np.zeros(len(ids), bool)
        return [
            (self.names[p], self.labels[p]) if ok else None
            for p, ok in zip(pos.tolist(), found.tolist(), strict=True)
        ]


_CATALOGS: dict[str, tuple[int | None, _Catalog]] = {}


def _catalog(db: Any, version: int | None) -> _Catalog:
    key = os.fspath(db.store.path)
    cached = _CATALOGS.get(key)
    if cached is not None and cached[0] == version and version is not None:
        return cached[1]
    t = db.store.shapes(["id", "name", "label"])
    cat = _Catalog(
        t.column("id").to_numpy(), t.column("name").to_pylist(), t.column("label").to_pylist()
    )
    _CATALOGS[key] = (version, cat)
    return cat
