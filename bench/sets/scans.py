"""Query shapes made from a model's mesh: depth scans, surface samplings and cropped halves.

Every function takes a mesh's ``vertices`` (v, 3) float and ``faces`` (f, 3) int and a
``seed``, and returns numpy arrays; the same mesh and seed give the same result.

- :func:`one_sided_scan`: what one depth camera sees (perspective, first hits only,
  depth noise quadratic in range, fewer points far away and at grazing incidence).
- :func:`even_cloud`, :func:`vertex_cloud`, :func:`falloff_cloud`: the whole surface
  sampled evenly by area, at 20 % of the vertices (crowded where the mesh is fine), and
  with a density falling with the distance from a viewpoint (all around, no occlusion).
- :func:`cropped_mesh`: the triangles on one side of a random plane through the
  surface's centroid, an open mesh of about half the area.

Visibility is open3d's ``RaycastingScene``; face orientation is not used, so triangle
soups work too.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bench.sets.datasets import point_cloud
from bench.support.baselines import sample_surface
from shapedb.signature.view_words import image_rays

__all__ = [
    "SCAN_POINTS", "SCAN_NOISE", "bounding_sphere", "viewpoint", "one_sided_scan",
    "even_cloud", "vertex_cloud", "falloff_cloud", "cropped_mesh",
]  # fmt: skip

Points = NDArray[np.float64]
Faces = NDArray[np.int64]

#: Points of a scan and of the even and falloff clouds (the order of the vertex clouds').
SCAN_POINTS = 3000
#: Depth noise (standard deviation) as a fraction of the range at the camera's distance
#: to the centre; a consumer depth sensor's 0.1-0.5 % of range, here the middle.
SCAN_NOISE = 0.003
#: Camera distance from the bounding sphere's centre, in radii (drawn uniformly).
CAMERA_DISTANCE = (2.0, 3.0)
#: Exponent of ``|cos(incidence)|`` in the probability that a hit is kept.
INCIDENCE_POWER = 1.0
#: Exponent of ``nearest / depth`` in the probability that a hit (or sample) is kept.
RANGE_POWER = 2.0
#: Rays cast per requested scan point (covers the image's empty corners and the drops).
RAYS_PER_POINT = 8


def bounding_sphere(vertices: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Centre (3,) (the bounding box's) and radius (largest vertex distance from it)."""
    v = np.asarray(vertices, dtype=np.float64)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = float(np.linalg.norm(v - centre, axis=1).max())
    return centre, max(radius, 1e-12)


def _unit(rng: np.random.Generator) -> NDArray[np.float64]:
    d = rng.normal(size=3)
    return np.asarray(d / np.linalg.norm(d))


def viewpoint(vertices: NDArray[np.float64], *, seed: int) -> NDArray[np.float64]:
    """The camera position (3,) of :func:`one_sided_scan` and :func:`falloff_cloud`.

    A uniformly random direction from the bounding sphere's centre, at
    :data:`CAMERA_DISTANCE` radii (uniform in that range), drawn from ``seed``.
    """
    rng = np.random.default_rng(seed)
    centre, radius = bounding_sphere(vertices)
    return np.asarray(centre + _unit(rng) * rng.uniform(*CAMERA_DISTANCE) * radius)


def _scene(v: NDArray[np.float64], faces: NDArray[np.int64]) -> object:
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.ascontiguousarray(v, dtype=np.float32)),
        o3d.core.Tensor(np.ascontiguousarray(faces, dtype=np.uint32)),
    )
    return scene


