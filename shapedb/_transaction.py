"""Durable building blocks of the store (private): the lock, the manifest, transactions.

A :class:`Transaction` stages new Parquet segments under ``staging/<txn>/`` (each
written and fsynced), then :meth:`Transaction.publish` renames them into ``data/``,
fsyncs the directories and swaps the manifest atomically with
:func:`write_manifest`. Until that last ``os.replace`` nothing a reader can see has
changed; after it, everything has.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import time
import uuid
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from shapedb.errors import StoreLockedError

__all__ = [
    "FileLock",
    "Transaction",
    "cleanup",
    "write_manifest",
    "fsync_dir",
    "MANIFEST",
    "DATA",
    "STAGING",
]

MANIFEST = "manifest.json"
DATA = "data"
STAGING = "staging"


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
        """Take the lock, waiting up to ``timeout`` seconds; else StoreLockedError."""
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
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
                        "wait for it to finish or retry with a lock timeout",
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
        self.stage_dir = root / STAGING / uuid.uuid4().hex[:12]
        self._staged: list[tuple[str, Path]] = []
        self._retired: list[str] = []

    @property
    def tables(self) -> dict[str, list[dict[str, Any]]]:
        """The manifest's segment lists, to edit in place."""
        return self.data["tables"]  # type: ignore[no-any-return]

    def stage(self, table: str, t: pa.Table, id_column: str | None) -> dict[str, Any]:
        """Write ``t`` as a new segment of ``table``; returns its manifest entry."""
        self.stage_dir.mkdir(parents=True, exist_ok=True)
        name = f"{self.version:08d}-{uuid.uuid4().hex[:8]}.parquet"
        path = self.stage_dir / f"{table}-{name}"
        pq.write_table(t, path, compression="zstd", row_group_size=1 << 17)
        _fsync_file(path)
        self._staged.append((table, path))
        seg: dict[str, Any] = {"file": f"{DATA}/{table}/{name}", "rows": t.num_rows}
        if id_column is not None and t.num_rows:
            ids = t.column(id_column)
            seg["min_id"] = int(pc.min(ids).as_py())
            seg["max_id"] = int(pc.max(ids).as_py())
        return seg

    def retire(self, files: list[str]) -> None:
        """Mark segments as replaced: kept for older readers, removed later."""
        self._retired.extend(files)

    def publish(self, **fields: Any) -> int:
        """Move the staged segments into place and swap the manifest; returns the version."""
        for table, path in self._staged:
            os.rename(path, self.root / DATA / table / path.name.split("-", 1)[1])
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
        return self.version


def cleanup(
    root: Path, manifest: dict[str, Any], tables: tuple[str, ...], retain_seconds: float
) -> int:
    """Remove what no manifest needs: staging leftovers, orphans, expired retired files.

    Must run with the write lock held. Returns the number of segments removed.
    """
    staging = root / STAGING
    if staging.exists():
        for txn in staging.iterdir():
            if txn.is_dir():
                for f in txn.iterdir():
                    f.unlink(missing_ok=True)
                txn.rmdir()
            else:
                txn.unlink(missing_ok=True)
    for tmp in root.glob(f".{MANIFEST}.*.tmp"):
        tmp.unlink(missing_ok=True)
    live = {s["file"] for t in tables for s in manifest["tables"][t]}
    retired = {r["file"]: float(r["since"]) for r in manifest.get("retired", [])}
    now = time.time()
    expired = {f for f, since in retired.items() if now - since > retain_seconds}
    removed = 0
    for t in tables:
        folder = root / DATA / t
        folder.mkdir(parents=True, exist_ok=True)
        for f in folder.iterdir():
            rel = f"{DATA}/{t}/{f.name}"
            if rel in live or (rel in retired and rel not in expired):
                continue
            f.unlink(missing_ok=True)
            removed += 1
    if expired:
        data = dict(manifest)
        data["retired"] = [r for r in data["retired"] if r["file"] not in expired]
        write_manifest(root, data)  # same version: nothing a reader sees changes
    return removed
