"""Views of the ball union: silhouettes and depth images, from the balls alone.

What a shape looks like from outside, in the spirit of the light field descriptor
(Chen, Tian, Shen and Ouhyoung, "On visual similarity based 3D model retrieval",
Eurographics 2003), but computed from the decomposition so that it stays
representation-agnostic: seen along a direction ``d``, a ball of centre ``c`` and
radius ``r`` projects to a disc of radius ``r`` about ``c``'s projection, its front
at depth ``c . d + sqrt(r^2 - rho^2)`` at distance ``rho`` from the disc's centre. The
union of the discs is the silhouette; the nearest front is the depth image.

* Frame: the balls' volume centroid ``o`` and the scale ``R`` of
  :mod:`shapedb.signature.union` (twice the RMS radius of the union's volume), so the images do
  not change when the balls are moved or scaled.
* Directions: :data:`DIRECTIONS` unit vectors spread evenly over a half sphere
  (a Fibonacci lattice; a direction and its opposite see mirrored silhouettes).
* Images, sampled on a polar grid about ``o``'s projection: ``rings`` circles of radii
  ``(k + 1/2) R / rings`` times ``samples`` even angles.

  - silhouette: soft coverage ``max_i clip((r_i - |p - c_i|) / w + 1/2, 0, 1)``, ``w``
    the ring spacing, so a disc counts by how far it reaches past a sample;
  - depth: ``(h / R + 1) / 2`` clipped to [0, 1] where some disc covers the sample
    (``h`` the front's height towards the viewer), 0 elsewhere; seen from ``d`` and from
    ``-d`` (the back), both pooled as depth images.
* Per image: the magnitudes of the first ``harmonics`` Fourier coefficients along each
  ring, divided by ``samples``: invariant to turning the image in its plane and to
  mirroring it.
* Over the directions: the mean and the standard deviation of each number (depth
  images: over both sides), so that the vector does not depend on how the shape is
  turned, up to the sampling of the directions.

The vector is ``[sil mean, sil std, depth mean, depth std]``, each ``rings *
harmonics`` long (ring-major), compared with L1.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.signature.union import centred_balls

__all__ = [
    "view_features",
    "view_images",
    "view_directions",
    "view_dim",
    "DIRECTIONS",
    "RINGS",
    "HARMONICS",
    "SAMPLES",
]

FloatArray = NDArray[np.float64]

#: View directions over the half sphere.
DIRECTIONS = 24
#: Circles of the polar sampling of each image.
RINGS = 8
#: Fourier magnitudes kept along each circle (0 .. HARMONICS - 1).
HARMONICS = 8
#: Samples along each circle.
SAMPLES = 32
#: Image samples per chunk (bounds the (samples, balls) temporaries).
_CHUNK = 2048


def view_dim(rings: int = RINGS, harmonics: int = HARMONICS) -> int:
    """Length of :func:`view_features`' vector: ``4 * rings * harmonics``."""
    return 4 * rings * harmonics


@lru_cache(maxsize=8)
def view_directions(n: int = DIRECTIONS) -> FloatArray:
    """(n, 3) unit view directions over the half sphere ``z > 0``.

    The upper half of a Fibonacci lattice of ``2 n`` points on the sphere (so the
    directions are evenly spread and no two are opposite).
    """
    i = np.arange(2 * n) + 0.5
    z = 1.0 - 2.0 * i / (2 * n)
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    s = np.sqrt(1.0 - z * z)
    d = np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)
    out = d[z > 0]
    out.setflags(write=False)
    return out


