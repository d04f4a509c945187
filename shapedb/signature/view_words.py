"""View words: the surface words of what a camera sees of a shape, from fixed directions.

A depth camera's one-sided scan holds one side of its model, and one side's surface
words (:mod:`shapedb.signature.surface_words`) are not the whole's. They are near the
words of the same side seen by a simulated camera, though: :func:`view_words` raycasts
the shape's surface from :data:`VIEWS` directions spread evenly over the sphere
(:func:`view_directions`, the camera :data:`VIEW_DISTANCE` bounding radii from the
centre, first hits of a square image of :data:`VIEW_RAYS` x :data:`VIEW_RAYS` rays
thinned as a depth camera's) and keeps each view's words; a scan's distance to a shape is the least chi-square
distance of its words to the shape's views (:func:`view_words_distances`).

A scan's depth noise roughens its surface at the scale the features read, so scan and
views alike are :func:`flattened` first: each point moved onto the least-squares plane
of its neighbours within :data:`FLAT_RADIUS`. The view path of ``db.search`` fuses these
distances with the silhouettes' (:mod:`query.search.view_search`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from shapedb.errors import DegenerateGeometryError
from shapedb.geometry.base import Geometry

__all__ = [
    "VIEWS",
    "VIEW_DISTANCE",
    "VIEW_RAYS",
    "VIEW_POINTS",
    "INCIDENCE_POWER",
    "RANGE_POWER",
    "FLAT_RADIUS",
    "view_directions",
    "image_rays",
    "flattened",
    "visible_points",
    "view_words",
    "scan_words",
    "view_words_distances",
]

#: Simulated views of each shape, and the camera's distance from the bounding sphere's
#: centre in bounding radii: the settings of the study that measured the path
#: (``python -m bench.studies.view_words``, validation one-sided scans).
VIEWS = 20
VIEW_DISTANCE = 2.5
#: Rays along each side of a view's square image, and the most hits a view keeps (drawn
#: at random, seeded by the view): the bench's scans keep 3,000 points.
VIEW_RAYS = 155
VIEW_POINTS = 3000
#: A hit is kept with probability ``|cos(incidence)| ** INCIDENCE_POWER * (t_min / t) **
#: RANGE_POWER``, as a depth camera loses points at grazing incidence and with range.
#: Validation scans' words against views with these drops / with every hit: CAPOD NN
#: 0.700 / 0.667, parts 0.708 / 0.646 (a one-off script; 60 and 48 queries).
INCIDENCE_POWER = 1.0
RANGE_POWER = 2.0
#: Neighbourhood of :func:`flattened`, in units of the points' bounding radius. Validation
#: one-sided scans at the bench's depth noise, words flattened against views flattened:
#: CAPOD NN 0.350 -> 0.767, parts 0.375 -> 0.688 (``python -m bench.studies.view_words``).
FLAT_RADIUS = 0.06
#: Fewest neighbours (the point included) of a point :func:`flattened` moves.
_PLANE_POINTS = 5


def view_directions(n: int = VIEWS) -> NDArray[np.float64]:
    """(n, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n)
    azimuth = np.pi * (1.0 + 5.0**0.5) * i
    return np.stack(
        [np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1
    )


def flattened(points: ArrayLike, radius: float = FLAT_RADIUS) -> NDArray[np.float64]:
    """(n, 3) ``points`` each moved onto the least-squares plane of its neighbours within
    ``radius`` x the points' bounding radius (about their bounding box's centre); a point
    with fewer than 5 neighbours (itself included) stays where it is."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    if len(p) < _PLANE_POINTS:
        return p.copy()
    lo, hi = p.min(axis=0), p.max(axis=0)
    reach = float(np.linalg.norm(p - (lo + hi) / 2, axis=1).max())
    if not reach > 0:
        return p.copy()
    pairs = cKDTree(p).query_pairs(radius * reach, output_type="ndarray")
    i = np.concatenate([np.arange(len(p)), pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([np.arange(len(p)), pairs[:, 1], pairs[:, 0]])
    count = np.bincount(i, minlength=len(p)).astype(np.float64)
    local = p[j] - p[i]  # about the point itself: no cancellation far from the origin
    sums = np.stack([np.bincount(i, local[:, a], len(p)) for a in range(3)], axis=1)
    mean = sums / count[:, None]
    outer = local[:, :, None] * local[:, None, :]
    second = np.zeros((len(p), 3, 3))
    np.add.at(second, i, outer)
    cov = second / count[:, None, None] - mean[:, :, None] * mean[:, None, :]
    normal = np.linalg.eigh(cov)[1][:, :, 0]  # the least-variance direction
    # the point's offset from its neighbours' centroid, along the plane's normal
    offset = np.einsum("ij,ij->i", -mean, normal)
    moved = p - offset[:, None] * normal
    return np.where((count >= _PLANE_POINTS)[:, None], moved, p)


def image_rays(forward: ArrayLike, half_angle: float, rays: int = VIEW_RAYS) -> NDArray[np.float64]:
    """(rays ** 2, 3) unit directions of a square perspective image looking along the unit
    vector ``forward``, ``half_angle`` (radians) from its centre to an edge's middle."""
    forward = np.asarray(forward, np.float64)
    helper = np.eye(3)[int(np.argmin(np.abs(forward)))]
    right = np.cross(forward, helper)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    s = np.linspace(-1.0, 1.0, rays) * np.tan(half_angle)
    u, w = np.meshgrid(s, s, indexing="ij")
    d = forward + u.reshape(-1, 1) * right + w.reshape(-1, 1) * up
    return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True))


