"""A store's ``shapes`` columns, read segment by segment as numpy blocks.

The derived indexes read whole list columns of a store of up to 10^6 shapes: the field
vector index (:mod:`query.search.field_index`) the ``field_vector`` column (950 floats
each at the defaults), the feature index (:mod:`query.search.index_segments`) the
``feature`` and ``view_feature`` columns. As Python lists that is unusable, and as one
Arrow table beside its numpy copy it costs twice the matrix. Here the Parquet segments
that one manifest lists are scanned in record batches of :data:`READ_BATCH` rows
(:func:`batches`), each list column flattened to numpy (:func:`list_rows`:
``pyarrow.compute.list_flatten`` of its non-null rows) and handed on, so the caller's
float32 matrix is the only large allocation; :func:`read_rows` also scales the field
vectors (:meth:`query.search.field_fusion.FieldFusion.scaled`).

A snapshot (:func:`snapshot`) is one read of the manifest: its version and its segments
of the ``shapes`` table. Segment files are immutable, so an index that records which
ones it has read can later read only the segments it has not (:func:`read_rows` with a
subset of the snapshot's segments); a segment a deletion or compaction wrote names the
segments it copies its rows from (:func:`copied_from`).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
import pyarrow.parquet as pq
from numpy.typing import NDArray

from query.search.field_fusion import FIELD, FieldFusion
from shapedb.errors import StoreError
from shapedb.store.manifest import check_sizes, read_manifest, unreadable
from shapedb.store.schema import shapes_schema
from shapedb.store.transaction import REPLACES

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "READ_BATCH",
    "Snapshot",
    "snapshot",
    "batches",
    "list_rows",
    "copied_from",
    "read_rows",
    "read_ids",
    "consistent",
]

#: Rows per record batch: the float64 scaling temporary of a batch stays ~30 MB at d = 950.
READ_BATCH = 4096
_ATTEMPTS = 5
_PARQUET = ds.ParquetFileFormat(
    default_fragment_scan_options=ds.ParquetFragmentScanOptions(page_checksum_verification=True)
)
T = TypeVar("T")


@dataclass(frozen=True)
class Snapshot:
    """One read of a store's manifest: its version and its ``shapes`` segments."""

    root: Path
    version: int
    dim: int
    segments: tuple[dict[str, Any], ...]

    @property
    def files(self) -> tuple[str, ...]:
        """The segments' file names (relative to the store), in manifest order."""
        return tuple(str(s["file"]) for s in self.segments)

    def only(self, files: set[str] | frozenset[str]) -> Snapshot:
        """The same snapshot restricted to the segments whose file is in ``files``."""
        kept = tuple(s for s in self.segments if str(s["file"]) in files)
        return Snapshot(self.root, self.version, self.dim, kept)

    @property
    def rows(self) -> int:
        """Rows of its segments (with and without field vectors), from the manifest."""
        return sum(int(s.get("rows", 0)) for s in self.segments)


def snapshot(db: StoreHandle) -> Snapshot:
    """The manifest of ``db``'s store as it is now (StoreError when unreadable)."""
    root = Path(db.store.path)
    data = read_manifest(root)
    segments = tuple(dict(s) for s in data["tables"]["shapes"])
    return Snapshot(root, int(data["version"]), int(data["dim"]), segments)


def consistent(db: StoreHandle, read: Callable[[Snapshot], T]) -> T:
    """``read(snapshot(db))``, again from a fresh manifest when a writer retired one of
    its segments meanwhile (FileNotFoundError); StoreError after a few attempts."""
    for attempt in range(_ATTEMPTS):
        try:
            return read(snapshot(db))
        except FileNotFoundError:
            time.sleep(0.01 * (attempt + 1))
    raise StoreError("cannot read a consistent snapshot of shapes", source=str(db.store.path))


def batches(snap: Snapshot, columns: list[str]) -> Iterator[pa.RecordBatch]:
    """The snapshot's rows of ``columns``, in record batches of at most :data:`READ_BATCH`
    rows, segment after segment in the manifest's order (older segments' missing columns
    as nulls); StoreError when a segment is damaged, FileNotFoundError when one is gone."""
    if not snap.segments:
        return
    segs = list(snap.segments)
    check_sizes(snap.root, segs)
    try:
        paths = [str(snap.root / s["file"]) for s in segs]
        dataset = ds.dataset(paths, schema=shapes_schema(snap.dim), format=_PARQUET)
        yield from dataset.to_batches(
            columns=columns, batch_size=READ_BATCH, batch_readahead=1, fragment_readahead=1
        )
    except FileNotFoundError:
        raise
    except (pa.ArrowException, OSError) as exc:
        raise unreadable(snap.root, segs, exc) from exc


def read_ids(snap: Snapshot) -> NDArray[np.int64]:
    """(n,) ids of every row of the snapshot's segments, in segment order."""
    parts = [b.column(0).to_numpy() for b in batches(snap, ["id"])]
    return np.concatenate(parts).astype(np.int64) if parts else np.empty(0, np.int64)


def read_rows(
    snap: Snapshot, fusion: FieldFusion, dim: int
) -> Iterator[tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float32]]]:
    """The snapshot's rows, batch by batch: ``(ids, with_vector, scaled)``.

    Parameters
    ----------
    snap : Snapshot
        The segments to read.
    fusion : FieldFusion
        Scales the field vectors (:meth:`FieldFusion.scaled`).
    dim : int
        Length of a stored field vector.

    Yields
    ------
    ids : (b,) int64
        Every row of the batch.
    with_vector : (m,) int64
        The ids of its rows that have a field vector.
    scaled : (m, d') float32
        Their scaled field vectors.

    Raises
    ------
    StoreError
        A segment is damaged, or a field vector is not ``dim`` long.
    """
    for batch in batches(snap, ["id", FIELD]):
        ids = batch.column(0).to_numpy().astype(np.int64)
        valid, vectors = list_rows(batch.column(1), dim, snap.root)
        yield ids, ids[valid], fusion.scaled(vectors)


def list_rows(
    column: pa.Array, dim: int, source: Path | str
) -> tuple[NDArray[np.bool_], NDArray[Any]]:
    """``(valid, rows)`` of a list column: (b,) bool, whether each row is set, and the
    (valid.sum(), dim) numbers of those that are (as stored: float32 for float32 lists).

    Raises
    ------
    StoreError
        A set row is not ``dim`` long (``source`` names the store).
    """
    valid = np.asarray(column.is_valid().to_numpy(zero_copy_only=False), bool)
    m = int(valid.sum())
    flat = pc.list_flatten(column).to_numpy(zero_copy_only=False) if m else np.zeros(0)
    if flat.size != m * dim:
        raise StoreError(
            f"rows of {flat.size / max(m, 1):g} values, expected {dim}", source=str(source)
        )
    return valid, flat.reshape(m, dim)


def copied_from(snap: Snapshot, file: str) -> tuple[str, ...]:
    """The segments whose rows the segment ``file`` copies (its ``shapedb.replaces``
    metadata, written by a deletion or a compaction); () for a segment of new rows."""
    try:
        meta = pq.read_schema(snap.root / file).metadata or {}
    except (pa.ArrowException, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise StoreError(f"cannot read segment {file}: {exc}", source=str(snap.root)) from exc
    return tuple(str(f) for f in json.loads(meta[REPLACES])) if REPLACES in meta else ()
