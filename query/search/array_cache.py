"""Memory-mapped copies of a store's per-record array columns, kept in step with the store.

The ``"lightfield"`` stage reads the light fields and field vectors of a few hundred
candidate ids per query. Read from the store, each such read scans a filter over every
segment (seconds at 10^6 shapes); read from here it is a binary search and a gather of
the rows asked for. This is derived state, like the feature index
(:mod:`query.search.index`): ``<store>/index_arrays/<column>/`` is a versioned directory
(:func:`query.search.versioned.save_version`) whose live sub-directory holds

- ``ids.npy`` (n,) int64: the alive shapes' ids, ascending;
- ``rows.npy`` (n,) int64: each id's row in the chunks, -1 where its column is null;
- ``segs.npy`` (n,) int32: the segment holding each id (an index into ``segments`` of
  ``current.json``, each named by its file and sha256 as the manifest names it);
- ``chunk-<k>.npy`` (r_k, L) float32: the rows, chunk after chunk (a row's number counts
  across the chunks); rows no id points at any more are dead.

A new store version is taken in incrementally (:meth:`ColumnCache.synced`): the rows of
the segments the manifest added are appended as one new chunk (the older chunks are
hard-linked into the new version, never rewritten, and the last chunks merged while one
is no more than twice the next's size, so there are O(log n) of them), the rows of the
segments a deletion or compaction rewrote (their ``shapedb.replaces`` metadata names
the segments they copy) are only re-pointed, and the ids of segments gone without a
copy are dropped. The cache is rebuilt from the store when it is missing, damaged,
inconsistent with the manifest, or more than :data:`REBUILD_DEAD_FRACTION` dead.

A store the process may not write keeps an update in memory (one warning); without a
usable cache on disk there, :func:`open_column` answers None and the caller reads the
store itself. Rows are read without Python lists (``pyarrow.compute.list_flatten``).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
import pyarrow.parquet as pq
from numpy.typing import NDArray

from query.search.versioned import POINTER, current, save_version
from shapedb.errors import ShapeDBError, StoreError
from shapedb.store.manifest import read_manifest
from shapedb.store.schema import schema_for
from shapedb.store.transaction import REPLACES

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "ColumnCache",
    "best_rows",
    "CACHE_DIR",
    "REBUILD_DEAD_FRACTION",
    "open_column",
    "on_commit",
    "forget",
]

log = logging.getLogger(__name__)

CACHE_DIR = "index_arrays"
_FORMAT = 1
#: A cache whose chunks hold more than this share of dead rows is rebuilt (the feature
#: index's threshold for tombstones, taken as is).
REBUILD_DEAD_FRACTION = 0.2
#: Segments read at once while a cache is built (1,000-row segments of 5,520-byte rows:
#: about 350 MB of Arrow data at a time).
_BUILD_SEGMENTS = 64
_PARQUET = ds.ParquetFileFormat(
    default_fragment_scan_options=ds.ParquetFragmentScanOptions(page_checksum_verification=True)
)


class _Inconsistent(Exception):
    """The cache and the manifest disagree: rebuild."""


@dataclass(frozen=True, eq=False)
class ColumnCache:
    """One array column of a store's alive shapes, at one store version.

    Attributes
    ----------
    column : str
        The ``shapes`` column (a list of float32 per record).
    store_id : str
        The manifest's ``store_id`` (a re-created store is another store).
    version : int
        The store version the cache reflects.
    segments : tuple of str
        ``"<file>#<sha256>"`` of each ``shapes`` segment taken in.
    ids : (n,) int64
        Alive ids, ascending.
    rows : (n,) int64
        Row of each id across the chunks; -1 where the record's column is null.
    segs : (n,) int32
        Index into ``segments`` of each id's segment.
    chunks : tuple of (r_k, L) float32 arrays
        The rows (memory-mapped when read from disk).
    """

    column: str
    store_id: str
    version: int
    segments: tuple[str, ...]
    ids: NDArray[np.int64]
    rows: NDArray[np.int64]
    segs: NDArray[np.int32]
    chunks: tuple[NDArray[np.float32], ...]

    @property
    def n_rows(self) -> int:
        """Rows held by the chunks, dead ones included."""
        return int(sum(len(c) for c in self.chunks))

    @property
    def width(self) -> int:
        """L, the numbers of a row (0 while no record has the column)."""
        return int(self.chunks[0].shape[1]) if self.chunks else 0

    @property
    def dead_fraction(self) -> float:
        """Share of the chunks' rows no id points at."""
        return 1.0 - int(np.count_nonzero(self.rows >= 0)) / max(self.n_rows, 1)

    def get(self, ids: NDArray[np.int64]) -> NDArray[np.float64] | None:
        """(m, L) float64 rows of ``ids``; NaN rows for ids without (not stored, or null).

        None when no id of ``ids`` has a row.
        """
        q = np.asarray(ids, np.int64).ravel()
        if not len(self.ids) or not self.chunks or not len(q):
            return None
        at = np.minimum(np.searchsorted(self.ids, q), len(self.ids) - 1)
        row = np.where(self.ids[at] == q, self.rows[at], -1)
        has = np.flatnonzero(row >= 0)
        if not len(has):
            return None
        out = np.full((len(q), self.width), np.nan)
        starts = np.cumsum([0] + [len(c) for c in self.chunks])
        which = np.searchsorted(starts, row[has], side="right") - 1
        for k in np.unique(which):
            pick = has[which == k]
            local = row[pick] - starts[k]
            order = np.argsort(local, kind="stable")  # ascending offsets: sequential pages
            out[pick[order]] = self.chunks[k][local[order]]
        return out

    def synced(self, root: Path, manifest: dict[str, Any]) -> ColumnCache:
        """The cache at the manifest's version, from this one (raises :class:`_Inconsistent`
        when only a rebuild can tell)."""
        now = _segment_keys(manifest)
        if now == self.segments:
            return replace(self, version=int(manifest["version"]))
        known = {key: i for i, key in enumerate(self.segments)}
        remap = np.full(len(self.segments), -1, np.int32)
        for j, key in enumerate(now):
            if key in known:
                remap[known[key]] = j
        segs = remap[self.segs]  # -1: its segment is gone (rewritten, or the id deleted)
        keep = np.ones(len(self.ids), bool)
        new_ids, new_rows, new_segs, values = [], [], [], []
        n_rows = self.n_rows
        replaced = {_file_of(key): known[key] for key in self.segments if key not in now}
        dim = int(manifest["dim"])
        for j, key in enumerate(now):
            if key in known:
                continue
            path = root / _file_of(key)
            sources = _replaces(path)
            if sources and all(s in replaced for s in sources):
                ids = _read(path, dim, ["id"]).column("id").to_numpy()
                at = _positions(self.ids, ids)
                allowed = [replaced[s] for s in sources]
                if np.any(at < 0) or not np.all(np.isin(self.segs[at], allowed)):
                    raise _Inconsistent(f"{path.name} copies rows the cache does not hold")
                segs[at] = j
                continue
            ids, valid, flat = _column_rows(path, dim, self.column)
            if len(flat) and self.chunks and flat.shape[1] != self.width:
                raise _Inconsistent("rows of another length")
            at = _positions(self.ids, ids)
            if np.any(segs[at[at >= 0]] >= 0):
                raise _Inconsistent(f"{path.name} holds ids the cache holds elsewhere")
            keep[at[at >= 0]] = False  # rebuilt in place (same id, new record)
            rows = np.full(len(ids), -1, np.int64)
            rows[valid] = n_rows + np.arange(int(valid.sum()))
            n_rows += int(valid.sum())
            new_ids.append(ids)
            new_rows.append(rows)
            new_segs.append(np.full(len(ids), j, np.int32))
            if len(flat):
                values.append(flat)
        keep &= segs >= 0
        ids = np.concatenate([self.ids[keep], *new_ids])
        order = np.argsort(ids, kind="stable")
        if len(ids) and np.any(np.diff(ids[order]) == 0):
            raise _Inconsistent("an id is held by two segments")
        chunks = self.chunks
        if values:
            if len({v.shape[1] for v in values}) > 1:
                raise _Inconsistent("rows of another length")
            chunks = (*chunks, np.ascontiguousarray(np.concatenate(values), np.float32))
        return replace(
            self,
            version=int(manifest["version"]),
            segments=now,
            ids=ids[order],
            rows=np.concatenate([self.rows[keep], *new_rows])[order],
            segs=np.concatenate([segs[keep], *new_segs])[order],
            chunks=chunks,
        )

    def save(self, directory: Path, *, merge: bool = True) -> None:
        """Write this cache as the directory's new version; chunks already on disk are
        hard-linked (copied where links fail), the last ones merged (:func:`_merge_plan`)
        with ``merge``."""
        sizes = [len(c) for c in self.chunks]
        plan = _merge_plan(sizes) if merge else [[i] for i in range(len(sizes))]

        def write(sub: Path) -> None:
            np.save(sub / "ids.npy", self.ids)
            np.save(sub / "rows.npy", self.rows)
            np.save(sub / "segs.npy", self.segs)
            for k, group in enumerate(plan):
                _write_chunk(sub / f"chunk-{k}.npy", [self.chunks[i] for i in group])

        meta = {
            "format": _FORMAT,
            "column": self.column,
            "store_id": self.store_id,
            "version": self.version,
            "segments": list(self.segments),
            "chunks": [int(sum(len(self.chunks[i]) for i in g)) for g in plan],
            "width": self.width,
            "n": len(self.ids),
        }
        save_version(directory, write, meta, version=self.version)


