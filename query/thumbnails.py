"""Thumbnails of stored shapes, drawn when they are committed and kept beside the store.

A thumbnail is a small PNG of a shape's MDBD balls as shaded spheres, seen from the
3-D view's starting camera (elevation 20°, azimuth -60°, z up) and scaled to fill the
picture. It is drawn by a small z-buffered sphere rasteriser in numpy and written with
:mod:`zlib` (no plotting library: a few milliseconds a shape), so
:meth:`query.database.Database.commit` draws the thumbnails of the shapes it commits
(:func:`draw_committed`) and the page shows every result at once. A shape without one
(a store made before, or a failed drawing) gets it at its first request
(:func:`thumbnail`).

Files are ``<store>/thumbnails/<id // 1000>/<id>-<key>.png`` (a folder per thousand ids,
so finding a shape's older files reads one small folder at any store size) where ``key``
hashes the record's content hash and build time: a shape rebuilt under the same id
(``ingest --force``) gets a new file. A commit of more than :data:`DRAWN_AT_COMMIT`
shapes (a bulk load; an ingest commits 32 at a time) draws none: the page draws each at
its first view. They are written to a temporary name and renamed, so a reader never sees
half a PNG; the folder is derived state, safe to delete, and never part of the Parquet
tables.
"""

from __future__ import annotations

import hashlib
import logging
import os
import struct
import tempfile
import zlib
from collections.abc import Iterable
from datetime import timezone
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "THUMBNAIL_DIR",
    "DRAWN_AT_COMMIT",
    "draw_committed",
    "draw_thumbnail",
    "render_balls",
    "thumbnail",
    "thumbnail_path",
]

log = logging.getLogger(__name__)

THUMBNAIL_DIR = "thumbnails"
#: A commit draws its shapes' thumbnails only up to this many shapes: at about 55 ms a
#: shape (real CAPOD packings of ~480 balls), a bulk commit of 1,000 would spend 55 s here.
DRAWN_AT_COMMIT = 64
_PER_FOLDER = 1000
#: Side of a thumbnail, pixels.
SIZE = 192
#: Drawing style, part of every file's key: a new style draws the thumbnails again.
_STYLE = "spheres-1"
_SUPERSAMPLE = 2  # pixels drawn per thumbnail pixel and axis (antialiasing)
_MARGIN = 0.04  # empty border, fraction of the side
_BALL = np.array([0x4C, 0x9B, 0xD6]) / 255.0  # the balls' colour in the page's 3-D view
# the camera of the 3-D view's start (toward the viewer), its right and up, z up
_TOWARD = np.array([0.47, -0.814, 0.342])
_RIGHT = np.array([0.866, 0.5, 0.0])
_UP = np.cross(_TOWARD, _RIGHT)
_LIGHT = np.array([-0.35, 0.55, 0.76])  # in camera axes (right, up, toward): upper left


def thumbnail_path(root: str | os.PathLike[str], record: Any) -> Path:
    """Where the thumbnail of ``record`` (a ShapeRecord with its id) lives in store ``root``."""
    made = record.created_at
    made = made.replace(tzinfo=timezone.utc) if made.tzinfo is None else made
    stamp = f"{_STYLE}\0{record.content_hash}\0{made.astimezone(timezone.utc).isoformat()}"
    key = hashlib.sha256(stamp.encode()).hexdigest()[:12]
    return _folder(root, int(record.id)) / f"{int(record.id)}-{key}.png"


def _folder(root: str | os.PathLike[str], sid: int) -> Path:
    """The folder of the thumbnails of shape ``sid``: one per thousand ids."""
    return Path(root) / THUMBNAIL_DIR / f"{sid // _PER_FOLDER:05d}"


def render_balls(centers: ArrayLike, radii: ArrayLike, size: int = SIZE) -> NDArray[np.uint8]:
    """Balls as shaded spheres on white, orthographic, scaled to fill the picture.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, model units, z up.
    radii : (n,) float
        Ball radii, model units.
    size : int
        Side of the picture, pixels.

    Returns
    -------
    (size, size, 3) uint8
        RGB rows from the top; all white when there are no balls.
    """
    n = size * _SUPERSAMPLE
    image = np.ones((n, n, 3))
    depth = np.full((n, n), -np.inf)
    c = np.asarray(centers, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).ravel()
    if len(r):
        cam = c @ np.stack([_RIGHT, _UP, _TOWARD]).T
        lo, hi = (cam[:, :2] - r[:, None]).min(0), (cam[:, :2] + r[:, None]).max(0)
        scale = n * (1 - 2 * _MARGIN) / (float((hi - lo).max()) or 1.0)
        xy = (cam[:, :2] - (lo + hi) / 2) * scale + n / 2
        for i in np.argsort(-cam[:, 2]):  # nearest first: most hidden balls cost little
            _splat(image, depth, xy[i], cam[i, 2] * scale, r[i] * scale)
    small = image.reshape(size, _SUPERSAMPLE, size, _SUPERSAMPLE, 3).mean(axis=(1, 3))
    return np.asarray(np.round(small[::-1] * 255), np.uint8)  # rows from the top


