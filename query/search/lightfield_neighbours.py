"""The shared-neighbour term of the ``"lightfield"`` stage and its per-store-version table.

The term (``StageTuning.shared_neighbours`` ``k`` and ``shared_weight``
``beta``, :mod:`query.search.rerank_lightfield`): for a query ``q`` with candidates ``C`` (in
list order) and stage distances ``dl(q, x)``,

* ``N_k(q)``: the query's ``k`` nearest other candidates by ``dl`` (ties in list order;
  the query itself left out, and for an outside query a stored copy with ``dl == 0``:
  the scorer's ``own`` mask), :func:`nearest_others`;
* ``N_k(x)`` of a stored shape ``x``: its ``k`` nearest other stored shapes by the
  stage distance among its own stage candidates, what a search for the stored id ``x``
  re-ranks (version 4's ``K`` nearest, then the field vectors' ``K2`` extras:
  :func:`query.search.rerank.stage_batch`), ties in list order, ``x`` left out;
* ``S(q, x) = |({q} ∪ N_k(q)) ∩ ({x} ∪ N_k(x))| / (k + 1)`` (:func:`shared_scores`):
  a stored query is its id, so ``q ∈ N_k(x)`` counts (the reciprocal case); an outside
  query matches no stored id, so only ``x ∈ N_k(q)`` and common neighbours count. For
  every candidate ``x``, the stored query's ``S`` is the outside copy's plus ``1 / (k +
  1)`` exactly where ``q ∈ {x} ∪ N_k(x)``, and nothing else differs.

The lists ``N_k(x)`` depend on the whole store (a new shape changes its neighbours'
lists). Like the spreads (:mod:`query.search.lightfield_spread`), they are computed on demand
for the candidates a search needs (only queries whose gate is open read them), kept in
process per store version (:class:`NeighbourTable`), and written to
``<store>/index_neighbours/`` (a versioned table, :mod:`query.search.shape_table`) by the
commit hook (:func:`on_commit`): created at an ingest's end while the whole table costs
at most :data:`FULL_AT_COMMIT` stage distances (recomputed whole at each commit while it
does), or by :func:`refresh` at any size; once written, each commit *carries* it: the
shapes still alive keep their lists (an old list does not gain a new shape; the table
records the version each was computed at), a deleted id is in no result but may stay in
an old list, where it matches no candidate, and only the new shapes' lists are computed.
Read back while the parameters match. A list computed for one shape or for all at one
version is the same (deterministic, from the stored vectors, light fields and field
vectors). Cost: one stage per shape (``K + K2`` stage distances at most, and a search of
each index). The lists are those of the store's own stored distance (no learned metric).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from query.search.field_fusion import FieldFusion
from query.search.rerank import Candidates, stage_batch
from query.search.shape_table import ShapeTable, index_version, shared_table, update
from query.search.tuning import PRODUCT, StageTuning
from query.search.versioned import POINTER

if TYPE_CHECKING:
    from query.search.rerank import ArrayReader
    from shapedb.config.core import Config
    from shapedb.store.handle import StoreHandle

__all__ = [
    "forget",
    "NEIGHBOURS",
    "NEIGHBOUR_DIR",
    "FULL_AT_COMMIT",
    "StageRows",
    "nearest_others",
    "shared_scores",
    "keep_first",
    "stage_lists",
    "commit_distances",
    "NeighbourTable",
    "neighbour_table",
    "store_neighbours",
    "on_commit",
    "refresh",
]

log = logging.getLogger(__name__)

#: The pseudo-column of the stored shapes' lists, read through ``Candidates.arrays``:
#: (m, k) float64 ids, -1 pads.
NEIGHBOURS = "light_field_neighbours"
NEIGHBOUR_DIR = "index_neighbours"
_FORMAT = 2
_CHUNK = 16
#: The lists are computed whole (the table created at an ingest's end, or recomputed
#: exactly at a commit) only while that costs at most this many stage distances
#: (:func:`commit_distances`; 100 shapes each reaching the whole store): larger stores
#: keep no table until one is written (:func:`refresh`), then carry it.
FULL_AT_COMMIT = 10_000
_CACHE: dict[tuple[str, int], NeighbourTable] = {}
_LOCK = threading.Lock()


def forget(path: str) -> None:
    """Drop the tables this process keeps for the store at ``path`` (as a new process)."""
    with _LOCK:
        for key in [k for k in _CACHE if k[0] == path]:
            _CACHE.pop(key, None)


class StageRows(Protocol):
    """The scorer's side the table needs (:class:`query.search.rerank_lightfield.LightFieldFusion`)."""

    tuning: StageTuning

    def stage_rows(
        self, batch: Candidates
    ) -> Iterator[tuple[int, NDArray[np.intp], NDArray[np.float64], NDArray[np.bool_]]]: ...

    def extra_candidates(
        self, batch: Candidates, allowed: Any = None
    ) -> NDArray[np.int64] | None: ...

    def score(self, batch: Candidates) -> NDArray[np.float64]: ...


