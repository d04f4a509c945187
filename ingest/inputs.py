"""What to ingest: inputs expanded into files and shapes, and their content hashes.

:func:`expand` turns paths, folders and in-memory shapes into a flat list of inputs
(folders walked recursively in sorted order, symlinked folders followed once);
:func:`content_hash` and :func:`geometry_hash` identify an input by its content, so a
re-run skips what a store already holds.
"""

from __future__ import annotations

import hashlib
import logging
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ingest.loaders import SUPPORTED, detect_format
from shapedb.errors import ShapeDBError
from shapedb.geometry.base import Geometry
from shapedb.store.schema import safe_text

__all__ = ["expand", "content_hash", "geometry_hash", "COMPANION_SUFFIXES"]

log = logging.getLogger(__name__)

COMPANION_SUFFIXES = frozenset(
    {
        ".mtl",
        ".png",
        ".jpg",
        ".jpeg",
        ".bmp",
        ".tga",
        ".tif",
        ".tiff",
        ".gif",
        ".bin",
        ".txt",
        ".md",
        ".csv",
        ".json",
        ".cla",
        ".pdf",
        ".html",
        ".log",
        ".ini",
        ".yaml",
        ".yml",
        ".db",
        ".parquet",
    }
)
"""Files left out while walking a folder (materials, textures, docs, tables)."""


# ---------------------------------------------------------------- hashing
def content_hash(path: str | os.PathLike[str], *, as_: str | None = None) -> str:
    """sha256 of a file's bytes (followed by ``\\0as=<as_>`` when a representation is forced)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    if as_ is not None:
        h.update(f"\0as={as_}".encode())
    return h.hexdigest()


def geometry_hash(geometry: Geometry) -> str:
    """sha256 of an in-memory shape: its arrays, or its distance on a fixed lattice."""
    from shapedb.geometry.pointcloud import PointCloud

    h = hashlib.sha256(type(geometry).__qualname__.encode())
    # a cloud's given normals only: asking for ``normals`` would estimate them here, in
    # the model's frame, and its decomposition would then reuse them (PointCloud.transformed)
    normals = "_given_normals" if isinstance(geometry, PointCloud) else "normals"
    arrays = [
        getattr(geometry, a, None)
        for a in ("vertices", "faces", "points", normals, "occupancy", "origin", "pitch")
    ]
    arrays = [a for a in arrays if a is not None]
    if arrays:
        for a in arrays:
            arr = np.ascontiguousarray(np.asarray(a))
            h.update(str((arr.dtype.str, arr.shape)).encode())
            h.update(arr.tobytes())
    else:  # implicit and other functional shapes: sample the distance
        b = np.asarray(geometry.bounds, dtype=np.float64)
        h.update(b.tobytes())
        t = np.linspace(0.0, 1.0, 9)
        g = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
        pts = b[0] + g * (b[1] - b[0])
        h.update(np.round(np.asarray(geometry.signed_distance(pts)), 9).tobytes())
    return h.hexdigest()


# ---------------------------------------------------------------- inputs
def expand(
    inputs: Any, *, ignored: list[tuple[str, str]] | None = None
) -> Iterator[tuple[str, Path | Geometry, bool, str | None]]:
    """Yield ``(source, path_or_geometry, explicit, label)`` for files, folders and shapes.

    Inputs are paths, Geometry objects, ``(name, geometry)`` or
    ``(name, label, geometry)`` tuples, or a ``{name: geometry}`` mapping. Folders are
    walked recursively in sorted order; hidden files and folders, companion files
    (:data:`COMPANION_SUFFIXES`) and files of no supported type found there are left
    out, and appended to ``ignored`` as ``(path, why)`` when it is given. ``explicit``
    is False for files found by walking; ``label`` is set only by
    ``(name, label, geometry)``.
    """
    sink: list[tuple[str, str]] = [] if ignored is None else ignored
    if isinstance(inputs, (str, os.PathLike, Geometry)):
        inputs = [inputs]
    elif isinstance(inputs, Mapping):  # {name: geometry}
        inputs = list(inputs.items())
    for entry in inputs:
        if isinstance(entry, Geometry):
            yield (getattr(entry, "name", None) or "", entry, True, None)
        elif isinstance(entry, tuple) and entry and isinstance(entry[-1], Geometry):
            label = str(entry[1]) if len(entry) == 3 and entry[1] is not None else None
            yield (str(entry[0]), entry[-1], True, label)
        else:
            p = Path(entry).absolute()
            if p.is_dir():
                for q in _walk(p, sink):
                    yield (str(q), q, False, None)
            else:
                yield (str(p), p, True, None)


def _walk(top: Path, ignored: list[tuple[str, str]]) -> Iterator[Path]:
    """Files under ``top`` in sorted order, following symlinked folders, each folder once.

    Hidden entries, companion files and files of no supported type are left out and
    appended to ``ignored`` with the reason; so is a folder reached a second time (a
    symlink loop, or two links to one folder), and a folder that cannot be listed.
    """
    visited: set[tuple[int, int]] = set()

    def unreadable(exc: OSError) -> None:
        log.warning("cannot list %s: %s", safe_text(str(exc.filename)), exc.strerror)
        ignored.append((safe_text(str(exc.filename)), f"cannot list the folder: {exc.strerror}"))

    for root, dirs, files in os.walk(top, followlinks=True, onerror=unreadable):
        try:
            st = os.stat(root)
        except OSError:
            dirs[:] = []
            continue
        key = (st.st_dev, st.st_ino)
        if key in visited:
            log.warning(
                "skipping %s: this folder was already walked (symlink loop?)", safe_text(root)
            )
            ignored.append((safe_text(root), "folder already walked (a symlink loop?)"))
            dirs[:] = []
            continue
        visited.add(key)
        for d in sorted(d for d in dirs if d.startswith(".")):
            ignored.append((safe_text(os.path.join(root, d)), "hidden folder"))
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for f in sorted(files):
            q = Path(root) / f
            why = _why_ignored(q)
            if why is None:
                yield q
            else:
                ignored.append((safe_text(str(q)), why))


def _why_ignored(path: Path) -> str | None:
    """Why a file found by walking a folder is not ingested, or None when it is."""
    suffix = path.suffix.lower()
    if path.name.startswith("."):
        return "hidden file"
    if suffix in COMPANION_SUFFIXES:
        return f"companion file ({suffix})"
    if suffix in SUPPORTED:
        return None
    try:
        detect_format(path)  # a file that announces a supported format is read
    except ShapeDBError:
        return f"unsupported file type {suffix or '(no extension)'!r}"
    except OSError as exc:
        return f"unreadable: {exc.strerror or exc}"
    return None