def _segment_keys(manifest: dict[str, Any]) -> tuple[str, ...]:
    return tuple(f"{s['file']}#{s.get('sha256', '')}" for s in manifest["tables"]["shapes"])


def _file_of(key: str) -> str:
    return key.rsplit("#", 1)[0]


def _positions(keys: NDArray[np.int64], ids: NDArray[np.int64]) -> NDArray[np.int64]:
    """Position of each of ``ids`` in the ascending ``keys``; -1 where absent."""
    if not len(keys):
        return np.full(len(ids), -1, np.int64)
    at = np.minimum(np.searchsorted(keys, ids), len(keys) - 1)
    return np.where(keys[at] == ids, at, -1).astype(np.int64)


def _replaces(path: Path) -> list[str]:
    """The segments a segment copies rows from (``shapedb.replaces``), [] for new rows."""
    meta = pq.read_schema(path).metadata or {}
    return [str(f) for f in json.loads(meta[REPLACES])] if REPLACES in meta else []


def _read(path: Path | list[Path], dim: int, columns: list[str]) -> pa.Table:
    """Columns of segments, older files' missing columns as nulls (the store's schema)."""
    paths = [str(p) for p in (path if isinstance(path, list) else [path])]
    dataset = ds.dataset(paths, schema=schema_for("shapes", dim), format=_PARQUET)
    return dataset.to_table(columns=columns)


