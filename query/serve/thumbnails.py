"""Thumbnails of stored shapes, drawn once and kept beside the store's data.

A thumbnail is a small PNG of a shape's MDBD balls (and its source surface when the
source file is still there), drawn with :func:`query.render.draw_model` on a
matplotlib ``Figure`` (no pyplot: no global state). It is written lazily, at its
first request, to ``<store>/thumbnails/<id>-<key>.png`` where ``key`` hashes the
record's content hash and build time: a shape rebuilt under the same id (``ingest
--force``) gets a new file. Files are written to a temporary name and renamed, so a
reader never sees half a PNG; the folder is derived state, safe to delete, and
never part of the Parquet tables.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from shapedb.errors import require

if TYPE_CHECKING:
    from query.database import Database

__all__ = ["THUMBNAIL_DIR", "thumbnail", "thumbnail_path", "draw_thumbnail"]

log = logging.getLogger(__name__)

THUMBNAIL_DIR = "thumbnails"
#: Side of a thumbnail, pixels.
SIZE = 192
_DRAW = threading.Lock()  # matplotlib's 3-D artists are not thread-safe


def thumbnail_path(root: str | os.PathLike[str], record: Any) -> Path:
    """Where the thumbnail of ``record`` (a ShapeRecord with its id) lives in store ``root``."""
    stamp = f"{record.content_hash}\0{record.created_at.isoformat()}"
    key = hashlib.sha256(stamp.encode()).hexdigest()[:12]
    return Path(root) / THUMBNAIL_DIR / f"{int(record.id)}-{key}.png"


def draw_thumbnail(record: Any, out: str | os.PathLike[str], *, geometry: Any = None) -> Path:
    """Draw ``record``'s balls (over ``geometry``'s surface, if given) into the PNG ``out``.

    Parameters
    ----------
    record : ShapeRecord
    out : path
        Written atomically (temporary file, then rename).
    geometry : Geometry, optional
        The shape's surface, drawn lightly under the balls.

    Returns
    -------
    Path
        ``out``.
    """
    require("matplotlib", extra="plot", feature="thumbnails")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from query.render import draw_model

    d = record.decomposition
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    dpi = 64
    with _DRAW:
        fig = Figure(figsize=(SIZE / dpi, SIZE / dpi), dpi=dpi)
        FigureCanvasAgg(fig)
        ax: Any = fig.add_axes((0.0, 0.0, 1.0, 1.0), projection="3d")
        ax.view_init(20.0, -60.0)
        draw_model(ax, d.centers, d.radii, geometry=geometry, max_balls=256)
        fd, tmp = tempfile.mkstemp(prefix=".thumb-", suffix=".png", dir=out.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                fig.savefig(fh, format="png", dpi=dpi)
            os.replace(tmp, out)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    return out


def thumbnail(db: Database, id_or_name: int | str, *, surface: bool = True) -> Path:
    """The thumbnail of a stored shape, drawn now if it is not cached yet.

    Parameters
    ----------
    db : shapedb.Database
    id_or_name : int or str
    surface : bool
        Draw the source surface under the balls when the source file is still there.

    Returns
    -------
    Path
        The PNG under ``<store>/thumbnails/``.

    Raises
    ------
    NotFoundError
        No such shape.
    """
    from query.serve.viewer import stored_record

    sid = id_or_name if isinstance(id_or_name, int) else db.store.resolve(id_or_name)
    record = stored_record(db, sid)
    path = thumbnail_path(db.path, record)
    if path.is_file():
        return path
    geometry = None
    if surface and record.source and Path(record.source).is_file():
        try:
            geometry = db.load(record.source)
        except Exception:  # noqa: BLE001 - a thumbnail without its surface is still useful
            log.debug("cannot reload %s for its thumbnail", record.source, exc_info=True)
    for stale in path.parent.glob(f"{int(record.id)}-*.png"):
        stale.unlink(missing_ok=True)  # an older build of the same id
    log.debug("drawing thumbnail of shape %s", record.id)
    return draw_thumbnail(record, path, geometry=geometry)
