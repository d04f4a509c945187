"""Pictures of models, their MDBD balls and matched parts (matplotlib, Agg, imported lazily).

* :func:`render_model` draws one model: its surface (mesh faces or points, light
  grey) and its balls (discs scaled to their radii, coloured by radius).
* :func:`render_matches` draws a query and its matches side by side, the query's
  part and each match's part highlighted as solid spheres, the other balls faint.

Both write a PNG and return its path. ``shapedb show MODEL --out x.png`` and
``shapedb match ... --out x.png`` call them.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.errors import QueryError, require

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["render_model", "render_matches", "render_part_matches", "draw_model"]

log = logging.getLogger(__name__)

_MAX_FACES = 30_000
_MAX_POINTS = 20_000
_QUERY_COLOUR = "#d62728"
_MATCH_COLOUR = "#1f77b4"


def _pyplot() -> Any:
    mpl = require("matplotlib", extra="plot", feature="rendering")
    mpl.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _surface(geometry: Any) -> tuple[NDArray[np.float64] | None, NDArray[np.int64] | None]:
    """(vertices or points, faces or None) of a mesh / point cloud, or (None, None)."""
    if geometry is None:
        return None, None
    if hasattr(geometry, "faces") and hasattr(geometry, "vertices"):
        return np.asarray(geometry.vertices, np.float64), np.asarray(geometry.faces, np.int64)
    if hasattr(geometry, "points"):
        return np.asarray(geometry.points, np.float64), None
    if getattr(geometry, "representation", None) == "implicit" or hasattr(geometry, "grid_sdf"):
        try:  # implicit solids (and complements): marching cubes, when scikit-image is there
            from shapedb.examples import to_mesh

            m = to_mesh(geometry, resolution=64)
            return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
        except ImportError:
            log.info("no surface drawn for %r: scikit-image is not installed", geometry)
    return None, None


def _sphere(c: NDArray[np.float64], r: float, n: int = 10) -> tuple[NDArray, NDArray, NDArray]:
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 2 * n), np.linspace(0, np.pi, n))
    return (
        c[0] + r * np.cos(u) * np.sin(v),
        c[1] + r * np.sin(u) * np.sin(v),
        c[2] + r * np.cos(v),
    )


def draw_model(
    ax: Any,
    centers: ArrayLike,
    radii: ArrayLike,
    *,
    geometry: Any = None,
    highlight: Sequence[int] | None = None,
    colour: str = _MATCH_COLOUR,
    title: str | None = None,
    max_balls: int = 512,
) -> None:
    """Draw one model on a 3-D matplotlib axes.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.Axes3D
    centers : (n, 3) float
    radii : (n,) float
    geometry : mesh, point cloud or implicit solid, optional
        Surface drawn lightly under the balls.
    highlight : sequence of int, optional
        Balls drawn as solid spheres in ``colour``; the others become faint dots.
    title : str, optional
    max_balls : int
        Draw at most this many (the largest) balls.
    """
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    c = np.asarray(centers, np.float64).reshape(-1, 3)
    r = np.asarray(radii, np.float64).ravel()
    verts, faces = _surface(geometry)
    if verts is not None and faces is not None:
        f = faces
        if len(f) > _MAX_FACES:
            f = f[np.random.default_rng(0).choice(len(f), _MAX_FACES, replace=False)]
        poly = Poly3DCollection(verts[f], facecolor=(0.6, 0.6, 0.6, 0.08), edgecolor="none")
        ax.add_collection3d(poly)
    elif verts is not None:
        p = verts
        if len(p) > _MAX_POINTS:
            p = p[np.random.default_rng(0).choice(len(p), _MAX_POINTS, replace=False)]
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=0.3, c="0.6", alpha=0.3, depthshade=False)
    lo = np.min(c - r[:, None], axis=0) if len(r) else np.zeros(3)
    hi = np.max(c + r[:, None], axis=0) if len(r) else np.ones(3)
    if verts is not None and len(verts):
        lo, hi = np.minimum(lo, verts.min(axis=0)), np.maximum(hi, verts.max(axis=0))
    span = float((hi - lo).max()) or 1.0
    keep = np.arange(min(len(r), max_balls))
    hl = np.zeros(len(r), bool)
    if highlight is not None:
        hl[np.asarray(list(highlight), np.int64)] = True
    # marker area in points^2 ~ (radius as a fraction of the view, times axes size)^2
    size = (r / span * 260.0) ** 2
    rest = keep[~hl[keep]]
    alpha = 0.15 if highlight is not None else 0.55
    if len(rest):
        ax.scatter(
            *c[rest].T,
            s=size[rest],
            c=r[rest],
            cmap="viridis",
            alpha=alpha,
            edgecolors="none",
            depthshade=False,
        )
    for i in np.flatnonzero(hl):
        ax.plot_surface(*_sphere(c[i], r[i]), color=colour, alpha=0.85, linewidth=0, shade=True)
    mid = 0.5 * (lo + hi)
    for setter, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid, strict=True):
        setter(m - 0.5 * span, m + 0.5 * span)
    ax.set_box_aspect((1, 1, 1))
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=9)


def _save(fig: Any, out: str | os.PathLike[str], plt: Any) -> Path:
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    log.info("wrote %s", path)
    return path


def render_model(
    decomposition: Any,
    out: str | os.PathLike[str],
    *,
    geometry: Any = None,
    highlight: Sequence[int] | None = None,
    title: str | None = None,
    view: tuple[float, float] = (20.0, -60.0),
) -> Path:
    """Draw a model with its MDBD balls into a PNG.

    Parameters
    ----------
    decomposition : Decomposition or ContactGraph
        The balls (``centers`` (n, 3), ``radii`` (n,)).
    out : path
        PNG to write.
    geometry : TriangleMesh, PointCloud, trimesh.Trimesh or Implicit, optional
        The surface, drawn lightly.
    highlight : sequence of int, optional
        Balls drawn as solid spheres.
    title : str, optional
    view : (elevation, azimuth) in degrees

    Returns
    -------
    Path
        ``out``.
    """
    plt = _pyplot()
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    ax.view_init(*view)
    n = len(decomposition.radii)
    draw_model(
        ax,
        decomposition.centers,
        decomposition.radii,
        geometry=geometry,
        highlight=highlight,
        colour=_QUERY_COLOUR,
        title=title or f"{n} balls",
    )
    return _save(fig, out, plt)


def render_matches(
    query: Any,
    matches: Sequence[Any],
    targets: Sequence[Any],
    out: str | os.PathLike[str],
    *,
    query_geometry: Any = None,
    target_geometries: Sequence[Any] | None = None,
    query_nodes: Sequence[int] | None = None,
    title: str | None = None,
    view: tuple[float, float] = (20.0, -60.0),
) -> Path:
    """Draw a query and its matches side by side, matched balls highlighted.

    Parameters
    ----------
    query : Decomposition or ContactGraph
        The query's balls.
    matches : sequence of PartMatch
        Best first; ``nodes`` are highlighted in the target, ``query_nodes`` of the
        first match (or ``query_nodes``) in the query.
    targets : sequence of Decomposition or ContactGraph
        The balls of each match's shape, in the order of ``matches``.
    out : path
        PNG to write.
    query_geometry, target_geometries : optional
        Surfaces (meshes, point clouds, implicit solids), drawn lightly.
    query_nodes : sequence of int, optional
        Query part; default ``matches[0].query_nodes``.
    title : str, optional
    view : (elevation, azimuth) in degrees

    Returns
    -------
    Path
        ``out``.
    """
    plt = _pyplot()
    n = 1 + len(matches)
    cols = min(n, 4)
    rows = int(np.ceil(n / cols))
    fig = plt.figure(figsize=(3.6 * cols, 3.6 * rows))
    qn = query_nodes if query_nodes is not None else (matches[0].query_nodes if matches else None)
    ax = fig.add_subplot(rows, cols, 1, projection="3d")
    ax.view_init(*view)
    draw_model(
        ax,
        query.centers,
        query.radii,
        geometry=query_geometry,
        highlight=qn,
        colour=_QUERY_COLOUR,
        title="query",
    )
    geoms = list(target_geometries) if target_geometries is not None else [None] * len(matches)
    for i, (m, t, g) in enumerate(zip(matches, targets, geoms, strict=True)):
        ax = fig.add_subplot(rows, cols, i + 2, projection="3d")
        ax.view_init(*view)
        label = m.name if m.name is not None else f"#{i + 1}"
        draw_model(
            ax,
            t.centers,
            t.radii,
            geometry=g,
            highlight=m.nodes,
            title=f"{label}  k={m.similarity:.3f}",
        )
    if title:
        fig.suptitle(title)
    return _save(fig, out, plt)


def render_part_matches(
    db: StoreHandle | None,
    query: Any,
    matches: Sequence[Any],
    out: str | os.PathLike[str],
    **options: Any,
) -> Path:
    """:func:`render_matches` for the result of ``query.parts.match.match``.

    Parameters
    ----------
    db : shapedb.Database or None
        Stored matches (``m.id`` not None) are read from it.
    query : Model, Decomposition, Geometry, id or path
        The query as given to ``match`` (resolved again if it is not a ``Model``).
    matches : sequence of PartMatch
    out : path
    **options
        Passed to :func:`render_matches` (``title``, ``view``, ``target_geometries``).
        For a pairwise match give ``targets=[decomposition of b]``.
    """
    from query.parts.match import Model, resolve

    complement = bool(options.pop("complement", False))
    q = query if isinstance(query, Model) else resolve(db, query, complement=complement)
    targets = options.pop("targets", None)
    if targets is None:
        if db is None:
            raise QueryError("drawing stored matches needs a database", source="db=None")
        targets = [db.get(m.id).decomposition for m in matches]
    elif len(targets) == 1 and len(matches) > 1:
        targets = list(targets) * len(matches)
    qg = options.pop("query_geometry", q.geometry)
    return render_matches(q.graph, matches, targets, out, query_geometry=qg, **options)


def show(db: StoreHandle | None, model: Any, out: str | os.PathLike[str], **options: Any) -> Path:
    """Draw ``model`` (a path, Geometry, or stored id/name) with its MDBD balls.

    The ``shapedb.extensions`` entry point behind ``shapedb show``. A stored shape is
    drawn with the surface of its source file when that file is still readable.

    Parameters
    ----------
    db : shapedb.Database or None
        Needed for stored ids and names; its configuration decomposes files.
    model : path, Geometry, Decomposition, int or str
    out : path
        PNG to write.
    **options
        ``complement=True`` draws the decomposition of the model's complement;
        the rest goes to :func:`render_model`.
    """
    from query.parts.match import resolve

    m = resolve(db, model, complement=bool(options.pop("complement", False)))
    geometry = m.geometry
    if geometry is None and m.id is not None and db is not None:
        source = db.get(m.id).source
        if source and Path(source).exists():
            try:
                geometry = db.load(source)
            except Exception:  # noqa: BLE001 - a picture without its surface is still useful
                log.debug("cannot reload %s for drawing", source, exc_info=True)
    title = options.pop("title", None) or f"{m.name or model}: {len(m.graph.radii)} balls"
    return render_model(m.decomposition or m.graph, out, geometry=geometry, title=title, **options)