def nearest_others(
    dl: NDArray[np.float64], own: NDArray[np.bool_], ids: NDArray[np.int64], k: int
) -> NDArray[np.int64]:
    """(k,) ids of the ``k`` nearest candidates by ``dl`` that are not ``own``; -1 pads.

    ``dl``, ``own`` and ``ids`` are (c,) in list order; ties keep it.
    """
    others = np.flatnonzero(~np.asarray(own, bool))
    near = others[np.argsort(np.asarray(dl)[others], kind="stable")[:k]]
    out = np.full(k, -1, np.int64)
    out[: len(near)] = np.asarray(ids, np.int64)[near]
    return out


def shared_scores(
    query_list: NDArray[np.int64],
    query_id: int,
    ids: NDArray[np.int64],
    lists: NDArray[np.int64],
    k: int,
) -> NDArray[np.float64]:
    """(c,) ``S(q, x)`` of a query's candidates (see the module docstring).

    Parameters
    ----------
    query_list : (k,) int64
        ``N_k(q)`` (:func:`nearest_others`), -1 pads.
    query_id : int
        The query's stored id; -1 for an outside query (it matches no stored id).
    ids : (c,) int64
        The candidates ``x``.
    lists : (c, k) int64
        Their stored lists ``N_k(x)``, -1 pads (an unknown list: all -1).
    k : int
        ``k`` (the denominator is ``k + 1``).
    """
    a = np.asarray(query_list, np.int64)
    a = a[a >= 0]
    if query_id >= 0:
        a = np.append(a, np.int64(query_id))
    b = np.concatenate([np.asarray(ids, np.int64)[:, None], np.asarray(lists, np.int64)], 1)
    hit = np.isin(b, a) & (b >= 0)
    return np.asarray(hit.sum(axis=1) / (k + 1.0), np.float64)


def keep_first(
    plain: NDArray[np.float64],
    shared: NDArray[np.float64],
    own: NDArray[np.bool_],
    ids: NDArray[np.int64],
) -> NDArray[np.float64]:
    """``shared`` with the first other candidate of ``plain`` first among the others again.

    ``plain`` and ``shared`` are one query's fused distances (c,) without and with the
    term, ordered by (distance, id) as :func:`query.search.rerank.rerank_candidates` orders
    them; the candidate first among those not ``own`` by ``plain`` takes the least
    distance of the others by ``shared`` (others tied with it and of a smaller id are
    moved one ulp up), so it stays first and the rest keep the term's order.
    """
    out = np.array(shared, np.float64, copy=True)
    others = np.flatnonzero(~np.asarray(own, bool))
    if len(others) < 2:
        return out
    ids = np.asarray(ids, np.int64)
    first = others[np.lexsort((ids[others], plain[others]))[0]]
    now = others[np.lexsort((ids[others], out[others]))[0]]
    if first == now:
        return out
    value = out[now]
    out[first] = value
    tied = others[(out[others] == value) & (ids[others] < ids[first]) & (others != first)]
    out[tied] = np.nextafter(value, np.inf)
    return out