def _column_rows(
    path: Path | list[Path], dim: int, column: str
) -> tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.float32]]:
    """``(ids, valid, rows)`` of segments: every id, whether its column is set, and the
    (valid.sum(), L) float32 rows of those that are (ValueError: rows of several lengths)."""
    t = _read(path, dim, ["id", column])
    ids = t.column("id").to_numpy().astype(np.int64)
    col = t.column(column).combine_chunks()
    valid = col.is_valid().to_numpy(zero_copy_only=False)
    set_rows = col.filter(pa.array(valid))
    if not len(set_rows):
        return ids, valid, np.zeros((0, 0), np.float32)
    lengths = pc.list_value_length(set_rows).to_numpy(zero_copy_only=False)
    if lengths.min() != lengths.max():
        raise ValueError(f"rows of {column} of several lengths in {path}")
    flat = pc.list_flatten(set_rows).to_numpy(zero_copy_only=False)
    return ids, valid, np.asarray(flat, np.float32).reshape(len(set_rows), int(lengths[0]))


def _merge_plan(sizes: list[int]) -> list[list[int]]:
    """Groups of consecutive chunks written as one: the last two merge while the earlier
    is at most twice the later's size (a binary counter: O(log n) chunks)."""
    groups = [[i] for i in range(len(sizes))]
    rows = list(sizes)
    while len(rows) >= 2 and rows[-2] <= 2 * rows[-1]:
        groups[-2:] = [groups[-2] + groups[-1]]
        rows[-2:] = [rows[-2] + rows[-1]]
    return groups


def _write_chunk(target: Path, parts: list[NDArray[np.float32]]) -> None:
    """One chunk file of ``parts`` in order; a single part already on disk is hard-linked."""
    one = parts[0]
    if len(parts) == 1 and isinstance(one, np.memmap) and one.filename:
        try:
            os.link(one.filename, target)
            return
        except OSError:
            pass  # another filesystem, or the file was superseded meanwhile: copy it
    out = np.lib.format.open_memmap(
        target, mode="w+", dtype=np.float32, shape=(sum(len(p) for p in parts), one.shape[1])
    )
    at = 0
    for p in parts:
        out[at : at + len(p)] = p
        at += len(p)
    out.flush()
    del out


