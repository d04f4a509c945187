"""Durable building blocks of the store (private): the lock, the manifest, transactions.

A :class:`Transaction` first writes a *journal* (``journal/<txn>.json``: the store's
id and the staging folder), stages new Parquet segments under ``staging/<txn>/``
(each written, fsynced, and its size and sha256 recorded), then
:meth:`Transaction.publish` rewrites the journal with the ``data/`` paths the
segments will take, renames them into ``data/``, fsyncs the directories and swaps the
manifest atomically with :func:`write_manifest`. Until that last ``os.replace``
nothing a reader can see has changed; after it, everything has.

:func:`cleanup` removes only what a journal of this store proves belongs to a
transaction that never published (its staging folder, and its ``data/`` files the
manifest does not list), plus retired segments the manifest itself lists. A file
no journal names is never deleted, whatever the manifest says.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import logging
import os
import time
import uuid
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from shapedb.errors import StoreError, StoreLockedError
from shapedb.store.manifest import DATA, MANIFEST, check_sizes, unreadable
from shapedb.store.schema import schema_for

__all__ = [
    "FileLock",
    "Transaction",
    "cleanup",
    "write_manifest",
    "fsync_dir",
    "file_digest",
    "MANIFEST",
    "DATA",
    "STAGING",
    "JOURNAL",
    "REPLACES",
]

log = logging.getLogger(__name__)

STAGING = "staging"
JOURNAL = "journal"
REPLACES = b"shapedb.replaces"


def fsync_dir(path: Path) -> None:
    """Flush a directory's entries (renames, creations) to disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def file_digest(path: Path) -> tuple[int, str]:
    """``(size in bytes, sha256 hex)`` of a file."""
    h = hashlib.sha256()
    size = 0
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
            size += len(chunk)
    return size, h.hexdigest()


