"""The field vector: depth buffers and spherical harmonics of the field's inside.

Two rotation-invariant descriptors of the inside of the signed field the MDBD packs
(:class:`shapedb.geometry.inside.Inside`: its shell of cells, model units), both compared by L1
(so a faiss index holds them):

- :func:`depth_buffer_descriptor` (Vranic's depth buffer descriptor): the shell cells in
  their principal frame, six orthographic depth images (+-x, +-y, +-z), their low 2D
  Fourier magnitudes made invariant to the frame's sign flips (each image's magnitudes
  symmetrised over flips of its axes; opposite views paired by their sum and absolute
  difference);
- :func:`harmonic_energies` (Kazhdan's spherical-harmonic descriptor): per concentric
  sphere about the volume centroid and per degree, the norm of the spherical-harmonic
  coefficients of the shell cells, with each cell's direction snapped to an angle grid
  on which the harmonics are evaluated once per process.

:func:`field_vector` concatenates them, ``[depth, harmonic]`` (:func:`field_vector_parts`),
float32, under a :class:`shapedb.config.core.FieldVectorConfig`; a store with
``Config.stores_field_vectors`` keeps it per record (``field_vector`` column), and the
``"lightfield"`` scorer fuses its parts' L1 distances into the light field distance
(:class:`query.search.tuning.StageTuning`).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.config.core import Config
from shapedb.config.field_vector import FieldVectorConfig
from shapedb.geometry.inside import Inside
from shapedb.mdbd.decomposition import Decomposition

__all__ = [
    "principal_coordinates",
    "depth_images",
    "depth_buffer_descriptor",
    "spherical_coordinates",
    "harmonic_energies",
    "field_vector",
    "field_vector_dim",
    "field_vector_parts",
    "decomposition_field_vector",
]

FloatArray = NDArray[np.float64]


def _section(config: FieldVectorConfig | Config | None) -> FieldVectorConfig:
    if config is None:
        return FieldVectorConfig()
    if isinstance(config, Config):
        return config.field_vector
    if not isinstance(config, FieldVectorConfig):
        raise TypeError(f"config must be a FieldVectorConfig or Config, got {type(config)}")
    return config


# --------------------------------------------------------------------------------------
# Depth buffer descriptor
# --------------------------------------------------------------------------------------


def principal_coordinates(shell: ArrayLike, centroid: ArrayLike) -> tuple[FloatArray, float]:
    """The shell's cells about ``centroid`` in their principal frame, scaled into the unit cube.

    Parameters
    ----------
    shell : (s, 3) float
        Cell centres, model units; s >= 1.
    centroid : (3,) float
        The solid's volume centroid, model units.

    Returns
    -------
    (s, 3) float64, float
        Coordinates along the principal axes (largest variance first), divided by the
        largest absolute coordinate so they lie in [-1, 1]; and that divisor (model units).
        Axis signs are arbitrary: the descriptors are invariant to them.

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    x = np.asarray(shell, dtype=np.float64) - np.asarray(centroid, dtype=np.float64)
    if len(x) == 0:
        raise ValueError("empty shell: no inside cell")
    _, v = np.linalg.eigh(x.T @ x / len(x))
    y = x @ v[:, ::-1]
    s = float(np.abs(y).max())
    if not s > 0:
        raise ValueError("degenerate shell: every cell on the centroid")
    return y / s, s


def depth_images(coords: ArrayLike, half_cell: float, resolution: int) -> FloatArray:
    """Six orthographic depth images of cells (cubes of ``2 * half_cell`` splatted as squares).

    Parameters
    ----------
    coords : (s, 3) float
        Cell centres in [-1, 1].
    half_cell : float
        Half a cell's edge in the same units.
    resolution : int
        Pixels per side.

    Returns
    -------
    (6, resolution, resolution) float64
        Views from +x, -x, +y, -y, +z, -z; image axes are the two other coordinates in
        increasing order (no mirroring between opposite views). A pixel holds the
        nearest surface's height above the far face of the unit cube, in [0, 1]
        (0: nothing seen).
    """
    c = np.asarray(coords, dtype=np.float64)
    n = int(resolution)
    pix = 2.0 / n
    r = int(np.ceil(max(half_cell - pix / 2, 0.0) / pix))
    out = np.zeros((6, n * n))
    for axis in range(3):
        a, b = [k for k in range(3) if k != axis]
        iu = np.floor((c[:, a] + 1.0) / pix).astype(np.int64)
        iv = np.floor((c[:, b] + 1.0) / pix).astype(np.int64)
        for sign, view in ((1.0, 2 * axis), (-1.0, 2 * axis + 1)):
            depth = (1.0 + sign * c[:, axis]) / 2.0
            img = out[view]
            for du in range(-r, r + 1):
                for dv in range(-r, r + 1):
                    u = np.clip(iu + du, 0, n - 1)
                    v = np.clip(iv + dv, 0, n - 1)
                    np.maximum.at(img, u * n + v, depth)
    return out.reshape(6, n, n)


