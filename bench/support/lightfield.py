"""The light field descriptor (Chen, Tian, Shen and Ouhyoung, Eurographics 2003), in numpy.

A model is seen from the 20 vertices of a regular dodecahedron around it; opposite
vertices see mirror-image silhouettes, so a *light field* is 10 silhouettes. Each
silhouette is described by the magnitudes of its Zernike moments up to order 10
(36 numbers, in-plane-rotation invariant) and by the first 10 Fourier descriptors of
its outer contour (the magnitudes of the Fourier transform of the centroid distance,
divided by the mean distance). A model has ``n_fields`` light fields from dodecahedra
turned in fixed, spread-out ways. The distance between two models is the smallest,
over every pair of their light fields and over the 60 rotations of the dodecahedron
(which permute the 10 views), of the summed L1 distances between corresponding
silhouettes (Chen et al.'s Eq. 1-2).

Silhouettes are rendered by dense surface splats: ``n_points`` points sampled by area
on the triangles (plus the vertices), scaled into the unit sphere about their mean,
projected orthographically onto a ``resolution`` x ``resolution`` image of the
unit disc and closed morphologically (one pixel), so that a surface seen face-on
leaves no holes while thin rods and sheets seen edge-on stay visible. Orientation,
connectivity and watertightness of the mesh do not matter. Chen et al. render filled
polygons at 256 x 256 and quantise each coefficient to 8 bits; here the silhouettes are
splats, smaller, and the coefficients stay floats. This is the simplified, earlier peer:
the published method is :mod:`bench.support.lightfield_peer`, which ``bench.studies.rerank_stage
--mesh-lfd`` compares against (this one is its ``--mesh-lfd-splat`` row).

Only the mesh splatting lives here; the dodecahedron, the silhouette features, the
descriptor's layout and the distance are :mod:`shapedb.signature.lightfield`'s, which also
renders the light fields of a decomposition's balls.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bench.support.baselines import sample_surface
from shapedb.config.core import LightFieldConfig
from shapedb.signature.lightfield import (
    dodecahedron_rotations,
    dodecahedron_views,
    field_directions,
    image_axes,
    light_field_distance,
    silhouette_features,
    view_permutations,
)

__all__ = [
    "LFDConfig",
    "dodecahedron_views",
    "dodecahedron_rotations",
    "view_permutations",
    "render_silhouettes",
    "silhouette_features",
    "lfd_descriptor",
    "lfd_distance",
    "lfd_similarity",
    "lfd_matrix",
    "lfd_split_matrix",
]

#: The distance of :mod:`shapedb.signature.lightfield` under the baseline's name.
lfd_distance = light_field_distance


@dataclass(frozen=True)
class LFDConfig(LightFieldConfig):
    """Parameters of the mesh light field descriptor: :class:`~shapedb.config.core.LightFieldConfig`
    plus the surface sampling.

    Attributes
    ----------
    n_points : int
        Surface samples splatted into each silhouette (``seed`` seeds the sampling too).
    """

    n_points: int = 40000


def _surface_points(
    vertices: ArrayLike, faces: ArrayLike, n: int, seed: int, resolution: int
) -> NDArray[np.float32]:
    """Surface samples in the unit sphere about their mean, one per occupied half-pixel voxel.

    ``n`` area-weighted samples plus the used vertices; samples that share a cube of
    half a pixel's side (1 / ``resolution``) are merged to that cube's centre, which
    moves no silhouette pixel by more than about half a pixel.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    p = sample_surface(v, f, n, rng=np.random.default_rng(seed))
    p = np.vstack([p, v[np.unique(f)]])
    p = p - p[:n].mean(axis=0)
    radius = float(np.linalg.norm(p, axis=1).max())
    if not radius > 0:
        raise ValueError("the mesh is a single point: no silhouette")
    side = 2 * resolution + 2  # cell indices lie in [-resolution, resolution]
    cells = np.floor(p / radius * resolution).astype(np.int64) + resolution
    key = np.unique((cells[:, 0] * side + cells[:, 1]) * side + cells[:, 2])
    cells = np.stack([key // (side * side), key // side % side, key % side], axis=1) - resolution
    return ((cells + 0.5) / resolution).astype(np.float32)


def render_silhouettes(
    points: ArrayLike, directions: ArrayLike, resolution: int
) -> NDArray[np.bool_]:
    """Orthographic silhouettes of a point set in the unit sphere.

    Parameters
    ----------
    points : (k, 3) float
        Dense surface samples, inside the unit sphere.
    directions : (m, 3) float
        Unit view directions.
    resolution : int
        Image side, pixels; the image spans [-1, 1]^2.

    Returns
    -------
    (m, resolution, resolution) bool
        One closed (3 x 3) silhouette per direction.
    """
    from scipy import ndimage

    p = np.asarray(points, dtype=np.float32)
    d = np.asarray(directions, dtype=np.float32)
    u, w = image_axes(d)
    half = np.float32(0.5 * resolution)
    px = np.clip(((p @ u.T + 1.0) * half).astype(np.int32), 0, resolution - 1)
    py = np.clip(((p @ w.T + 1.0) * half).astype(np.int32), 0, resolution - 1)
    m = len(d)
    flat = (np.arange(m, dtype=np.int32)[None, :] * resolution + py) * resolution + px
    img = np.zeros(m * resolution * resolution, dtype=bool)
    img[flat.ravel()] = True
    img = img.reshape(m, resolution, resolution)
    pad = np.pad(img, ((0, 0), (1, 1), (1, 1)))
    ball = np.zeros((1, 3, 3), dtype=bool)
    ball[0] = True
    closed = ndimage.binary_erosion(ndimage.binary_dilation(pad, ball), ball)
    return np.asarray(closed[:, 1:-1, 1:-1] | img)


def lfd_descriptor(
    vertices: ArrayLike, faces: ArrayLike, config: LFDConfig | None = None
) -> NDArray[np.float64]:
    """The light fields of a triangle mesh: (n_fields, 10, features) float64.

    Parameters
    ----------
    vertices : (v, 3) float
        Vertex positions.
    faces : (f, 3) int
        Triangles (a soup is fine: orientation and connectivity are not used).
    config : LFDConfig, optional
        Fields, resolution, sampling and feature orders.

    Returns
    -------
    (config.n_fields, 10, features) float64
        Per light field, per dodecahedron view (:func:`dodecahedron_views` turned by
        the field's rotation), the :func:`silhouette_features`. Invariant to
        translation and scale; rotations are handled by :func:`lfd_distance`.

    Raises
    ------
    ValueError
        For a mesh of zero area.
    """
    cfg = config or LFDConfig()
    p = _surface_points(vertices, faces, cfg.n_points, cfg.seed, cfg.resolution)
    dirs = field_directions(cfg.n_fields, cfg.seed)
    feats = silhouette_features(render_silhouettes(p, dirs, cfg.resolution), cfg)
    return feats.reshape(cfg.n_fields, 10, -1)


def lfd_similarity(descriptors: ArrayLike, others: ArrayLike | None = None) -> NDArray[np.float64]:
    """Similarity ``-`` :func:`lfd_distance` (larger is more similar): (n, m) float64."""
    return -lfd_distance(descriptors, others)


def _code_digest() -> str:
    """sha256 (12 hex) of this module's bytes: the key of the cached descriptors."""
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:12]


def lfd_matrix(ds: Any) -> np.ndarray:
    """Light field distances between the split's meshes, (n, n); descriptors cached."""
    from bench.sets.datasets import CACHE_DIR, mesh_arrays

    code = _code_digest()
    folder = CACHE_DIR / "lfd"
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for m in ds.models:
        key = hashlib.sha256(f"{m.source}|{m.name}".encode()).hexdigest()[:20]
        path = folder / f"{key}_{code}.npy"
        if not path.exists():
            np.save(path, lfd_descriptor(*mesh_arrays(m), LFDConfig()))
        out.append(np.load(path))
    return np.asarray(lfd_distance(np.stack(out)), np.float64)


def lfd_split_matrix(models: Sequence[Any]) -> np.ndarray:
    """:func:`lfd_matrix` of any models together (several sets' splits), (n, n), cached
    under ``$SHAPEDB_BENCH_CACHE/lfd/matrices`` by the models and the descriptor's code."""
    from types import SimpleNamespace

    from bench.sets.datasets import CACHE_DIR

    keys = "\n".join(f"{m.source}|{m.name}" for m in models)
    code = _code_digest()
    key = hashlib.sha256((code + keys).encode()).hexdigest()[:16]
    path = CACHE_DIR / "lfd" / "matrices" / f"{key}.npy"
    if path.exists():
        return np.load(path)
    t = time.perf_counter()
    d = lfd_matrix(SimpleNamespace(models=list(models)))  # type: ignore[arg-type]
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, d)
    print(f"  mesh light field distances {d.shape}: {time.perf_counter() - t:.0f} s", flush=True)
    return d
