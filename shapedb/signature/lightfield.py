"""Light fields of a ball union or of a field's inside (Chen et al. 2003's descriptor).

The descriptor itself (the dodecahedron, the image features, the distance) is
:mod:`shapedb.signature.lightfield_descriptor`, re-exported here. This module renders the images
of a ball union, which keeps the descriptor representation-agnostic: seen along ``d``, a
ball of centre ``c`` and radius ``r`` projects to a disc of radius ``r`` about ``c``'s
projection, its front at height ``c . d + sqrt(r^2 - rho^2)``. The balls are centred on
their volume centroid (:func:`shapedb.signature.union.centred_balls`) and scaled so that the
farthest ball's far side lies on the unit sphere; images span the unit disc, a pixel is
covered when its centre lies within ``r`` plus half a pixel of a disc's centre (so that
balls thinner than a pixel, as on thickened sheets, stay visible). With ``depth_weight >
0`` each view also carries the Zernike magnitudes of its front and back depth images,
``(h + 1) / 2`` where covered (``h`` the nearest front's height, unit sphere), 0
elsewhere; opposite views swap front and back, so the two enter as their sum and
absolute difference. With ``LightFieldConfig.framing = "view"`` (the default of new
stores) each image is rendered a second time about the centroid of its covered pixels,
spanning the largest reach of a disc from its image's centroid over its light field, as
the published descriptor frames its silhouettes (a centre of their own, one scale per
light field).

The light fields of the inside of the decomposition's field (``LightFieldConfig.source
= "field"``, :func:`inside_light_field`) are those of its inside cells, each a ball of
half a cell, seen about all the cells' centroid or the mean of the shell's it renders
(``LightFieldConfig.centre``, :mod:`shapedb.geometry.inside`).

Silhouettes of other sources (surface splats of a mesh, ``bench/lightfield.py``) use
:func:`silhouette_features`, :func:`field_directions` and :func:`light_field_distance`
the same way.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from shapedb.config.core import LightFieldConfig
from shapedb.signature.lightfield_descriptor import (
    dodecahedron_rotations,
    dodecahedron_views,
    field_directions,
    field_rotations,
    image_axes,
    light_field_dim,
    light_field_distance,
    silhouette_features,
    view_permutations,
    zernike_magnitudes,
)
from shapedb.signature.union import centred_balls

if TYPE_CHECKING:
    from shapedb.geometry.inside import Inside
    from shapedb.mdbd.decomposition import Decomposition

__all__ = [
    "dodecahedron_views",
    "dodecahedron_rotations",
    "view_permutations",
    "field_rotations",
    "field_directions",
    "image_axes",
    "zernike_magnitudes",
    "silhouette_features",
    "render_discs",
    "ball_light_field",
    "record_light_field",
    "inside_light_field",
    "decomposition_light_field",
    "cloud_light_field",
    "light_field_dim",
    "light_field_distance",
]

FloatArray = NDArray[np.float64]
#: Views of one light field (a dodecahedron's 20 cameras, opposite ones mirror images).
VIEWS_PER_FIELD = 10


# --------------------------------------------------------------------------------------
# Images of a ball union
# --------------------------------------------------------------------------------------


@njit(cache=True)
def _splat_discs(
    x: NDArray[np.float32],
    r: NDArray[np.float32],
    edges: NDArray[np.int64],
    u: NDArray[np.float32],
    w: NDArray[np.float32],
    d: NDArray[np.float32],
    res: int,
    depth: bool,
    grow: float,
    shift: NDArray[np.float32],
    scale: NDArray[np.float32],
) -> tuple[NDArray[np.bool_], NDArray[np.float32], NDArray[np.float32]]:
    m, n = u.shape[0], x.shape[0]
    sil = np.zeros((m, res, res), dtype=np.bool_)
    shape = (m, res, res) if depth else (1, 1, 1)
    front = np.full(shape, -2.0, dtype=np.float32)
    back = np.full(shape, -2.0, dtype=np.float32)
    half = np.float32(0.5 * res)
    slack = np.float32(1.0 / res + grow)  # half a pixel (plus the growth), image units
    pu = np.empty(n, dtype=np.float32)
    pw = np.empty(n, dtype=np.float32)
    rr = np.empty(n, dtype=np.float32)
    for k in range(m):
        inv = np.float32(1.0) / scale[k]
        for i in range(n):
            pu[i] = (x[i, 0] * u[k, 0] + x[i, 1] * u[k, 1] + x[i, 2] * u[k, 2] - shift[k, 0]) * inv
            pw[i] = (x[i, 0] * w[k, 0] + x[i, 1] * w[k, 1] + x[i, 2] * w[k, 2] - shift[k, 1]) * inv
            pd = (x[i, 0] * d[k, 0] + x[i, 1] * d[k, 1] + x[i, 2] * d[k, 2]) * inv
            rr[i] = r[i] * inv
            reach = rr[i] + slack
            c0 = max(int((pu[i] - reach + 1.0) * half), 0)
            c1 = min(int((pu[i] + reach + 1.0) * half), res - 1)
            r0 = max(int((pw[i] - reach + 1.0) * half), 0)
            r1 = min(int((pw[i] + reach + 1.0) * half), res - 1)
            for row in range(r0, r1 + 1):
                yw = (row + 0.5) / half - 1.0 - pw[i]
                for col in range(c0, c1 + 1):
                    xu = (col + 0.5) / half - 1.0 - pu[i]
                    rho2 = xu * xu + yw * yw
                    if rho2 > reach * reach:
                        continue
                    sil[k, row, col] = True
                    if depth:
                        h = np.sqrt(max(rr[i] * rr[i] - rho2, 0.0))
                        front[k, row, col] = max(front[k, row, col], pd + h)
                        back[k, row, col] = max(back[k, row, col], -pd + h)
        for e in range(edges.shape[0]):
            # the convex hull of the two discs: pixels p with |p - a_t| <= r_t + slack for
            # some t in [0, 1] (a_t, r_t interpolate the two discs); the excess
            # |p - a_t| - r_t is convex in t, its minimum in closed form
            i, j = edges[e, 0], edges[e, 1]
            au, aw, bu, bw = pu[i], pw[i], pu[j], pw[j]
            ra, rb = rr[i] + slack, rr[j] + slack
            eu, ew = bu - au, bw - aw
            length = np.sqrt(eu * eu + ew * ew)
            dr = rb - ra
            if length <= abs(dr) + 1e-12:
                continue  # one disc holds the other: nothing beyond the discs
            eu, ew = eu / length, ew / length
            k_ = dr / length
            tan = k_ / np.sqrt(1.0 - k_ * k_)
            c0 = max(int((min(au - ra, bu - rb) + 1.0) * half), 0)
            c1 = min(int((max(au + ra, bu + rb) + 1.0) * half), res - 1)
            r0 = max(int((min(aw - ra, bw - rb) + 1.0) * half), 0)
            r1 = min(int((max(aw + ra, bw + rb) + 1.0) * half), res - 1)
            for row in range(r0, r1 + 1):
                yw = (row + 0.5) / half - 1.0 - aw
                for col in range(c0, c1 + 1):
                    if sil[k, row, col]:
                        continue
                    xu = (col + 0.5) / half - 1.0 - au
                    s = xu * eu + yw * ew
                    hh = abs(xu * ew - yw * eu)
                    t = min(max((s + tan * hh) / length, 0.0), 1.0)
                    du, dw = xu - t * length * eu, yw - t * length * ew
                    rt = ra + t * dr
                    if du * du + dw * dw <= rt * rt:
                        sil[k, row, col] = True
    return sil, front, back


def _unit_balls(
    centers: ArrayLike, radii: ArrayLike, frame: tuple[ArrayLike, float] | None = None
) -> tuple[FloatArray, FloatArray]:
    """Balls about their volume centroid, scaled so the farthest far side is at radius 1;
    or about ``frame``'s centre, divided by its extent."""
    if frame is not None:
        c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
        rr = np.asarray(radii, dtype=np.float64).reshape(-1)
        o, ext = np.asarray(frame[0], dtype=np.float64).reshape(3), float(frame[1])
        if len(c) != len(rr) or not ext > 0 or not np.any(rr > 0):
            raise ValueError(f"{len(c)} centres, {len(rr)} radii, extent {ext}: no light field")
        keep = rr > 0
        return (c[keep] - o) / ext, rr[keep] / ext
    x, r, scale = centred_balls(centers, radii)
    if not scale > 0:
        raise ValueError("no ball of positive radius: no light field")
    extent = float(np.max(np.linalg.norm(x, axis=1) + r))
    return x / extent, r / extent