def _write_durably(path: Path, text: str) -> None:
    """Write a new small file and fsync it and its folder (no rename: a torn file is unreadable)."""
    with open(path, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    fsync_dir(path.parent)


def _floating(f: pa.Field) -> str | None:
    """The Parquet path of ``f``'s numbers when they are floating point, else None."""
    if pa.types.is_list(f.type) or pa.types.is_fixed_size_list(f.type):
        return f"{f.name}.list.element" if pa.types.is_floating(f.type.value_type) else None
    return f.name if pa.types.is_floating(f.type) else None


def write_segment(t: pa.Table, path: Path) -> None:
    """Write one segment: zstd, with page checksums, and floating-point columns (numbers and
    lists of numbers) byte-stream split so zstd sees their exponents together.

    The split takes a store of real models from 39.2 to 25.9 KB a shape (179 CAPOD models,
    the same rows written both ways); DuckDB and pyarrow read it as any Parquet file.
    """
    floats = [leaf for f in t.schema if (leaf := _floating(f)) is not None]
    others = [f.name for f in t.schema if _floating(f) is None]
    pq.write_table(
        t, path, compression="zstd", row_group_size=1 << 17, write_page_checksum=True,
        use_byte_stream_split=floats or False, use_dictionary=others or False,
    )  # fmt: skip


def write_manifest(root: Path, data: dict[str, Any]) -> None:
    """Atomically replace ``root/manifest.json`` (temp + fsync + replace + fsync dir)."""
    tmp = root / f".{MANIFEST}.{uuid.uuid4().hex[:8]}.tmp"
    text = json.dumps(data, indent=1, sort_keys=True)
    with open(tmp, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, root / MANIFEST)
    fsync_dir(root)


class FileLock:
    """An exclusive ``fcntl.flock`` on a file; not re-entrant (the Store counts depth).

    Parameters
    ----------
    path : Path
        The lock file (created if missing). Holds the holder's pid, for messages.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        """Whether this object holds the lock."""
        return self._fd is not None

    def acquire(self, timeout: float, *, source: str) -> None:
        """Take the lock, waiting up to ``timeout`` seconds; else StoreLockedError.

        A lock file that cannot be opened or created (a read-only or missing folder)
        is a :class:`StoreError` naming the reason.
        """
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise StoreError(
                f"cannot open the store's lock file {self.path.name} ({exc.strerror})",
                source=source,
            ) from exc
        deadline = time.monotonic() + max(timeout, 0.0)
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except OSError as exc:
                if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                    os.close(fd)
                    raise
                if time.monotonic() >= deadline:
                    holder = _holder(fd)
                    os.close(fd)
                    raise StoreLockedError(
                        f"another writer holds the store's lock{holder}; "
                        "wait for it to finish, or wait longer with --lock-timeout SECONDS "
                        "(lock_timeout= in Python)",
                        source=source,
                    ) from None
                time.sleep(0.05)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd

    def release(self) -> None:
        """Release the lock (no-op when not held)."""
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None


def _holder(fd: int) -> str:
    try:
        pid = os.pread(fd, 32, 0).decode().strip()
    except OSError:
        return ""
    return f" (pid {pid})" if pid else ""


class Transaction:
    """New segments and a new manifest, published atomically.

    Parameters
    ----------
    root : Path
        The store directory.
    manifest : dict
        The manifest the transaction starts from (copied).
    """

    def __init__(self, root: Path, manifest: dict[str, Any]) -> None:
        self.root = root
        self.data: dict[str, Any] = json.loads(json.dumps(manifest))  # deep copy
        self.version = int(self.data["version"]) + 1
        self.txn = uuid.uuid4().hex[:12]
        self.stage_dir = root / STAGING / self.txn
        self.journal = root / JOURNAL / f"{self.txn}.json"
        self._staged: list[tuple[str, Path]] = []
        self._retired: list[str] = []

    @property
    def tables(self) -> dict[str, list[dict[str, Any]]]:
        """The manifest's segment lists, to edit in place."""
        return self.data["tables"]  # type: ignore[no-any-return]

    def _journal(self, files: list[str]) -> None:
        """Write ``journal/<txn>.json`` (at start) or ``<txn>.files.json`` (before renames)."""
        self.journal.parent.mkdir(exist_ok=True)
        entry = {
            "store": self.data.get("store_id"),
            "txn": self.txn,
            "base_version": self.version - 1,
            "files": files,
        }
        path = self.journal.with_suffix(".files.json") if files else self.journal
        _write_durably(path, json.dumps(entry))

    def stage(
        self,
        table: str,
        t: pa.Table,
        id_column: str | None,
        *,
        replaces: list[str] = (),  # type: ignore[assignment]
    ) -> dict[str, Any]:
        """Write ``t`` as a new segment of ``table``; returns its manifest entry.

        The entry records the file's size (``bytes``) and ``sha256``, which
        ``shapedb check`` verifies. ``replaces`` (segments this one supersedes, after a
        deletion or compaction) is written into the file's metadata
        (``shapedb.replaces``), so ``shapedb repair`` never resurrects deleted rows.
        """
        if replaces:
            meta = dict(t.schema.metadata or {})
            meta[REPLACES] = json.dumps(sorted(replaces)).encode()
            t = t.replace_schema_metadata(meta)
        if not self._staged and not self.journal.exists():
            self._journal([])  # before anything is written: the staging folder is ours
        self.stage_dir.mkdir(parents=True, exist_ok=True)
        name = f"{self.version:08d}-{uuid.uuid4().hex[:8]}.parquet"
        path = self.stage_dir / f"{table}-{name}"
        write_segment(t, path)
        _fsync_file(path)
        size, digest = file_digest(path)
        self._staged.append((table, path))
        seg: dict[str, Any] = {
            "file": f"{DATA}/{table}/{name}",
            "rows": t.num_rows,
            "bytes": size,
            "sha256": digest,
        }
        if id_column is not None and t.num_rows:
            ids = t.column(id_column)
            seg["min_id"] = int(pc.min(ids).as_py())
            seg["max_id"] = int(pc.max(ids).as_py())
        return seg

    def delete(self, ids: set[int], dim: int) -> None:
        """Copy-on-write deletion: rewrite every segment holding one of ``ids`` without
        them, and retire it (the new file names it in its ``shapedb.replaces``)."""
        lo, hi = min(ids), max(ids)
        doomed = pa.array(sorted(ids), pa.int64())
        for table, col in (("shapes", "id"), ("balls", "shape_id"), ("edges", "shape_id")):
            kept = []
            for seg in self.tables[table]:
                if "min_id" not in seg or seg["max_id"] < lo or seg["min_id"] > hi:
                    kept.append(seg)
                    continue
                t = self.read_segment(seg, table, dim)
                mask = pc.is_in(t.column(col), doomed)
                if not pc.any(mask).as_py():
                    kept.append(seg)
                    continue
                rest = t.filter(pc.invert(mask))
                self.retire([seg["file"]])
                # even when empty: the new file says which one it replaces (for repair)
                kept.append(self.stage(table, rest, col, replaces=[seg["file"]]))
            self.tables[table] = kept

    def read_segment(self, seg: dict[str, Any], table: str, dim: int) -> pa.Table:
        """One committed segment of ``table``, its size and page checksums verified
        (a damaged file is one :class:`StoreError` naming it)."""
        try:
            check_sizes(self.root, [seg], missing=True)
            return pq.read_table(
                self.root / seg["file"],
                schema=schema_for(table, dim),
                page_checksum_verification=True,
            )
        except (pa.ArrowException, OSError) as exc:
            if isinstance(exc, StoreError):
                raise
            raise unreadable(self.root, [seg], exc) from exc

    def retire(self, files: list[str]) -> None:
        """Mark segments as replaced: kept for older readers, removed later."""
        self._retired.extend(files)

    def _target(self, table: str, path: Path) -> Path:
        return self.root / DATA / table / path.name.split("-", 1)[1]

    def publish(self, **fields: Any) -> int:
        """Move the staged segments into place and swap the manifest; returns the version."""
        if self._staged:  # the journal names every file before any of them lands in data/
            self._journal([str(self._target(t, p).relative_to(self.root)) for t, p in self._staged])
        for table in {t for t, _ in self._staged}:  # a store whose data/ was lost gets it back
            (self.root / DATA / table).mkdir(parents=True, exist_ok=True)
        for table, path in self._staged:
            os.rename(path, self._target(table, path))
        for table in {t for t, _ in self._staged}:
            fsync_dir(self.root / DATA / table)
        if self.stage_dir.exists():
            self.stage_dir.rmdir()
        now = time.time()
        self.data.update(fields)
        self.data["version"] = self.version
        self.data["updated_at"] = now
        self.data["retired"] = self.data.get("retired", []) + [
            {"file": f, "since": now} for f in self._retired
        ]
        write_manifest(self.root, self.data)
        self.journal.with_suffix(".files.json").unlink(missing_ok=True)  # nothing to undo
        self.journal.unlink(missing_ok=True)
        return self.version


def _read_journal(path: Path) -> dict[str, Any] | None:
    try:
        entry = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(entry, dict) or not isinstance(entry.get("files"), list):
        return None
    return entry


def _undo(root: Path, entry: dict[str, Any], live: set[str]) -> int:
    """Remove the unpublished files of one aborted transaction; returns how many."""
    removed = 0
    for rel in entry["files"]:
        parts = Path(str(rel)).parts
        if len(parts) != 3 or parts[0] != DATA or rel in live:
            continue  # not a segment path, or published after all
        (root / rel).unlink(missing_ok=True)
        removed += 1
    staging = root / STAGING / str(entry.get("txn", ""))
    if entry.get("txn") and staging.is_dir():
        for f in staging.iterdir():
            f.unlink(missing_ok=True)
        staging.rmdir()
    return removed


def cleanup(
    root: Path, manifest: dict[str, Any], tables: tuple[str, ...], retain_seconds: float
) -> int:
    """Remove what a journal or the manifest proves no reader needs.

    Must run with the write lock held, on a manifest that was read and validated.
    Removes the staging folder and the unpublished ``data/`` files of every journal of
    this store (same ``store_id``), temporary manifests, and retired segments older
    than ``retain_seconds``. Files no journal names are left alone (and logged).
    Returns the number of segments removed.
    """
    for tmp in root.glob(f".{MANIFEST}.*.tmp"):
        tmp.unlink(missing_ok=True)
    live = {s["file"] for t in tables for s in manifest["tables"][t]}
    retired = {r["file"]: float(r["since"]) for r in manifest.get("retired", [])}
    removed = 0
    journals = root / JOURNAL
    if journals.is_dir():
        for path in sorted(journals.iterdir()):
            entry = _read_journal(path)
            if entry is None or entry.get("store") != manifest.get("store_id"):
                log.warning("store %s: leaving %s alone (not a journal of this store)", root, path)
                continue
            removed += _undo(root, entry, live)
            path.unlink(missing_ok=True)
    now = time.time()
    expired = {f for f, since in retired.items() if now - since > retain_seconds}
    for rel in sorted(expired):
        if rel not in live:
            (root / rel).unlink(missing_ok=True)
            removed += 1
    if expired:
        data = dict(manifest)
        data["retired"] = [r for r in data["retired"] if r["file"] not in expired]
        write_manifest(root, data)  # same version: nothing a reader sees changes
    return removed