def one_sided_scan(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    seed: int,
    points: int = SCAN_POINTS,
    noise: float = SCAN_NOISE,
    eye: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """What one depth camera sees of the mesh: (k, 3) float64 points, k <= ``points``.

    The camera sits at :func:`viewpoint` and looks at the bounding sphere's centre
    through a square perspective image just wider than the sphere; each ray keeps its
    first hit only, so the far side is missing. A hit at depth ``t`` along its ray is
    kept with probability ``|cos(incidence)| ** INCIDENCE_POWER * (t_min / t) **
    RANGE_POWER`` (fewer points at grazing incidence and far away, on top of the
    perspective's own fall-off), then moved along its ray by Gaussian noise of standard
    deviation ``noise * t ** 2 / distance`` (``distance``: the camera's to the centre).
    When more than ``points`` hits remain, ``points`` of them are drawn at random.

    Parameters
    ----------
    vertices, faces : (v, 3) float, (f, 3) int
        The mesh (a triangle soup is fine).
    seed : int
        Seeds the viewpoint, the drops, the noise and the thinning.
    points : int
        Most points returned.
    noise : float
        Depth noise as a fraction of the range at ``distance`` (0: exact hits).
    eye : (3,) float, optional
        The camera's position (default: :func:`viewpoint` of ``seed``).

    Raises
    ------
    ValueError
        When no ray hits the mesh (an empty or degenerate mesh).
    """
    import open3d as o3d

    v = np.asarray(vertices, dtype=np.float64)
    centre, radius = bounding_sphere(v)
    eye = viewpoint(v, seed=seed) if eye is None else np.asarray(eye, np.float64)
    rng = np.random.default_rng([seed, 1])
    distance = float(np.linalg.norm(eye - centre))
    half_angle = 1.05 * float(np.arcsin(min(radius / distance, 1.0)))
    grid = int(np.ceil(np.sqrt(RAYS_PER_POINT * points)))
    dirs = image_rays((centre - eye) / distance, half_angle, grid)
    origin = np.broadcast_to(eye - centre, dirs.shape)
    rays = np.hstack([origin, dirs]).astype(np.float32)
    cast = _scene(v - centre, faces).cast_rays(o3d.core.Tensor(rays))  # type: ignore[attr-defined]
    t = cast["t_hit"].numpy().astype(np.float64)
    hit = np.isfinite(t)
    if not hit.any():
        raise ValueError("no ray of the scan hits the mesh")
    t, dirs = t[hit], dirs[hit]
    normals = cast["primitive_normals"].numpy()[hit].astype(np.float64)
    cos = np.abs(np.einsum("ij,ij->i", dirs, normals))
    keep = cos**INCIDENCE_POWER * (t.min() / t) ** RANGE_POWER
    kept = rng.random(len(t)) < keep
    t, dirs = t[kept], dirs[kept]
    t = t + rng.normal(size=len(t)) * noise * t**2 / distance
    out = eye + dirs * t[:, None]
    if len(out) > points:
        out = out[np.sort(rng.choice(len(out), size=points, replace=False))]
    return np.asarray(out)


def even_cloud(vertices: Points, faces: Faces, *, seed: int, points: int = SCAN_POINTS) -> Points:
    """``points`` points (points, 3) sampled uniformly by area over the whole surface."""
    return sample_surface(vertices, faces, points, rng=np.random.default_rng(seed))


#: The paper's cloud: ``fraction`` (default 20 %) of the mesh's vertices, crowded where the
#: mesh is fine (meshes with fewer such vertices than ``min_points`` are sampled evenly).
vertex_cloud = point_cloud


def falloff_cloud(
    vertices: Points, faces: Faces, *, seed: int, points: int = SCAN_POINTS
) -> Points:
    """The whole surface sampled with a density falling with distance from a viewpoint.

    Even samples (:data:`RAYS_PER_POINT` x ``points``) are each kept with probability
    ``(d_min / d) ** (2 * RANGE_POWER)``, ``d`` their distance from :func:`viewpoint`
    (no occlusion: the far side is sparse, not missing); then at most ``points`` of
    them are drawn at random. Returns (k, 3) float64, k <= ``points``.
    """
    rng = np.random.default_rng([seed, 2])
    dense = sample_surface(vertices, faces, RAYS_PER_POINT * points, rng=rng)
    d = np.linalg.norm(dense - viewpoint(vertices, seed=seed), axis=1)
    keep = rng.random(len(d)) < (d.min() / d) ** (2 * RANGE_POWER)
    out = dense[keep]
    if len(out) > points:
        out = out[np.sort(rng.choice(len(out), size=points, replace=False))]
    return np.asarray(out)


def cropped_mesh(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], *, seed: int
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Half of the mesh: the triangles on one side of a random plane, kept whole.

    The plane passes through the surface's area-weighted centroid with a uniformly
    random normal (from ``seed``); a triangle is kept when its centroid lies on the
    normal's side. Unused vertices are dropped and the faces renumbered.

    Returns
    -------
    vertices : (u, 3) float64
    faces : (g, 3) int64
        An open mesh (a closed one is cut open) holding about half the area.

    Raises
    ------
    ValueError
        When no triangle lies on the kept side.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    mid = tri.mean(axis=1)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    centroid = (mid * area[:, None]).sum(axis=0) / max(float(area.sum()), 1e-300)
    normal = _unit(np.random.default_rng(seed))
    kept = f[(mid - centroid) @ normal > 0.0]
    if not len(kept):
        raise ValueError("no triangle lies on the kept side of the cut")
    used, new = np.unique(kept.ravel(), return_inverse=True)
    return v[used], new.reshape(-1, 3).astype(np.int64)
