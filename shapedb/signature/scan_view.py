"""The silhouette a one-sided scan shows its camera, as a light field view.

A depth camera sees one side of a solid, so the solid a one-sided cloud bounds is not the
model's and its packing resembles no stored one. What the scan does show exactly is the
model's silhouette from the camera: every pixel the solid covers holds a visible point.
:func:`scan_view_features` turns the scan into that silhouette, seen along the cloud's own
viewing direction (:func:`shapedb.geometry.view.viewing_direction`), and describes it as
the light fields describe each of their views (:func:`silhouette_features` under the
store's :class:`~shapedb.config.lightfield.LightFieldConfig`): a search compares it with
every view of every stored shape's light fields (:mod:`query.search.view_search`).

The image is framed as a stored view whose reach is its light field's largest: about the
centroid of its covered pixels, the farthest point (plus one splat) on the unit circle.
Each point covers a disc of the median spacing of the points in the image plane, as a
ball covers its disc; a closing of :data:`CLOSING_PX` pixels and a hole fill bridge the
gaps that grazing incidence and range leave between samples.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage
from scipy.spatial import cKDTree

from shapedb.config.lightfield import LightFieldConfig
from shapedb.signature.lightfield_descriptor import image_axes, silhouette_features

__all__ = ["CLOSING_PX", "scan_silhouette", "scan_view_features"]

#: Pixels of binary closing after splatting; on CAPOD validation scans 1-2x the points'
#: spacing as the splat were within two queries of each other (60 scans, 2 pixels of closing).
CLOSING_PX = 2


def _splat(xy: NDArray[np.float64], radius: float, res: int) -> NDArray[np.bool_]:
    """(res, res) pixels whose centre lies within ``radius`` plus half a pixel of a point;
    ``xy`` (n, 2) and ``radius`` in image units ([-1, 1]^2, row along the second axis)."""
    half = 0.5 * res
    px, py = (xy[:, 0] + 1.0) * half, (xy[:, 1] + 1.0) * half
    reach = radius * half + 0.5
    img = np.zeros((res, res), dtype=bool)
    ix, iy = np.floor(px).astype(np.int64), np.floor(py).astype(np.int64)
    span = int(np.ceil(reach))
    for dx in range(-span, span + 1):
        for dy in range(-span, span + 1):
            cx, cy = ix + dx, iy + dy
            ok = (cx >= 0) & (cy >= 0) & (cx < res) & (cy < res)
            ok &= (cx + 0.5 - px) ** 2 + (cy + 0.5 - py) ** 2 <= reach * reach
            img[cy[ok], cx[ok]] = True
    return img


def scan_silhouette(points: ArrayLike, direction: ArrayLike, resolution: int) -> NDArray[np.bool_]:
    """The silhouette of ``points`` seen along ``direction``, framed as a light field view.

    Parameters
    ----------
    points : (n, 3) float
        The scan, any units; n >= 3.
    direction : (3,) float
        Viewing direction (its sign does not matter: silhouettes seen from opposite
        sides are mirror images, which the image features do not tell apart).
    resolution : int
        Image side, pixels.

    Returns
    -------
    (resolution, resolution) bool
        Centred on its covered pixels' centroid, the farthest point plus its splat on the
        unit circle of [-1, 1]^2.

    Raises
    ------
    ValueError
        Fewer than 3 points, non-finite values, or points that project to one spot.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(direction, dtype=np.float64).reshape(3)
    if len(p) < 3 or not np.all(np.isfinite(p)) or not np.all(np.isfinite(d)):
        raise ValueError(f"a scan silhouette needs 3 or more finite points ({len(p)} given)")
    u, w = image_axes(d[None] / np.linalg.norm(d))
    xy = np.stack([p @ u[0].astype(np.float64), p @ w[0].astype(np.float64)], axis=1)
    spacing = float(np.median(cKDTree(xy).query(xy, k=2)[0][:, 1]))
    centre = xy.mean(axis=0)
    reach = float(np.sqrt(((xy - centre) ** 2).sum(axis=1)).max()) + spacing
    if not reach > 0:
        raise ValueError("the scan's points project to one spot")
    # first framing about the points' mean, then about the covered pixels' centroid
    img = _splat((xy - centre) / (1.05 * reach), spacing / (1.05 * reach), resolution)
    rows, cols = np.nonzero(img)
    pixel = 2.0 / resolution
    shift = np.array([cols.mean() + 0.5, rows.mean() + 0.5]) * pixel - 1.0
    centre = centre + shift * 1.05 * reach
    reach = float(np.sqrt(((xy - centre) ** 2).sum(axis=1)).max()) + spacing
    img = _splat((xy - centre) / reach, spacing / reach, resolution)
    # closed on a padded canvas: the silhouette touches the image's edge, which an
    # erosion would otherwise eat into
    pad = np.pad(img, CLOSING_PX)
    closed = ndimage.binary_closing(pad, iterations=CLOSING_PX)
    return np.asarray(closed[CLOSING_PX:-CLOSING_PX, CLOSING_PX:-CLOSING_PX], dtype=bool)


def scan_view_features(
    points: ArrayLike, direction: ArrayLike, config: LightFieldConfig | None = None
) -> NDArray[np.float32]:
    """:func:`silhouette_features` of :func:`scan_silhouette`: (``silhouette_dim(config)``,)
    float32, comparable number for number with the leading
    :func:`~shapedb.signature.lightfield_descriptor.silhouette_dim` numbers of each view of a
    stored light field of the same ``config``.

    Raises
    ------
    ValueError
        As :func:`scan_silhouette`.
    """
    cfg = config or LightFieldConfig()
    img = scan_silhouette(points, direction, cfg.resolution)
    return silhouette_features(img[None], cfg)[0].astype(np.float32)