def _view_frames(
    sil: NDArray[np.bool_],
    x: FloatArray,
    r: FloatArray,
    u: NDArray[np.float32],
    w: NDArray[np.float32],
    group: int,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Each silhouette's frame: per image of ``sil`` (m, res, res) on [-1, 1]^2 the
    centroid of its covered pixels (m, 2), and per run of ``group`` images (a light field)
    the largest distance of a disc's far side from its image's centroid (m,), the discs
    those of the balls ``x`` (n, 3), ``r`` (n,) seen along the image axes ``u``, ``w``."""
    m, res = sil.shape[0], sil.shape[1]
    px = (np.arange(res) + 0.5) * (2.0 / res) - 1.0
    shift = np.zeros((m, 2))
    for k in range(m):
        rows, cols = np.nonzero(sil[k])
        if len(rows):
            shift[k] = px[cols].mean(), px[rows].mean()
    pu, pw = x @ u.T.astype(np.float64), x @ w.T.astype(np.float64)  # (n, m)
    reach = (np.hypot(pu - shift[:, 0], pw - shift[:, 1]) + r[:, None]).max(axis=0)
    if m % group == 0:
        scale = np.repeat(reach.reshape(-1, group).max(axis=1), group)
    else:
        scale = np.full(m, reach.max())
    return shift.astype(np.float32), np.maximum(scale, 1e-12).astype(np.float32)


def _kept_edges(radii: ArrayLike, edges: ArrayLike | None) -> NDArray[np.int64]:
    """(k, 2) contact edges among the balls of positive radius, indexed in that subset."""
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if edges is None:
        return np.zeros((0, 2), dtype=np.int64)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if len(e) and (e.min() < 0 or e.max() >= len(r)):
        raise ValueError(f"contact edges index balls outside 0..{len(r) - 1}")
    keep = r > 0
    new = np.cumsum(keep) - 1
    e = e[keep[e[:, 0]] & keep[e[:, 1]]]
    return np.ascontiguousarray(new[e], dtype=np.int64)


def _closed(sil: NDArray[np.bool_], px: int) -> NDArray[np.bool_]:
    """Morphological closing of each image by a disc of ``px`` pixels (image edge padded)."""
    from scipy import ndimage

    yy, xx = np.mgrid[-px : px + 1, -px : px + 1]
    disc = (xx * xx + yy * yy <= px * px + px)[None]
    pad = np.pad(sil, ((0, 0), (px, px), (px, px)))
    out = ndimage.binary_erosion(ndimage.binary_dilation(pad, disc), disc)
    return np.asarray(out[:, px:-px, px:-px] | sil)


def render_discs(
    centers: ArrayLike,
    radii: ArrayLike,
    directions: ArrayLike,
    resolution: int,
    *,
    depth: bool = False,
    edges: ArrayLike | None = None,
    dilate_px: float = 0.0,
    close_px: int = 0,
    frame: tuple[ArrayLike, float] | None = None,
    framing: str = "sphere",
) -> tuple[NDArray[np.bool_], NDArray[np.float32] | None]:
    """Orthographic images of the union of balls, in the unit-sphere frame of the module.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, any units.
    radii : (n,) float
        Ball radii, same units (balls of radius <= 0 are left out).
    directions : (m, 3) float
        Unit view directions.
    resolution : int
        Image side, pixels; the image spans [-1, 1]^2 along :func:`image_axes`.
    depth : bool
        Also return the depth images.
    edges : (e, 2) int, optional
        Contact edges (indices into ``centers``): each also fills the convex hull of its
        two balls' discs (the projection of the two balls' convex hull), which closes
        the gap between touching balls. Silhouettes only: depth images show the discs.
    dilate_px : float
        Every disc (and hull) grows by this many pixels, >= 0.
    close_px : int
        Morphological closing of each silhouette by a disc of this many pixels, >= 0.
    frame : ((3,) float, float), optional
        The centre and the extent the balls are seen in (the image spans the disc of
        radius ``extent`` about ``centre``, units of ``centers``); by default the
        balls' volume centroid and the farthest ball's far side.
    framing : {"sphere", "view"}
        ``"sphere"``: every image spans the unit disc of that frame. ``"view"``: each
        image is rendered again about the centroid of its covered pixels, spanning the
        largest reach of a disc from its image's centroid over its light field
        (each run of 10 directions), as the published descriptor frames its silhouettes
        (about a centre of their own, one scale per light field): the frame's centre no
        longer matters, and the centroid turns with the shape.

    Returns
    -------
    silhouettes : (m, resolution, resolution) bool
    depth : (m, 2, resolution, resolution) float32 or None
        Front (seen from ``+d``) and back (from ``-d``, in the same image axes) depth,
        ``(h + 1) / 2`` in [0, 1] where covered, 0 elsewhere; None unless ``depth``.

    Raises
    ------
    ValueError
        If no ball has a positive radius, the arrays' shapes disagree, an edge names
        a ball that does not exist, or ``dilate_px`` / ``close_px`` is negative.
    """
    if not dilate_px >= 0 or close_px < 0:
        raise ValueError(f"dilate_px {dilate_px} and close_px {close_px} must be >= 0")
    x, r = _unit_balls(centers, radii, frame)
    e = _kept_edges(radii, edges)
    d = np.asarray(directions, dtype=np.float32).reshape(-1, 3)
    u, w = image_axes(d)
    res = int(resolution)
    xf, rf, grow = x.astype(np.float32), r.astype(np.float32), float(dilate_px) * 2.0 / res
    shift, scale = np.zeros((len(d), 2), np.float32), np.ones(len(d), np.float32)
    sil, front, back = _splat_discs(xf, rf, e, u, w, d, res, bool(depth), grow, shift, scale)
    if framing == "view":  # again, each image about its own centroid and light field's reach
        shift, scale = _view_frames(sil, x, r, u, w, VIEWS_PER_FIELD)
        sil, front, back = _splat_discs(xf, rf, e, u, w, d, res, bool(depth), grow, shift, scale)
    if close_px > 0:
        sil = _closed(sil, int(close_px))
    if not depth:
        return sil, None
    img = np.stack([front, back], axis=1)
    return sil, np.where(img > -2.0, np.clip((img + 1.0) / 2.0, 0.0, 1.0), 0.0).astype(np.float32)


def ball_light_field(
    centers: ArrayLike,
    radii: ArrayLike,
    config: LightFieldConfig | None = None,
    *,
    edges: ArrayLike | None = None,
    frame: tuple[ArrayLike, float] | None = None,
) -> FloatArray:
    """The light fields of a ball union: (n_fields, 10, :func:`light_field_dim`) float64.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres (a decomposition's), any units.
    radii : (n,) float
        Ball radii, same units.
    config : LightFieldConfig, optional
        Fields, resolution, orders, weights, and how silhouettes are filled
        (``edges``, ``dilate_px``, ``close_px``: :func:`render_discs`).
    edges : (e, 2) int, optional
        The decomposition's contact edges; needed when ``config.edges``, ignored
        otherwise.
    frame : ((3,) float, float), optional
        Centre and extent the balls are seen in (:func:`render_discs`).

    Returns
    -------
    (config.n_fields, 10, dim) float64
        Per light field and dodecahedron view, :func:`silhouette_features` of the disc
        union's silhouette, then (``depth_weight > 0``) ``depth_weight`` times the
        sum and the absolute difference of the front and back depth images' Zernike
        magnitudes. Invariant to translation and scale of the balls; rotations are
        handled by :func:`light_field_distance`.

    Raises
    ------
    ValueError
        If no ball has a positive radius, or ``config.edges`` is set without ``edges``.
    """
    cfg = config or LightFieldConfig()
    if cfg.edges and edges is None:
        raise ValueError("light fields with lf_edges need the decomposition's contact edges")
    depth = cfg.depth_weight > 0
    dirs = field_directions(cfg.n_fields, cfg.seed)
    sil, dep = render_discs(
        centers, radii, dirs, cfg.resolution, depth=depth,
        edges=edges if cfg.edges else None, dilate_px=cfg.dilate_px, close_px=cfg.close_px,
        frame=frame, framing=cfg.framing,
    )  # fmt: skip
    feats = silhouette_features(sil, cfg)
    if dep is not None:
        m, res = len(dirs), cfg.resolution
        z = zernike_magnitudes(dep.reshape(2 * m, res, res), cfg.zernike_order).reshape(m, 2, -1)
        both = np.hstack([z[:, 0] + z[:, 1], np.abs(z[:, 0] - z[:, 1])])
        feats = np.hstack([feats, cfg.depth_weight * both])
    return feats.reshape(cfg.n_fields, 10, -1)


def record_light_field(
    centers: ArrayLike,
    radii: ArrayLike,
    config: LightFieldConfig | None = None,
    *,
    edges: ArrayLike | None = None,
    frame: tuple[ArrayLike, float] | None = None,
) -> NDArray[np.float32]:
    """:func:`ball_light_field` as a store keeps it: float32, computed with one BLAS thread.

    The Zernike projections are small matrix products on which a multi-threaded BLAS
    spends more time waking threads than computing, so the call is limited to one BLAS
    thread (:mod:`threadpoolctl`) whatever the process's setting.

    Returns
    -------
    (config.n_fields, 10, dim) float32

    Raises
    ------
    ValueError
        If no ball has a positive radius, or ``config.edges`` is set without ``edges``.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return ball_light_field(centers, radii, config, edges=edges, frame=frame).astype(np.float32)


def inside_light_field(
    inside: Inside, config: LightFieldConfig | None = None
) -> NDArray[np.float32]:
    """Light fields of the inside cells, each a ball of half a cell, as a store keeps them.

    :func:`shapedb.signature.lightfield.record_light_field` of the shell's cells, normalised as a
    ball union is but over all the inside cells: about their centroid
    (``config.centre="volume"``) or the mean of the shell cells (``"surface"``), the
    farthest cell's far side at radius 1 (the farthest inside cell is a shell cell).

    Returns
    -------
    (config.n_fields, 10, dim) float32
        As :func:`shapedb.signature.lightfield.ball_light_field` (``config.edges`` has no effect:
        cells have no contact edges).

    Raises
    ------
    ValueError
        If no cell is inside.
    """
    if inside.count == 0 or not len(inside.shell):
        raise ValueError("the field has no inside cell: no light field")
    cfg = config or LightFieldConfig()
    half = 0.5 * inside.cell
    centre = inside.centroid if cfg.centre == "volume" else inside.shell.mean(axis=0)
    extent = float(np.max(np.linalg.norm(inside.shell - centre, axis=1))) + half
    radii = np.full(len(inside.shell), half)
    cfg = replace(cfg, edges=False) if cfg.edges else cfg
    return record_light_field(inside.shell, radii, cfg, frame=(centre, extent))


def decomposition_light_field(
    decomposition: Decomposition, config: LightFieldConfig | None = None
) -> NDArray[np.float32]:
    """:func:`record_light_field` of a decomposition's balls and its tail, if any; with
    ``config.source == "field"``, :func:`inside_light_field` of its inside.

    The balls are :meth:`shapedb.mdbd.decomposition.Decomposition.longer_packing` (the decomposition's
    balls, then the tail that ``decompose(tail_balls=...)`` packed past them; with
    ``LightFieldConfig.n_balls`` the ingest and an outside query decompose with the same
    tail). With ``config.edges`` and a tail, the contact edges are those of all the
    balls at the decomposition's contact tolerance; without a tail, its own edges.

    Returns
    -------
    (config.n_fields, 10, dim) float32

    Raises
    ------
    ValueError
        If no ball has a positive radius.
    ConfigError
        With ``source="field"``, if the decomposition has no inside (it was not
        decomposed with ``keep_inside=True``).
    """
    cfg = config or LightFieldConfig()
    if cfg.source == "field":
        if decomposition.inside is None:
            from shapedb.errors import ConfigError

            raise ConfigError(
                "light fields of the field need the decomposition's inside: decompose "
                "with keep_inside=True (as ingest does for lf_source=field)"
            )
        return inside_light_field(decomposition.inside, cfg)
    centers, radii = decomposition.longer_packing()
    edges = decomposition.edges
    if cfg.edges and len(radii) > decomposition.n_balls:
        from shapedb.mdbd.graph import contact_edges

        tol = decomposition.config.contact_tol_cells * decomposition.spacing
        edges = contact_edges(centers, radii, tol)
    return record_light_field(centers, radii, cfg, edges=edges)


#: Largest number of a cloud's points :func:`cloud_light_field` splats (a seeded random
#: subset of a larger cloud: 20,000 discs render 30 views in well under a second).
CLOUD_POINTS = 20_000
#: A cloud's points are first evened out to one per cube of this quantile of their
#: nearest-neighbour distances (a voxel grid keeps one point a cell), so that a scanner's
#: uneven density (dense near it, sparse far and at grazing angles) leaves no holes in the
#: discs. Through ``db.search``, validation clouds with scanner fall-off found their class
#: 0.958 -> 0.979 (parts), 0.786 -> 0.810 (enclosures), 0.907 -> 0.945 (generic), CAPOD
#: 0.967 either way (0.5: generic 0.923, the rest as 0.9); even and vertex clouds the same.
#: The discs grow with the spacing: an even box cloud's light fields lie 3.5 from its
#: solid's instead of 1.1 (thinner boxes' 12.8).
CLOUD_EVEN_QUANTILE = 0.9
#: Pixels of closing of a cloud's splatted silhouettes, bridging the gaps its sampling
#: leaves: on CAPOD validation clouds of 3,000 points NN by the light fields alone 0.967
#: at 2 pixels against 0.933-0.967 at none, discs of the median spacing.
CLOUD_CLOSE_PX = 2


def cloud_light_field(
    points: ArrayLike, config: LightFieldConfig | None = None
) -> NDArray[np.float32]:
    """Light fields of the surface a point cloud samples, as a store keeps a shape's.

    Seen from any direction, the samples of a surface all around a solid cover the
    solid's silhouette, so a cloud's silhouettes need no inside: the points, evened out
    to one a cube of their :data:`CLOUD_EVEN_QUANTILE` spacing, are each drawn as a disc
    of their median spacing (:func:`record_light_field` of those discs, about the points'
    mean, closed by :data:`CLOUD_CLOSE_PX` pixels), which a sparse cloud's decomposed
    inside draws far less faithfully. A cloud of more than :data:`CLOUD_POINTS` points is
    drawn from a seeded random subset of them.

    Parameters
    ----------
    points : (n, 3) float
        Surface samples, any units; n >= 3, finite.
    config : LightFieldConfig, optional
        The store's (``close_px`` and ``edges`` are this function's own).

    Returns
    -------
    (config.n_fields, 10, dim) float32
        Comparable view for view with :func:`decomposition_light_field` of a stored shape
        of the same configuration.

    Raises
    ------
    ValueError
        Fewer than 3 distinct finite points.
    """
    from scipy.spatial import cKDTree

    cfg = config or LightFieldConfig()
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(p)):
        raise ValueError("a cloud's light fields need finite points")
    p = np.unique(p, axis=0)
    if len(p) < 3:
        raise ValueError(f"a cloud's light fields need 3 or more distinct points ({len(p)} given)")
    if len(p) > CLOUD_POINTS:
        keep = np.random.default_rng(0).choice(len(p), CLOUD_POINTS, replace=False)
        p = p[np.sort(keep)]
    p = _evened(p, float(np.quantile(cKDTree(p).query(p, k=2)[0][:, 1], CLOUD_EVEN_QUANTILE)))
    spacing = float(np.median(cKDTree(p).query(p, k=2)[0][:, 1]))
    centre = p.mean(axis=0)
    extent = float(np.linalg.norm(p - centre, axis=1).max()) + spacing
    radii = np.full(len(p), spacing)
    splat = replace(cfg, close_px=CLOUD_CLOSE_PX, edges=False)
    return record_light_field(p, radii, splat, frame=(centre, extent))


def _evened(points: NDArray[np.float64], cell: float) -> NDArray[np.float64]:
    """``points`` (n, 3) kept one a cube of side ``cell`` (open3d's voxel grid: the mean
    of each occupied cube's points); as they are when that leaves fewer than 3."""
    import open3d as o3d

    if not cell > 0:
        return points
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    kept = np.asarray(cloud.voxel_down_sample(cell).points, np.float64)
    return kept if len(kept) >= 3 else points
