"""Filled-polygon silhouettes of a mesh and the published light field descriptor's image features.

What Chen, Tian, Shen and Ouhyoung (Eurographics 2003) compute per silhouette, as their
released code does it (the features of :mod:`shapedb.signature.lightfield_descriptor`
are a simplification: fixed disc, angle bins):

* **Rendering**: every triangle is filled (a pixel is covered when its centre lies in the
  projected triangle, whichever way the triangle turns) and its three edges are drawn
  as one-pixel lines, as an OpenGL render draws an edge-on triangle; so orientation,
  connectivity and watertightness do not matter and a sheet seen edge-on stays a line.
* **Centre and scale**: each silhouette is seen about the centre of its bounding box;
  the radius of the moments' unit disc is the largest distance of a covered pixel from
  its silhouette's centre over the light field's 10 silhouettes (one scale per light
  field, as the released code's ``FindRadius``).
* **Zernike moments**: the magnitudes ``|A_nm|`` (n <= 10, 0 <= m <= n, n - m even) of
  the mean of ``conj(V_nm)`` over the covered pixels, so ``|A_00| = 1`` always; it is
  dropped, which leaves the paper's 35 coefficients, each in [0, 1].
* **Fourier descriptors**: the outer contour (the longest iso-contour of the silhouette),
  resampled by arc length; its distance to the silhouette's centre, Fourier transformed;
  the magnitudes 1..10 divided by the constant term. A silhouette of several parts is
  described by the longest part's contour (the released code erodes, then thins).
"""

from __future__ import annotations

import functools
from math import factorial

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from shapedb.signature.lightfield_descriptor import image_axes

__all__ = [
    "normalised_vertices",
    "render_polygons",
    "zernike_35",
    "contour_fourier",
    "field_features",
    "ZERNIKE_ORDER",
    "FOURIER",
]

#: The paper's Zernike order (36 moments, 35 after the constant one).
ZERNIKE_ORDER = 10
#: The paper's Fourier descriptors per silhouette.
FOURIER = 10
#: Points the outer contour is resampled to before its Fourier transform.
CONTOUR_SAMPLES = 256

FloatArray = NDArray[np.float64]


