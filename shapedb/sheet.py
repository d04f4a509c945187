"""Solids for surfaces without an inside: sheets, open parts and flat models.

Web and CAD models are often built of zero-thickness quads (walls, wings, table tops)
and of open or flat parts, so the generalised winding number finds little or no
inside and no ball fits. Such a model is decomposed as its *thickened* surface: the
solid dilated by ``t`` (``MDBDConfig.sheet_cells`` grid cells), i.e. every point within
``t`` of the surface or inside the solid. Its signed distance is exactly the mesh's
plus ``t``, so a sheet becomes a slab ``2 t`` thick and a solid part grows by ``t``.

Which models are thickened (:func:`needs_thickening`), decided on the grid field:

* any mesh in which no ball of the minimum radius fits (the decomposition would fail:
  flat, empty or thinner than the grid);
* an open mesh (not every edge used twice in opposite directions) where more than
  :data:`SHEET_FRACTION` of the cells touching the surface have no inside cell within
  :data:`SHEET_REACH` cells: surfaces with outside on both sides (sheets, and parts
  thinner than the grid).

Closed meshes in which a ball fits, and every other representation, are never
thickened: their decompositions do not change.
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapedb.geometry import Geometry, Grid, as_points

__all__ = ["Thickened", "sheet_fraction", "needs_thickening", "SHEET_FRACTION", "SHEET_REACH"]

logger = logging.getLogger(__name__)

#: Fraction of the surface cells with no inside nearby above which an open mesh is
#: thickened.
SHEET_FRACTION = 0.2
#: Cells around a surface cell searched for an inside cell.
SHEET_REACH = 2


class Thickened(Geometry):
    """A geometry dilated by ``thickness``: its solid plus every point that close to its surface.

    Parameters
    ----------
    base : Geometry
        The geometry (usually a :class:`~shapedb.mesh.TriangleMesh` in the
        decomposition's frame).
    thickness : float
        Dilation, model units, > 0.

    Raises
    ------
    ValueError
        If ``thickness`` is not positive and finite.
    """

    def __init__(self, base: Geometry, thickness: float) -> None:
        if not (np.isfinite(thickness) and thickness > 0):
            raise ValueError(f"thickness must be positive and finite, got {thickness!r}")
        self.base = base
        self.thickness = float(thickness)
        self.representation = base.representation  # type: ignore[misc]
        self.name = getattr(base, "name", None)

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: the base's bounds grown by the thickness."""
        b = np.asarray(self.base.bounds, dtype=np.float64)
        return np.stack([b[0] - self.thickness, b[1] + self.thickness])

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """The base's signed distance (n,) plus the thickness, model units, positive inside."""
        p = as_points(points)
        return np.asarray(self.base.signed_distance(p), dtype=np.float64) + self.thickness

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """(n,) bool: inside the base, or within the thickness of its surface."""
        p = as_points(points)
        if len(p) == 0:
            return np.zeros(0, dtype=bool)
        near = np.asarray(self.base.unsigned_distance(p)) < self.thickness
        out = near.copy()
        out[~near] = np.asarray(self.base.contains(p[~near]), dtype=bool)
        return out

    def unsigned_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """``|signed_distance|`` (n,), model units."""
        return np.abs(self.signed_distance(points))

    def closest_points(self, points: ArrayLike) -> NDArray[np.float64]:
        """Closest points (n, 3) on the dilated surface: the base's, moved out by the thickness.

        A point exactly on the base surface has no direction and gets the base's point.
        """
        p = as_points(points)
        if len(p) == 0:
            return np.zeros((0, 3))
        q = np.asarray(self.base.closest_points(p), dtype=np.float64)
        v = p - q
        n = np.linalg.norm(v, axis=1)
        sign = np.where(np.asarray(self.base.contains(p), dtype=bool), -1.0, 1.0)
        unit = v / np.maximum(n, 1e-300)[:, None] * sign[:, None]
        unit[n <= 0] = 0.0
        return q + self.thickness * unit

    def transformed(self, rotation: ArrayLike, translation: ArrayLike) -> Thickened:
        """The base moved by ``x -> rotation @ x + translation``, thickened alike."""
        return Thickened(self.base.transformed(rotation, translation), self.thickness)

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """The base's grid field plus the thickness, ``grid.shape`` float32."""
        f = np.asarray(self.base.grid_sdf(grid), dtype=np.float32)
        return f + np.float32(self.thickness)

    def __repr__(self) -> str:
        return f"Thickened({self.base!r}, {self.thickness:.4g})"


def sheet_fraction(F: NDArray[np.floating], spacing: float, reach: int = SHEET_REACH) -> float:
    """Fraction of the surface cells with no inside cell within ``reach`` cells.

    Parameters
    ----------
    F : (nx, ny, nz) float
        Signed distance on a grid, model units, positive inside.
    spacing : float
        Grid cell size, model units.
    reach : int
        Chessboard radius (cells) searched for an inside cell.

    Returns
    -------
    float
        In [0, 1]; 1.0 when no cell is within a cell of the surface.
    """
    near = np.abs(F) < spacing
    count = int(near.sum())
    if count == 0:
        return 1.0
    inside = F > 0
    if not inside.any():
        return 1.0
    grown = ndimage.maximum_filter(inside.view(np.uint8), size=2 * reach + 1).astype(bool)
    return float((near & ~grown).sum()) / count


def needs_thickening(
    geometry: Geometry, F: NDArray[np.floating], spacing: float, min_radius: float
) -> bool:
    """Whether a model's surface is decomposed thickened (see the module docstring).

    Parameters
    ----------
    geometry : Geometry
        The geometry whose grid field ``F`` is; only triangle meshes are ever thickened.
    F : (nx, ny, nz) float
        Its signed distance on the grid, model units.
    spacing : float
        Grid cell size, model units.
    min_radius : float
        Smallest ball radius the decomposition accepts, model units.
    """
    from shapedb.mesh import TriangleMesh

    if not isinstance(geometry, TriangleMesh):
        return False
    if not float(F.max()) >= min_radius or not float(F.max()) > 0:
        logger.debug("%r: no ball fits inside, thickened", geometry)
        return True
    if geometry.closed:
        return False
    frac = sheet_fraction(F, spacing)
    logger.debug("%r: open, sheet fraction %.3f", geometry, frac)
    return frac > SHEET_FRACTION
