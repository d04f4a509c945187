"""How a search re-ranks the index's candidates: :class:`RerankConfig`.

A section of :class:`shapedb.config.core.Config` (``Config.rerank``, re-exported from
:mod:`shapedb.config.core`); flat options ``rerank`` and ``rerank_<field>``. The stage itself
is :mod:`query.search.rerank`.
"""

from __future__ import annotations

from dataclasses import dataclass

from shapedb.config.checks import check as _check
from shapedb.config.checks import is_int as _is_int

__all__ = ["RerankConfig"]


@dataclass(frozen=True)
class RerankConfig:
    """How a search re-ranks the candidates the index proposes (:mod:`query.search.rerank`).

    The index proposes the ``candidates`` nearest shapes by the stored vector's L1
    distance; a named exact scorer re-ranks them; past them, results keep the
    stored-vector order. Search and evaluation rank alike. The default stage is
    ``"lightfield"`` (:mod:`query.search.rerank_lightfield`: the balls' light fields, gated by
    the store's local spreads; it loses no set against ``"none"`` on the validation and
    test splits, alone or in mixed stores); stores written before layout 3 read
    ``"none"`` (:mod:`shapedb.config.migrations`). The adaptive fusion's fields are the setting
    chosen on the validation splits (``python -m bench.rerank_select --grid ratio``).

    Attributes
    ----------
    scorer : str
        ``"lightfield"`` (the default): the light field stage. ``"none"``: no stage,
        the stored vector's distance decides. ``"adaptive"``:
        the distance without ``block`` plus ``weight * g(q)`` times ``block``'s,
        ``g(q)`` the overlap of the query's ``neighbours`` nearest candidates by either
        part, to the power ``power``. Other names are scorers registered with
        :func:`query.search.rerank.register_scorer`.
    candidates : int
        K, candidates re-ranked per query, in [1, 100000].
    neighbours : int
        Neighbourhood size of ``g(q)`` among the candidates, in [1, 1000].
    power : float
        Exponent of the overlap in ``g(q)``, in [0, 8]; 0 ignores the overlap (the
        ``ratio`` ceiling alone then gates the block).
    weight : float
        Weight of ``block`` at ``g = 1``, in the units of the descriptor's block weights
        (:data:`shapedb.signature.descriptor.LAYOUTS`: the stored vector has ``block`` at its own
        weight), in [0, 1000].
    block : str
        The descriptor block ``g(q)`` scales (a layout without it: the stored distance).
    ratio : float
        0, or a ceiling on ``r``, the median of the candidates' ``block`` distances over
        the median of their other distances: ``g(q)`` is then also multiplied by
        ``clip((ratio - r) / 0.1, 0, 1)``, so the block counts less where it spreads the
        candidates more than the rest does (a pose changing its silhouettes). In [0, 10].
    """

    scorer: str = "lightfield"
    candidates: int = 100
    neighbours: int = 10
    power: float = 0.0
    weight: float = 16.0
    block: str = "views"
    ratio: float = 0.35

    def __post_init__(self) -> None:
        name_ok = isinstance(self.scorer, str) and self.scorer.replace("_", "a").isalnum()
        _check(name_ok, "rerank", self.scorer, "must be a scorer's name, e.g. 'none' or 'adaptive'")
        _check(
            _is_int(self.candidates) and 1 <= self.candidates <= 100_000,
            "rerank_candidates",
            self.candidates,
            "must be an integer in [1, 100000]",
        )
        _check(
            _is_int(self.neighbours) and 1 <= self.neighbours <= 1000,
            "rerank_neighbours",
            self.neighbours,
            "must be an integer in [1, 1000]",
        )
        _check(0.0 <= self.power <= 8.0, "rerank_power", self.power, "must be in [0, 8]")
        _check(0.0 <= self.weight <= 1000.0, "rerank_weight", self.weight, "must be in [0, 1000]")
        _check(isinstance(self.block, str), "rerank_block", self.block, "must be a block name")
        _check(0.0 <= self.ratio <= 10.0, "rerank_ratio", self.ratio, "must be in [0, 10]")
