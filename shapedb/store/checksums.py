"""Are a segment's bytes the ones committed? Checked against the manifest's sha256.

Every commit records each new segment's size and sha256 in the manifest
(:meth:`shapedb.store.transaction.Transaction.stage`). :func:`verify_segments`
compares the files a reader is about to hand to an engine that does not verify Parquet
page checksums itself (DuckDB) with those records, and caches each verdict by the
file's path, size, mtime, ctime and inode, so an unchanged file is hashed once per
process and any later write to it (which moves its ctime) is hashed again.
"""

from __future__ import annotations

import collections
import threading
import time
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq

from shapedb.errors import StoreError
from shapedb.store.manifest import check_sizes, read_manifest, repair_hint
from shapedb.store.transaction import file_digest

__all__ = ["segment_fault", "verify_segments", "verified_files"]

_CACHE_SIZE = 65536
"""Verdicts kept (one per segment file; far more than a store holds segments)."""

_verified: collections.OrderedDict[tuple[str, int, int, int, int], str] = collections.OrderedDict()
_guard = threading.Lock()


def segment_fault(root: Path, seg: dict[str, Any]) -> str | None:
    """Why a listed segment's bytes are not the committed ones, or None.

    A segment with a recorded sha256 is hashed and compared; one without (stores
    written before checksums were recorded) is read with Parquet page checksums.

    Returns
    -------
    str or None
        ``"missing"``, ``"damaged: ..."`` or ``"unreadable (...)"``; None when intact.
    """
    path = root / seg["file"]
    if not path.is_file():
        return "missing"
    if "sha256" in seg:
        size, digest = file_digest(path)
        if size != int(seg.get("bytes", size)):
            return f"damaged: {size} bytes, the manifest records {seg['bytes']}"
        if digest != seg["sha256"]:
            return "damaged: checksum differs from the one recorded at commit"
        return None
    try:
        pq.read_table(path, page_checksum_verification=True)
    except Exception as exc:  # any unreadable file
        return f"unreadable ({type(exc).__name__}: {' '.join(str(exc).split())[:120]})"
    return None


def verify_segments(root: Path, segments: list[dict[str, Any]]) -> None:
    """Refuse to serve a segment whose bytes differ from the committed ones.

    Parameters
    ----------
    root : Path
        The store directory.
    segments : list of dict
        Manifest entries (``file``, and ``bytes`` / ``sha256`` when recorded).

    Raises
    ------
    FileNotFoundError
        A file is missing (a writer may have just retired it: re-read the manifest).
    StoreError
        A file is damaged; the one-line message names the segment and how to repair.
    """
    for seg in segments:
        path = root / seg["file"]
        st = path.stat()
        key = (str(path), st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino)
        want = str(seg.get("sha256", ""))
        with _guard:
            if _verified.get(key) == want:
                _verified.move_to_end(key)
                continue
        fault = segment_fault(root, seg)
        if fault == "missing":
            raise FileNotFoundError(str(path))
        if fault is not None:
            raise StoreError(
                f"segment {seg['file']} is {fault}; {repair_hint(root)}", source=str(root)
            )
        with _guard:
            _verified[key] = want
            while len(_verified) > _CACHE_SIZE:
                _verified.popitem(last=False)


def verified_files(root: Path, tables: tuple[str, ...]) -> dict[str, list[str]]:
    """Absolute paths of the committed segments of ``tables``, from one manifest
    version, each verified by :func:`verify_segments`.

    Raises
    ------
    StoreError
        A listed segment is missing (after re-reading the manifest) or damaged.
    """
    for attempt in range(5):
        manifest = read_manifest(root)
        try:
            for table in tables:
                verify_segments(root, manifest["tables"][table])
        except FileNotFoundError:  # a writer retired it after we read the manifest
            time.sleep(0.01 * (attempt + 1))
            continue
        return {t: [str(root / s["file"]) for s in manifest["tables"][t]] for t in tables}
    manifest = read_manifest(root)
    for table in tables:
        check_sizes(root, manifest["tables"][table], missing=True)
    raise StoreError("cannot read a consistent snapshot of the store", source=str(root))
