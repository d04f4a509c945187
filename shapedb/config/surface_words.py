"""Configuration of the surface words each record stores: :class:`SurfaceWordsConfig`.

A section of :class:`shapedb.config.core.Config` (``Config.surface_words``), with no flat
option: a new store keeps the words, a store written before them reads ``enabled``
False and searches without them; a study may set the section itself. The words are
:func:`shapedb.signature.surface_words.surface_words`: a histogram of local surface
features over a fixed codebook; their parameters are constants of that module. The
view words (:mod:`shapedb.signature.view_words`: the words of the shape seen from 20
directions, what a one-sided scan is matched against) cost about a second of ingest and
20 KB a record, and only one-sided scans use them: a store that will never see a scan
may leave them out (``Config(surface_words=SurfaceWordsConfig(enabled=True,
view_words=False))``; not a flat option).
"""

from __future__ import annotations

from dataclasses import dataclass

from shapedb.config.checks import check as _check

__all__ = ["SurfaceWordsConfig", "product_surface_words"]


@dataclass(frozen=True)
class SurfaceWordsConfig:
    """The surface words of a record (:mod:`shapedb.signature.surface_words`).

    Ingest computes and stores them when
    :attr:`shapedb.config.core.Config.stores_surface_words` (``enabled`` and a store with
    the ``"lightfield"`` stage, which fuses them).

    Attributes
    ----------
    enabled : bool
        Store each record's surface words (the ``surface_words`` column). False: none
        (stores written before the section read False).
    view_words : bool
        Also store each record's view words (the ``view_words`` column), with which
        ``db.search`` ranks a one-sided scan. False (stores written before the field read
        False): one-sided scans are ranked by their silhouettes alone; a store that will
        never be searched with scans saves the ingest time and the space.
    """

    enabled: bool = False
    view_words: bool = False

    def __post_init__(self) -> None:
        _check(
        isinstance(self.enabled, bool), "surface_words.enabled", self.enabled,
        "must be true or false",
    )  # fmt: skip
        _check(
        isinstance(self.view_words, bool), "surface_words.view_words", self.view_words,
        "must be true or false",
    )  # fmt: skip


def product_surface_words() -> SurfaceWordsConfig:
    """The surface words a new store keeps: enabled, with the view words."""
    return SurfaceWordsConfig(enabled=True, view_words=True)
