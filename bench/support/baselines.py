"""Baselines measured beside the MDBD kernel: the D2 shape distribution and GraKeL kernels.

D2 (Osada, Funkhouser, Chazelle and Dobkin, "Shape distributions", ACM TOG 2002)
    ``n_pairs`` random pairs of points sampled uniformly (by area) on the surface;
    the histogram of their distances, normalised by the mean distance (the
    normalisation the paper found best), ``bins`` fixed-size bins, reduced to a
    piecewise-linear function of ``vertices`` samples, compared with the L1 norm
    of the PDFs. The paper's defaults are 1024**2 pairs, 1024 bins, 64 vertices.

Spherical harmonic descriptor (Kazhdan, Funkhouser and Rusinkiewicz, SGP 2003)
    A view- and rotation-independent peer of the light field descriptor: ``n_points``
    points sampled uniformly (by area) on the surface, centred on their mean and
    divided by their mean distance from it; ``shells`` concentric shells out to twice
    that distance (points beyond go to the last); per shell the spherical-harmonic
    expansion of the points' directions (a sum of deltas, degrees ``l < bands``) and
    its energy per degree, ``sqrt(sum_m |a_lm|^2)``, divided by the number of points;
    compared with the L2 norm. Kazhdan's original expands a voxelised, blurred surface
    indicator (32 shells, 16 degrees); sampling the surface is the same function up to
    the blur.

Light field descriptor (Chen, Tian, Shen and Ouhyoung, Eurographics 2003)
    Zernike and Fourier descriptors of silhouettes from the 10 view pairs of a
    dodecahedron, several light fields per model, the distance minimised over the 60
    rotations of the dodecahedron and over light-field pairs; in its own module,
    :mod:`bench.support.lightfield` (``LFDConfig``, ``lfd_descriptor``, ``lfd_similarity``),
    which samples surfaces with :func:`sample_surface` from here.

GraKeL graph kernels (Siglidis et al., JMLR 2020) on the MDBD contact graphs
    Shortest-Path, Weisfeiler-Lehman subtree and Pyramid Match, all normalised
    (k(x, y) / sqrt(k(x, x) k(y, y))), with discrete node labels
    ``round(25 * r / r1) / 25`` as in the MDBD paper (section 3.2.2).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "D2Config",
    "sample_surface",
    "d2_descriptor",
    "SHConfig",
    "sh_descriptor",
    "l1_similarity",
    "l2_similarity",
    "radius_labels",
    "to_grakel",
    "GRAKEL_KERNELS",
    "grakel_similarity",
    "KernelRun",
]


# --------------------------------------------------------------------------------------
# D2 shape distribution
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class D2Config:
    """Parameters of the D2 shape distribution.

    Attributes
    ----------
    n_pairs : int
        Random point pairs (Osada et al.: 1024**2).
    bins : int
        Fixed-size histogram bins over ``[0, max_ratio]`` (Osada et al.: 1024).
    vertices : int
        Samples of the piecewise-linear PDF that is compared (Osada et al.: 64).
    max_ratio : float
        Upper end of the histogram, in multiples of the mean distance.
    seed : int
        Seed of the point sampling, so that descriptors are reproducible.
    """

    n_pairs: int = 1024**2
    bins: int = 1024
    vertices: int = 64
    max_ratio: float = 4.0
    seed: int = 0


def sample_surface(
    vertices: ArrayLike, faces: ArrayLike, n: int, *, rng: np.random.Generator
) -> NDArray[np.float64]:
    """Points sampled uniformly by area on a triangle soup.

    Parameters
    ----------
    vertices : (v, 3) float
        Vertex positions.
    faces : (f, 3) int
        Triangles (orientation and connectivity are irrelevant).
    n : int
        Number of points.
    rng : numpy.random.Generator
        Source of randomness.

    Returns
    -------
    (n, 3) float64
        The sampled points.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total = float(area.sum())
    if not total > 0:
        raise ValueError("the mesh has zero surface area: cannot sample it")
    idx = rng.choice(len(f), size=n, p=area / total)
    u = rng.random((n, 2))
    flip = u.sum(axis=1) > 1.0
    u[flip] = 1.0 - u[flip]
    t = tri[idx]
    return t[:, 0] + u[:, :1] * (t[:, 1] - t[:, 0]) + u[:, 1:] * (t[:, 2] - t[:, 0])


