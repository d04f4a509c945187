"""Features of the ball union: what a shape looks like at the scale of its parts.

The distribution blocks of :mod:`shapedb.signature.descriptor` see the balls as a bag of sizes
and distances, and its graph blocks see their contacts; neither sees *where* the
volume lies around the shape (a table's top over four legs, a house's walls under a
roof). This block does, and stays representation-agnostic because it is computed from
the decomposition's balls only: the occupancy of the union of the balls, restricted
to concentric spheres about its volume centroid, expanded in spherical harmonics, and
reduced to the energy of each degree on each sphere (Kazhdan, Funkhouser and
Rusinkiewicz, "Rotation invariant spherical harmonic representation of 3D shape
descriptors", SGP 2003). The energies do not change when the shape turns.

* Centre: the balls' volume centroid ``o = sum v_i c_i`` (``v_i = r_i^3 / sum r^3``).
* Scale: ``R = 2 sqrt(sum v_i (|c_i - o|^2 + 0.6 r_i^2))``, twice the RMS radius of the
  union's volume (a ball's own second moment is 3/5 r^2); ``shells`` spheres of radii
  ``(k + 1/2) R / shells``.
* Occupancy: soft, ``max_i clip((r_i - |p - c_i|) / w + 1/2, 0, 1)`` with ``w`` the
  shell spacing, so that a ball crossing a sphere counts by how deep it crosses.
* Sphere sampling: Gauss-Legendre in ``cos(theta)`` times an even grid in ``phi``
  (exact for the degrees used); energies ``sqrt(sum_m |a_lm|^2)`` for
  ``l < bands``, divided by ``sqrt(4 pi)`` (a full sphere has energy 1 at ``l = 0``).

:func:`shell_energies` is the expansion itself, for any function sampled on the
spheres (the bench's spherical-harmonic baseline uses it on surface samples).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["union_features", "centred_balls", "shell_energies", "sphere_grid", "SHELLS", "BANDS"]

FloatArray = NDArray[np.float64]

#: Concentric spheres of :func:`union_features`.
SHELLS = 16
#: Spherical-harmonic degrees 0..BANDS-1 of :func:`union_features`.
BANDS = 8
#: Points per sphere: Gauss-Legendre nodes in cos(theta) x even steps in phi.
_N_THETA = 24
_N_PHI = 48
#: Balls considered per chunk of sample points (bounds the temporary arrays).
_CHUNK = 4096


def centred_balls(centers: ArrayLike, radii: ArrayLike) -> tuple[FloatArray, FloatArray, float]:
    """The balls of positive radius about their volume centroid, and the union's scale.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres.
    radii : (n,) float
        Ball radii, same units; balls of radius <= 0 are left out.

    Returns
    -------
    x : (m, 3) float64
        Centres relative to the volume-weighted centroid (weights ``r^3``).
    r : (m,) float64
        Their radii.
    R : float
        ``2 sqrt(sum v (|x|^2 + 0.6 r^2))`` with ``v = r^3 / sum r^3``: twice the radius
        of gyration of the union (each ball a solid sphere); 0 when no ball is left.

    Raises
    ------
    ValueError
        If the arrays' lengths disagree.
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if len(c) != len(r):
        raise ValueError(f"centers ({len(c)}) and radii ({len(r)}) must have the same length")
    keep = r > 0
    c, r = c[keep], r[keep]
    if len(r) == 0:
        return np.zeros((0, 3)), r, 0.0
    v = r**3 / (r**3).sum()
    x = c - v @ c
    return x, r, 2.0 * float(np.sqrt(v @ ((x**2).sum(axis=1) + 0.6 * r**2)))


