"""Whether a store's searches re-rank the index's candidates: :class:`RerankConfig`.

A section of :class:`shapedb.config.core.Config` (``Config.rerank``; flat option
``rerank``). The stage itself is :mod:`query.search.stage`; its tuned numbers are not
options (:mod:`query.search.tuning`).
"""

from __future__ import annotations

from dataclasses import dataclass

from shapedb.config.checks import check as _check

__all__ = ["RerankConfig", "SCORERS"]

#: The stages a store can keep: the light field stage, or none.
SCORERS = ("lightfield", "none")


@dataclass(frozen=True)
class RerankConfig:
    """How a search re-ranks the candidates the index proposes.

    The index proposes the stage's ``K`` nearest shapes by the stored vector's L1
    distance; the stage re-ranks them exactly; past them, results keep the stored-vector
    order. Search and evaluation rank alike. Stores written before layout 3 read
    ``"none"`` (:mod:`shapedb.config.migrations`).

    Attributes
    ----------
    scorer : str
        ``"lightfield"`` (the default): the light field stage (the light fields and field
        vectors of the field the MDBD packs, gated by the store; it is also the switch that
        makes ingest keep each record's light fields). ``"none"``: the stored vector's
        distance decides (a user turns it off to rank by the descriptor alone, or to
        ingest faster without light fields).
    """

    scorer: str = "lightfield"

    def __post_init__(self) -> None:
        ok = isinstance(self.scorer, str) and self.scorer in SCORERS
        _check(ok, "rerank", self.scorer, f"must be one of {', '.join(SCORERS)}")
