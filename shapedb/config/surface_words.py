"""Configuration of the surface words each record stores: :class:`SurfaceWordsConfig`.

A section of :class:`shapedb.config.core.Config` (``Config.surface_words``), with no flat
option: a new store keeps the words, a store written before them reads ``enabled``
False and searches without them; a study may set the section itself. The words are
:func:`shapedb.signature.surface_words.surface_words`: a histogram of local surface
features over a fixed codebook; their parameters are constants of that module.
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
    """

    enabled: bool = False

    def __post_init__(self) -> None:
        _check(
        isinstance(self.enabled, bool), "surface_words.enabled", self.enabled,
        "must be true or false",
    )  # fmt: skip


def product_surface_words() -> SurfaceWordsConfig:
    """The surface words a new store keeps: enabled."""
    return SurfaceWordsConfig(enabled=True)
