"""The published light field descriptor (Chen, Tian, Shen and Ouhyoung, Eurographics 2003): the
bench's view-based peer, and its simplified variants beside it.

The method, as the paper and its released code have it:

* the mesh is centred on its bounding box and scaled into the unit sphere;
* 10 light fields, each the 20 vertices of a regular dodecahedron turned in a fixed way;
  the turns are spread out (:func:`spread_rotations`: greedily, each turn's 20 cameras
  as far as possible from every earlier turn's), as the paper picks them so that no two
  light fields share a camera position; opposite cameras see mirror silhouettes, so a
  light field is 10 silhouettes;
* filled-polygon orthographic silhouettes at 256 x 256 (:mod:`bench.support.lightfield_render`);
* per silhouette 35 Zernike magnitudes (order <= 10, the constant one dropped: it is 1
  for every silhouette once the moments are means over the covered pixels) and 10
  Fourier descriptors of the outer contour's centroid distance;
* each coefficient quantised to 8 bits as the released code does it: ``min(int(256 c),
  255)`` for a Zernike magnitude, ``min(int(512 c), 255)`` for a Fourier one;
* the distance between two silhouettes: the L1 distance of the Zernike bytes plus twice
  that of the Fourier bytes (the released code's ``MatchLF``); between two light fields
  the minimum over the 60 rotations of the dodecahedron (which permute the 10 views) of
  the summed silhouette distances; between two models the minimum over the 10 x 10
  pairs of light fields.

:class:`FaithfulLFDConfig`'s switches give the variants (:data:`VARIANTS`): 1 light
field, Zernike only, 128 px, no quantisation; the splat peer of
:mod:`bench.support.lightfield` is the fifth. Descriptors and split matrices are cached
like :func:`bench.support.lightfield.lfd_split_matrix`'s, keyed by the models, a digest
of this module's and the renderer's code and the config.
"""

from __future__ import annotations

import functools
import hashlib
import time
from collections.abc import Callable, Sequence
from dataclasses import astuple, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from bench.support import lightfield_render
from bench.support.lightfield_render import field_features, normalised_vertices, render_polygons
from shapedb.signature.lightfield_descriptor import dodecahedron_views, view_permutations

__all__ = [
    "FaithfulLFDConfig",
    "spread_rotations",
    "peer_directions",
    "peer_features",
    "peer_descriptor",
    "peer_distance",
    "peer_matrix",
    "peer_split_matrix",
    "VARIANTS",
    "variant_matrices",
]

FloatArray = NDArray[np.float64]
#: Candidate turns :func:`spread_rotations` picks from.
CANDIDATE_TURNS = 4000


@dataclass(frozen=True)
class FaithfulLFDConfig:
    """Parameters of the published light field descriptor; the defaults are the paper's.

    Attributes
    ----------
    n_fields : int
        Light fields, 1-10 (each 10 silhouettes).
    resolution : int
        Silhouette side, pixels, >= 16.
    fourier : bool
        Also the 10 Fourier descriptors (else the 35 Zernike magnitudes alone).
    quantise : bool
        Quantise each coefficient to 8 bits (else the same scales, unrounded).
    fourier_weight : float
        Weight of the Fourier bytes' L1 distance against the Zernike bytes'.
    """

    n_fields: int = 10
    resolution: int = 256
    fourier: bool = True
    quantise: bool = True
    fourier_weight: float = 2.0

    def __post_init__(self) -> None:
        if not (1 <= self.n_fields <= 10 and self.resolution >= 16 and self.fourier_weight >= 0):
            raise ValueError(f"{self}: n_fields in 1-10, resolution >= 16, weight >= 0")


