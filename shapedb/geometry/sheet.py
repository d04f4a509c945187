"""Solids for surfaces without an inside: sheets, open parts and flat models.

Web and CAD models are often built of zero-thickness quads (walls, wings, table tops)
and of open or flat parts, so the generalised winding number finds little or no
inside and no ball fits. Such a model is decomposed as its *thickened* surface: the
solid dilated by ``t`` (``MDBDConfig.sheet_cells`` grid cells), i.e. every point within
``t`` of the surface or inside the solid. Its signed distance is exactly the mesh's
plus ``t``, so a sheet becomes a slab ``2 t`` thick and a solid part grows by ``t``.

Which models are thickened whole (:func:`needs_thickening`), decided on the grid field:

* any mesh in which no ball of the minimum radius fits (the decomposition would fail:
  flat, empty or thinner than the grid);
* an open mesh (not every edge used twice in opposite directions) where more than
  :data:`SHEET_FRACTION` of the cells touching the surface are *sheet cells*, with no
  inside cell within :data:`SHEET_REACH` cells: surfaces with outside on both sides
  (sheets, and parts thinner than the grid).

A mesh that is not thickened whole but whose sheet cells are at least
:data:`LOCAL_FRACTION` of its surface cells (the wings of an airplane whose fuselage is
closed, a desk's sheet top on box legs, rods thinner than the grid) is thickened
*locally* (``MDBDConfig.sheet_rule="local"``, :func:`sheet_region`,
:class:`LocallyThickened`): the field grows by ``t`` only in the cells within a few
cells of its sheet cells, so its sheets become slabs ``2 t`` thick and the rest of the
solid keeps its field. Without it such sheets have no inside cell and vanish from the
decomposition and from the field's light fields.

Meshes with no sheet cells in which a ball fits, and every other representation, are
never thickened: their decompositions do not change.
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapedb.geometry.base import Geometry, Grid, as_points, offset_closest

__all__ = [
    "Thickened",
    "LocallyThickened",
    "sheet_cells",
    "sheet_fraction",
    "sheet_region",
    "needs_thickening",
    "SHEET_FRACTION",
    "SHEET_REACH",
    "LOCAL_FRACTION",
]

logger = logging.getLogger(__name__)

#: Fraction of the surface cells with no inside nearby above which an open mesh is
#: thickened.
SHEET_FRACTION = 0.2
#: Cells around a surface cell searched for an inside cell.
SHEET_REACH = 2
#: Fraction of the surface cells that are sheet cells from which a mesh not thickened
#: whole is thickened locally (``MDBDConfig.sheet_rule="local"``).
LOCAL_FRACTION = 0.01


class Thickened(Geometry):
    """A geometry dilated by ``thickness``: its solid plus every point that close to its surface.

    Parameters
    ----------
    base : Geometry
        The geometry (usually a :class:`~shapedb.geometry.mesh.TriangleMesh` in the
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
        inward = np.asarray(self.base.contains(p), dtype=bool)
        return offset_closest(p, q, inward, self.thickness)

    def transformed(self, rotation: ArrayLike, translation: ArrayLike) -> Thickened:
        """The base moved by ``x -> rotation @ x + translation``, thickened alike."""
        return Thickened(self.base.transformed(rotation, translation), self.thickness)

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """The base's grid field plus the thickness, ``grid.shape`` float32."""
        f = np.asarray(self.base.grid_sdf(grid), dtype=np.float32)
        return f + np.float32(self.thickness)

    def __repr__(self) -> str:
        return f"Thickened({self.base!r}, {self.thickness:.4g})"


def sheet_cells(
    F: NDArray[np.floating], spacing: float, reach: int = SHEET_REACH
) -> tuple[NDArray[np.bool_], int]:
    """The sheet cells of a grid field and the number of its surface cells.

    A *surface cell* is within one cell of the surface (``|F| < spacing``); a *sheet
    cell* is a surface cell with no inside cell (``F > 0``) within ``reach`` cells
    (chessboard distance).

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
    sheets : (nx, ny, nz) bool
        The sheet cells.
    surface : int
        The number of surface cells.
    """
    near = np.abs(F) < spacing
    inside = F > 0
    if not inside.any():
        return near, int(near.sum())
    grown = ndimage.maximum_filter(inside.view(np.uint8), size=2 * reach + 1).astype(bool)
    return near & ~grown, int(near.sum())


def sheet_fraction(F: NDArray[np.floating], spacing: float, reach: int = SHEET_REACH) -> float:
    """Fraction of the surface cells that are sheet cells (:func:`sheet_cells`).

    Returns
    -------
    float
        In [0, 1]; 1.0 when no cell is within a cell of the surface or none is inside.
    """
    if not (F > 0).any():
        return 1.0
    sheets, surface = sheet_cells(F, spacing, reach)
    return float(sheets.sum()) / surface if surface else 1.0


def sheet_region(
    geometry: Geometry, F: NDArray[np.floating], spacing: float, thickness: float
) -> NDArray[np.bool_] | None:
    """The cells a mesh not thickened whole is thickened in, or None (see the module
    docstring).

    The sheet cells (:func:`sheet_cells`) grown by ``ceil(thickness / spacing) +``
    :data:`SHEET_REACH` cells (chessboard), so that the slab of every sheet lies inside
    and reaches the solid the sheet meets; None when ``geometry`` is not a triangle mesh
    or its sheet cells are fewer than :data:`LOCAL_FRACTION` of its surface cells.

    Parameters
    ----------
    geometry : Geometry
        The geometry whose grid field ``F`` is.
    F : (nx, ny, nz) float
        Its signed distance on the grid, model units.
    spacing : float
        Grid cell size, model units.
    thickness : float
        The dilation the region will get, model units, > 0.

    Returns
    -------
    (nx, ny, nz) bool or None
    """
    from shapedb.geometry.mesh import TriangleMesh

    if not isinstance(geometry, TriangleMesh):
        return None
    sheets, surface = sheet_cells(F, spacing)
    count = int(sheets.sum())
    if count == 0 or count < LOCAL_FRACTION * surface:
        return None
    k = int(np.ceil(thickness / spacing - 1e-9)) + SHEET_REACH
    grown = ndimage.maximum_filter(sheets.view(np.uint8), size=2 * k + 1).astype(bool)
    logger.debug("%r: %d sheet cells, thickened locally", geometry, count)
    return grown


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
    from shapedb.geometry.mesh import TriangleMesh

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


class LocallyThickened(Thickened):
    """A geometry dilated by ``thickness`` in a region of grid cells only.

    In the cells of ``region`` (nearest cell centre; points off the grid are outside
    it) the signed distance is the base's plus ``thickness``, as in :class:`Thickened`;
    elsewhere it is the base's. :func:`sheet_region` chooses the region so that it
    holds the model's sheets and their slabs.

    Parameters
    ----------
    base : Geometry
        The geometry (a :class:`~shapedb.geometry.mesh.TriangleMesh` in the decomposition's frame).
    thickness : float
        Dilation, model units, > 0.
    grid : Grid
        The grid ``region`` lies on.
    region : (nx, ny, nz) bool
        The cells dilated, ``grid.shape``.

    Raises
    ------
    ValueError
        If ``thickness`` is not positive and finite, or ``region`` is not ``grid.shape``.
    """

    def __init__(
        self, base: Geometry, thickness: float, grid: Grid, region: NDArray[np.bool_]
    ) -> None:
        super().__init__(base, thickness)  # checks the thickness; bounds grow by it
        region = np.asarray(region, dtype=bool)
        if region.shape != tuple(grid.shape):
            raise ValueError(f"region has shape {region.shape}, the grid {tuple(grid.shape)}")
        self.grid = grid
        self.region = region

    def in_region(self, points: ArrayLike) -> NDArray[np.bool_]:
        """(n,) bool: whether each point's nearest cell is in the region (never off the grid)."""
        return self.grid.mask_at(self.region, points)

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """The base's signed distance (n,), plus the thickness in the region; model units."""
        p = as_points(points)
        d = np.asarray(self.base.signed_distance(p), dtype=np.float64)
        return d + self.thickness * self.in_region(p)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """(n,) bool: inside the base, or in the region within the thickness of its surface."""
        p = as_points(points)
        out = np.zeros(len(p), dtype=bool)
        if len(p) == 0:
            return out
        r = self.in_region(p)
        if r.any():
            out[r] = np.asarray(self.base.unsigned_distance(p[r])) < self.thickness
        rest = ~out
        out[rest] = np.asarray(self.base.contains(p[rest]), dtype=bool)
        return out

    def closest_points(self, points: ArrayLike) -> NDArray[np.float64]:
        """Closest points (n, 3) on the surface: in the region the base's moved out by the
        thickness (as :meth:`Thickened.closest_points`), elsewhere the base's."""
        p = as_points(points)
        q = np.asarray(self.base.closest_points(p), dtype=np.float64)
        r = self.in_region(p)
        if r.any():
            v = p[r] - q[r]
            n = np.linalg.norm(v, axis=1)
            sign = np.where(np.asarray(self.base.contains(p[r]), dtype=bool), -1.0, 1.0)
            unit = v / np.maximum(n, 1e-300)[:, None] * sign[:, None]
            unit[n <= 0] = 0.0
            q[r] = q[r] + self.thickness * unit
        return q

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """The base's grid field plus the thickness in the region, ``grid.shape`` float32."""
        f = np.asarray(self.base.grid_sdf(grid), dtype=np.float32)
        g = self.grid
        if (
            grid.shape == g.shape
            and grid.spacing == g.spacing
            and np.array_equal(grid.origin, g.origin)
        ):
            region = self.region
        else:
            region = self.in_region(grid.points()).reshape(grid.shape)
        return np.asarray(f + np.float32(self.thickness) * region, dtype=np.float32)

    def __repr__(self) -> str:
        return (
            f"LocallyThickened({self.base!r}, {self.thickness:.4g}, {int(self.region.sum())} cells)"
        )
