"""The crash-safe store: Parquet segments, one manifest, checks and repair.

:class:`Store` commits records atomically (staging, journal, manifest swap); the schema
module holds the versioned Arrow schemas and record types; :func:`check` verifies every
segment against its checksum and :func:`repair` rebuilds a lost manifest.
"""

from __future__ import annotations

from shapedb.store.integrity import CheckReport, RepairReport, check, repair
from shapedb.store.schema import Failure, ShapeRecord
from shapedb.store.store import CommitResult, Store

__all__ = [
    "Store",
    "CommitResult",
    "ShapeRecord",
    "Failure",
    "check",
    "repair",
    "CheckReport",
    "RepairReport",
]