@lru_cache(maxsize=8)
def sphere_grid(n_theta: int = _N_THETA, n_phi: int = _N_PHI) -> tuple[FloatArray, FloatArray]:
    """Unit directions (n_theta * n_phi, 3) and quadrature weights (n_theta * n_phi,), sum 4 pi."""
    x, wx = np.polynomial.legendre.leggauss(n_theta)
    theta = np.arccos(x)
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    w = np.repeat(wx * (2 * np.pi / n_phi), n_phi)
    return dirs.reshape(-1, 3), w


@lru_cache(maxsize=8)
def _harmonics(
    bands: int, n_theta: int, n_phi: int
) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Conjugate spherical harmonics (n_dirs, bands^2) on :func:`sphere_grid`, and each column's degree."""
    from scipy.special import sph_harm_y

    dirs, _ = sphere_grid(n_theta, n_phi)
    theta = np.arccos(np.clip(dirs[:, 2], -1.0, 1.0))
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    cols, degree = [], []
    for n in range(bands):
        for m in range(-n, n + 1):
            cols.append(np.conj(sph_harm_y(n, m, theta, phi)))
            degree.append(n)
    return np.stack(cols, axis=1), np.asarray(degree)


def shell_energies(
    values: ArrayLike, bands: int, *, n_theta: int = _N_THETA, n_phi: int = _N_PHI
) -> FloatArray:
    """Energy per degree of functions sampled on :func:`sphere_grid`: (shells, bands).

    Parameters
    ----------
    values : (shells, n_theta * n_phi) float
        One function per sphere, at the directions of ``sphere_grid(n_theta, n_phi)``.
    bands : int
        Degrees 0..bands-1 (at most ``n_theta``, for exact quadrature).

    Returns
    -------
    (shells, bands) float64
        ``sqrt(sum_m |a_lm|^2) / sqrt(4 pi)``: invariant to rotations of the functions.
    """
    f = np.asarray(values, dtype=np.float64)
    _, w = sphere_grid(n_theta, n_phi)
    y, degree = _harmonics(bands, n_theta, n_phi)
    a = (f * w) @ y  # (shells, bands^2)
    power = np.abs(a) ** 2
    out = np.zeros((len(f), bands))
    for n in range(bands):
        out[:, n] = power[:, degree == n].sum(axis=1)
    return np.sqrt(out) / np.sqrt(4 * np.pi)


def union_features(
    centers: ArrayLike, radii: ArrayLike, *, shells: int = SHELLS, bands: int = BANDS
) -> FloatArray:
    """Spherical-harmonic energies of the ball union's occupancy: (shells * bands,) float64.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, any units.
    radii : (n,) float
        Ball radii, same units, >= 0.
    shells : int
        Concentric spheres (see the module docstring).
    bands : int
        Degrees per sphere, at most 16.

    Returns
    -------
    (shells * bands,) float64
        Shell-major energies in [0, 1]; invariant to rotation, translation and scale of
        the balls; zeros when there is no ball of positive radius.

    Raises
    ------
    ValueError
        If the arrays' shapes disagree.
    """
    out = np.zeros(shells * bands)
    x, r, R = centred_balls(centers, radii)
    if not R > 0:
        return out
    width = R / shells
    rho = (np.arange(shells) + 0.5) * width
    dirs, _ = sphere_grid()
    pts = (rho[:, None, None] * dirs[None, :, :]).reshape(-1, 3).astype(np.float32)
    xc, rc = x.astype(np.float32), r.astype(np.float32)
    occ = np.zeros(len(pts), dtype=np.float32)
    cc = (xc**2).sum(axis=1)
    for lo in range(0, len(pts), _CHUNK):
        p = pts[lo : lo + _CHUNK]
        d2 = (p**2).sum(axis=1)[:, None] + cc[None, :] - 2.0 * (p @ xc.T)
        depth = rc[None, :] - np.sqrt(np.maximum(d2, 0.0))
        occ[lo : lo + _CHUNK] = np.clip(depth.max(axis=1) / width + 0.5, 0.0, 1.0)
    e = shell_energies(occ.reshape(shells, -1).astype(np.float64), bands)
    return e.reshape(-1)