def visible_points(
    vertices: ArrayLike, faces: ArrayLike, directions: ArrayLike
) -> list[NDArray[np.float64]]:
    """What a camera sees of the mesh from each of ``directions`` (d, 3): d arrays (k_i, 3)
    of first hits, model units, k_i <= :data:`VIEW_POINTS`; deterministic.

    The camera sits :data:`VIEW_DISTANCE` bounding radii from the bounding box's centre
    along the direction and looks at the centre through a square image just wider than the
    bounding sphere, one ray per pixel of :data:`VIEW_RAYS` x :data:`VIEW_RAYS`; faces are
    seen from both sides. A hit at depth ``t`` is kept with probability
    ``|cos(incidence)| ** INCIDENCE_POWER * (t_min / t) ** RANGE_POWER``, then
    :data:`VIEW_POINTS` of those left at random, seeded by the view's number; a view that
    hits nothing is empty.
    """
    import open3d as o3d

    v = np.asarray(vertices, np.float64)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = max(float(np.linalg.norm(v - centre, axis=1).max()), 1e-12)
    scene = o3d.t.geometry.RaycastingScene()
    verts = np.ascontiguousarray((v - centre) / radius, np.float32)
    tris = np.ascontiguousarray(np.asarray(faces), np.uint32)
    scene.add_triangles(o3d.core.Tensor.from_numpy(verts), o3d.core.Tensor.from_numpy(tris))
    half_angle = 1.05 * float(np.arcsin(1.0 / VIEW_DISTANCE))
    out = []
    for k, d in enumerate(np.asarray(directions, np.float64).reshape(-1, 3)):
        d = d / np.linalg.norm(d)
        rays = image_rays(-d, half_angle)
        eye = np.broadcast_to(d * VIEW_DISTANCE, rays.shape)
        ray_table = np.ascontiguousarray(np.hstack([eye, rays]), np.float32)
        cast = scene.cast_rays(o3d.core.Tensor.from_numpy(ray_table))
        t = cast["t_hit"].numpy().astype(np.float64)
        hit = np.flatnonzero(np.isfinite(t))
        if not len(hit):
            out.append(np.zeros((0, 3)))
            continue
        normals = cast["primitive_normals"].numpy()[hit].astype(np.float64)
        cos = np.abs(np.einsum("ij,ij->i", rays[hit], normals))
        keep = cos**INCIDENCE_POWER * (t[hit].min() / t[hit]) ** RANGE_POWER
        rng = np.random.default_rng(k)
        hit = hit[rng.random(len(hit)) < keep]
        if len(hit) > VIEW_POINTS:
            hit = np.sort(rng.choice(hit, VIEW_POINTS, replace=False))
        out.append(centre + radius * (eye[hit] + t[hit, None] * rays[hit]))
    return out


def view_words(geometry: Geometry, spacing: float) -> NDArray[np.float32]:
    """(VIEWS, WORDS) float32: the words of ``geometry`` seen from each of
    :func:`view_directions`, each view :func:`flattened` first (a row of zeros for a
    view with no features).

    A triangle mesh is raycast as it is; any other representation through the
    marching-cubes surface of its grid SDF at ``spacing`` (model units).

    Raises
    ------
    DegenerateGeometryError
        The geometry has no surface to see.
    """
    from shapedb.geometry.view import boundary_mesh
    from shapedb.signature.surface_words import surface_words

    surface: Any = geometry
    if getattr(geometry, "faces", None) is None:
        surface = boundary_mesh(geometry, spacing)
    if surface is None or not len(surface.faces):
        name = getattr(geometry, "name", None) or "shape"
        raise DegenerateGeometryError("no surface to see for its view words", source=name)
    views = visible_points(surface.vertices, surface.faces, view_directions(VIEWS))
    return np.stack([surface_words(flattened(points)) for points in views])


def scan_words(points: ArrayLike) -> NDArray[np.float32]:
    """(WORDS,) float32: a one-sided scan's words, its points (n, 3) :func:`flattened` first."""
    from shapedb.signature.surface_words import surface_words

    return surface_words(flattened(points))


def view_words_distances(words: ArrayLike, views: ArrayLike) -> NDArray[np.float64]:
    """(m,) the least chi-square distance of ``words`` (WORDS,) to each shape's views
    ``views`` (m, VIEWS * WORDS) or (m, VIEWS, WORDS)."""
    from shapedb.signature.surface_words import WORDS, words_distance

    q = np.asarray(words, np.float64).ravel()
    v = np.asarray(views, np.float64).reshape(-1, WORDS)
    if not len(v):
        return np.zeros(0)
    return np.asarray(words_distance(q, v).reshape(-1, VIEWS).min(axis=1))