def load(directory: Path, column: str, store_id: str) -> ColumnCache:
    """The cache saved under ``directory`` (StoreError when it is damaged or another's)."""
    try:
        meta, sub = current(directory)
        if meta.get("format") != _FORMAT or meta.get("column") != column:
            raise ValueError(f"format {meta.get('format')!r} of column {meta.get('column')!r}")
        if meta.get("store_id") != store_id:
            raise ValueError("written for another store")
        ids = np.load(sub / "ids.npy", mmap_mode="r")
        rows = np.load(sub / "rows.npy", mmap_mode="r")
        segs = np.load(sub / "segs.npy", mmap_mode="r")
        chunks = tuple(
            np.load(sub / f"chunk-{k}.npy", mmap_mode="r") for k in range(len(meta["chunks"]))
        )
        cache = ColumnCache(
            column, store_id, int(meta["version"]), tuple(meta["segments"]), ids, rows, segs, chunks
        )
        _check(cache, meta)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise StoreError(f"damaged array cache: {exc}", source=str(directory)) from exc
    return cache


def _check(cache: ColumnCache, meta: dict[str, Any]) -> None:
    """ValueError when the files disagree with each other or with the pointer."""
    n, width = int(meta["n"]), int(meta["width"])
    if not (len(cache.ids) == len(cache.rows) == len(cache.segs) == n):
        raise ValueError("ids, rows and segments of different lengths")
    if (cache.ids.dtype, cache.rows.dtype, cache.segs.dtype) != (np.int64, np.int64, np.int32):
        raise ValueError("unexpected dtypes")
    for c, r in zip(cache.chunks, meta["chunks"], strict=True):
        if c.dtype != np.float32 or c.shape != (int(r), width):
            raise ValueError(f"a chunk of shape {c.shape}, expected ({r}, {width})")
    if n and (np.any(np.diff(cache.ids) <= 0) or int(cache.rows.max()) >= cache.n_rows):
        raise ValueError("ids out of order or rows out of range")
    if n and (int(cache.segs.min()) < 0 or int(cache.segs.max()) >= len(cache.segments)):
        raise ValueError("segments out of range")


def build(root: Path, manifest: dict[str, Any], column: str, directory: Path) -> ColumnCache:
    """Read ``column`` of every segment into a new cache saved under ``directory``.

    Streamed: :data:`_BUILD_SEGMENTS` segments at a time, each batch's rows written as
    one chunk. OSError when the cache cannot be written, ValueError when the column has
    rows of several lengths.
    """
    segments = manifest["tables"]["shapes"]
    dim = int(manifest["dim"])
    directory.mkdir(parents=True, exist_ok=True)
    # a ".tmp-" folder a dead builder leaves is swept by a later save_version
    staging = Path(tempfile.mkdtemp(prefix=".tmp-build-", dir=directory))
    try:
        ids: list[NDArray[np.int64]] = []
        valid: list[NDArray[np.bool_]] = []
        chunks: list[NDArray[np.float32]] = []
        for lo in range(0, len(segments), _BUILD_SEGMENTS):
            paths = [root / s["file"] for s in segments[lo : lo + _BUILD_SEGMENTS]]
            got_ids, got_valid, flat = _column_rows(paths, dim, column)
            ids.append(got_ids)
            valid.append(got_valid)
            if len(flat):
                if chunks and flat.shape[1] != chunks[0].shape[1]:
                    raise ValueError(f"rows of {column} of several lengths")
                target = staging / f"chunk-{len(chunks)}.npy"
                np.save(target, flat)
                chunks.append(np.load(target, mmap_mode="r"))
        all_ids = np.concatenate(ids) if ids else np.zeros(0, np.int64)
        all_valid = np.concatenate(valid) if valid else np.zeros(0, bool)
        counts = [int(s["rows"]) for s in segments]
        if len(all_ids) != sum(counts):
            raise ValueError("the segments hold other row counts than the manifest says")
        rows = np.full(len(all_ids), -1, np.int64)
        rows[all_valid] = np.arange(int(all_valid.sum()))
        keys = _segment_keys(manifest)
        segs = np.repeat(np.arange(len(keys), dtype=np.int32), counts)
        order = np.argsort(all_ids, kind="stable")
        if len(order) and np.any(np.diff(all_ids[order]) == 0):
            raise ValueError("an id is held by two segments")
        store_id = str(manifest.get("store_id", ""))
        cache = ColumnCache(
            column, store_id, int(manifest["version"]), keys,
            all_ids[order], rows[order], segs[order], tuple(chunks),
        )  # fmt: skip
        cache.save(directory, merge=False)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return load(directory, column, store_id)


# ------------------------------------------------------------------ store glue
_OPEN: dict[tuple[str, str], ColumnCache] = {}
_WARNED: set[tuple[str, str]] = set()
_LOCK = threading.Lock()


