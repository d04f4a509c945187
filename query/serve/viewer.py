"""What the web page draws of a shape: its balls, contact graph and surface, as JSON.

:func:`decomposition_payload` turns a :class:`~shapedb.mdbd.decomposition.Decomposition` into the
balls and edges the 3-D view draws; :func:`surface_payload` turns a geometry into a
triangle soup or a point set small enough to send (at most ``max_faces`` faces or
``max_points`` points, a seeded random subset beyond); :func:`stored_surface` reads a
stored shape's source file again when it is still there. Coordinates are model units
rounded to 6 significant digits, so the payloads are plain JSON lists.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import NotFoundError, ShapeDBError

if TYPE_CHECKING:
    from query.database import Database

__all__ = [
    "decomposition_payload",
    "record_payload",
    "stored_record",
    "stored_surface",
    "surface_payload",
]

log = logging.getLogger(__name__)

MAX_FACES = 40_000
MAX_POINTS = 30_000
_IMPLICIT_RESOLUTION = 48


#: The columns of ``shapes`` a record is rebuilt from here: all but the feature vectors,
#: which are most of a row and which the page never shows.
_RECORD_COLUMNS = [
    "id",
    "name",
    "label",
    "metadata",
    "representation",
    "source",
    "content_hash",
    "config",
    "n_balls",
    "n_edges",
    "spacing",
    "bounds",
    "frame",
    "sampling",
    "timings",
    "build_seconds",
    "created_at",
]


def stored_record(db: Database, sid: int) -> Any:
    """A stored shape as ``db.get`` returns it, but read without its feature vectors.

    Parameters
    ----------
    db : shapedb.Database
    sid : int
        Stored shape id.

    Returns
    -------
    ShapeRecord
        With its decomposition; ``feature`` is empty and ``view_feature`` None.

    Raises
    ------
    NotFoundError
        No shape with this id.
    """
    from shapedb.store.schema import record_from_rows

    table = db.store.shapes(_RECORD_COLUMNS, ids=[int(sid)])
    if table.num_rows == 0:
        raise NotFoundError("no shape with this id", source=sid)
    row = table.to_pylist()[0]
    row["feature"], row["view_feature"] = (), None
    return record_from_rows(row, db.store.balls(ids=[int(sid)]), db.store.edges(ids=[int(sid)]))


def _rounded(a: NDArray[Any]) -> list[Any]:
    return np.asarray(a, np.float64).round(6).tolist()  # type: ignore[no-any-return]


def decomposition_payload(decomposition: Any) -> dict[str, Any]:
    """The balls and contact edges of a decomposition.

    Parameters
    ----------
    decomposition : Decomposition or ContactGraph
        Anything with ``centers`` (n, 3), ``radii`` (n,) and ``edges`` (m, 2).

    Returns
    -------
    dict
        ``{"centers": (n, 3) list, "radii": (n,) list, "edges": (m, 2) list,
        "bounds": [[xmin, ymin, zmin], [xmax, ymax, zmax]]}``; the bounds are the
        source's when known, else the balls'.
    """
    c = np.asarray(decomposition.centers, np.float64).reshape(-1, 3)
    r = np.asarray(decomposition.radii, np.float64).ravel()
    e = np.asarray(decomposition.edges, np.int64).reshape(-1, 2)
    bounds = getattr(decomposition, "bounds", None)
    if bounds is None or np.asarray(bounds).size != 6:
        bounds = (
            np.stack([(c - r[:, None]).min(0), (c + r[:, None]).max(0)])
            if len(r)
            else np.zeros((2, 3))
        )
    return {
        "centers": _rounded(c),
        "radii": _rounded(r),
        "edges": e.tolist(),
        "bounds": _rounded(np.asarray(bounds, np.float64).reshape(2, 3)),
    }


def record_payload(record: Any) -> dict[str, Any]:
    """A stored shape for the page: identity, sizes, balls and edges.

    Parameters
    ----------
    record : ShapeRecord
        As returned by ``db.get(id)``.

    Returns
    -------
    dict
        ``{"id", "name", "label", "representation", "metadata", "source",
        "n_balls", "n_edges", "spacing", "created_at"}`` plus the keys of
        :func:`decomposition_payload`.
    """
    d = record.decomposition
    return {
        "id": record.id,
        "name": record.name,
        "label": record.label,
        "representation": record.representation,
        "metadata": dict(record.metadata or {}),
        "source": record.source,
        "n_balls": int(d.n_balls),
        "n_edges": len(d.edges),
        "spacing": float(d.spacing),
        "created_at": record.created_at.isoformat() if record.created_at else None,
        **decomposition_payload(d),
    }


def surface_payload(
    geometry: Any, *, max_faces: int = MAX_FACES, max_points: int = MAX_POINTS
) -> dict[str, Any]:
    """A geometry's surface as a triangle mesh or a point set, capped in size.

    Parameters
    ----------
    geometry : TriangleMesh, PointCloud, Implicit or other Geometry, or None
    max_faces, max_points : int
        Beyond these a seeded random subset is sent (``"subsampled": true``).

    Returns
    -------
    dict
        ``{"kind": "mesh", "vertices": (v, 3), "faces": (f, 3)}``,
        ``{"kind": "points", "points": (p, 3)}`` or ``{"kind": "none"}``; implicit
        solids are meshed by marching cubes on a coarse grid.
    """
    if geometry is None:
        return {"kind": "none"}
    rng = np.random.default_rng(0)
    if hasattr(geometry, "faces") and hasattr(geometry, "vertices"):
        v = np.asarray(geometry.vertices, np.float64)
        f = np.asarray(geometry.faces, np.int64)
        sub = len(f) > max_faces
        if sub:
            f = np.sort(rng.choice(len(f), max_faces, replace=False))
            f = np.asarray(geometry.faces, np.int64)[f]
        used, f = np.unique(f, return_inverse=True)
        return {
            "kind": "mesh",
            "vertices": _rounded(v[used]),
            "faces": f.reshape(-1, 3).tolist(),
            "subsampled": bool(sub),
        }
    if hasattr(geometry, "points"):
        p = np.asarray(geometry.points, np.float64)
        sub = len(p) > max_points
        if sub:
            p = p[np.sort(rng.choice(len(p), max_points, replace=False))]
        return {"kind": "points", "points": _rounded(p), "subsampled": bool(sub)}
    if hasattr(geometry, "grid_sdf"):
        try:
            from shapedb.examples import to_mesh

            m = to_mesh(geometry, resolution=_IMPLICIT_RESOLUTION)
        except (ImportError, ShapeDBError, ValueError, RuntimeError):
            log.debug("no surface for %r", geometry, exc_info=True)
            return {"kind": "none"}
        return surface_payload(m, max_faces=max_faces, max_points=max_points)
    return {"kind": "none"}


def stored_surface(db: Database, record: Any) -> dict[str, Any]:
    """The surface of a stored shape, read again from its source file if it is still there.

    Parameters
    ----------
    db : shapedb.Database
    record : ShapeRecord

    Returns
    -------
    dict
        As :func:`surface_payload`; ``{"kind": "none"}`` for in-memory shapes, for
        sources that are only a file name (uploads), and for sources that are gone
        or no longer load.
    """
    source = record.source
    # a relative source is a name only (an uploaded model): never a file of the server's
    if not source or not Path(source).is_absolute() or not Path(source).is_file():
        return {"kind": "none"}
    try:
        geometry = db.load(source)
    except ShapeDBError as exc:
        log.info("no surface for shape %s: %s", record.id, exc)
        return {"kind": "none"}
    return surface_payload(geometry)
