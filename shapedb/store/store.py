"""A crash-safe store: a directory of Parquet segments and one JSON manifest.

Layout of a store directory (see ``docs/store.md``)::

    DIR/
      manifest.json              the only source of truth: committed segments, config, version
      .lock                      fcntl lock file: one writer at a time
      data/shapes/*.parquet      segments of each table
      data/balls/*.parquet
      data/edges/*.parquet
      data/failures/*.parquet
      staging/<txn>/             segments being written (never read)
      journal/<txn>.json         what a transaction in flight will write (for cleanup)

A commit writes its new segments under ``staging/``, fsyncs them, renames them into
``data/`` and then swaps the manifest atomically (temp file + fsync + ``os.replace`` +
fsync of the directory). Readers only open the files the manifest lists, so a reader
sees a batch entirely or not at all, and a crash at any moment leaves the store as it
was before the batch or after it. Files a commit replaced (deletion, compaction) are
*retired*: kept for ``retain_seconds`` so that readers holding an older manifest can
finish, then removed by a later writer, which also removes what the journal of a
writer that died before its manifest swap proves it left (:mod:`shapedb.store.transaction`).
A store is created only in a missing or empty folder, and a folder whose manifest is
missing or damaged is never written to (:mod:`shapedb.store.manifest`); ``shapedb check``
and ``shapedb repair`` (:mod:`shapedb.store.integrity`) verify and rebuild it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
from numpy.typing import NDArray

from shapedb.config.core import Config
from shapedb.errors import ConfigError, NotFoundError, QueryError, ShapeDBError, StoreError
from shapedb.store.checksums import verified_files
from shapedb.store.compaction import TARGET_SHAPES, merge_small_segments
from shapedb.store.manifest import (
    DATA,
    FORMAT_VERSION,
    MANIFEST,
    check_sizes,
    new_manifest,
    read_manifest,
    require_empty,
    unreadable,
)
from shapedb.store.schema import (
    TABLES,
    Failure,
    ShapeRecord,
    balls_table,
    edges_table,
    failures_table,
    record_from_rows,
    schema_for,
    shapes_table,
)
from shapedb.store.transaction import FileLock, Transaction, cleanup, write_manifest

__all__ = ["Store", "CommitResult", "FORMAT_VERSION", "MANIFEST"]

log = logging.getLogger(__name__)

_LOCK = ".lock"
_PARQUET = ds.ParquetFileFormat(
    default_fragment_scan_options=ds.ParquetFragmentScanOptions(page_checksum_verification=True)
)


@dataclass(frozen=True)
class CommitResult:
    """What one commit did.

    Attributes
    ----------
    version : int
        Manifest version after the commit.
    added : tuple[int, ...]
        Ids of the shapes added.
    deleted : tuple[int, ...]
        Ids of the shapes removed.
    failures : int
        Failures recorded.
    """

    version: int
    added: tuple[int, ...] = ()
    deleted: tuple[int, ...] = ()
    failures: int = 0


@dataclass(frozen=True)
class _Snapshot:
    """A parsed manifest: one consistent view of the store."""

    data: dict[str, Any] = field(repr=False)

    @property
    def version(self) -> int:
        return int(self.data["version"])

    def segments(self, table: str) -> list[dict[str, Any]]:
        return list(self.data["tables"][table])


def _matrix(column: Any, n: int, dim: int) -> NDArray[np.float32]:
    """(n, dim) float32 copy of the non-null rows of a fixed-size-list column."""
    flat = pc.list_flatten(column).to_numpy(zero_copy_only=False) if n else np.zeros(0)
    return np.array(flat, dtype=np.float32).reshape(n, dim)


class Store:
    """A shape store on disk; open one with :meth:`open` or :meth:`create`.

    Reading methods take a fresh snapshot of the manifest on each call (so they see
    every commit made so far, and only whole commits). Writing methods take the
    store's write lock for the duration of the call, or use :meth:`writer` to hold it
    across several commits.

    Parameters
    ----------
    path : str or Path
        The store directory; it must hold a ``manifest.json``.
    lock_timeout : float
        Seconds a writer waits for the lock before raising :class:`StoreLockedError`;
        0 fails at once.
    retain_seconds : float
        How long replaced segments are kept for readers still using an older manifest.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        lock_timeout: float = 0.0,
        retain_seconds: float = 300.0,
    ) -> None:
        self.path = Path(path).absolute()
        self.lock_timeout = float(lock_timeout)
        self.retain_seconds = float(retain_seconds)
        self._lock = FileLock(self.path / _LOCK)
        self._lock_depth = 0
        self._read_as: tuple[tuple[int, ...], _Snapshot] | None = None
        snap = self._snapshot()  # validates
        self._config = Config.from_dict(snap.data["config"])
        self._dim = int(snap.data["dim"])

    # ------------------------------------------------------------------ opening
    @classmethod
    def open(cls, path: str | os.PathLike[str], **kwargs: Any) -> Store:
        """Open an existing store; :class:`StoreError` when there is none."""
        return cls(path, **kwargs)

    @classmethod
    def create(
        cls, path: str | os.PathLike[str], config: Config | None = None, **kwargs: Any
    ) -> Store:
        """Create an empty store in ``path`` (which must not hold one already).

        Parameters
        ----------
        path : str or Path
            Directory to create (it may exist and be empty).
        config : Config, optional
            Configuration every record of the store is built with; the default one
            when omitted.
        """
        config = config or Config()
        root = Path(path).absolute()
        if root.exists() and not root.is_dir():
            raise StoreError("exists and is not a directory", source=str(root))
        # before the lock: refuse a foreign folder without leaving a lock file in it;
        # what a concurrent creator may have written so far is checked under the lock
        require_empty(root, ignore=(_LOCK, DATA, MANIFEST, "journal", "staging"))
        with _writing(root, "create the store"):
            root.mkdir(parents=True, exist_ok=True)
            lock = FileLock(root / _LOCK)
            lock.acquire(max(float(kwargs.get("lock_timeout", 0.0)), 5.0), source=str(root))
            try:  # under the lock: a second creator sees this store, or an empty folder
                require_empty(root, ignore=(_LOCK,))
                for t in TABLES:
                    (root / DATA / t).mkdir(parents=True, exist_ok=True)
                write_manifest(root, new_manifest(config))
            finally:
                lock.release()
        log.info("created store %s (config %s)", root, config.fingerprint)
        return cls(root, **kwargs)

    @staticmethod
    def exists(path: str | os.PathLike[str]) -> bool:
        """Whether ``path`` holds a store."""
        return (Path(path) / MANIFEST).is_file()

    # --------------------------------------------------------------- properties
    @property
    def config(self) -> Config:
        """The configuration every record of this store was built with."""
        return self._config

    @property
    def dim(self) -> int:
        """Length of the stored feature vectors (``config.dim``)."""
        return self._dim

    @property
    def version(self) -> int:
        """Manifest version: 0 when created, +1 on every commit."""
        return self._snapshot().version

    def __len__(self) -> int:
        return sum(int(s["rows"]) for s in self._snapshot().segments("shapes"))

    def __repr__(self) -> str:
        return f"<Store {str(self.path)!r} version={self.version} shapes={len(self)}>"

    # ------------------------------------------------------------------ reading
    def _snapshot(self, *, fresh: bool = False) -> _Snapshot:
        """The manifest as it is now. Readers share the parsed copy while the file is the
        same (its inode, size and times: a commit replaces it by a new file), since a
        search reads it several times; ``fresh`` (writers, which change what they read)
        parses it again."""
        if not fresh:
            try:
                st = (self.path / MANIFEST).stat()
                key = (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
            except OSError:
                key = None
            if key is not None and self._read_as is not None and self._read_as[0] == key:
                return self._read_as[1]
            snap = _Snapshot(read_manifest(self.path))
            if key is not None:
                self._read_as = (key, snap)
            return snap
        return _Snapshot(read_manifest(self.path))

    def files(self, table: str = "shapes") -> list[str]:
        """Absolute paths of the committed Parquet files of ``table`` (for DuckDB)."""
        _check_table(table)
        return [str(self.path / s["file"]) for s in self._snapshot().segments(table)]

    def verified_files(self) -> dict[str, list[str]]:
        """The committed files of every table, from one manifest version, each verified.

        For readers that do not check Parquet page checksums themselves (DuckDB): each
        file's bytes are compared with the sha256 the manifest recorded at commit
        (:func:`shapedb.store.checksums.verify_segments`; cached while the file is
        unchanged, so an unchanged store is hashed once per process).

        Returns
        -------
        dict
            Table name -> absolute paths of its segments.

        Raises
        ------
        StoreError
            A listed segment is missing or its bytes differ; the message names it.
        """
        return verified_files(self.path, TABLES)

    def _read(
        self,
        table: str,
        *,
        columns: Sequence[str] | None = None,
        filter: pc.Expression | None = None,
        snapshot: _Snapshot | None = None,
    ) -> pa.Table:
        _check_table(table)
        for attempt in range(5):
            snap = snapshot if snapshot is not None and attempt == 0 else self._snapshot()
            schema = schema_for(table, int(snap.data["dim"]))
            paths = [str(self.path / s["file"]) for s in snap.segments(table)]
            if columns is not None:
                unknown = set(columns) - set(schema.names)
                if unknown:
                    raise QueryError(f"unknown column(s) of {table}: {sorted(unknown)}")
            try:
                if not paths:
                    out = schema.empty_table()
                    if filter is not None:
                        out = out.filter(filter)
                    return out.select(list(columns)) if columns is not None else out
                check_sizes(self.path, snap.segments(table))
                dataset = ds.dataset(paths, schema=schema, format=_PARQUET)
                return dataset.to_table(columns=list(columns) if columns else None, filter=filter)
            except FileNotFoundError:
                # a writer retired a file after we read the manifest: read again
                time.sleep(0.01 * (attempt + 1))
            except (pa.ArrowException, OSError) as exc:
                if isinstance(exc, StoreError):
                    raise
                raise unreadable(self.path, snap.segments(table), exc) from exc
        snap = self._snapshot()
        check_sizes(self.path, snap.segments(table), missing=True)
        raise StoreError(f"cannot read a consistent snapshot of {table}", source=str(self.path))

    def shapes(
        self, columns: Sequence[str] | None = None, *, ids: Iterable[int] | None = None
    ) -> pa.Table:
        """The ``shapes`` table (all columns, or ``columns``), sorted by id.

        Parameters
        ----------
        columns : sequence of str, optional
            Columns to read (``id`` is always read first for sorting).
        ids : iterable of int, optional
            Only these shapes.
        """
        cols = None if columns is None else list(dict.fromkeys(["id", *columns]))
        t = self._read("shapes", columns=cols, filter=_ids_filter("id", ids))
        t = t.sort_by("id")
        return t if columns is None else t.select(list(columns))

    def balls(self, ids: Iterable[int] | None = None) -> pa.Table:
        """The ``balls`` table, or the balls of the shapes ``ids``, sorted."""
        t = self._read("balls", filter=_ids_filter("shape_id", ids))
        return t.sort_by([("shape_id", "ascending"), ("ball", "ascending")])

    def edges(self, ids: Iterable[int] | None = None) -> pa.Table:
        """The ``edges`` table, or the edges of the shapes ``ids``, sorted."""
        t = self._read("edges", filter=_ids_filter("shape_id", ids))
        return t.sort_by([("shape_id", "ascending"), ("i", "ascending"), ("j", "ascending")])

    def failures(self) -> pa.Table:
        """The ``failures`` table: inputs that could not be ingested, and why."""
        return self._read("failures").sort_by("time")

    def ids(self) -> NDArray[np.int64]:
        """Ids of all stored shapes, ascending."""
        return self.shapes(["id"]).column("id").to_numpy()

    def features(self, *, view: bool = False) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
        """All feature vectors.

        Parameters
        ----------
        view : bool
            Return each shape's sparse-view feature (``view_feature``) instead, and
            its own feature where it has no view (:mod:`shapedb.geometry.view`).

        Returns
        -------
        ids : (n,) int64
            Shape ids, ascending.
        matrix : (n, d) float32
            Row k is the feature of ``ids[k]``; d = ``Config.dim``.
        """
        t = self.shapes(["id", "feature", "view_feature"] if view else ["id", "feature"])
        ids = t.column("id").to_numpy()
        out = _matrix(t.column("feature"), len(ids), self.dim)
        if view:
            views = t.column("view_feature").combine_chunks()
            has = views.is_valid().to_numpy(zero_copy_only=False)
            if has.any():
                out[has] = _matrix(views, int(has.sum()), self.dim)
        return ids, out

    def sparse_ids(self) -> NDArray[np.int64]:
        """Ids of the shapes whose source is a sparse sample (:func:`shapedb.geometry.view.is_sparse`)."""
        from shapedb.geometry.view import SPARSE_CELLS

        t = self.shapes(["id", "sampling", "spacing"])
        sampling = np.nan_to_num(t.column("sampling").to_numpy(zero_copy_only=False), nan=0.0)
        spacing = t.column("spacing").to_numpy()
        return t.column("id").to_numpy()[(spacing > 0) & (sampling >= SPARSE_CELLS * spacing)]

    def hashes(self) -> dict[str, int]:
        """Content hash -> id of every stored shape (for idempotent ingest)."""
        t = self.shapes(["id", "content_hash"])
        return dict(
            zip(t.column("content_hash").to_pylist(), t.column("id").to_pylist(), strict=True)
        )

    def resolve(self, id_or_name: int | str) -> int:
        """The id of a shape given its id or its name.

        An int is an id. A string is a name; a string of digits that is no shape's
        name is taken as an id. Raises :class:`NotFoundError` when there is no such
        shape, and :class:`QueryError` when a name is ambiguous.
        """
        if isinstance(id_or_name, (int, np.integer)) and not isinstance(id_or_name, bool):
            sid = int(id_or_name)
            if len(self.shapes(["id"], ids=[sid])) == 0:
                raise NotFoundError("no shape with this id", source=sid)
            return sid
        name = str(id_or_name)
        t = self._read("shapes", columns=["id"], filter=pc.field("name") == name)
        ids = sorted(t.column("id").to_pylist())
        if len(ids) == 1:
            return int(ids[0])
        if len(ids) > 1:
            raise QueryError(f"name is ambiguous: shapes {ids} have it; use an id", source=name)
        if name.strip().isdigit():
            return self.resolve(int(name))
        raise NotFoundError("no shape with this name or id", source=name)

    def get(self, id_or_name: int | str) -> ShapeRecord:
        """One shape as a :class:`ShapeRecord`, with its :class:`Decomposition` rebuilt."""
        sid = self.resolve(id_or_name)
        snap = self._snapshot()
        rows = self._read("shapes", filter=pc.field("id") == sid, snapshot=snap).to_pylist()
        if not rows:
            raise NotFoundError("no shape with this id", source=sid)
        balls = self._read("balls", filter=pc.field("shape_id") == sid, snapshot=snap)
        edges = self._read("edges", filter=pc.field("shape_id") == sid, snapshot=snap)
        return record_from_rows(rows[0], balls, edges)

    # ------------------------------------------------------------------ locking
    @contextlib.contextmanager
    def writer(self, *, timeout: float | None = None) -> Iterator[Store]:
        """Hold the write lock for the duration of a ``with`` block (re-entrant).

        Parameters
        ----------
        timeout : float, optional
            Seconds to wait for the lock; defaults to ``lock_timeout``.
        """
        self._acquire(self.lock_timeout if timeout is None else timeout)
        try:
            yield self
        finally:
            self._release()

    def _acquire(self, timeout: float) -> None:
        if self._lock_depth:
            self._lock_depth += 1
            return
        self._lock.acquire(timeout, source=str(self.path))
        self._lock_depth = 1
        try:
            self._cleanup()
        except Exception:
            self._release()
            raise

    def _release(self) -> None:
        self._lock_depth -= 1
        if self._lock_depth == 0:
            self._lock.release()

    def _cleanup(self) -> None:
        """Remove staging leftovers, orphans and expired retired files (lock held)."""
        removed = cleanup(self.path, self._snapshot(fresh=True).data, TABLES, self.retain_seconds)
        if removed:
            log.info("store %s: removed %d orphan or expired segment(s)", self.path, removed)

    # ------------------------------------------------------------------ writing
    def add(
        self, records: Sequence[ShapeRecord], failures: Sequence[Failure] = ()
    ) -> list[ShapeRecord]:
        """Commit records (and failures) atomically; returns them with their ids."""
        with self.writer():
            out: list[ShapeRecord] = []
            self.commit(records, failures=failures, assigned=out)
            return out

    def delete(self, ids: Iterable[int]) -> int:
        """Remove shapes by id in one commit; returns how many were removed."""
        result = self.commit(delete=ids)
        return len(result.deleted)

    def commit(
        self,
        records: Sequence[ShapeRecord] = (),
        *,
        failures: Sequence[Failure] = (),
        delete: Iterable[int] = (),
        assigned: list[ShapeRecord] | None = None,
    ) -> CommitResult:
        """One atomic transaction: delete shapes, add records, record failures.

        Parameters
        ----------
        records : sequence of ShapeRecord
            New shapes. A record without an id gets the next free one; a record with
            an id keeps it (the id must be free or deleted by this same commit).
        failures : sequence of Failure
            Inputs that failed. Earlier failures of the same sources, and of the
            sources of ``records``, are dropped, so the table says what is wrong now.
        delete : iterable of int
            Ids to remove (unknown ids are ignored).
        assigned : list, optional
            Receives the committed records, with their ids.

        Returns
        -------
        CommitResult
        """
        with self.writer(), _writing(self.path, "commit"):
            snap = self._snapshot(fresh=True)
            self._check_config(snap, records)
            new, delete_ids, next_id = self._plan(snap, records, delete)
            if not new and not delete_ids and not failures:
                return CommitResult(version=snap.version)
            txn = Transaction(self.path, snap.data)
            dim = int(snap.data["dim"])
            if delete_ids:
                txn.delete(delete_ids, dim)
            if new:
                txn.tables["shapes"].append(txn.stage("shapes", shapes_table(new, dim), "id"))
                for table, t in (("balls", balls_table(new)), ("edges", edges_table(new))):
                    if t.num_rows:
                        txn.tables[table].append(txn.stage(table, t, "shape_id"))
            self._stage_failures(txn, snap, failures, new)
            version = txn.publish(next_id=next_id)
            if assigned is not None:
                assigned.extend(new)
            log.info(
                "store %s: committed version %d (+%d shapes, -%d, %d failures)",
                self.path,
                version,
                len(new),
                len(delete_ids),
                len(failures),
            )
            return CommitResult(
                version=version,
                added=tuple(int(r.id) for r in new),  # type: ignore[arg-type]
                deleted=tuple(sorted(delete_ids)),
                failures=len(failures),
            )

    def _check_config(self, snap: _Snapshot, records: Sequence[ShapeRecord]) -> None:
        """Refuse records built with another configuration than the manifest's (lock held).

        The manifest is the one just re-read under the lock, so a store re-created
        with another configuration since this object opened it is caught too.
        """
        stored = Config.from_dict(snap.data["config"])
        if stored != self._config:
            raise StoreError(
                f"the store's configuration changed since it was opened (now "
                f"{stored.fingerprint}, opened as {self._config.fingerprint}); reopen it",
                source=str(self.path),
            )
        for r in records:
            if r.config != stored:
                raise ConfigError(
                    f"record was built with configuration {r.config.fingerprint} "
                    f"({r.config.to_json()}), but this store holds configuration "
                    f"{stored.fingerprint} ({stored.to_json()})",
                    source=r.name,
                )

    def _plan(
        self, snap: _Snapshot, records: Sequence[ShapeRecord], delete: Iterable[int]
    ) -> tuple[list[ShapeRecord], set[int], int]:
        """(records with their ids, live ids to delete, next free id) of one commit.

        New ids start above the manifest's ``next_id`` and above every stored id (read
        from the segments and their manifest entries), so an id is never reused even
        when the manifest's ``next_id`` is wrong.
        """
        delete_ids = {int(i) for i in delete}
        segments = snap.segments("shapes")
        # every segment's largest id is in the manifest: new shapes alone need no id read
        # (reading every id made a commit grow with the store)
        unknown = any("max_id" not in s and s.get("rows", 1) for s in segments)
        explicit = any(r.id is not None for r in records)
        live_ids: set[int] = set()
        if delete_ids or explicit or (records and unknown):
            live_ids = set(self.ids().tolist())
        elif records:  # what reading them checked: no listed segment missing or resized
            for table in TABLES:
                check_sizes(self.path, snap.segments(table), missing=True)
        delete_ids &= live_ids
        recorded = (int(s.get("max_id", 0)) + 1 for s in segments)
        next_id = max(int(snap.data["next_id"]), max(live_ids, default=0) + 1, *recorded)
        new: list[ShapeRecord] = []
        for r in records:
            if r.id is None:
                new.append(replace(r, id=next_id))
                next_id += 1
            else:
                if r.id in live_ids and r.id not in delete_ids:
                    raise StoreError(f"id {r.id} is already in use", source=r.name)
                new.append(r)
                next_id = max(next_id, int(r.id) + 1)
        if len({r.id for r in new}) != len(new):
            raise StoreError("duplicate ids in one commit", source=str(self.path))
        return new, delete_ids, next_id

    def _stage_failures(
        self,
        txn: Transaction,
        snap: _Snapshot,
        failures: Sequence[Failure],
        new: Sequence[ShapeRecord],
    ) -> None:
        """Failures: one small segment, rewritten whenever it changes.

        Earlier failures of the same sources, and of the sources and names of the new
        records, are dropped.
        """
        gone = {f.source for f in failures} | {r.source for r in new if r.source}
        gone |= {r.name for r in new}
        old = self._read("failures", snapshot=snap)
        remaining = old
        if old.num_rows and gone:
            keep = pc.invert(pc.is_in(old.column("source"), pa.array(sorted(gone))))
            remaining = old.filter(keep)
        if failures or remaining.num_rows != old.num_rows:
            merged = pa.concat_tables([remaining, failures_table(failures)])
            txn.retire([s["file"] for s in txn.tables["failures"]])
            txn.tables["failures"] = (
                [txn.stage("failures", merged, None)] if merged.num_rows else []
            )

    def compact(self, *, target_shapes: int = TARGET_SHAPES) -> CommitResult:
        """Merge runs of small segments into segments of about ``target_shapes`` shapes, in
        one commit (readers unaffected; the merged files are retired, not removed).

        Each table's runs are planned on its own rows (:func:`shapedb.store.compaction.merge_runs`;
        ``balls`` and ``edges`` scaled by their rows per shape) and read one run at a
        time, so memory holds one merged segment, never the table. Segments already
        that large are left alone: compacting again does nothing.

        Parameters
        ----------
        target_shapes : int
            Shapes of a full segment.
        """
        if int(target_shapes) < 1:
            raise ConfigError("must be >= 1", source=f"target_shapes={target_shapes!r}")
        with self.writer(), _writing(self.path, "compact"):
            snap = self._snapshot(fresh=True)
            txn = Transaction(self.path, snap.data)
            merged = merge_small_segments(txn, self.dim, target_shapes)
            if not merged:
                return CommitResult(version=snap.version)
            return CommitResult(version=txn.publish())


@contextlib.contextmanager
def _writing(root: Path, doing: str) -> Iterator[None]:
    """Turn an operating-system error while writing (no such folder, read-only,
    disk full) into one StoreError naming the store and the reason."""
    try:
        yield
    except OSError as exc:
        if isinstance(exc, ShapeDBError):
            raise
        raise StoreError(
            f"cannot {doing} here ({exc.strerror or type(exc).__name__})", source=str(root)
        ) from exc


def _check_table(table: str) -> None:
    if table not in TABLES:
        raise QueryError(f"unknown table {table!r}; the store has {list(TABLES)}")


def _ids_filter(column: str, ids: Iterable[int] | None) -> pc.Expression | None:
    if ids is None:
        return None
    values = pa.array(sorted({int(i) for i in ids}), pa.int64())
    return pc.field(column).isin(values)
