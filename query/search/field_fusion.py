"""The field vectors in the light field stage: the fused distance and the scaled vectors.

A store with field vectors (``Config.stores_field_vectors``: each record's
``field_vector`` column, :func:`shapedb.signature.field_vector.field_vector` of its field's
inside) and a field weight in its fusion (``StageTuning.field_depth_weight``
``alpha`` or ``field_harmonic_weight`` ``gamma`` above 0) replaces the light field distance
``l`` of the ``"lightfield"`` stage (:mod:`query.search.rerank_lightfield`: its ranks, its gate,
and the stored local statistics of :mod:`query.search.lightfield_spread`) by

    ``l + alpha * b + gamma * h``

with ``b`` and ``h`` the L1 distances of the two parts of the field vectors (the depth
buffer descriptor and the harmonic energies,
:func:`shapedb.signature.field_vector.field_vector_parts`). The fused distance is in the
light field's units; the stage divides it by ``StageTuning.scale`` where it needs a
unit (the local spread, the shared-neighbour term). A query or a candidate without a
field vector keeps ``l`` for its whole row (one warning per :class:`FieldFusion`).

The *scaled* field vector ``[alpha * depth, gamma * harmonic]`` (:meth:`FieldFusion.scaled`)
makes ``alpha * b + gamma * h`` a plain L1 distance: the one the field vector index
(:mod:`query.search.field_index`) ranks by, for the stage's extra candidates
(``StageTuning.field_candidates``).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.search.tuning import PRODUCT, StageTuning

if TYPE_CHECKING:
    from shapedb.config.core import Config

__all__ = ["FIELD", "FieldFusion", "query_field_vectors", "stores_field_vectors"]

log = logging.getLogger(__name__)

#: The per-record column (and ``Candidates.query_arrays`` key) of the field vectors.
FIELD = "field_vector"


def stores_field_vectors(config: Config) -> bool:
    """Whether ``config``'s records keep field vectors (``Config.stores_field_vectors``)."""
    return bool(config.stores_field_vectors)