def _warn_once(path: str, message: str, *args: Any) -> None:
    """Log ``message`` once per process and cache directory."""
    if (path, message) not in _WARNED:
        _WARNED.add((path, message))
        log.warning(message, *args)


def open_column(db: StoreHandle, column: str) -> ColumnCache | None:
    """The cache of ``column`` at the store's current version: kept in process, read from
    ``<store>/index_arrays/<column>/``, updated, or built.

    None when there is no usable cache and none can be written (a read-only store), or
    the column cannot be cached (rows of several lengths): the caller reads the store.
    """
    root = Path(db.store.path)
    directory = root / CACHE_DIR / column
    key = (os.fspath(root), column)
    with _LOCK:
        try:
            manifest = read_manifest(root)
        except (OSError, ShapeDBError) as exc:
            log.warning("array cache of %s: cannot read the manifest (%s)", root, exc)
            return None
        store_id = str(manifest.get("store_id", ""))
        cache = _OPEN.get(key)
        if cache is not None and cache.store_id != store_id:
            cache = None
        if cache is None and (directory / POINTER).exists():
            try:
                cache = load(directory, column, store_id)
            except StoreError as exc:
                log.warning("rebuilding the array cache of %s: %s", column, exc)
        try:
            cache = _brought_up(root, manifest, column, directory, cache)
        except (OSError, ValueError, pa.ArrowException, ShapeDBError) as exc:
            _warn_once(
                os.fspath(directory), "no array cache of %s (%s); reading the store", column, exc
            )
            _OPEN.pop(key, None)
            return None
        _OPEN[key] = cache
        return cache


def _brought_up(
    root: Path, manifest: dict[str, Any], column: str, directory: Path, cache: ColumnCache | None
) -> ColumnCache:
    """``cache`` at the manifest's version: as is, updated (saved, or kept in memory with a
    warning when it cannot be written) or rebuilt (OSError when that cannot be written)."""
    if cache is not None and cache.segments == _segment_keys(manifest):
        return (
            cache
            if cache.version == manifest["version"]
            else replace(cache, version=int(manifest["version"]))
        )
    if cache is not None:
        try:
            updated = cache.synced(root, manifest)
            if updated.dead_fraction <= REBUILD_DEAD_FRACTION:
                try:
                    updated.save(directory)
                    return load(directory, column, updated.store_id)
                except OSError as exc:
                    _warn_once(
                        os.fspath(directory),
                        "array cache of %s kept in memory only: cannot write %s (%s)",
                        column,
                        directory,
                        exc.strerror,
                    )
                    return updated
        except _Inconsistent as exc:
            log.warning("rebuilding the array cache of %s: %s", column, exc)
    return build(root, manifest, column, directory)


def on_commit(db: StoreHandle) -> None:
    """Store commit hook: update the caches that exist (on disk or in process); a store
    never searched gets its cache at its first search."""
    root = Path(db.store.path)
    where = root / CACHE_DIR
    columns = {c for p, c in _OPEN if p == os.fspath(root)}
    if where.is_dir():
        columns |= {d.name for d in where.iterdir() if (d / POINTER).exists()}
    for column in sorted(columns):
        open_column(db, column)


def forget(path: str) -> None:
    """Drop the in-process caches of the store at ``path`` (as a new process would)."""
    for key in [k for k in _OPEN if k[0] == path]:
        _OPEN.pop(key, None)


def best_rows(
    cache: ColumnCache,
    ids: NDArray[np.int64],
    keep: int,
    score: Any,
    *,
    block: int,
    width: int | None = None,
) -> NDArray[np.int64]:
    """The (at most) ``keep`` of ``ids`` whose rows ``score`` highest, best first (ties by
    ascending id): ``score`` maps (m, L) float64 rows to (m,) numbers. The rows are read
    ``block`` ids at a time (bounded memory at any store size); ids without a row (or a
    row of another ``width`` than asked) are left out."""
    best_ids, best = np.zeros(0, np.int64), np.zeros(0)
    for start in range(0, len(ids), block):
        chunk = ids[start : start + block]
        got = cache.get(chunk)
        if got is None or (width is not None and got.shape[1] != width):
            continue
        known = np.isfinite(got).all(axis=1)
        best_ids = np.concatenate([best_ids, chunk[known]])
        best = np.concatenate([best, np.asarray(score(got[known]), np.float64)])
        if len(best_ids) > keep:
            top = np.lexsort((best_ids, -best))[:keep]
            best_ids, best = best_ids[top], best[top]
    return np.asarray(best_ids[np.lexsort((best_ids, -best))], np.int64)