def _flip_invariant(img: FloatArray, k: int) -> FloatArray:
    """Fourier magnitudes of an image made invariant to flipping either image axis."""
    f = np.abs(np.fft.fft2(img)) / img.size
    feats = []
    for u in range(k + 1):
        for v in range(k + 1 - u):
            a, b = f[u, v], f[-u, v]  # |F(u, v)|, |F(-u, v)| = |F(u, -v)|
            feats.append(a + b)
            if u and v:
                feats.append(abs(a - b))
    return np.asarray(feats)


def _depth_dim(frequencies: int) -> int:
    """Numbers of :func:`depth_buffer_descriptor` at ``frequencies``."""
    k = int(frequencies)
    per_image = (k + 1) * (k + 2) // 2 + k * (k - 1) // 2
    return 6 * per_image


def depth_buffer_descriptor(
    shell: ArrayLike,
    centroid: ArrayLike,
    cell: float,
    config: FieldVectorConfig | Config | None = None,
) -> FloatArray:
    """Vranic's depth buffer descriptor of a solid's shell cells.

    The cells in their principal frame (:func:`principal_coordinates`), six depth
    images (:func:`depth_images`, ``config.depth_resolution`` px), their Fourier
    magnitudes with ``u + v <= config.depth_frequencies`` made invariant to the
    principal axes' signs: each image's to flips of its axes, each pair of opposite
    views by the sum and the absolute difference of their features. Invariant to
    rotation, translation, uniform scale and mirroring up to the principal frame's
    stability (axes of nearly equal variance may swap); compare by L1.

    Parameters
    ----------
    shell : (s, 3) float
        Cell centres, model units.
    centroid : (3,) float
        Volume centroid, model units.
    cell : float
        Cell edge, model units, > 0.
    config : FieldVectorConfig or Config, optional
        Its depth fields (default: :class:`FieldVectorConfig`'s).

    Returns
    -------
    (6 * ((k + 1)(k + 2) / 2 + k (k - 1) / 2),) float64
        ``k = depth_frequencies``: 438 numbers at the default 8.

    Raises
    ------
    ValueError
        As :func:`principal_coordinates`.
    """
    cfg = _section(config)
    y, s = principal_coordinates(shell, centroid)
    imgs = depth_images(y, cell / 2.0 / s, cfg.depth_resolution)
    out = []
    for axis in range(3):
        p = _flip_invariant(imgs[2 * axis], cfg.depth_frequencies)
        m = _flip_invariant(imgs[2 * axis + 1], cfg.depth_frequencies)
        out += [p + m, np.abs(p - m)]
    return np.concatenate(out)


# --------------------------------------------------------------------------------------
# Spherical-harmonic energies
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=4)
def _harmonics_on_grid(bands: int, n_theta: int) -> tuple[FloatArray, NDArray[np.complex128]]:
    """Conjugate harmonics ``Y_lm`` (l < bands, 0 <= m <= l) at the centres of an angle grid.

    Returns the per-column weights (2 for m > 0, else 1) and (n_theta * 2 n_theta, columns).
    """
    from scipy.special import sph_harm_y

    n_phi = 2 * n_theta
    t = (np.arange(n_theta) + 0.5) * np.pi / n_theta
    p = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    tt, pp = (a.reshape(-1) for a in np.meshgrid(t, p, indexing="ij"))
    cols, weights = [], []
    for n in range(bands):
        for m in range(n + 1):
            cols.append(np.conj(sph_harm_y(n, m, tt, pp)))
            weights.append(2.0 if m else 1.0)
    return np.asarray(weights), np.stack(cols, axis=1)


def spherical_coordinates(
    shell: ArrayLike, centroid: ArrayLike, shells: int
) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Each shell cell's ring, polar angle and azimuth about ``centroid``.

    Parameters
    ----------
    shell : (s, 3) float
        Cell centres, model units.
    centroid : (3,) float
        Volume centroid, model units.
    shells : int
        Rings: distances to ``centroid`` over twice their mean, cut into ``shells`` equal
        rings (farther cells in the last).

    Returns
    -------
    (s,) int64, (s,) float64, (s,) float64
        Ring in [0, shells), polar angle in [0, pi] (from +z), azimuth in (-pi, pi].

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    x = np.asarray(shell, dtype=np.float64) - np.asarray(centroid, dtype=np.float64)
    dist = np.linalg.norm(x, axis=1)
    mean = float(dist.mean()) if len(x) else 0.0
    if not mean > 0:
        raise ValueError("degenerate shell: empty or every cell on the centroid")
    ring = np.minimum((dist / (2.0 * mean) * shells).astype(np.int64), shells - 1)
    theta = np.arccos(np.clip(x[:, 2] / np.maximum(dist, 1e-300), -1.0, 1.0))
    return ring, theta, np.arctan2(x[:, 1], x[:, 0])