def normalised_vertices(vertices: ArrayLike) -> FloatArray:
    """Vertices about their bounding box's centre, divided by the largest distance from it.

    Raises
    ------
    ValueError
        If the mesh has no vertex or all its vertices coincide.
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    if not len(v):
        raise ValueError("a mesh without vertices has no silhouette")
    v = v - 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = float(np.linalg.norm(v, axis=1).max())
    if not radius > 0:
        raise ValueError("a mesh whose vertices coincide has no silhouette")
    return v / radius


@njit(cache=True)
def _line(img: NDArray[np.bool_], x0: float, y0: float, x1: float, y1: float) -> None:
    """A one-pixel line between two points in pixel units (DDA, both ends drawn)."""
    res = img.shape[0]
    steps = int(np.ceil(max(abs(x1 - x0), abs(y1 - y0)))) + 1
    for s in range(steps + 1):
        t = s / steps
        c = int(np.floor(x0 + t * (x1 - x0)))
        r = int(np.floor(y0 + t * (y1 - y0)))
        if 0 <= c < res and 0 <= r < res:
            img[r, c] = True


@njit(cache=True)
def _rasterise(
    x: NDArray[np.float64], y: NDArray[np.float64], faces: NDArray[np.int64],
    img: NDArray[np.bool_],
) -> None:  # fmt: skip
    res = img.shape[0]
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, bx, by, cx, cy = x[a], y[a], x[b], y[b], x[c], y[c]
        _line(img, ax, ay, bx, by)
        _line(img, bx, by, cx, cy)
        _line(img, cx, cy, ax, ay)
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if area == 0.0:
            continue
        sign = 1.0 if area > 0 else -1.0
        c0 = max(int(np.floor(min(ax, bx, cx))), 0)
        c1 = min(int(np.ceil(max(ax, bx, cx))), res - 1)
        r0 = max(int(np.floor(min(ay, by, cy))), 0)
        r1 = min(int(np.ceil(max(ay, by, cy))), res - 1)
        for r in range(r0, r1 + 1):
            py = r + 0.5
            for col in range(c0, c1 + 1):
                px = col + 0.5
                e0 = ((bx - ax) * (py - ay) - (by - ay) * (px - ax)) * sign
                e1 = ((cx - bx) * (py - by) - (cy - by) * (px - bx)) * sign
                e2 = ((ax - cx) * (py - cy) - (ay - cy) * (px - cx)) * sign
                if e0 >= 0.0 and e1 >= 0.0 and e2 >= 0.0:
                    img[r, col] = True


def render_polygons(
    vertices: ArrayLike, faces: ArrayLike, directions: ArrayLike, resolution: int
) -> NDArray[np.bool_]:
    """Orthographic filled-polygon silhouettes of a mesh inside the unit sphere.

    Parameters
    ----------
    vertices : (v, 3) float
        Vertex positions, within the unit sphere (:func:`normalised_vertices`).
    faces : (f, 3) int
        Triangles; orientation, connectivity and duplicates do not matter.
    directions : (m, 3) float
        Unit view directions.
    resolution : int
        Image side, pixels; the image spans [-1, 1]^2 along
        :func:`~shapedb.signature.lightfield_descriptor.image_axes` (row along ``w``).

    Returns
    -------
    (m, resolution, resolution) bool
        Covered pixels: centres inside a projected triangle, or on a drawn edge.
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.ascontiguousarray(np.asarray(faces, dtype=np.int64).reshape(-1, 3))
    u, w = image_axes(directions)
    half = 0.5 * resolution
    out = np.zeros((len(u), resolution, resolution), dtype=bool)
    for k in range(len(u)):
        px = (v @ u[k].astype(np.float64) + 1.0) * half
        py = (v @ w[k].astype(np.float64) + 1.0) * half
        _rasterise(px, py, f, out[k])
    return out