def _basis(d: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors spanning the image plane of direction ``d``."""
    a = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(d, a)
    u /= np.linalg.norm(u)
    return u, np.cross(d, u)


def view_images(
    centers: ArrayLike,
    radii: ArrayLike,
    *,
    directions: int = DIRECTIONS,
    rings: int = RINGS,
    samples: int = SAMPLES,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Silhouettes and front and back depth images of the ball union on polar grids.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, any units.
    radii : (n,) float
        Ball radii, same units, >= 0 (balls of radius 0 are left out).
    directions : int
        Number of view directions (:func:`view_directions`).
    rings, samples : int
        Circles, and samples along each, of the polar grid (see the module docstring).

    Returns
    -------
    silhouette, front, back : (directions, rings, samples) float64 each
        In [0, 1]; all zeros when there is no ball of positive radius. ``back`` is the
        depth image seen from the opposite direction.

    Raises
    ------
    ValueError
        If the arrays' shapes disagree.
    """
    shape = (directions, rings, samples)
    x, r, big_r = centred_balls(centers, radii)
    if not big_r > 0:
        return np.zeros(shape), np.zeros(shape), np.zeros(shape)
    width = big_r / rings
    rho = (np.arange(rings) + 0.5) * width
    ang = 2.0 * np.pi * np.arange(samples) / samples
    grid = np.stack([np.outer(rho, np.cos(ang)).ravel(), np.outer(rho, np.sin(ang)).ravel()], 1)
    dirs = view_directions(directions)
    # every direction's grid at once: sample points (directions * rings * samples, 2)
    planes = np.stack([np.stack(_basis(d), axis=1) for d in dirs])  # (directions, 3, 2)
    proj = np.einsum("nk,dkj->dnj", x, planes).astype(np.float32)  # (directions, n, 2)
    height = (x @ dirs.T).T.astype(np.float32)  # (directions, n)
    rf = r.astype(np.float32)
    r2 = rf**2
    g = grid.astype(np.float32)
    m = len(g)
    sil = np.zeros((directions, m))
    front = np.zeros((directions, m))
    back = np.zeros((directions, m))
    step = max(1, _CHUNK // m) if m < _CHUNK else 1
    for lo in range(0, directions, step):
        p = proj[lo : lo + step]  # (b, n, 2)
        h = height[lo : lo + step]  # (b, n)
        d2 = (
            (g**2).sum(1)[None, :, None]
            + (p**2).sum(2)[:, None, :]
            - 2.0 * np.einsum("sj,bnj->bsn", g, p)
        )
        d2 = np.maximum(d2, 0.0)  # (b, m, n)
        reach = (rf - np.sqrt(d2)).max(axis=2)
        sil[lo : lo + step] = np.clip(reach / width + 0.5, 0.0, 1.0)
        half = np.sqrt(np.maximum(r2 - d2, 0.0))
        inside = d2 < r2
        top = np.where(inside, h[:, None, :] + half, -np.inf).max(axis=2)
        bottom = np.where(inside, h[:, None, :] - half, np.inf).min(axis=2)
        hit = np.isfinite(top)
        front[lo : lo + step] = np.where(hit, np.clip((top / big_r + 1.0) / 2.0, 0.0, 1.0), 0.0)
        back[lo : lo + step] = np.where(hit, np.clip((1.0 - bottom / big_r) / 2.0, 0.0, 1.0), 0.0)
    return sil.reshape(shape), front.reshape(shape), back.reshape(shape)


def _ring_spectra(images: FloatArray, harmonics: int) -> FloatArray:
    """(k, rings * harmonics): Fourier magnitudes along each ring, / samples."""
    spec = np.abs(np.fft.rfft(images, axis=-1))[..., :harmonics] / images.shape[-1]
    if spec.shape[-1] < harmonics:
        spec = np.concatenate(
            [spec, np.zeros((*spec.shape[:-1], harmonics - spec.shape[-1]))], axis=-1
        )
    return spec.reshape(len(images), -1)


def view_features(
    centers: ArrayLike,
    radii: ArrayLike,
    *,
    directions: int = DIRECTIONS,
    rings: int = RINGS,
    harmonics: int = HARMONICS,
    samples: int = SAMPLES,
) -> FloatArray:
    """The view signature of a ball union: (view_dim(rings, harmonics),) float64.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, any units.
    radii : (n,) float
        Ball radii, same units, >= 0.
    directions, rings, samples : int
        As :func:`view_images`.
    harmonics : int
        Fourier magnitudes kept per ring, at most ``samples // 2 + 1`` carry content
        (the rest are 0).

    Returns
    -------
    (4 * rings * harmonics,) float64
        ``[silhouette mean, silhouette std, depth mean, depth std]`` over the
        directions (see the module docstring); invariant to translation and scale of
        the balls, to rotation up to the sampling of the directions; zeros when there
        is no ball of positive radius.

    Raises
    ------
    ValueError
        If the arrays' shapes disagree.
    """
    sil, front, back = view_images(
        centers, radii, directions=directions, rings=rings, samples=samples
    )
    s = _ring_spectra(sil, harmonics)
    d = _ring_spectra(np.concatenate([front, back]), harmonics)
    return np.concatenate([s.mean(axis=0), s.std(axis=0), d.mean(axis=0), d.std(axis=0)])