def _splat(
    image: NDArray[np.float64], depth: NDArray[np.float64], xy: Any, z: float, r: float
) -> None:
    """Draw one sphere (pixel units, y up) where it is nearer than what is drawn."""
    n = depth.shape[0]
    x0, x1 = max(int(xy[0] - r), 0), min(int(xy[0] + r) + 2, n)
    y0, y1 = max(int(xy[1] - r), 0), min(int(xy[1] + r) + 2, n)
    if x0 >= x1 or y0 >= y1:
        return
    dx = (np.arange(x0, x1) + 0.5 - xy[0]) / r
    dy = (np.arange(y0, y1) + 0.5 - xy[1]) / r
    d2 = dy[:, None] ** 2 + dx[None, :] ** 2
    dz = np.sqrt(np.clip(1.0 - d2, 0.0, None))
    front = z + r * dz
    take = (d2 < 1.0) & (front > depth[y0:y1, x0:x1])
    if not take.any():
        return
    lambert = np.clip(_LIGHT[0] * dx[None, :] + _LIGHT[1] * dy[:, None] + _LIGHT[2] * dz, 0, 1)
    shine = np.clip(lambert * 2 * dz - _LIGHT[2], 0, 1) ** 24  # reflection toward the viewer
    rgb = _BALL * (0.35 + 0.65 * lambert)[..., None] + 0.35 * shine[..., None]
    depth[y0:y1, x0:x1][take] = front[take]
    image[y0:y1, x0:x1][take] = np.clip(rgb[take], 0, 1)


def _png(rgb: NDArray[np.uint8]) -> bytes:
    """An RGB picture (rows from the top) as the bytes of a PNG file."""
    h, w, _ = rgb.shape
    rows = np.concatenate([np.zeros((h, 1), np.uint8), rgb.reshape(h, 3 * w)], axis=1)

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8-bit RGB
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(rows.tobytes(), 6))
        + chunk(b"IEND", b"")
    )


def draw_thumbnail(record: Any, out: str | os.PathLike[str]) -> Path:
    """Draw ``record``'s balls into the PNG ``out``, written atomically.

    Parameters
    ----------
    record : ShapeRecord
        With its decomposition.
    out : path
        Written to a temporary file beside it, then renamed.

    Returns
    -------
    Path
        ``out``.
    """
    d = record.decomposition
    data = _png(render_balls(d.centers, d.radii))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".thumb-", suffix=".png", dir=out.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out


def _replace(root: str | os.PathLike[str], record: Any) -> Path:
    """Draw ``record``'s thumbnail unless it is there, removing older builds of its id."""
    path = thumbnail_path(root, record)
    if path.is_file():
        return path
    for stale in path.parent.glob(f"{int(record.id)}-*.png"):
        stale.unlink(missing_ok=True)
    log.debug("drawing thumbnail of shape %s", record.id)
    return draw_thumbnail(record, path)


def draw_committed(
    root: str | os.PathLike[str], records: Iterable[Any], deleted: Iterable[int] = ()
) -> None:
    """Draw the thumbnails of just committed records and drop those of deleted ids.

    Parameters
    ----------
    root : path
        The store's folder.
    records : iterable of ShapeRecord
        Committed, with their ids and decompositions.
    deleted : iterable of int
        Ids removed by the commit.

    Raises
    ------
    OSError
        The folder cannot be written (the caller logs it: thumbnails are derived state).
    """
    for sid in deleted:
        for stale in _folder(root, int(sid)).glob(f"{int(sid)}-*.png"):
            stale.unlink(missing_ok=True)
    records = list(records)
    if len(records) > DRAWN_AT_COMMIT:
        log.info("%d shapes committed: their thumbnails are drawn at first view", len(records))
        return
    for record in records:
        _replace(root, record)


def thumbnail(root: str | os.PathLike[str], record: Any) -> Path:
    """The thumbnail of a stored record, drawn now if it is not there yet.

    Parameters
    ----------
    root : path
        The store's folder.
    record : ShapeRecord
        A stored shape with its id and decomposition.

    Returns
    -------
    Path
        The PNG under ``<store>/thumbnails/``.
    """
    return _replace(root, record)
