"""Surface words: a shape's bag of local surface features (FPFH) over a fixed codebook.

A shape's surface is sampled (:func:`surface_points`), scaled into the unit sphere and
thinned to one point per :data:`VOXEL` cube; each point is described by its fast point
feature histogram (Rusu et al. 2009, ``open3d``'s ``compute_fpfh_feature``: 33 bins of
the angles between the normals of its neighbours within :data:`FEATURE_RADIUS`), and
each feature by the nearest of the :data:`WORDS` words of the shipped codebook
(``surface_words.npy``: k-means over the bench's validation splits,
``python -m bench.studies.surface_words --write-codebook``). The shape's signature is
its histogram of words (:func:`surface_words`, (WORDS,) float32 summing to 1), and two
shapes are as near as their histograms' chi-square distance (:func:`words_distance`).

Local words see what silhouettes and ball packings do not (a frame of thin rods, a
sheet's folds, a panel's edges) and are blind to how the parts are arranged: a person in
two poses has the same words as another person. The ``"lightfield"`` stage fuses them
only where its gate says pose does not vary (:mod:`query.search.word_fusion`).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.errors import DegenerateGeometryError
from shapedb.geometry.base import Geometry

__all__ = [
    "SAMPLES",
    "WORDS",
    "CODEBOOK_FILE",
    "surface_points",
    "surface_features",
    "train_codebook",
    "codebook",
    "surface_words",
    "words_distance",
]

#: Surface samples drawn (by area) before the thinning. The voxel of the thinning, and
#: the radii of the normals and of the features, are in units of the sample's bounding
#: radius: the first setting measured, not tuned (one-off scripts, docs/results.md
#: "Surface words"; 0.04 / 0.08 / 0.2 and 0.06 / 0.12 / 0.3 were tried for one-sided scans
#: only, no better).
SAMPLES = 6000
VOXEL = 0.02
NORMAL_RADIUS = 0.05
FEATURE_RADIUS = 0.12
#: Words of the codebook: 256 against 64 and 128 (words alone, web validation NN 0.730
#: against 0.692 and 0.702, each family's own codebook; one-off scripts).
WORDS = 256
#: Bins of one FPFH feature.
FEATURE_BINS = 33
#: The shipped codebook, (WORDS, FEATURE_BINS) float32.
CODEBOOK_FILE = Path(__file__).with_name("surface_words.npy")


def surface_points(geometry: Geometry, spacing: float) -> NDArray[np.float64]:
    """(n, 3) float64 points on ``geometry``'s surface, model units, deterministic.

    A triangle mesh: :data:`SAMPLES` points by area on its faces (hidden and doubled
    faces too: what the mesh says). A point cloud: its own points. Any other
    representation: :data:`SAMPLES` points on the marching-cubes surface of its grid
    SDF at ``spacing`` (model units; the grid of its decomposition).

    Raises
    ------
    DegenerateGeometryError
        The geometry has no surface to sample (no zero crossing, zero area).
    """
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.geometry.view import boundary_mesh, surface_area

    name = getattr(geometry, "name", None) or "shape"
    if isinstance(geometry, PointCloud):
        return np.asarray(geometry.points, np.float64)
    surface: Any = geometry
    if getattr(geometry, "faces", None) is None or not hasattr(geometry, "sample_surface"):
        surface = boundary_mesh(geometry, spacing)
    if surface is None:
        raise DegenerateGeometryError("no surface to sample for its words", source=name)
    area = surface_area(surface.vertices, surface.faces)
    if not np.isfinite(area) or area <= 0:
        raise DegenerateGeometryError("its surface has no area to sample", source=name)
    return np.asarray(surface.sample_surface(SAMPLES, seed=0), np.float64)


def surface_features(points: ArrayLike, *, reach: float = 1.0) -> NDArray[np.float32]:
    """(m, 33) float32 FPFH features of a surface sample ``points`` (n, 3), model units.

    Scale-, rotation- and translation-invariant: the sample is centred on its bounding
    box and scaled into the sphere of radius ``1 / reach``, thinned to one point per
    :data:`VOXEL` cube; normals by local PCA within :data:`NORMAL_RADIUS`, turned away
    from the thinned sample's centroid. ``m`` is 0 for fewer than two distinct points.

    ``reach`` is the bounding radius of the whole the sample is part of, in units of the
    sample's own: 1 for a whole shape; a half of a shape, read at its whole's scale, is
    about 1.2 (:mod:`query.parts.part_words`).

    Raises
    ------
    ValueError
        ``reach`` not a finite number > 0.
    """
    if not (np.isfinite(reach) and reach > 0):
        raise ValueError(f"reach must be a finite number > 0, got {reach!r}")
    import open3d as o3d

    p = np.asarray(points, np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) < 2:
        return np.zeros((0, FEATURE_BINS), np.float32)
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(p - centre, axis=1).max()) * float(reach)
    if not radius > 0:
        return np.zeros((0, FEATURE_BINS), np.float32)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector((p - centre) / radius))
    cloud = cloud.voxel_down_sample(VOXEL)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=NORMAL_RADIUS, max_nn=30))
    n, q = np.asarray(cloud.normals), np.asarray(cloud.points)
    sign = np.where(np.einsum("ij,ij->i", n, q - q.mean(axis=0)) < 0, -1.0, 1.0)
    cloud.normals = o3d.utility.Vector3dVector(n * sign[:, None])
    search = o3d.geometry.KDTreeSearchParamHybrid(radius=FEATURE_RADIUS, max_nn=100)
    # every point (open3d 0.20's stubs ask for the indices its binding defaults; 0.18 has none)
    feature = o3d.pipelines.registration.compute_fpfh_feature(cloud, search)  # type: ignore[call-arg]
    return np.ascontiguousarray(np.asarray(feature.data, dtype=np.float32).T)


def train_codebook(features: list[NDArray[np.float32]], words: int = WORDS) -> NDArray[np.float32]:
    """(words, 33) float32 centroids of faiss k-means over the stacked ``features`` (seeded)."""
    import faiss

    x = np.ascontiguousarray(np.vstack(features), dtype=np.float32)
    km = faiss.Kmeans(x.shape[1], words, niter=25, seed=1, max_points_per_centroid=512)
    km.train(x)
    return np.asarray(km.centroids, np.float32)


@functools.lru_cache(maxsize=1)
def codebook() -> Any:
    """The shipped codebook as a faiss flat L2 index (loaded once per process)."""
    import faiss

    centroids = np.load(CODEBOOK_FILE).astype(np.float32)
    index = faiss.IndexFlatL2(centroids.shape[1])
    index.add(centroids)
    return index


def surface_words(
    points: ArrayLike, words: Any = None, *, reach: float = 1.0
) -> NDArray[np.float32]:
    """(WORDS,) float32 histogram of the sample's features over the codebook, summing to 1.

    ``points``: (n, 3) a surface sample (:func:`surface_points`); ``words``: a faiss index
    of centroids (default: the shipped :func:`codebook`); ``reach``: as
    :func:`surface_features` takes it (a part of a shape read at its whole's scale). All
    zeros when the sample has no features.
    """
    book = codebook() if words is None else words
    f = surface_features(points, reach=reach)
    h = np.zeros(book.ntotal, np.float64)
    if len(f):
        _, word = book.search(f, 1)
        h = np.bincount(word[:, 0], minlength=book.ntotal).astype(np.float64)
        h /= h.sum()
    return h.astype(np.float32)


def words_distance(query: ArrayLike, others: ArrayLike) -> NDArray[np.float64]:
    """(m,) chi-square distances ``0.5 sum (a - b)^2 / (a + b)`` of the histogram ``query``
    (WORDS,) to each row of ``others`` (m, WORDS); in [0, 1] for histograms summing to 1."""
    a = np.asarray(query, np.float64)[None, :]
    b = np.asarray(others, np.float64).reshape(-1, a.shape[1])
    s = a + b
    return 0.5 * np.where(s > 0, (a - b) ** 2 / np.where(s > 0, s, 1.0), 0.0).sum(axis=1)
