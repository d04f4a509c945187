"""The store's re-ranking stage: which scorer a search of a store passes its candidates to.

A store keeps one switch, ``RerankConfig.scorer``: ``"lightfield"`` (the default) re-ranks
the index's candidates with the light field stage (:mod:`query.search.rerank_lightfield`,
its numbers in :mod:`query.search.tuning`); ``"none"`` keeps the stored vector's order.
Search (:mod:`query.search.engine`) and evaluation (:mod:`query.evaluate`) both ask here,
so they rank alike.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from query.search.rerank_lightfield import LightFieldFusion
from query.search.tuning import StageTuning, active

if TYPE_CHECKING:
    from shapedb.config.core import Config

__all__ = ["scorer_for"]


def scorer_for(config: Config, *, tuning: StageTuning | None = None) -> LightFieldFusion | None:
    """The stage of a store of ``config``; None when its searches do not re-rank.

    ``tuning``: the stage's numbers; None: :func:`query.search.tuning.active` (the product's).
    """
    if config.rerank.scorer == "none":
        return None
    return LightFieldFusion(config, tuning=tuning if tuning is not None else active())