class FieldFusion:
    """The fused light field distance of one configuration (see the module docstring).

    Parameters
    ----------
    depth, harmonic : slice
        Where the depth buffer part and the harmonic part lie in a field vector.
    depth_weight, harmonic_weight : float
        ``alpha`` and ``gamma``, >= 0 (light field units per unit of ``b`` and ``h``).
    candidates : int
        ``K2``, the extra candidates by the scaled field vectors (0: none).
    stored : bool
        Whether the store keeps field vectors; False turns the fusion and the extra
        candidates off whatever the weights.
    """

    def __init__(
        self,
        depth: slice,
        harmonic: slice,
        *,
        depth_weight: float = 0.0,
        harmonic_weight: float = 0.0,
        candidates: int = 0,
        stored: bool = True,
    ) -> None:
        self.depth, self.harmonic = depth, harmonic
        self.alpha, self.gamma = float(depth_weight), float(harmonic_weight)
        self.candidates = int(candidates)
        self.stored = bool(stored)
        self._warned = False

    @classmethod
    def from_config(cls, config: Config, tuning: StageTuning = PRODUCT) -> FieldFusion:
        """The fusion of ``tuning`` over ``config.field_vector``'s parts.

        Off (:attr:`active` and :attr:`proposes` False) for a store without field
        vectors.
        """
        f = tuning
        stored = stores_field_vectors(config)
        depth, harmonic = slice(0, 0), slice(0, 0)
        if stored:
            from shapedb.signature.field_vector import field_vector_parts

            depth, harmonic = field_vector_parts(config.field_vector)
        return cls(
            depth, harmonic,
            depth_weight=f.field_depth_weight,
            harmonic_weight=f.field_harmonic_weight,
            candidates=f.field_candidates,
            stored=stored,
        )  # fmt: skip

    @property
    def active(self) -> bool:
        """Whether the light field distance is fused (field vectors stored, a weight > 0)."""
        return self.stored and (self.alpha > 0 or self.gamma > 0)

    @property
    def proposes(self) -> bool:
        """Whether the stage takes extra candidates by the field vectors (``K2 > 0``)."""
        return self.stored and self.candidates > 0

    def key(self) -> dict[str, Any] | None:
        """What the fused distance depends on (for the spread table's key); None when off."""
        if not self.active:
            return None
        return {
            "alpha": self.alpha, "gamma": self.gamma,
            "depth": [self.depth.start, self.depth.stop],
            "harmonic": [self.harmonic.start, self.harmonic.stop],
        }  # fmt: skip

    def scaled(self, vectors: NDArray[Any]) -> NDArray[np.float32]:
        """(n, d') float32 ``[alpha * depth, gamma * harmonic]`` of field vectors (n, d)."""
        v = np.atleast_2d(np.asarray(vectors, np.float64))
        parts = [self.alpha * v[:, self.depth], self.gamma * v[:, self.harmonic]]
        out = np.concatenate(parts, axis=1)
        return np.ascontiguousarray(out, np.float32)

    def parts(
        self, query: NDArray[Any], candidates: NDArray[Any]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(b, h)``, (c,) each: L1 distances of the depth and harmonic parts.

        ``query`` (d,) and ``candidates`` (c, d) are field vectors (float64 sums).
        """
        q = np.asarray(query, np.float64)
        x = np.asarray(candidates, np.float64)
        b = np.abs(x[:, self.depth] - q[self.depth]).sum(axis=1)
        h = np.abs(x[:, self.harmonic] - q[self.harmonic]).sum(axis=1)
        return b, h

    def combine(
        self, light: NDArray[Any], depth: NDArray[Any], harmonic: NDArray[Any]
    ) -> NDArray[np.float64]:
        """``l + alpha * b + gamma * h``, elementwise (float64)."""
        lf, b, h = (np.asarray(v, np.float64) for v in (light, depth, harmonic))
        return np.asarray(lf + self.alpha * b + self.gamma * h, np.float64)

    def distance(
        self,
        light: NDArray[Any],
        query: NDArray[Any] | None,
        candidates: NDArray[Any] | None,
    ) -> NDArray[np.float64]:
        """The fused distances (c,) of one query's candidates; ``light`` where it cannot.

        Parameters
        ----------
        light : (c,) float
            Light field distances ``l``.
        query : (d,) float, optional
            The query's field vector (None or NaN: none).
        candidates : (c, d) float, optional
            The candidates' field vectors (None, or a NaN row: none).

        Returns
        -------
        (c,) float64
            ``light`` itself when the fusion is off, and (with one warning per
            instance) when the query or any candidate has no field vector.
        """
        light = np.asarray(light, np.float64)
        if not self.active:
            return light
        if (
            query is None
            or candidates is None
            or not np.all(np.isfinite(query))
            or not np.all(np.isfinite(candidates))
        ):
            if not self._warned:
                log.warning(
                    "field vector fusion: a query or a candidate has no field vector; "
                    "its row keeps the light field distance"
                )
                self._warned = True
            return light
        b, h = self.parts(query, candidates)
        return self.combine(light, b, h)


def query_field_vectors(config: Config, decompositions: Sequence[Any]) -> NDArray[np.float64]:
    """(q, d) field vectors of queries' decompositions; NaN rows where there is none.

    ``decompositions[i]`` is a :class:`shapedb.mdbd.decomposition.Decomposition` (decomposed with its
    inside kept, ``keep_inside=True``, as ingest does), or None for a query that is a
    stored shape (its vector is read by id) or has no decomposition. A decomposition
    without its inside gets a NaN row: its row keeps the light field distance.
    """
    from shapedb.signature.field_vector import decomposition_field_vector, field_vector_dim

    cfg = config.field_vector
    out = np.full((len(decompositions), field_vector_dim(cfg)), np.nan)
    for k, d in enumerate(decompositions):
        if d is None or getattr(d, "inside", None) is None:
            continue
        try:
            out[k] = decomposition_field_vector(d, cfg)
        except ValueError as exc:
            log.warning("query without a field vector: %s", exc)
    return out
