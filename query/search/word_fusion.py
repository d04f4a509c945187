"""The surface words in the light field stage: the last reciprocal rank fusion.

A store with surface words (``Config.stores_surface_words``: each record's
``surface_words`` column, :func:`shapedb.signature.surface_words.surface_words` of its
surface) re-orders each query's candidates once more after the ``"lightfield"`` stage
(:mod:`query.search.rerank_lightfield`) has ranked them:

    ``(1 + v p) / o - (1 / (o + rank_s) + v p / (o + rank_w))``

``rank_s`` a candidate's rank in the stage's order, ``rank_w`` its rank by the chi-square
distance of the words (:func:`shapedb.signature.surface_words.words_distance`), both from
0 among the query's candidates in their list order; ``o`` and ``v`` are
``StageTuning.word_offset`` and ``word_weight``, and ``p`` is the stage's pose gate
(:meth:`query.search.rerank_lightfield.LightFieldFusion.pose_gate`): local words cannot
tell one subject in many poses from another, so jointed subjects, whose silhouettes
spread their near neighbours, keep the stage's order. A query or a candidate without
words keeps the stage's order for its whole row.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from query.search.rerank import list_ranks
from query.search.tuning import StageTuning

__all__ = ["WORDS_COLUMN", "query_words", "fuse_words"]

#: The per-record column (and ``Candidates.query_arrays`` key) of the surface words.
WORDS_COLUMN = "surface_words"


def query_words(words: Sequence[Any]) -> NDArray[np.float64]:
    """(q, WORDS) float64 of the queries' own words; NaN rows for None (read by id, or none)."""
    from shapedb.signature.surface_words import WORDS

    out = np.full((len(words), WORDS), np.nan)
    for k, w in enumerate(words):
        if w is not None:
            out[k] = np.asarray(w, np.float64).ravel()
    return out


def fuse_words(
    stage: NDArray[np.float64],
    words: NDArray[np.float64],
    gate: float,
    tuning: StageTuning,
) -> NDArray[np.float64]:
    """(c,) distances >= 0 of one query's candidates, the stage's and the words' ranks fused.

    Parameters
    ----------
    stage : (c,) float64
        The stage's distances of the candidates (lower first), list order.
    words : (c,) float64
        The words' chi-square distances of the candidates to the query.
    gate : float
        The pose gate ``p`` in [0, 1]; 0 (or ``word_weight`` 0) keeps the stage's order.
    tuning : StageTuning
        ``word_offset`` and ``word_weight``.
    """
    o, v = float(tuning.word_offset), float(tuning.word_weight) * float(gate)
    if v <= 0:
        return np.array(stage, dtype=np.float64, copy=True)
    rank_s = list_ranks(np.asarray(stage, np.float64))
    rank_w = list_ranks(np.asarray(words, np.float64))
    return np.maximum((1.0 + v) / o - (1.0 / (o + rank_s) + v / (o + rank_w)), 0.0)
