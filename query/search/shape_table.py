"""Per-shape values of one store version, computed as searches ask for them.

The ``"lightfield"`` stage keeps two such tables beside a store: the local spreads
(:mod:`query.search.lightfield_spread`) and the shared-neighbour lists
(:mod:`query.search.lightfield_neighbours`). Both depend on the whole store, so they belong to a
store version: :class:`ShapeTable` computes the values of the ids asked for and keeps them
in process; a search never writes. After a commit the store's derived-state update
computes every alive shape's value and saves the table (:meth:`ShapeTable.save`) to a
versioned directory under the store (:func:`query.search.versioned.save_version`:
``ids.npy`` and the values' file, the store version and the parameters in
``current.json``), read back while the version and the parameters match. :func:`shared_table` hands every reader of a store
version the same table.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from query.search.versioned import POINTER, current, save_version

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["ShapeTable", "index_version", "shared_table"]

log = logging.getLogger(__name__)


def index_version(db: StoreHandle) -> int:
    """The store version of ``db``'s index (the store's when the index has none)."""
    from query.search.index import open_index

    v = open_index(db).version_
    return int(v if v is not None else db.store.version)


class ShapeTable:
    """One value per alive shape of a store version, filled as asked for.

    Subclasses name the directory (:attr:`directory`), the values' file (:attr:`file`),
    and compute values (:meth:`compute`: alive ids only, so a count tells completeness).
    Values are rows of one array: ``(n,)`` or ``(n, k)``.

    Parameters
    ----------
    db : shapedb.Database
    meta : dict
        The parameters the values depend on, with ``version`` (JSON-serialisable); a
        stored table is read only when its pointer holds the same.
    """

    directory: ClassVar[str]
    file: ClassVar[str]
    what: ClassVar[str] = "values"

    def __init__(self, db: StoreHandle, meta: dict[str, Any]) -> None:
        from query.search.index import open_index

        self.db = db
        self.index = open_index(db)
        self.version = int(meta["version"])
        self.meta = meta
        self.values: dict[int, Any] = {}
        self.n_alive = int(np.count_nonzero(self.index.alive_))
        self.complete = False
        self._lock = threading.Lock()
        self._read()

    @property
    def root(self) -> Path:
        return Path(self.db.store.path) / self.directory

    def compute(self, ids: NDArray[np.int64] | None) -> tuple[NDArray[np.int64], Any]:
        """``(ids, values)`` of the alive ``ids`` (every alive shape when None)."""
        raise NotImplementedError

    def check(self, values: NDArray[Any]) -> None:
        """Raise ValueError if a stored values' array does not fit the parameters."""

    def _read(self) -> None:
        if not (self.root / POINTER).exists():
            return
        try:
            stored, sub = current(self.root)
            if all(stored.get(key) == v for key, v in self.meta.items()):
                ids, values = np.load(sub / "ids.npy"), np.load(sub / self.file)
                if len(values) != len(ids):
                    raise ValueError(f"{len(values)} values for {len(ids)} ids")
                self.check(values)
                self.values = {int(i): v for i, v in zip(ids, values, strict=True)}
                self.complete = True
        except (OSError, ValueError, KeyError) as exc:
            log.warning("recomputing the %s of %s: %s", self.what, self.db.store.path, exc)

    def save(self) -> None:
        """Write the complete table beside the store (the commit's update calls this; no-op
        while some alive shape has no value yet)."""
        if not self.complete:
            return
        ids = np.array(sorted(self.values), np.int64)
        values = np.asarray([self.values[int(i)] for i in ids])

        def write(sub: Path) -> None:
            np.save(sub / "ids.npy", ids)
            np.save(sub / self.file, values)

        save_version(self.root, write, self.meta, version=self.version)
        log.info("%s of %d shapes at store version %s", self.what, len(ids), self.version)

    def known(self, ids: NDArray[np.int64] | None = None) -> tuple[NDArray[np.int64], list[Any]]:
        """``(ids, values)``: every asked id's value (None where it has none; every alive
        shape's when ``ids`` is None).

        Computes the ids not known yet, in this process (nothing is written: :meth:`save`).
        """
        with self._lock:
            want = None if ids is None else np.asarray(ids, np.int64).ravel()
            if not self.complete:
                pending = want
                if want is not None:
                    pending = np.array(sorted({int(i) for i in want} - set(self.values)), np.int64)
                if pending is None or len(pending):
                    got_ids, got = self.compute(pending)
                    self.values.update({int(i): v for i, v in zip(got_ids, got, strict=True)})
                    if len(self.values) >= self.n_alive:  # compute answers alive ids only
                        self.complete = True
            if want is None:
                want = np.array(sorted(self.values), np.int64)
            return want, [self.values.get(int(i)) for i in want]


def shared_table(
    cache: dict[tuple[str, int], Any],
    lock: threading.Lock,
    db: StoreHandle,
    meta: Callable[[int], dict[str, Any]],
    make: Callable[[dict[str, Any]], ShapeTable],
) -> Any:
    """The table of ``db``'s store at its index's current version, one per process.

    ``cache`` and ``lock`` are the caller's (one per kind of table); ``meta(version)``
    gives the parameters, ``make(meta)`` a new table. A new version or new parameters
    make a new table, and the tables of the store's other versions leave the cache.
    """
    version = index_version(db)
    key = (os.fspath(db.store.path), version)
    want = meta(version)
    with lock:
        table = cache.get(key)
        if table is None or table.meta != want:
            table = cache[key] = make(want)
            for old in [k for k in cache if k[0] == key[0] and k[1] != version]:
                cache.pop(old, None)
    return table