def d2_descriptor(
    vertices: ArrayLike, faces: ArrayLike, config: D2Config | None = None
) -> NDArray[np.float64]:
    """The D2 shape distribution of a triangle mesh, as a ``(vertices,)`` PDF.

    Parameters
    ----------
    vertices : (v, 3) float
        Vertex positions.
    faces : (f, 3) int
        Triangles.
    config : D2Config, optional
        Sampling and histogram parameters.

    Returns
    -------
    (config.vertices,) float64
        Piecewise-linear PDF of the mean-normalised distances, summing to 1;
        invariant to translation, rotation and scale.
    """
    cfg = config or D2Config()
    rng = np.random.default_rng(cfg.seed)
    # Sample in chunks to bound memory: 2 points per pair.
    chunk = 1 << 18
    dists = np.empty(cfg.n_pairs, dtype=np.float64)
    for s in range(0, cfg.n_pairs, chunk):
        m = min(chunk, cfg.n_pairs - s)
        p = sample_surface(vertices, faces, 2 * m, rng=rng)
        dists[s : s + m] = np.linalg.norm(p[:m] - p[m:], axis=1)
    mean = float(dists.mean())
    if not mean > 0:
        raise ValueError("all sampled distances are zero: degenerate mesh")
    hist, _ = np.histogram(dists / mean, bins=cfg.bins, range=(0.0, cfg.max_ratio))
    hist = hist.astype(np.float64)
    # Piecewise-linear reduction: average consecutive bins into ``vertices`` samples.
    if cfg.bins % cfg.vertices == 0:
        pdf = hist.reshape(cfg.vertices, -1).sum(axis=1)
    else:
        x = (np.arange(cfg.bins) + 0.5) / cfg.bins
        xv = (np.arange(cfg.vertices) + 0.5) / cfg.vertices
        pdf = np.interp(xv, x, hist)
    return pdf / max(pdf.sum(), 1e-300)


@dataclass(frozen=True)
class SHConfig:
    """Parameters of the spherical harmonic descriptor.

    Attributes
    ----------
    n_points : int
        Surface samples.
    shells : int
        Concentric shells out to twice the mean distance (Kazhdan et al.: 32).
    bands : int
        Degrees 0..bands-1 per shell (Kazhdan et al.: 16).
    seed : int
        Seed of the sampling.
    """

    n_points: int = 8000
    shells: int = 32
    bands: int = 16
    seed: int = 0


def sh_descriptor(
    vertices: ArrayLike, faces: ArrayLike, config: SHConfig | None = None
) -> NDArray[np.float64]:
    """The spherical harmonic descriptor of a triangle mesh: (shells * bands,) float64.

    Parameters
    ----------
    vertices : (v, 3) float
        Vertex positions.
    faces : (f, 3) int
        Triangles (orientation and connectivity are irrelevant).
    config : SHConfig, optional
        Sampling, shells and degrees.

    Returns
    -------
    (config.shells * config.bands,) float64
        Shell-major energies; invariant to rotation, translation and scale.
    """
    from scipy.special import sph_harm_y

    cfg = config or SHConfig()
    rng = np.random.default_rng(cfg.seed)
    p = sample_surface(vertices, faces, cfg.n_points, rng=rng)
    x = p - p.mean(axis=0)
    dist = np.linalg.norm(x, axis=1)
    mean = float(dist.mean())
    if not mean > 0:
        raise ValueError("all surface samples coincide: degenerate mesh")
    shell = np.minimum((dist / (2.0 * mean) * cfg.shells).astype(np.int64), cfg.shells - 1)
    theta = np.arccos(np.clip(x[:, 2] / np.maximum(dist, 1e-300), -1.0, 1.0))
    phi = np.arctan2(x[:, 1], x[:, 0])
    out = np.zeros((cfg.shells, cfg.bands))
    for n in range(cfg.bands):
        power = np.zeros(cfg.shells)
        for m in range(n + 1):  # |a_l,-m| = |a_lm| for a real function
            y = sph_harm_y(n, m, theta, phi)
            a = np.bincount(shell, weights=y.real, minlength=cfg.shells) + 1j * np.bincount(
                shell, weights=y.imag, minlength=cfg.shells
            )
            power += (2.0 if m else 1.0) * np.abs(a) ** 2
        out[:, n] = np.sqrt(power) / len(p)
    return out.reshape(-1)


def l2_similarity(descriptors: ArrayLike, others: ArrayLike | None = None) -> NDArray[np.float64]:
    """Similarity ``-L2`` between rows of descriptor matrices: (n, m) float64.

    Parameters
    ----------
    descriptors : (n, d) float
        Query descriptors.
    others : (m, d) float, optional
        Database descriptors; defaults to ``descriptors``.
    """
    a = np.asarray(descriptors, dtype=np.float64)
    b = a if others is None else np.asarray(others, dtype=np.float64)
    d2 = (a**2).sum(axis=1)[:, None] + (b**2).sum(axis=1)[None, :] - 2.0 * a @ b.T
    return -np.sqrt(np.maximum(d2, 0.0))


