"""Ingest: read models of any format and add them to a shapedb store.

>>> import shapedb
>>> db = shapedb.connect("shapes.db")                   # doctest: +SKIP
>>> report = db.ingest(["models/"], label_from_folder=True)  # doctest: +SKIP

``db.ingest`` (:mod:`query.database`) calls :func:`ingest.pipeline.ingest`, which
reports one outcome for every input (stored, unchanged, failed or ignored) and shows
progress (:mod:`ingest.progress`). The loaders (:mod:`ingest.loaders`) check what
they read: PLY bodies against their headers (:mod:`ingest.ply`), and coordinates
(:mod:`ingest.shapes`).
"""

from __future__ import annotations

from ingest.labels import LabelEntry, LabelTable, folder_label, read_labels
from ingest.loaders import SUPPORTED, detect_format, load
from ingest.pipeline import IngestReport, build_record, content_hash, geometry_hash, ingest

__all__ = [
    "load",
    "detect_format",
    "SUPPORTED",
    "ingest",
    "IngestReport",
    "build_record",
    "content_hash",
    "geometry_hash",
    "read_labels",
    "folder_label",
    "LabelTable",
    "LabelEntry",
]
