"""The store's id -> (name, label) table, read once per store version.

:func:`catalog` gives the :class:`Catalog` of a store at a version (the store's
``Store.version`` or an index's ``version_``), kept in memory per store path and
replaced when the version changes; a ``None`` version is never kept.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["Catalog", "catalog", "forget"]


class Catalog:
    """id -> (name, label) for one store version, sorted by id for searchsorted.

    Attributes
    ----------
    ids : (n,) int64
        Stored ids, ascending.
    names, labels : list
        Name and label (None when unlabelled) of each id.
    sparse : (m,) int64
        Ids of the shapes that are sparse samples (:func:`shapedb.geometry.view.is_sparse`), sorted.
    """

    def __init__(
        self,
        ids: NDArray[np.int64],
        names: list[str],
        labels: list[str | None],
        sparse: NDArray[np.int64],
    ):
        self.ids = ids
        self.names = names
        self.labels = labels
        self.sparse = sparse

    def lookup(self, ids: NDArray[np.int64]) -> list[tuple[str, str | None] | None]:
        """(name, label) of each id; None for an id this catalog does not hold."""
        ids = np.asarray(ids, dtype=np.int64)
        pos = np.minimum(np.searchsorted(self.ids, ids), max(len(self.ids) - 1, 0))
        found = (self.ids[pos] == ids) if len(self.ids) else np.zeros(len(ids), bool)
        return [
            (self.names[p], self.labels[p]) if ok else None
            for p, ok in zip(pos.tolist(), found.tolist(), strict=True)
        ]


_CATALOGS: dict[str, tuple[int | None, Catalog]] = {}


def catalog(db: StoreHandle, version: int | None) -> Catalog:
    """The catalog of ``db`` at ``version`` (read from the store unless kept)."""
    key = os.fspath(db.store.path)
    cached = _CATALOGS.get(key)
    if cached is not None and cached[0] == version and version is not None:
        return cached[1]
    from shapedb.geometry.view import SPARSE_CELLS

    t = db.store.shapes(["id", "name", "label", "sampling", "spacing"])
    ids = t.column("id").to_numpy()
    order = np.argsort(ids, kind="stable")
    ids = ids[order]
    sampling = np.nan_to_num(t.column("sampling").to_numpy(zero_copy_only=False), nan=0.0)[order]
    spacing = t.column("spacing").to_numpy()[order]
    sparse = ids[(spacing > 0) & (sampling >= SPARSE_CELLS * spacing)]
    names, labels = t.column("name").to_pylist(), t.column("label").to_pylist()
    cat = Catalog(ids, [names[i] for i in order], [labels[i] for i in order], sparse)
    _CATALOGS[key] = (version, cat)
    return cat


def forget(key: str) -> None:
    """Drop the catalog kept for the store at path ``key`` (tests, closed stores)."""
    _CATALOGS.pop(key, None)