@functools.lru_cache(maxsize=1)
def _zernike_terms() -> tuple[list[tuple[int, int]], FloatArray, list[tuple[int, int]]]:
    """The (n, m) moments, the (k, m) complex moments ``sum (x^2 + y^2)^k (x - iy)^m`` they
    are made of, and the (moments, complex moments) coefficients."""
    nm = [(n, m) for n in range(ZERNIKE_ORDER + 1) for m in range(n % 2, n + 1, 2)]
    km = [(k, m) for m in range(ZERNIKE_ORDER + 1) for k in range((ZERNIKE_ORDER - m) // 2 + 1)]
    index = {t: i for i, t in enumerate(km)}
    coef = np.zeros((len(nm), len(km)))
    for i, (n, m) in enumerate(nm):
        for s in range((n - m) // 2 + 1):
            c = (-1) ** s * factorial(n - s)
            c /= factorial(s) * factorial((n + m) // 2 - s) * factorial((n - m) // 2 - s)
            # rho^(n - 2s) e^{-im theta} = (x^2 + y^2)^((n - 2s - m) / 2) (x - iy)^m
            coef[i, index[((n - 2 * s - m) // 2, m)]] += c
    return nm, coef, km


@njit(cache=True)
def _complex_moments(
    img: NDArray[np.bool_], cx: float, cy: float, scale: float, kk: NDArray[np.int64],
    mm: NDArray[np.int64],
) -> NDArray[np.complex128]:  # fmt: skip
    """Mean over covered pixels of ``(x^2 + y^2)^k (x - iy)^m``, ``(x, y)`` the pixel centre
    minus ``(cx, cy)`` times ``scale``."""
    out = np.zeros(len(kk), dtype=np.complex128)
    pw = np.empty(ZERNIKE_ORDER + 1, dtype=np.complex128)
    r2 = np.empty(ZERNIKE_ORDER // 2 + 1)
    count = 0
    res = img.shape[0]
    for r in range(res):
        for c in range(res):
            if not img[r, c]:
                continue
            x = (c + 0.5 - cx) * scale
            y = (r + 0.5 - cy) * scale
            z = complex(x, -y)
            pw[0] = 1.0
            for m in range(1, ZERNIKE_ORDER + 1):
                pw[m] = pw[m - 1] * z
            r2[0] = 1.0
            for k in range(1, ZERNIKE_ORDER // 2 + 1):
                r2[k] = r2[k - 1] * (x * x + y * y)
            for t in range(len(kk)):
                out[t] += r2[kk[t]] * pw[mm[t]]
            count += 1
    return out / max(count, 1)


def _centre_and_reach(img: NDArray[np.bool_]) -> tuple[float, float, float]:
    """Bounding-box centre (pixel units, x then y) and the farthest covered pixel centre."""
    rows, cols = np.nonzero(img)
    if not len(rows):
        return 0.0, 0.0, 0.0
    cx = 0.5 * (cols.min() + cols.max()) + 0.5
    cy = 0.5 * (rows.min() + rows.max()) + 0.5
    reach = float(np.sqrt(((cols + 0.5 - cx) ** 2 + (rows + 0.5 - cy) ** 2).max()))
    return float(cx), float(cy), reach


def zernike_35(img: NDArray[np.bool_], cx: float, cy: float, radius: float) -> FloatArray:
    """(35,) Zernike magnitudes (order <= 10, ``A_00`` dropped) of one silhouette, each in
    [0, 1], on the disc of ``radius`` pixels about ``(cx, cy)``; zeros if empty."""
    nm, coef, km = _zernike_terms()
    kk = np.asarray([k for k, _ in km], dtype=np.int64)
    mm = np.asarray([m for _, m in km], dtype=np.int64)
    if not img.any():
        return np.zeros(len(nm) - 1)
    moments = coef @ _complex_moments(img, cx, cy, 1.0 / max(radius, 0.5), kk, mm)
    return np.abs(moments[1:])


def contour_fourier(img: NDArray[np.bool_], cx: float, cy: float) -> FloatArray:
    """(10,) Fourier magnitudes 1..10 of the outer contour's distance to ``(cx, cy)``
    (pixel units), divided by the constant term; zeros for an empty or tiny silhouette."""
    from skimage.measure import find_contours

    if img.sum() < 2:
        return np.zeros(FOURIER)
    pad = np.pad(img.astype(np.float64), 1)
    contour = max(find_contours(pad, 0.5), key=len)  # (row, col) of the padded image
    if len(contour) < 8:
        return np.zeros(FOURIER)
    p = contour[:, ::-1] - 0.5  # (x, y) in pixel units of img, pixel centres at +0.5
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if not s[-1] > 0:
        return np.zeros(FOURIER)
    t = np.linspace(0.0, s[-1], CONTOUR_SAMPLES, endpoint=False)
    x, y = np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])
    spec = np.abs(np.fft.rfft(np.hypot(x - cx, y - cy)))
    return np.asarray(spec[1 : FOURIER + 1] / max(spec[0], 1e-12))


def field_features(images: NDArray[np.bool_], *, fourier: bool = True) -> FloatArray:
    """Per silhouette of one light field: 35 Zernike magnitudes then 10 Fourier magnitudes.

    Parameters
    ----------
    images : (10, r, r) bool
        One light field's silhouettes (:func:`render_polygons`).
    fourier : bool
        Compute the Fourier block (else zeros: it is not used).

    Returns
    -------
    (10, 45) float64
        Unquantised; the disc's radius is the largest reach over the 10 silhouettes.
    """
    geo = [_centre_and_reach(im) for im in images]
    radius = max(g[2] for g in geo)
    out = np.zeros((len(images), 35 + FOURIER))
    for i, (im, (cx, cy, _)) in enumerate(zip(images, geo, strict=True)):
        out[i, :35] = zernike_35(im, cx, cy, radius)
        if fourier:
            out[i, 35:] = contour_fourier(im, cx, cy)
    return out