def stage_lists(
    index: Any,
    fields: ArrayReader,
    config: Config,
    scorer: StageRows,
    ids: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Indexed shapes' lists ``N_k(x)`` (every alive shape's by default).

    Parameters
    ----------
    index : FeatureIndex
        Fitted over the stored vectors (the store's own, no learned metric); its alive
        ids are the shapes.
    fields : ArrayReader
        The store's per-record arrays (light fields, field vectors and their index), as
        a search reads them.
    config : Config
        What the store keeps.
    scorer : StageRows
        The stage (``LightFieldFusion(config)``): its extra candidates and distances.
    ids : (m,) int64, optional
        The shapes wanted; ids not alive in the index are left out.

    Returns
    -------
    ids : (n,) int64
        Ascending, alive.
    lists : (n, k) int64
        Each shape's ``k`` nearest others, nearest first; -1 pads (fewer candidates, or a
        shape whose row the stage cannot score: no light fields).
    """
    tuning = scorer.tuning
    k = int(tuning.shared_neighbours)
    alive = np.sort(np.asarray(index.ids_, np.int64)[np.asarray(index.alive_, bool)])
    ids = alive if ids is None else np.intersect1d(alive, np.asarray(ids, np.int64))
    out = np.full((len(ids), k), -1, np.int64)
    if len(ids) == 0 or k == 0:
        return ids, out
    x = np.asarray(index.features_, np.float64)[index.lookup(ids)]
    wanted = int(tuning.candidates)
    for lo in range(0, len(ids), _CHUNK):
        q = ids[lo : lo + _CHUNK]
        cand, dist = index.search(x[lo : lo + _CHUNK], wanted)
        batch = stage_batch(
            index, x[lo : lo + _CHUNK], cand, dist, config=config, scorer=scorer,
            query_ids=q, arrays=fields,
        )  # fmt: skip
        n_k = int(batch.head if batch.head is not None else wanted)
        head = Candidates(
            batch.query_ids, batch.queries, batch.ids[:, :n_k], batch.features[:, :n_k],
            batch.weights, batch.distances[:, :n_k], config, fields, None, n_k,
        )  # fmt: skip
        for row, cols, dl, own in scorer.stage_rows(head):
            out[lo + row] = nearest_others(dl, own, head.ids[row, cols], k)
    return ids, out


def commit_distances(n: int, config: Config, tuning: StageTuning = PRODUCT) -> int:
    """Stage distances the lists of a store of ``n`` shapes cost (each reaches ``K + K2``)."""
    f = tuning
    reach = int(tuning.candidates)
    if FieldFusion.from_config(config, tuning).proposes:
        reach += int(f.field_candidates)
    return int(n) * min(reach, int(n))


def _meta(config: Config, version: int, tuning: StageTuning) -> dict[str, Any]:
    f = tuning
    fusion = FieldFusion.from_config(config, tuning)
    return {
        "format": _FORMAT,
        "version": version,
        "shared_neighbours": int(f.shared_neighbours),
        "candidates": int(tuning.candidates),
        "light_field": repr(config.light_field),
        "descriptor": int(config.descriptor.version),
        "method": config.kernel.method,
        "field_fusion": fusion.key(),
        "field_candidates": int(f.field_candidates) if fusion.proposes else 0,
        "field_weights": [float(f.field_depth_weight), float(f.field_harmonic_weight)]
        if fusion.proposes
        else None,
        "field_vector": repr(config.field_vector) if config.stores_field_vectors else None,
    }


class NeighbourTable(ShapeTable):
    """The lists ``N_k(x)`` of one store version, filled as they are asked for.

    Parameters
    ----------
    db : shapedb.Database
    fields : ArrayReader
        The store's arrays by id (:func:`query.search.rerank_lightfield.stored_arrays`).
    scorer : StageRows
        The store's stage (``LightFieldFusion(db.config)``).
    meta : dict, optional
        The parameters (:func:`_meta` at the index's version by default).
    """

    directory = NEIGHBOUR_DIR
    file = "neighbours.npy"
    what = "shared-neighbour lists"

    def __init__(self, db: StoreHandle, fields: ArrayReader, scorer: StageRows,
                 meta: dict[str, Any] | None = None) -> None:  # fmt: skip
        self.fields, self.scorer = fields, scorer
        self.k = int(scorer.tuning.shared_neighbours)
        if meta is None:
            meta = _meta(db.config, index_version(db), scorer.tuning)
        super().__init__(db, meta)

    def check(self, values: NDArray[Any]) -> None:
        if values.ndim != 2 or values.shape[1] != self.k:
            raise ValueError(f"lists of shape {values.shape} for k = {self.k}")

    def compute(self, ids: NDArray[np.int64] | None) -> tuple[NDArray[np.int64], Any]:
        return stage_lists(self.index, self.fields, self.db.config, self.scorer, ids)

    def get(self, ids: NDArray[np.int64] | None = None) -> NDArray[np.int64]:
        """(m, k) lists of ``ids`` (every alive shape's when None); -1 rows for ids without.

        Computes the ids not known yet, in this process (a read writes nothing).
        """
        _, values = self.known(ids)
        none = np.full(self.k, -1, np.int64)
        rows = [none if v is None else np.asarray(v, np.int64) for v in values]
        return np.stack(rows) if rows else np.zeros((0, self.k), np.int64)


def neighbour_table(db: StoreHandle, fields: ArrayReader, scorer: StageRows) -> NeighbourTable:
    """The shared :class:`NeighbourTable` of ``db``'s store at its index's current version."""
    return shared_table(  # type: ignore[no-any-return]
        _CACHE, _LOCK, db, lambda v: _meta(db.config, v, scorer.tuning),
        lambda m: NeighbourTable(db, fields, scorer, m),
    )  # fmt: skip


def store_neighbours(db: StoreHandle, fields: ArrayReader, scorer: StageRows) -> dict[int, Any]:
    """Every stored shape's list at the store's current version, by id ((k,) int64 each).

    Read from ``<store>/index_neighbours/`` under the stage's parameters (carried: values of an
    earlier version kept, :mod:`query.search.shape_table`); the missing ones computed
    (:func:`stage_lists`), not written. :func:`refresh` gives the exact table.
    """
    table = neighbour_table(db, fields, scorer)
    table.get(None)
    return dict(table.values)


def on_commit(
    db: StoreHandle, fields: ArrayReader, scorer: StageRows, *, create: bool = False
) -> None:
    """Bring the lists up to date after a commit, for a store whose stage reads them.

    Only a store with the ``"lightfield"`` scorer and the term on
    (:attr:`query.search.tuning.StageTuning.shares_neighbours`) and a table written
    before, or, with ``create`` (the end of an ingest), a store whose whole table costs at
    most :data:`FULL_AT_COMMIT` stage distances (:func:`commit_distances`): the one place
    that writes the table (:func:`query.search.shape_table.update`: the new shapes'
    lists computed, the others carried; a table within the limit recomputed whole).
    Other stores' searches compute the lists they read, in memory.
    """
    cfg = db.config
    if cfg.rerank.scorer != "lightfield" or not scorer.tuning.shares_neighbours:
        return
    written = (Path(db.store.path) / NEIGHBOUR_DIR / POINTER).exists()
    if not written and not create:  # nothing to keep: no index opened, nothing computed
        return
    whole = commit_distances(len(db.store), cfg, scorer.tuning)
    if written or whole <= FULL_AT_COMMIT:
        update(neighbour_table(db, fields, scorer), whole, FULL_AT_COMMIT)


def refresh(db: StoreHandle, fields: ArrayReader, scorer: StageRows) -> NeighbourTable:
    """Recompute every stored shape's list at the store's version and save the table.

    The exact table (nothing carried, ``exact`` in its pointer), whatever the store's
    size (``commit_distances`` stage distances); a store the process cannot write keeps
    it in memory. Returns the shared table.
    """
    table = neighbour_table(db, fields, scorer)
    table.refresh()
    table.keep()
    return table
