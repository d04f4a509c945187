"""The ``"lightfield"`` re-ranking scorer: the balls' light fields fused with the stored distance.

A store created with ``rerank="lightfield"`` keeps each record's light fields (the
``light_field`` column: :func:`shapedb.signature.lightfield.record_light_field` of its balls under
``Config.light_field``). The scorer (:class:`LightFieldFusion`, which
:func:`query.search.stage.scorer_for` gives such a store) re-ranks a query's candidates by the gated
reciprocal rank fusion of :class:`query.search.tuning.StageTuning`: the stored
distance's rank plus the light field distance's rank, the latter weighted by a gate that
is off where the light field spreads near neighbours more than the stored distance does
(jointed subjects, whose silhouettes change with the pose: the stored local statistics
of the query's first candidates, :mod:`query.search.lightfield_spread`) and where the stored
distance already sets the query's nearest apart (a low contrast).

The candidates' light fields are read by id (``Candidates.arrays``); the query's are
read by its id when it is a stored shape, else taken from ``Candidates.query_arrays``
(computed from the query's own decomposition: :func:`query_light_fields`, or drawn from a
point cloud's points). The stored local spreads are read by id too, as the array
:data:`SPREAD`.

Records without light fields (a store written before the column, or with another scorer
when the records were built): the query's row keeps the stored-distance order (the
stage's default) and a warning is logged once per scorer.

A store with field vectors (:mod:`query.search.field_fusion`) fuses them into the light field
distance wherever the stage uses it (the ranks, the gate, the stored local statistics)
when a field weight is above 0, and with ``StageTuning.field_candidates > 0``
the scorer proposes the nearest shapes by the scaled field vectors as extra candidates
(:meth:`LightFieldFusion.extra_candidates`, through the field vector index of
:mod:`query.search.field_index`, which the store's reader offers: :meth:`StoredArrays.field_index`).

With ``StageTuning.shared_neighbours`` ``k > 0`` and ``shared_weight`` ``beta
> 0`` the light field's rank ranks by ``dl / scale - beta * S(q, x)`` (``scale`` the unit of
the stage's distance, :meth:`query.search.tuning.StageTuning.unit`), ``S`` the share of
the query's and the candidate's ``k`` nearest neighbours in common
(:mod:`query.search.lightfield_neighbours`, whose per-store-version table of the stored shapes'
lists the reader serves as :data:`NEIGHBOURS`); the gate reads ``dl`` alone, and the
first result among the query's other candidates is the one without the term
(:meth:`LightFieldFusion.fuse`).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.search.array_cache import ColumnCache, open_column
from query.search.array_cache import forget as forget_columns
from query.search.candidate_neighbours import candidate_shared, context_distance
from query.search.field_fusion import FIELD, FieldFusion, stores_field_vectors
from query.search.lightfield_neighbours import (
    NEIGHBOURS,
    keep_first,
    nearest_others,
    neighbour_table,
    shared_scores,
)
from query.search.lightfield_spread import calibration, local_statistic, pooled, spread_table
from query.search.rerank import Candidates, list_ranks
from query.search.tuning import PRODUCT, StageTuning, active
from query.search.word_fusion import WORDS_COLUMN, fuse_words
from shapedb.signature.surface_words import words_distance

if TYPE_CHECKING:
    from shapedb.config.core import Config

__all__ = [
    "LightFieldFusion",
    "StoredArrays",
    "stored_arrays",
    "query_light_fields",
    "forget",
    "COLUMN",
    "SPREAD",
    "NEIGHBOURS",
]

log = logging.getLogger(__name__)

#: The per-record column (and ``Candidates.query_arrays`` key) of the light fields.
COLUMN = "light_field"
#: The per-record array of the stored shapes' local light field spreads
#: (:mod:`query.search.lightfield_spread`), read through ``Candidates.arrays`` like a column.
SPREAD = "light_field_spread"


class LightFieldFusion:
    """Scorer ``"lightfield"``: ``(1 + w g) / o - (1 / (o + rank_d) + w g / (o + rank_l))``.

    The study's fused similarity turned into a distance >= 0, so the order is the
    study's: 0 for a candidate first by both distances (the query itself when stored),
    ``g = g(q)`` the query's gate, ``w`` the weight, ``o`` the offset. It is a rank
    distance, not the stored vector's: it only orders one query's results.

    The formula, the gate ``g(q)`` and the spread are those of
    :class:`query.search.tuning.StageTuning` (:data:`~query.search.tuning.PRODUCT`); ranks and
    the neighbourhoods are taken among the query's valid candidates in their list
    order (stored distance, ties by ascending id). With the shared-neighbour term
    (``shared_neighbours``, ``shared_weight``) ``rank_l`` ranks by ``dl / scale - beta *
    S(q, x)`` where the gate is open, and the first result among the query's others is
    the one without the term (:meth:`fuse`).

    Parameters
    ----------
    config : Config
        Reads ``config.light_field`` and the descriptor's layout.
    tuning : StageTuning
        The stage's numbers (:data:`query.search.tuning.PRODUCT`; studies vary them).
    """

    def __init__(self, config: Config, *, tuning: StageTuning = PRODUCT) -> None:
        self.config = config
        self.tuning = tuning
        self.calibration = calibration(config)
        self.field = FieldFusion.from_config(config, tuning)
        self._warned = False
        self._warned_index = False
        self._warned_lists = False

    def _warn(self, why: str) -> None:
        if not self._warned:
            log.warning("lightfield re-ranking: %s; those queries keep the stored order", why)
            self._warned = True

    def fuse(
        self,
        d: NDArray[np.float64],
        dl: NDArray[np.float64],
        own: NDArray[np.bool_],
        spreads: NDArray[np.float64] | None = None,
        *,
        gate: float | None = None,
        shared: NDArray[np.float64] | None = None,
        ids: NDArray[np.int64] | None = None,
        context: NDArray[np.float64] | None = None,
        weight: float | None = None,
    ) -> NDArray[np.float64]:
        """Fused scores (c,) of one query's candidates.

        With ``shared`` (the term's ``S(q, x)``, :mod:`query.search.lightfield_neighbours`) and
        an open gate, the light field's rank is taken by ``dl / scale - beta * S`` instead
        of ``dl`` (:class:`query.search.tuning.StageTuning`; ``scale``:
        :attr:`scale`); the gate reads ``dl`` alone. **The first result is kept**: the
        candidate first among those not ``own`` without the term (by fused score, ties
        by ascending id, as :func:`query.search.rerank.rerank_candidates` orders) is first among
        them with it (:func:`query.search.lightfield_neighbours.keep_first`), so the nearest
        neighbour never changes; the term only reorders the rest.

        Parameters
        ----------
        d : (c,) float64
            Stored distances, in list order (non-decreasing).
        dl : (c,) float64
            Light field distances (the stage's).
        own : (c,) bool
            The query itself among the candidates (left out of the gate and of the
            first result).
        spreads : (c,) float64, optional
            The candidates' stored local spreads (NaN: unknown), pooled when
            ``StageTuning.pool > 0``; None there: the term is off.
        gate : float, optional
            ``g(q)`` when already known (:meth:`gate` of the same arguments).
        shared : (c,) float64, optional
            ``S(q, x)`` of each candidate; None: no shared-neighbour term.
        ids : (c,) int64, optional
            The candidates' ids (the first result's ties); needed with ``shared`` and
            ``context``.
        context : (c,) float64, optional
            The stored distance with its shared-neighbour term
            (:func:`query.search.candidate_neighbours.context_distance`): ``rank_d`` ranks by it,
            its nearest other kept first; None: by ``d``.
        weight : float, optional
            The light field's rank weight ``w``; None: ``StageTuning.weight``.
        """
        f = self.tuning
        w = f.weight if weight is None else float(weight)
        d4 = d / self.calibration
        if context is not None and ids is not None:
            fused = 1.0 / (f.offset + list_ranks(keep_first(d4, context, own, ids)))
        else:
            fused = 1.0 / (f.offset + list_ranks(d4))
        g = self.gate(d4, dl, own, spreads) if gate is None else float(gate)
        if g <= 0:
            return np.maximum(1.0 / f.offset - fused, 0.0)
        top = (1.0 + w * g) / f.offset
        plain = np.maximum(top - (fused + w * g / (f.offset + list_ranks(dl))), 0.0)
        if shared is None or ids is None:
            return plain
        rank_s = list_ranks(dl / self.scale - f.shared_weight * np.asarray(shared, np.float64))
        term = np.maximum(top - (fused + w * g / (f.offset + rank_s)), 0.0)
        return keep_first(plain, term, own, ids)

    @property
    def scale(self) -> float:
        """The unit of ``dl`` in the spread and the shared-neighbour term: ``scale`` when the
        field vectors are fused into the light field distance, else ``light_field_unit``
        (:meth:`query.search.tuning.StageTuning.unit`)."""
        return self.tuning.unit(self.field.active)

    def gate(
        self,
        d4: NDArray[np.float64],
        dl: NDArray[np.float64],
        own: NDArray[np.bool_],
        spreads: NDArray[np.float64] | None,
    ) -> float:
        """``g(q)`` in [0, 1]: overlap, spread ceiling and contrast floor (the config's):
        :meth:`pose_gate` times :meth:`contrast_gate`.

        ``d4`` in calibrated units, list order; the arguments as :meth:`fuse`'s.
        """
        g = self.pose_gate(d4, dl, own, spreads)
        return g * self.contrast_gate(d4, own) if g > 0 else 0.0

    def contrast_gate(self, d4: NDArray[np.float64], own: NDArray[np.bool_]) -> float:
        """The gate's contrast floor in [0, 1]: 0 where the stored distance already sets the
        query's nearest others apart (their median over a farther one's is low); 1 without
        a floor. The arguments as :meth:`gate`'s."""
        f = self.tuning
        others = np.flatnonzero(~own)
        if f.contrast_floor <= 0 or not len(others):
            return 1.0
        others = others[np.argsort(d4[others], kind="stable")]  # nearest by d first
        far = d4[others[min(f.contrast_depth, len(others)) - 1]]
        contrast = float(np.median(d4[others[: f.neighbours]])) / max(float(far), 1e-300)
        return float(np.clip((contrast - f.contrast_floor) / f.contrast_ramp, 0.0, 1.0))

    def pose_gate(
        self,
        d4: NDArray[np.float64],
        dl: NDArray[np.float64],
        own: NDArray[np.bool_],
        spreads: NDArray[np.float64] | None,
    ) -> float:
        """The gate's spread ceiling alone, in [0, 1]: 0 where the query's near neighbours
        spread as a subject in many poses does (jointed subjects), 1 for rigid shapes.

        0 for a query without other candidates; the arguments as :meth:`gate`'s.
        """
        f = self.tuning
        others = np.flatnonzero(~own)
        if not len(others):
            return 0.0
        if f.ceiling <= 0:
            return 1.0
        if f.pool > 0:
            return 0.0 if spreads is None else self.spread_gate(spreads)
        others = others[np.argsort(d4[others], kind="stable")]  # the query's own statistic
        spread = local_statistic(d4[others], dl[others], self.tuning, self.scale)
        return float(np.clip((f.ceiling - spread) / f.ramp, 0.0, 1.0))

    def spread_gate(self, spreads: NDArray[np.float64]) -> float:
        """The gate's spread-ceiling factor in [0, 1]: the ``pool_quantile`` of the stored
        local spreads of a query's first ``pool`` candidates (``spreads``, (c,) in list
        order, NaN unknown) under the ceiling; 0 when none is known, 1 without a ceiling
        or a pool. Jointed subjects, whose silhouettes change with the pose, shut it."""
        f = self.tuning
        if f.ceiling <= 0 or f.pool <= 0:
            return 1.0
        pool = np.asarray(spreads, np.float64)[: f.pool]
        if not np.isfinite(pool).any():
            return 0.0
        return float(np.clip((f.ceiling - float(pooled(pool, f.pool_quantile))) / f.ramp, 0.0, 1.0))

    def stage_rows(
        self, batch: Candidates
    ) -> Iterator[tuple[int, NDArray[np.intp], NDArray[np.float64], NDArray[np.bool_]]]:
        """``(row, cols, dl, own)`` of each query of ``batch`` the stage can score.

        ``cols`` are the row's valid columns (list order), ``dl`` (len(cols),) the stage
        distance to them (the light field distance, fused with the field vectors when
        the store fuses them: :mod:`query.search.field_fusion`), ``own`` the query itself among
        them (for an outside query also a stored copy, ``dl == 0``). Rows without light
        fields (the query's or a candidate's) are left out, with one warning per scorer.
        """
        from shapedb.signature.lightfield import light_field_distance

        valid = batch.valid
        wanted = np.unique(
            np.concatenate([batch.ids[valid], batch.query_ids[batch.query_ids >= 0]])
        )
        stored = None if batch.arrays is None else batch.arrays(COLUMN, wanted)
        if stored is None:
            self._warn("the store keeps no light fields")
            return
        pos = {int(i): k for k, i in enumerate(wanted)}
        given = (batch.query_arrays or {}).get(COLUMN)
        fv = fv_given = None
        if self.field.active:
            fv = batch.arrays(FIELD, wanted) if batch.arrays is not None else None
            fv_given = (batch.query_arrays or {}).get(FIELD)
        for row in range(len(batch.ids)):
            cols = np.flatnonzero(valid[row])
            if not len(cols):
                continue
            lq = None
            if given is not None and np.all(np.isfinite(given[row])):
                lq = given[row]
            elif batch.query_ids[row] >= 0:
                lq = stored[pos[int(batch.query_ids[row])]]
            at = [pos[int(i)] for i in batch.ids[row, cols]]
            lc = stored[at]
            if lq is None or not np.all(np.isfinite(lq)) or not np.all(np.isfinite(lc)):
                self._warn("a query or a candidate has no stored light fields")
                continue
            dl = light_field_distance(lq[None], lc)[0]
            own = batch.ids[row, cols] == batch.query_ids[row]
            if batch.query_ids[row] < 0:  # an outside query's stored copy counts as itself
                own |= dl == 0.0
            if self.field.active:
                fq = None
                if fv_given is not None and np.all(np.isfinite(fv_given[row])):
                    fq = fv_given[row]
                elif fv is not None and batch.query_ids[row] >= 0:
                    fq = fv[pos[int(batch.query_ids[row])]]
                dl = self.field.distance(dl, fq, None if fv is None else fv[at])
            yield row, cols, dl, own

    def score(self, batch: Candidates) -> NDArray[np.float64]:
        """Fused distances, (q, c); rows without light fields keep the stored distances.

        With the shared-neighbour term on, the lists of the candidates of the queries
        whose gate is open are read through ``batch.arrays`` (:data:`NEIGHBOURS`); a
        reader without them leaves the term out (one warning per scorer).
        """
        out = np.array(batch.distances, dtype=np.float64, copy=True)
        rows = list(self.stage_rows(batch))
        if not rows:
            return out
        spreads = None
        if self.tuning.pool > 0 and self.tuning.ceiling > 0 and batch.arrays is not None:
            wanted = np.unique(np.concatenate([batch.ids[row, cols] for row, cols, _, _ in rows]))
            got = batch.arrays(SPREAD, wanted)
            if got is not None:
                spreads = dict(zip(wanted.tolist(), got, strict=True))
        gates, poses = [], []
        for row, cols, dl, own in rows:
            sp = None
            if spreads is not None:
                sp = np.array([spreads[int(i)] for i in batch.ids[row, cols]])
            d4 = batch.distances[row, cols] / self.calibration
            gates.append(self.gate(d4, dl, own, sp))  # a study's scorer may gate otherwise
            poses.append(self.pose_gate(d4, dl, own, sp))
        w = self.tuning.weight
        on = [r for r, g in zip(rows, gates, strict=True) if g > 0 and w > 0]
        lists = self._lists(batch, on)
        k = int(self.tuning.shared_neighbours)
        words = self._words(batch, rows)
        for (row, cols, dl, own), g, pose in zip(rows, gates, poses, strict=True):
            ids = batch.ids[row, cols]
            shared = None
            if lists is not None and g > 0:
                mine = nearest_others(dl, own, ids, k)
                theirs = np.stack([lists[int(i)] for i in ids])
                shared = shared_scores(mine, int(batch.query_ids[row]), ids, theirs, k)
            context = self._context(batch, row, cols, own)
            out[row, cols] = self.fuse(
                batch.distances[row, cols], dl, own, gate=g, shared=shared, ids=ids,
                context=context, weight=w,
            )  # fmt: skip
            if words is not None and row in words:
                out[row, cols] = fuse_words(out[row, cols], words[row], pose, self.tuning)
        return out

    def _words(self, batch: Candidates, rows: list[Any]) -> dict[int, NDArray[np.float64]] | None:
        """The words' distances of each row's candidates to its query, by row; None: off.

        Rows whose query or some candidate has no words are left out (the stage's order).
        """
        if self.tuning.word_weight <= 0 or batch.arrays is None or not rows:
            return None
        wanted = np.unique(
            np.concatenate([batch.ids[row, cols] for row, cols, _, _ in rows]
                           + [batch.query_ids[batch.query_ids >= 0]])
        )  # fmt: skip
        stored = batch.arrays(WORDS_COLUMN, wanted)
        if stored is None:
            return None
        pos = {int(i): k for k, i in enumerate(wanted)}
        given = (batch.query_arrays or {}).get(WORDS_COLUMN)
        out = {}
        for row, cols, _, _ in rows:
            wq = None
            if given is not None and np.all(np.isfinite(given[row])):
                wq = given[row]
            elif batch.query_ids[row] >= 0:
                wq = stored[pos[int(batch.query_ids[row])]]
            wc = stored[[pos[int(i)] for i in batch.ids[row, cols]]]
            if wq is not None and np.all(np.isfinite(wq)) and np.all(np.isfinite(wc)):
                out[row] = words_distance(wq, wc)
        return out

    def _context(
        self, batch: Candidates, row: int, cols: NDArray[np.intp], own: NDArray[np.bool_]
    ) -> NDArray[np.float64] | None:
        """The row's stored distance with the candidates' shared-neighbour term, or None
        (``descriptor_shared_weight`` 0)."""
        f = self.tuning
        if f.descriptor_shared_weight <= 0 or f.shared_neighbours < 1:
            return None
        d = batch.distances[row, cols]
        s = candidate_shared(
            d, batch.features[row, cols], batch.queries[row], batch.weights, own,
            int(f.shared_neighbours), int(f.candidates),
        )  # fmt: skip
        return context_distance(d, s, own, f.descriptor_shared_weight, int(f.candidates))

    def _lists(self, batch: Candidates, rows: list[Any]) -> dict[int, NDArray[np.int64]] | None:
        """The stored lists ``N_k(x)`` of the candidates of ``rows``, by id; None: no term."""
        if not self.tuning.shares_neighbours or not rows:
            return None
        wanted = np.unique(np.concatenate([batch.ids[row, cols] for row, cols, _, _ in rows]))
        got = None if batch.arrays is None else batch.arrays(NEIGHBOURS, wanted)
        if got is None:
            if not self._warned_lists:
                log.warning(
                    "lightfield re-ranking: no shared-neighbour lists; the term is left out"
                )
                self._warned_lists = True
            return None
        table = np.asarray(got, np.float64)
        table = np.where(np.isfinite(table), table, -1.0).astype(np.int64)
        return {int(i): table[n] for n, i in enumerate(wanted)}

    def extra_candidates(self, batch: Candidates, allowed: Any = None) -> NDArray[np.int64] | None:
        """(q, K2) nearest stored shapes by the scaled field vectors, or None (off).

        ``K2 = StageTuning.field_candidates``; the query's own field vector
        from ``batch.query_arrays`` or, for a stored query, read by id; the index from
        ``batch.arrays.field_index()`` (:mod:`query.search.field_index`). Within ``allowed``
        when given. A query without a field vector gets no extras (-1).
        """
        if not self.field.proposes or batch.arrays is None:  # no arrays: score() warns
            return None
        source = getattr(batch.arrays, "field_index", None)
        if source is None:
            if not self._warned_index:
                log.warning("lightfield re-ranking: no field vector index; no extra candidates")
                self._warned_index = True
            return None
        index = source()
        if not len(index):
            return None
        vectors = self._query_vectors(batch)
        if vectors is None:
            return np.full((len(batch.ids), self.field.candidates), -1, np.int64)
        ids, _ = index.search(self.field.scaled(vectors), self.field.candidates, allowed=allowed)
        return ids

    def _query_vectors(self, batch: Candidates) -> NDArray[np.float64] | None:
        """(q, d) the queries' field vectors (NaN rows: none); None when no query has one."""
        given = (batch.query_arrays or {}).get(FIELD)
        out = None if given is None else np.array(given, np.float64)
        stored = np.flatnonzero(batch.query_ids >= 0)
        if len(stored) and batch.arrays is not None:
            read = batch.arrays(FIELD, batch.query_ids[stored])
            if read is not None:
                if out is None or out.shape[1] != read.shape[1]:
                    out = np.full((len(batch.ids), read.shape[1]), np.nan)
                missing = ~np.all(np.isfinite(out[stored]), axis=1)
                out[stored[missing]] = read[missing]
        return out


class StoredArrays:
    """Reads a store's per-record array columns by ids (an ``ArrayReader``).

    The columns are ``light_field`` (:data:`COLUMN`) and, in a store with field vectors,
    ``field_vector`` (:data:`query.search.field_fusion.FIELD`). They are read from the
    store's memory-mapped array cache (:func:`query.search.array_cache.open_column`,
    opened at a column's first call, built or brought up to the store's version then).
    Where there is none (a read-only store never cached), rows read from the store are
    kept (float32) for the store's manifest version, shared by every reader of that
    store (:func:`stored_arrays`): later searches read only ids not seen yet, and a commit
    (a new version) starts afresh. Memory then: at most the whole columns (``n_fields *
    10 * 46 * 4`` bytes per record for the light fields, 5,520 at the defaults; 4 per
    number of a field vector).

    Parameters
    ----------
    db : shapedb.Database
    preload : bool
        Read a whole column on its first call (evaluation: every shape is asked for).
    """

    def __init__(self, db: Any, *, preload: bool = False) -> None:
        self.db = db
        self._columns = (
            (COLUMN,)
            + ((FIELD,) if stores_field_vectors(db.config) else ())
            + ((WORDS_COLUMN,) if db.config.stores_surface_words else ())
        )
        self._cache: dict[str, dict[int, NDArray[np.float32]]] = {c: {} for c in self._columns}
        # read, and null (rows older than the column)
        self._absent: dict[str, set[int]] = {c: set() for c in self._columns}
        self._preload = {c: preload for c in self._columns}
        self._complete: set[str] = set()
        self._shape = {
            COLUMN: (int(db.config.light_field.n_fields), 10, -1), FIELD: (-1,), WORDS_COLUMN: (-1,),
        }  # fmt: skip
        self._field_index: Any = None
        self._stage: LightFieldFusion | None = None
        self._mapped: dict[str, ColumnCache | None] = {}

    def _read(self, column: str, ids: list[int] | None) -> None:
        t = self.db.store.shapes(["id", column], ids=ids)
        cache, absent = self._cache[column], self._absent[column]
        for i, v in zip(t.column("id").to_pylist(), t.column(column).to_pylist(), strict=True):
            if v is not None:
                cache[int(i)] = np.asarray(v, np.float32).reshape(self._shape[column])
            else:
                absent.add(int(i))
        if ids is None:
            self._complete.add(column)

    def preload_all(self) -> None:
        """Read each column whole at its next call."""
        for c in self._columns:
            if c not in self._complete:
                self._preload[c] = True

    def field_index(self) -> Any:
        """The store's field vector index at this version (:func:`query.search.field_index.field_index`).

        Kept by the reader after its first call (the reader is its store version's).
        """
        if self._field_index is None:
            from query.search.field_index import field_index

            self._field_index = field_index(self.db)
        return self._field_index

    def __call__(self, name: str, ids: NDArray[np.int64]) -> NDArray[np.float64] | None:
        """(m, ...) float64 rows of column ``name`` for ``ids``; NaN for records without.

        ``light_field``: (m, fields, 10, d); ``field_vector``: (m, d). With ``name``
        :data:`SPREAD`, the (m,) local spreads of ``ids`` at the store's version
        (:func:`query.search.lightfield_spread.spread_table`, computed for the ids not known
        yet; NaN for ids without); with :data:`NEIGHBOURS`, in a store whose stage has
        the shared-neighbour term, the (m, k) lists ``N_k`` of ``ids`` as float ids, -1
        pads (:func:`query.search.lightfield_neighbours.neighbour_table`, computed likewise).
        None when ``name`` is none of these (or not stored) or no record of ``ids`` has
        it.
        """
        if name == SPREAD:
            return spread_table(self.db, self, active()).get(np.asarray(ids, np.int64))
        if name == NEIGHBOURS:
            if not active().shares_neighbours:
                return None
            if self._stage is None or self._stage.tuning != active():
                self._stage = LightFieldFusion(self.db.config, tuning=active())
            table = neighbour_table(self.db, self, self._stage)
            return table.get(np.asarray(ids, np.int64)).astype(np.float64)
        if name not in self._columns:
            return None
        ids = np.asarray(ids, np.int64)
        if name not in self._mapped:
            self._mapped[name] = open_column(self.db, name)
        mapped = self._mapped[name]
        if mapped is not None:
            rows = mapped.get(ids)
            return None if rows is None else rows.reshape(len(ids), *self._shape[name])
        cache = self._cache[name]
        if name not in self._complete:
            missing = sorted({int(i) for i in ids} - set(cache) - self._absent[name])
            if missing:
                self._read(name, None if self._preload[name] else missing)
                self._preload[name] = False
        found = [cache.get(int(i)) for i in ids]
        first = next((f for f in found if f is not None), None)
        if first is None:
            return None
        out = np.full((len(ids), *first.shape), np.nan)
        for k, f in enumerate(found):
            if f is not None and f.shape == first.shape:
                out[k] = f
        return out


#: Readers by (store path, manifest version): the most recent few.
_READERS: dict[tuple[str, int], StoredArrays] = {}
_KEEP = 4


def forget(path: str) -> None:
    """Drop the shared readers of the store at ``path`` (its files changed under one version)."""
    for key in [k for k in _READERS if k[0] == path]:
        _READERS.pop(key, None)
    forget_columns(path)


def stored_arrays(db: Any, *, preload: bool = False) -> StoredArrays:
    """The shared :class:`StoredArrays` of ``db``'s store at its current version."""
    import os

    key = (os.fspath(db.store.path), int(db.store.version))
    reader = _READERS.get(key)
    if reader is None:
        reader = _READERS[key] = StoredArrays(db, preload=preload)
        while len(_READERS) > _KEEP:
            _READERS.pop(next(iter(_READERS)))
    elif preload:
        reader.preload_all()
    return reader


def query_light_fields(config: Config, decompositions: list[Any]) -> NDArray[np.float64]:
    """(q, fields, 10, d) light fields of queries' decompositions; NaN rows for None.

    ``decompositions[i]`` is a :class:`shapedb.mdbd.decomposition.Decomposition`, or None for a query
    that is a stored shape (its light fields are read by id) or has no decomposition.
    A decomposition's light fields are those of its balls and its tail
    (:func:`shapedb.signature.lightfield.decomposition_light_field`): a query decomposed with
    ``tail_balls=config.light_field_tail`` is seen as ingest saw the records. In a store
    of the field's light fields (``Config.light_field_inside``) a decomposition without
    its inside (not decomposed with ``keep_inside=True``) gets a NaN row: the query keeps
    the stored order.
    """
    from shapedb.signature.lightfield import decomposition_light_field, light_field_dim

    cfg = config.light_field
    out = np.full((len(decompositions), cfg.n_fields, 10, light_field_dim(cfg)), np.nan)
    for k, d in enumerate(decompositions):
        if d is None or not d.n_balls:
            continue
        if config.light_field_inside and getattr(d, "inside", None) is None:
            continue
        out[k] = decomposition_light_field(d, cfg)
    return out