def harmonic_energies(
    shell: ArrayLike, centroid: ArrayLike, config: FieldVectorConfig | Config | None = None
) -> FloatArray:
    """Spherical-harmonic energies of the shell cells on concentric spheres (Kazhdan's SHD).

    Each cell is a point mass. About the volume centroid, distances are scaled by twice
    their mean and cut into ``config.harmonic_shells`` rings; each cell's direction is
    snapped to an ``harmonic_angles`` x ``2 harmonic_angles`` grid in polar and
    azimuthal angle (the harmonics are evaluated once per grid and process). Per ring
    and degree ``l < harmonic_bands``: the norm of the degree's coefficients, divided
    by the number of cells. Invariant to rotation (up to the grids), translation and
    uniform scale; compare by L1.

    Parameters
    ----------
    shell : (s, 3) float
        Cell centres, model units.
    centroid : (3,) float
        Volume centroid, model units.
    config : FieldVectorConfig or Config, optional
        Its harmonic fields (default: :class:`FieldVectorConfig`'s).

    Returns
    -------
    (harmonic_shells * harmonic_bands,) float64
        Ring-major: ring ``i``'s degrees at ``[i * bands, (i + 1) * bands)``.

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    cfg = _section(config)
    shells, bands, n_theta = cfg.harmonic_shells, cfg.harmonic_bands, cfg.harmonic_angles
    ring, theta, phi = spherical_coordinates(shell, centroid, shells)
    phi = phi % (2 * np.pi)
    n_phi = 2 * n_theta
    it = np.minimum((theta / np.pi * n_theta).astype(np.int64), n_theta - 1)
    ip = np.minimum((phi / (2 * np.pi) * n_phi).astype(np.int64), n_phi - 1)
    g = n_theta * n_phi
    counts = np.bincount(ring * g + it * n_phi + ip, minlength=shells * g).reshape(shells, g)
    weights, table = _harmonics_on_grid(bands, n_theta)
    power = weights * np.abs(counts @ table) ** 2  # (shells, columns)
    degree = np.repeat(np.arange(bands), np.arange(1, bands + 1))
    out = np.stack([power[:, degree == n].sum(axis=1) for n in range(bands)], axis=1)
    return (np.sqrt(out) / len(ring)).reshape(-1)


# --------------------------------------------------------------------------------------
# The field vector
# --------------------------------------------------------------------------------------


def field_vector_dim(config: FieldVectorConfig | Config | None = None) -> int:
    """Length of :func:`field_vector` under ``config`` (950 at the defaults: 438 + 512)."""
    cfg = _section(config)
    return _depth_dim(cfg.depth_frequencies) + cfg.harmonic_shells * cfg.harmonic_bands


def field_vector_parts(config: FieldVectorConfig | Config | None = None) -> tuple[slice, slice]:
    """The depth buffer part and the harmonic part of a field vector, as slices."""
    cfg = _section(config)
    d = _depth_dim(cfg.depth_frequencies)
    return slice(0, d), slice(d, d + cfg.harmonic_shells * cfg.harmonic_bands)


def field_vector(
    inside: Inside, config: FieldVectorConfig | Config | None = None
) -> NDArray[np.float32]:
    """The field vector of a field's inside: ``[depth buffer descriptor, harmonic energies]``.

    Parameters
    ----------
    inside : Inside
        The inside of a decomposition's field (:attr:`shapedb.mdbd.decomposition.Decomposition.inside`).
    config : FieldVectorConfig or Config, optional
        Default: :class:`FieldVectorConfig`'s fields (``enabled`` is not read).

    Computed with one BLAS thread (:mod:`threadpoolctl`) whatever the process's setting:
    the harmonics' matrix product is small enough that a multi-threaded BLAS spends more
    CPU waking threads than computing.

    Returns
    -------
    (field_vector_dim(config),) float32
        Finite; parts as :func:`field_vector_parts`.

    Raises
    ------
    ValueError
        If the inside has no cell, or all its shell cells sit on its centroid.
    """
    from threadpoolctl import threadpool_limits

    if inside.count == 0 or len(inside.shell) == 0:
        raise ValueError("the field's inside is empty: no field vector")
    cfg = _section(config)
    with threadpool_limits(limits=1, user_api="blas"):
        depth = depth_buffer_descriptor(inside.shell, inside.centroid, float(inside.cell), cfg)
        harmonic = harmonic_energies(inside.shell, inside.centroid, cfg)
    return np.concatenate([depth, harmonic]).astype(np.float32)


def decomposition_field_vector(
    decomposition: Decomposition, config: FieldVectorConfig | Config | None = None
) -> NDArray[np.float32]:
    """:func:`field_vector` of a decomposition's inside.

    Parameters
    ----------
    decomposition : Decomposition
        Computed with ``decompose(..., keep_inside=True)`` (as ingest and an outside
        query of a store with ``Config.stores_field_vectors`` do).
    config : FieldVectorConfig or Config, optional

    Raises
    ------
    ValueError
        If the decomposition kept no inside (``decomposition.inside`` is None; records
        read back from a store never carry it), or as :func:`field_vector`.
    """
    if decomposition.inside is None:
        raise ValueError(
            "the decomposition has no inside: decompose with keep_inside=True for a field vector"
        )
    return field_vector(decomposition.inside, config)