@functools.lru_cache(maxsize=2)
def spread_rotations(n: int = 10) -> FloatArray:
    """(n, 3, 3) the light fields' turns: the identity, then greedily the seeded candidate
    turn whose 20 cameras are farthest (smallest angle) from every chosen turn's cameras."""
    rng = np.random.default_rng(2003)
    q = rng.normal(size=(CANDIDATE_TURNS, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    cand = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)  # fmt: skip
    views = dodecahedron_views()
    cams = np.einsum("cij,vj->cvi", cand, views)  # (c, 10, 3); the opposite 10 are -these
    chosen = [np.eye(3)]
    near = np.abs(cams.reshape(-1, 3) @ views.T).reshape(len(cand), -1).max(axis=1)
    while len(chosen) < n:
        k = int(np.argmin(near))
        chosen.append(cand[k])
        cos = np.abs(cams.reshape(-1, 3) @ cams[k].T).reshape(len(cand), -1).max(axis=1)
        near = np.maximum(near, cos)
    return np.asarray(chosen)


def peer_directions(n_fields: int = 10) -> FloatArray:
    """(n_fields * 10, 3) unit view directions, field-major."""
    views = dodecahedron_views()
    return np.concatenate([views @ r.T for r in spread_rotations(10)[:n_fields]])


def peer_features(vertices: ArrayLike, faces: ArrayLike, resolution: int = 256) -> FloatArray:
    """Unquantised features of all 10 light fields: (10, 10, 45) float64.

    35 Zernike magnitudes then 10 Fourier magnitudes per silhouette
    (:func:`bench.support.lightfield_render.field_features`) of the filled-polygon
    silhouettes of the normalised mesh.

    Raises
    ------
    ValueError
        For a mesh without vertices or whose vertices coincide.
    """
    v = normalised_vertices(vertices)
    img = render_polygons(v, faces, peer_directions(10), resolution)
    return np.stack([field_features(img[i : i + 10]) for i in range(0, 100, 10)])


def encode(features: ArrayLike, config: FaithfulLFDConfig) -> NDArray[np.float32]:
    """(fields, 10, d) the descriptor of :func:`peer_features`' output under ``config``:
    the first ``n_fields`` light fields, scaled (and quantised) bytes, the Fourier block
    weighted by ``fourier_weight`` (or dropped), so that the plain L1 distance of two
    silhouettes' rows is the method's."""
    f = np.asarray(features, dtype=np.float64)[: config.n_fields]
    z = 256.0 * f[..., :35]
    fd = 512.0 * f[..., 35:]
    if config.quantise:
        z, fd = np.minimum(np.floor(z), 255.0), np.minimum(np.floor(fd), 255.0)
    parts = [z, config.fourier_weight * fd] if config.fourier else [z]
    return np.concatenate(parts, axis=-1).astype(np.float32)


def peer_descriptor(
    vertices: ArrayLike, faces: ArrayLike, config: FaithfulLFDConfig | None = None
) -> NDArray[np.float32]:
    """The light fields of a triangle mesh: (n_fields, 10, 45 or 35) float32.

    Invariant to translation and scale of the mesh (up to pixels); rotations are
    handled by :func:`peer_distance`.

    Raises
    ------
    ValueError
        For a mesh without vertices or whose vertices coincide.
    """
    cfg = config or FaithfulLFDConfig()
    return encode(peer_features(vertices, faces, cfg.resolution), cfg)


@njit(cache=True)
def _min_distances(
    a: NDArray[np.float32], b: NDArray[np.float32], perm: NDArray[np.int64], symmetric: bool
) -> NDArray[np.float64]:
    n, fa, d = a.shape[0], a.shape[1] // 10, a.shape[2]
    m, fb = b.shape[0], b.shape[1] // 10
    out = np.zeros((n, m))
    table = np.empty((fa * 10, fb * 10), dtype=np.float32)
    for i in range(n):
        for j in range(i + 1 if symmetric else 0, m):
            for p in range(fa * 10):
                for q in range(fb * 10):
                    s = np.float32(0.0)
                    for k in range(d):
                        s += abs(a[i, p, k] - b[j, q, k])
                    table[p, q] = s
            best = np.inf
            for f in range(fa):
                for g in range(fb):
                    for r in range(60):
                        s = np.float32(0.0)
                        for v in range(10):
                            s += table[f * 10 + v, g * 10 + perm[r, v]]
                        best = min(best, s)
            out[i, j] = best
            if symmetric:
                out[j, i] = best
    return out


def peer_distance(descriptors: ArrayLike, others: ArrayLike | None = None) -> FloatArray:
    """Distances between models' light fields: (n, m) float64.

    Parameters
    ----------
    descriptors : (n, fields, 10, d) float
        :func:`peer_descriptor` of the query models.
    others : (m, fields', 10, d) float, optional
        Of the candidates; defaults to ``descriptors`` (symmetric, 0 on the diagonal).

    Returns
    -------
    (n, m) float64
        Per pair, the minimum over light-field pairs and the 60 rotations of the
        dodecahedron of the summed L1 distances of corresponding silhouettes (the
        published method's, computed per pair from its 100 x 100 silhouette table).

    Raises
    ------
    ValueError
        For arrays not shaped (count, fields, 10, d), or of different ``d``.
    """
    a = np.asarray(descriptors, dtype=np.float32)
    b = a if others is None else np.asarray(others, dtype=np.float32)
    if a.ndim != 4 or b.ndim != 4 or a.shape[2] != 10 or b.shape[2:] != a.shape[2:]:
        raise ValueError(f"light fields of shapes {a.shape} and {b.shape} do not match")
    a2 = np.ascontiguousarray(a.reshape(len(a), -1, a.shape[3]))
    b2 = np.ascontiguousarray(b.reshape(len(b), -1, b.shape[3]))
    return _min_distances(a2, b2, view_permutations(), others is None)


# --------------------------------------------------------------------------------------
# Cached descriptors and matrices
# --------------------------------------------------------------------------------------


def _code_digest() -> str:
    """sha256 (12 hex) of this module's and the renderer's bytes."""
    h = hashlib.sha256(Path(__file__).read_bytes())
    h.update(Path(lightfield_render.__file__).read_bytes())
    return h.hexdigest()[:12]


def _cached_features(models: Sequence[Any], resolution: int) -> list[FloatArray]:
    """:func:`peer_features` of each model, cached under ``$SHAPEDB_BENCH_CACHE/lfd_peer``."""
    from bench.sets.datasets import CACHE_DIR, mesh_arrays

    folder = CACHE_DIR / "lfd_peer"
    folder.mkdir(parents=True, exist_ok=True)
    code, out = _code_digest(), []
    for m in models:
        key = hashlib.sha256(f"{m.source}|{m.name}".encode()).hexdigest()[:20]
        path = folder / f"{key}_{resolution}_{code}.npy"
        if not path.exists():
            np.save(path, peer_features(*mesh_arrays(m), resolution))
        out.append(np.load(path))
    return out


def peer_matrix(models: Sequence[Any], config: FaithfulLFDConfig | None = None) -> FloatArray:
    """:func:`peer_distance` between the models, (n, n); the features are cached."""
    cfg = config or FaithfulLFDConfig()
    feats = _cached_features(models, cfg.resolution)
    return peer_distance(np.stack([encode(f, cfg) for f in feats]))


def peer_split_matrix(models: Sequence[Any], config: FaithfulLFDConfig | None = None) -> FloatArray:
    """:func:`peer_matrix` of any models together (several sets' splits), (n, n), cached
    under ``$SHAPEDB_BENCH_CACHE/lfd_peer/matrices`` by the models, the code and the config."""
    from bench.sets.datasets import CACHE_DIR

    cfg = config or FaithfulLFDConfig()
    keys = "\n".join(f"{m.source}|{m.name}" for m in models)
    key = hashlib.sha256(f"{_code_digest()}{astuple(cfg)}{keys}".encode()).hexdigest()[:16]
    path = CACHE_DIR / "lfd_peer" / "matrices" / f"{key}.npy"
    if path.exists():
        return np.load(path)
    t = time.perf_counter()
    d = peer_matrix(models, cfg)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, d)
    print(f"  light field distances (the published method) {d.shape}: "
          f"{time.perf_counter() - t:.0f} s", flush=True)  # fmt: skip
    return d


