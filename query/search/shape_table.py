"""Per-shape values of a store, kept beside it and carried from version to version.

The ``"lightfield"`` stage keeps two such tables beside a store: the local spreads
(:mod:`query.search.lightfield_spread`) and the shared-neighbour lists
(:mod:`query.search.lightfield_neighbours`). A value depends on the whole store (a new shape
changes its neighbours' lists), but recomputing every value at every commit would make a
commit cost the store's size, so a table is *carried*:

* A :class:`ShapeTable` is the table of one store version (its index's). It starts from
  the newest table saved beside the store under the same parameters (every key of
  ``meta`` but ``version``): the values of that version when it is this one, else the
  values of the shapes still alive whose stored vector is bit for bit the one they were
  computed for (a fingerprint per value: a shape deleted, or re-added under its id with
  another vector, is dropped). It computes the ids asked for that have no value yet
  (:meth:`ShapeTable.known`) and keeps them in process; a search never writes.
* After a commit the store's derived-state update (:func:`update`, the modules'
  ``on_commit``) computes the values of the shapes that have none (the commit's new
  shapes) and saves the table at the new version; a table that costs at most the
  module's ``FULL_AT_COMMIT`` distances whole is recomputed whole instead, so a small
  store's table stays exact. Old shapes' values are not recomputed when new neighbours
  arrive: each value keeps the version it was computed at (``at.npy``), and the pointer
  says whether every value is of its version (``exact``), the oldest value's version
  (``oldest``) and how many were carried (``carried``). :meth:`ShapeTable.refresh`
  (the modules' ``refresh``) recomputes a whole table exactly.

A table is saved to a versioned directory under the store
(:func:`query.search.versioned.save_version`: ``ids.npy``, the values' file, ``at.npy``
and ``prints.npy``, the parameters in ``current.json``), rewritten whole at each
save (atomic: readers see the old table or the new one); a store the process cannot
write keeps it in memory. :func:`shared_table` hands every reader of a store version
the same table.
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

__all__ = ["ShapeTable", "fingerprints", "index_version", "shared_table", "update"]

log = logging.getLogger(__name__)

_PRINT_ROWS = 4096
_PRINT_SEED = 0x5EED


def index_version(db: StoreHandle) -> int:
    """The store version of ``db``'s index (the store's when the index has none)."""
    from query.search.index import open_index

    v = open_index(db).version_
    return int(v if v is not None else db.store.version)


def fingerprints(index: Any, ids: NDArray[np.int64]) -> NDArray[np.uint64]:
    """(m,) uint64 fingerprints of the indexed vectors of the alive ``ids``.

    An exact function of the vector's bits (a sum of its 32-bit words times fixed odd
    numbers, modulo 2 ** 64): equal vectors give equal prints in any process, and a
    changed vector gives another print but with chance 2 ** -64.
    """
    rows = np.asarray(index.lookup(ids), np.int64)
    feats = index.features_
    words = np.dtype(feats.dtype).itemsize * int(feats.shape[1]) // 4
    coef = np.random.default_rng(_PRINT_SEED).integers(1, 2**63, words, dtype=np.uint64)
    coef |= np.uint64(1)
    out = np.zeros(len(rows), np.uint64)
    for lo in range(0, len(rows), _PRINT_ROWS):
        x = np.ascontiguousarray(feats[rows[lo : lo + _PRINT_ROWS]]).view(np.uint32)
        x = x.reshape(-1, words).astype(np.uint64)
        out[lo : lo + _PRINT_ROWS] = (x * coef).sum(axis=1, dtype=np.uint64)
    return out


class ShapeTable:
    """One value per alive shape of a store version, carried and filled as asked for.

    Subclasses name the directory (:attr:`directory`), the values' file (:attr:`file`),
    and compute values (:meth:`compute`: alive ids only, so a count tells completeness).
    Values are rows of one array: ``(n,)`` or ``(n, k)``.

    Parameters
    ----------
    db : shapedb.Database
    meta : dict
        The parameters the values depend on, with ``version`` (JSON-serialisable); a
        stored table's values are read only when its pointer holds the same parameters,
        at this version or an earlier one (carried: see the module docstring).

    Attributes
    ----------
    values : dict
        The known values by id.
    at : dict
        The store version each known value was computed at, by id (``version`` for the
        values computed here; earlier for carried ones).
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
        self.at: dict[int, int] = {}
        self.n_alive = int(np.count_nonzero(self.index.alive_))
        self.complete = False
        self._saved = False  # the table on disk holds exactly these values
        self._prints: tuple[NDArray[np.int64], NDArray[np.uint64]] | None = None
        self._lock = threading.Lock()
        self._read()

    @property
    def root(self) -> Path:
        return Path(self.db.store.path) / self.directory

    @property
    def exact(self) -> bool:
        """Whether every known value was computed at this version (none carried)."""
        return all(v == self.version for v in self.at.values())

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
            if any(stored.get(key) != v for key, v in self.meta.items() if key != "version"):
                return
            version = int(stored["version"])
            if version > self.version:  # a later version's table: not this one's values
                return
            ids, values = np.load(sub / "ids.npy"), np.load(sub / self.file)
            if len(values) != len(ids):
                raise ValueError(f"{len(values)} values for {len(ids)} ids")
            self.check(values)
            at = np.load(sub / "at.npy") if (sub / "at.npy").exists() else None
            at = np.full(len(ids), version, np.int64) if at is None else at
            has_prints = (sub / "prints.npy").exists()
            prints = np.load(sub / "prints.npy") if has_prints else None
            if version < self.version:  # carried: the same shapes, still alive
                if prints is None:
                    raise ValueError("no fingerprints to carry the values by")
                keep = np.asarray(self.index.lookup(ids)) >= 0
                now = fingerprints(self.index, ids[keep])
                same = now == prints[keep]
                keep[keep] = same
                ids, values, at, prints = ids[keep], values[keep], at[keep], now[same]
            self._prints = None if prints is None else (ids, prints)
            self.values = dict(zip(ids.tolist(), values, strict=True))
            versions, which = np.unique(np.asarray(at, np.int64), return_inverse=True)
            one = versions.tolist()  # one int object per version, not one per value
            self.at = dict(zip(ids.tolist(), map(one.__getitem__, which.tolist()), strict=True))
            self.complete = version == self.version or len(self.values) >= self.n_alive
            self._saved = version == self.version
        except (OSError, ValueError, KeyError) as exc:
            self.values, self.at, self._prints = {}, {}, None
            log.warning("recomputing the %s of %s: %s", self.what, self.db.store.path, exc)

    def save(self) -> None:
        """Write the complete table beside the store, whole and atomically (no-op while
        some alive shape has no value yet, or when the table on disk holds these values).

        Raises OSError when the store's directory cannot be written (:meth:`keep`).
        """
        with self._lock:
            if not self.complete or self._saved:
                return
            keys = np.fromiter(self.values, np.int64, len(self.values))
            order = np.argsort(keys, kind="stable")
            ids, values = keys[order], np.asarray(list(self.values.values()))[order]
            at = np.fromiter((self.at[i] for i in self.values), np.int64, len(keys))[order]
        prints = self._fingerprints(ids)
        carried = int(np.count_nonzero(at < self.version))
        oldest = int(at.min()) if len(at) else self.version

        def write(sub: Path) -> None:
            np.save(sub / "ids.npy", ids)
            np.save(sub / self.file, values)
            np.save(sub / "at.npy", at)
            np.save(sub / "prints.npy", prints)

        meta = {**self.meta, "exact": not carried, "oldest": oldest, "carried": carried}
        save_version(self.root, write, meta, version=self.version)
        self._saved = True
        log.info(
            "%s of %d shapes at store version %s (%d carried from version %d on)",
            self.what, len(ids), self.version, carried, oldest,
        )  # fmt: skip

    def _fingerprints(self, ids: NDArray[np.int64]) -> NDArray[np.uint64]:
        """:func:`fingerprints` of the sorted ``ids``, those read or verified reused."""
        out = np.zeros(len(ids), np.uint64)
        todo = np.ones(len(ids), bool)
        if self._prints is not None and len(self._prints[0]):
            known, prints = self._prints
            pos = np.minimum(np.searchsorted(known, ids), len(known) - 1)
            hit = known[pos] == ids
            out[hit], todo = prints[pos[hit]], ~hit
        out[todo] = fingerprints(self.index, ids[todo])
        return out

    def keep(self) -> None:
        """:meth:`save`, or keep the table in memory only (one warning) when the store's
        directory cannot be written (read-only media, another user's files)."""
        try:
            self.save()
        except OSError as exc:
            log.warning("%s kept in memory only: cannot write %s (%s)",
                        self.what, self.root, exc.strerror)  # fmt: skip

    def refresh(self) -> None:
        """Recompute every alive shape's value at this version (nothing carried)."""
        with self._lock:
            ids, got = self.compute(None)
            self.values = dict(zip(ids.tolist(), got, strict=True))
            self.at = dict.fromkeys(self.values, self.version)
            self.complete, self._saved = True, False

    def fill(self, ids: NDArray[np.int64] | None = None) -> None:
        """Compute the values of the alive ``ids`` (every alive shape's when None) that have
        none yet, in this process (nothing is written: :meth:`save`); known values are kept."""
        with self._lock:
            if self.complete:
                return
            if ids is not None:
                asked = np.unique(np.asarray(ids, np.int64))
                pending: NDArray[np.int64] | None = np.array(
                    [i for i in asked.tolist() if i not in self.values], np.int64
                )
            elif self.values:  # the alive ids without a value
                lack = np.array(self.index.alive_, bool)
                pos = np.asarray(self.index.lookup(np.fromiter(self.values, np.int64)))
                lack[pos[pos >= 0]] = False
                pending = np.asarray(self.index.ids_, np.int64)[lack]
            else:
                pending = None
            if pending is None or len(pending):
                got_ids, got = self.compute(pending)
                self.values.update(zip(got_ids.tolist(), got, strict=True))
                self.at.update(dict.fromkeys(got_ids.tolist(), self.version))
                self._saved = False
            if len(self.values) >= self.n_alive:  # compute answers alive ids only
                self.complete = True

    def known(self, ids: NDArray[np.int64] | None = None) -> tuple[NDArray[np.int64], list[Any]]:
        """``(ids, values)``: every asked id's value (None where it has none; every alive
        shape's when ``ids`` is None), computing those without one (:meth:`fill`)."""
        self.fill(ids)
        with self._lock:
            want = np.array(sorted(self.values), np.int64) if ids is None else ids
            return want, [self.values.get(int(i)) for i in np.asarray(want, np.int64).ravel()]


def update(table: ShapeTable, whole: int, limit: int) -> None:
    """Bring a store's table up to date after a commit and save it (the commit's hook).

    ``whole`` is what computing the whole table costs, in the module's distances: at
    most ``limit``, every value is recomputed (an exact table, at a bounded cost); else
    only the shapes without a value (the commit's new shapes) are computed, the others
    carried. A store the process cannot write keeps the table in memory.
    """
    if whole <= limit:
        table.refresh()
    else:
        table.fill(None)
    table.keep()


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
