"""The adaptive re-ranking stage: one descriptor block weighted by how far it agrees.

A study, not kept (docs/studies.md, "The adaptive re-ranking stage"): the stored vector
without ``block`` plus ``weight * g(q)`` times ``block``'s part, ``g(q)`` the overlap of the
query's ``neighbours`` nearest candidates by either part, faded out where the block spreads
the candidates more than the rest does. It was the opt-in stage over descriptor version 7
(the views of the ball union); it lost on some set against the light field stage, and
stores written with it read as ``rerank="none"``. Pass it as the scorer of
:func:`query.search.rerank.search` (``scorer=AdaptiveFusion(config)``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from query.search.rerank import Candidates
from query.search.tuning import PRODUCT
from shapedb.config.core import Config

__all__ = ["AdaptiveSettings", "AdaptiveFusion", "block_slice"]

log = logging.getLogger(__name__)

_NO_ID = np.iinfo(np.int64).max
#: Width of the ramp of ``AdaptiveSettings.ratio``: the gate falls from 1 to 0 as the
#: candidates' block-to-rest spread rises from ``ratio - RATIO_RAMP`` to ``ratio``.
RATIO_RAMP = 0.1


@dataclass(frozen=True)
class AdaptiveSettings:
    """The adaptive stage's numbers: its grid's choice on validation (``--grid ratio``)."""

    candidates: int = 100
    neighbours: int = 10
    power: float = 0.0
    weight: float = 16.0
    block: str = "views"
    ratio: float = 0.35


def block_slice(config: Config, block: str) -> slice:
    """Where ``block`` lies in ``config``'s stored vector; an empty slice when absent."""
    if config.kernel.method == "mdbd":
        from shapedb.signature.descriptor import LAYOUTS

        at = 0
        for name, size, _, _ in LAYOUTS[config.descriptor.version]:
            if name == block:
                return slice(at, at + size)
            at += size
    return slice(0, 0)


def _block_weight(config: Config, block: str) -> float:
    from shapedb.signature.descriptor import LAYOUTS

    found = [b[3] for b in LAYOUTS.get(config.descriptor.version, ()) if b[0] == block]
    return float(found[0]) if found else 1.0


class AdaptiveFusion:
    """Scorer ``"adaptive"``: ``base + (weight / w_b) * g(q) * part``.

    ``part`` is the stored distance over ``block``'s numbers, ``base`` over the
    others (so ``base + part`` is the stored distance), ``w_b`` the block's weight in
    the store's descriptor version. ``g(q) = (|A ∩ B| / m) ** power`` with ``A`` and
    ``B`` the query's ``m = min(neighbours, valid candidates)`` nearest candidates by
    ``base`` and by ``part`` (the query itself left out; ties by ascending id).

    Parameters
    ----------
    config : Config
        Reads the block layout of ``config.descriptor``.
    settings : AdaptiveSettings, optional
        The fusion's numbers (the setting its grid chose on validation by default).
    """

    def __init__(self, config: Config, settings: AdaptiveSettings | None = None) -> None:
        r = settings or AdaptiveSettings()
        self.tuning = replace(PRODUCT, candidates=r.candidates)
        self.block = block_slice(config, r.block)
        self.neighbours = int(r.neighbours)
        self.power = float(r.power)
        self.factor = float(r.weight) / _block_weight(config, r.block)
        self.ratio = float(r.ratio)
        if self.block.stop == self.block.start:
            log.debug("rerank: no block %r in this layout: the stored distance decides", r.block)

    def parts(self, batch: Candidates) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(base, part)``, (q, c) each: the stored distance outside and inside the block."""
        diff = np.abs(batch.features - batch.queries[:, None, :]) * batch.weights
        part = diff[..., self.block].sum(axis=-1)
        inside = np.zeros(diff.shape[-1], bool)
        inside[self.block] = True
        base = diff[..., ~inside].sum(axis=-1)
        return base, part

    def gate(
        self, batch: Candidates, base: NDArray[np.float64], part: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """``g(q)``, (q,): overlap of the nearest candidates by ``base`` and by ``part``.

        With ``AdaptiveSettings.ratio > 0`` also times ``clip((ratio - r) / RATIO_RAMP, 0,
        1)``, ``r`` the median ``part`` over the median ``base`` of the candidates (the
        query left out).
        """
        ok = batch.valid & (batch.ids != batch.query_ids[:, None])
        key = np.where(ok, batch.ids, _NO_ID)
        g = np.zeros(len(key))
        for row in range(len(key)):
            m = min(self.neighbours, int(ok[row].sum()))
            if m == 0:
                continue
            b = np.where(ok[row], base[row], np.inf)
            p = np.where(ok[row], part[row], np.inf)
            g[row] = 1.0
            if self.power > 0:  # power 0: the overlap does not count
                a = np.lexsort((key[row], b))[:m]
                c = np.lexsort((key[row], p))[:m]
                g[row] = (len(np.intersect1d(a, c)) / m) ** self.power
            if self.ratio > 0:
                spread = np.median(p[ok[row]]) / max(float(np.median(b[ok[row]])), 1e-300)
                g[row] *= float(np.clip((self.ratio - spread) / RATIO_RAMP, 0.0, 1.0))
        return g

    def score(self, batch: Candidates) -> NDArray[np.float64]:
        """Fused distances, (q, c)."""
        base, part = self.parts(batch)
        if self.block.stop == self.block.start:
            return base
        g = self.gate(batch, base, part)
        return base + (self.factor * g)[:, None] * part