def _splat_peer(models: Sequence[Any]) -> FloatArray:
    from bench.support.lightfield import lfd_split_matrix

    return np.asarray(lfd_split_matrix(models), dtype=np.float64)


FULL = FaithfulLFDConfig()
#: The rows of the variants table: name -> distance matrix of a list of models.
VARIANTS: dict[str, Callable[[Sequence[Any]], FloatArray]] = {
    "published method (10 fields, 256 px, Z + F, 8 bits)": lambda m: peer_split_matrix(m, FULL),
    "1 light field": lambda m: peer_split_matrix(m, replace(FULL, n_fields=1)),
    "Zernike only": lambda m: peer_split_matrix(m, replace(FULL, fourier=False)),
    "128 px": lambda m: peer_split_matrix(m, replace(FULL, resolution=128)),
    "no quantisation": lambda m: peer_split_matrix(m, replace(FULL, quantise=False)),
    "splat peer (bench.support.lightfield)": _splat_peer,
}


def variant_matrices(models: Sequence[Any]) -> dict[str, FloatArray]:
    """Every :data:`VARIANTS` row's (n, n) distances between ``models``, timed."""
    out = {}
    for name, fn in VARIANTS.items():
        t = time.perf_counter()
        out[name] = fn(models)
        print(f"  {name}: {time.perf_counter() - t:.0f} s", flush=True)
    return out