def l1_similarity(descriptors: ArrayLike, others: ArrayLike | None = None) -> NDArray[np.float64]:
    """Similarity ``-L1`` between rows of descriptor matrices.

    Parameters
    ----------
    descriptors : (n, d) float
        Query descriptors.
    others : (m, d) float, optional
        Database descriptors; defaults to ``descriptors``.

    Returns
    -------
    (n, m) float64
        Negated L1 distances (larger is more similar).
    """
    a = np.asarray(descriptors, dtype=np.float64)
    b = a if others is None else np.asarray(others, dtype=np.float64)
    out = np.empty((len(a), len(b)))
    for i in range(len(a)):
        out[i] = -np.abs(b - a[i]).sum(axis=1)
    return out


# --------------------------------------------------------------------------------------
# GraKeL kernels on MDBD contact graphs
# --------------------------------------------------------------------------------------


def radius_labels(radii: ArrayLike, *, n_d: int = 25) -> NDArray[np.float64]:
    """Discrete node labels ``round(n_d * r / r1) / n_d`` (the paper's rounding).

    Parameters
    ----------
    radii : (n,) float
        Ball radii, largest first.
    n_d : int
        Number of levels per unit of r/r1 (the paper: 25).
    """
    r = np.asarray(radii, dtype=np.float64)
    if r.size == 0:
        return r
    return np.round(n_d * r / r.max()) / n_d


def to_grakel(radii: ArrayLike, edges: ArrayLike, *, n_d: int = 25) -> Any:
    """A :class:`grakel.Graph` with radius labels from a ball decomposition.

    Parameters
    ----------
    radii : (n,) float
        Ball radii.
    edges : (m, 2) int
        Contact edges (undirected).
    n_d : int
        Rounding of the labels, see :func:`radius_labels`.
    """
    from shapedb.errors import require

    grakel = require("grakel", extra="bench", feature="GraKeL baseline kernels")
    labels = radius_labels(radii, n_d=n_d)
    n = len(labels)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    e = e[e[:, 0] != e[:, 1]]
    adj = np.zeros((n, n), dtype=np.float64)
    adj[e[:, 0], e[:, 1]] = 1.0
    adj[e[:, 1], e[:, 0]] = 1.0
    # Integer-coded labels hash fast and compare exactly.
    node_labels = {i: int(round(lab * n_d)) for i, lab in enumerate(labels.tolist())}
    return grakel.Graph(adj, node_labels=node_labels)


def _kernel_factories() -> dict[str, Any]:
    from shapedb.errors import require

    kernels = require("grakel.kernels", extra="bench", feature="GraKeL baseline kernels")
    return {
        "shortest_path": lambda: kernels.ShortestPath(normalize=True, with_labels=True),
        "wl_subtree": lambda: kernels.WeisfeilerLehman(
            n_iter=5, base_graph_kernel=kernels.VertexHistogram, normalize=True
        ),
        "pyramid_match": lambda: kernels.PyramidMatch(normalize=True, with_labels=True),
    }


#: The three GraKeL kernels of the paper's Table 2, by name.
GRAKEL_KERNELS: tuple[str, ...] = ("shortest_path", "wl_subtree", "pyramid_match")


@dataclass(frozen=True)
class KernelRun:
    """A kernel matrix and the time it took.

    Attributes
    ----------
    name : str
        Kernel name.
    matrix : (n, n) float64
        Normalised kernel values (1 on the diagonal).
    seconds : float
        Wall-clock time of the whole matrix.
    """

    name: str
    matrix: NDArray[np.float64]
    seconds: float


def grakel_similarity(
    graphs: Sequence[tuple[ArrayLike, ArrayLike]],
    *,
    kernels: Sequence[str] = GRAKEL_KERNELS,
    n_d: int = 25,
) -> dict[str, KernelRun]:
    """Normalised GraKeL kernel matrices over MDBD graphs.

    Parameters
    ----------
    graphs : sequence of (radii (n,), edges (m, 2))
        One decomposition per model.
    kernels : sequence of str
        Names from :data:`GRAKEL_KERNELS`.
    n_d : int
        Label rounding, see :func:`radius_labels`.

    Returns
    -------
    dict[str, KernelRun]
        One run per kernel.
    """
    factories = _kernel_factories()
    unknown = set(kernels) - set(factories)
    if unknown:
        raise ValueError(f"unknown GraKeL kernel(s) {sorted(unknown)}; known: {GRAKEL_KERNELS}")
    t0 = time.perf_counter()
    gk = [to_grakel(r, e, n_d=n_d) for r, e in graphs]
    convert = time.perf_counter() - t0
    out: dict[str, KernelRun] = {}
    for name in kernels:
        t0 = time.perf_counter()
        k = np.asarray(factories[name]().fit_transform(gk), dtype=np.float64)
        k = np.nan_to_num(k, nan=0.0)
        out[name] = KernelRun(name, k, time.perf_counter() - t0 + convert)
    return out
