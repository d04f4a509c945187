"""The enclosed solid of a surface: what a flood from outside cannot reach.

Web and CAD models are built of faces with their builder's orientation, open walls,
single-sided sheets and interpenetrating parts; a winding number reads such a model
as a mix of inside, outside and half-inside. The *enclosed solid* does not look at
orientation or closedness at all. On the decomposition's grid:

1. every cell whose centre lies within :data:`BARRIER_CELLS` of the surface is a
   wall: a 6-connected path of cells that crosses the surface steps between two
   centres one cell apart, one of which is within half a cell of the crossing, so
   walls stop every such path;
2. a flood from the grid's border through the other cells (6-connected) reaches the
   outside; the cells it does not reach are *enclosed*;
3. the solid is the enclosed region plus every point within ``t`` of the surface
   (``MDBDConfig.sheet_cells`` cells): a house of walls becomes a solid house, a sink
   a basin whose wall is a slab ``2 t`` thick, a wheel keeps its hole, a closed solid
   grows by ``t``.

Its signed distance is ``t + d`` on the enclosed side of the surface and ``t - d`` on
the side the flood reaches (``d``: distance to the surface), exact up to the surface's
own distance field. A gap in a wall wider than about a cell lets the flood in: at the
grid's resolution a room with an open door is a room.

The decomposition uses it for triangle meshes that are not closed
(``MDBDConfig.sheet_rule="enclosed"``, the default): a closed mesh's inside is exact from
its winding number, and growing it by ``t`` merges limbs a cell apart.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapedb.geometry.base import Geometry, Grid, Transformed, as_points, offset_closest

__all__ = ["Enclosed", "BARRIER_CELLS", "TIE_CELLS", "enclosed_sides", "enclosed_field"]

#: Cells whose centre is within this many cells of the surface stop the flood (the
#: smallest radius that provably stops every 6-connected crossing: see the module).
BARRIER_CELLS = 0.5

#: Cells within which a point on the boundary between two cells takes the lower one
#: (far above coordinate rounding, far below any geometric scale).
TIE_CELLS = 1e-9

_FACES = ndimage.generate_binary_structure(3, 1)


def enclosed_sides(dist_cells: NDArray[np.floating]) -> NDArray[np.bool_]:
    """The cells on the enclosed side of the surface, from its unsigned distance field.

    Parameters
    ----------
    dist_cells : (nx, ny, nz) float
        Distance of every cell centre to the surface, in cells (exact within a cell of
        the surface; an upper bound elsewhere is fine).

    Returns
    -------
    (nx, ny, nz) bool
        True for the cells a flood from the grid's border cannot reach, and for the
        wall cells (within :data:`BARRIER_CELLS`) that touch such a cell and no
        reached one; False elsewhere.
    """
    wall = np.asarray(dist_cells) <= BARRIER_CELLS
    labels, n = ndimage.label(~wall, structure=_FACES)
    border = np.zeros(n + 1, dtype=bool)
    for axis in range(3):
        for end in (0, -1):
            border[np.take(labels, end, axis=axis).ravel()] = True
    border[0] = False  # walls
    enclosed = (labels > 0) & ~border[labels]
    if not enclosed.any():
        return enclosed
    reached = (labels > 0) & border[labels]
    near_enclosed = ndimage.binary_dilation(enclosed, structure=_FACES)
    near_reached = ndimage.binary_dilation(reached, structure=_FACES)
    return enclosed | (wall & near_enclosed & ~near_reached)


def enclosed_field(
    dist_cells: NDArray[np.floating], sides: NDArray[np.bool_], thickness_cells: float
) -> NDArray[np.float32]:
    """Signed distance of the enclosed solid in cells: ``t + d`` on the enclosed side, else ``t - d``.

    ``dist_cells`` and ``sides`` have the grid's shape (:func:`enclosed_sides`);
    ``thickness_cells`` is ``t`` in cells, > 0.
    """
    d = np.asarray(dist_cells, dtype=np.float32)
    t = np.float32(thickness_cells)
    return np.where(sides, t + d, t - d).astype(np.float32, copy=False)


class Enclosed(Geometry):
    """A surface's enclosed solid (see the module): its grid side mask plus a thickness.

    Off the grid's cell centres the side is that of the nearest cell (points off the
    grid are on the outside); the distance to the surface is the base's, exact.

    Parameters
    ----------
    base : Geometry
        The surface (a :class:`~shapedb.geometry.mesh.TriangleMesh`); only its
        unsigned distance and closest points are used.
    thickness : float
        ``t``, model units, > 0.
    grid : Grid
        The grid ``sides`` lies on.
    sides : (nx, ny, nz) bool
        :func:`enclosed_sides` of the surface on ``grid``.

    Raises
    ------
    ValueError
        If ``thickness`` is not positive and finite, or ``sides`` is not ``grid.shape``.
    """

    def __init__(
        self, base: Geometry, thickness: float, grid: Grid, sides: NDArray[np.bool_]
    ) -> None:
        if not (np.isfinite(thickness) and thickness > 0):
            raise ValueError(f"thickness must be positive and finite, got {thickness!r}")
        sides = np.asarray(sides, dtype=bool)
        if sides.shape != tuple(grid.shape):
            raise ValueError(f"sides has shape {sides.shape}, the grid {tuple(grid.shape)}")
        self.base = base
        self.thickness = float(thickness)
        self.representation = base.representation  # type: ignore[misc]
        self.name = getattr(base, "name", None)
        self.grid = grid
        self.sides = sides

    def enclosed_side(self, points: ArrayLike) -> NDArray[np.bool_]:
        """(n,) bool: whether each point's nearest cell is on the enclosed side.

        A point on a cell boundary, within :data:`TIE_CELLS` of it, takes the lower cell:
        the off-grid refinement queries points half a cell off the lattice, whose rounding
        (1e-16 relative) would otherwise pick the cell by the model's pose.
        """
        p = as_points(points)
        g = self.grid
        ijk = np.floor((p - g.origin) / g.spacing + (0.5 - TIE_CELLS)).astype(np.int64)
        on = np.all((ijk >= 0) & (ijk < np.asarray(g.shape)), axis=1)
        out = np.zeros(len(p), dtype=bool)
        i = ijk[on]
        out[on] = self.sides[i[:, 0], i[:, 1], i[:, 2]]
        return out

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """``t + d`` on the enclosed side, ``t - d`` elsewhere: (n,) model units, positive inside."""
        p = as_points(points)
        d = np.asarray(self.base.unsigned_distance(p), dtype=np.float64)
        return self.thickness + np.where(self.enclosed_side(p), d, -d)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """(n,) bool: on the enclosed side, or within the thickness of the surface."""
        p = as_points(points)
        if len(p) == 0:
            return np.zeros(0, dtype=bool)
        out = self.enclosed_side(p)
        rest = ~out
        out[rest] = np.asarray(self.base.unsigned_distance(p[rest])) < self.thickness
        return out

    def closest_points(self, points: ArrayLike) -> NDArray[np.float64]:
        """Closest points (n, 3) on the solid's boundary: the surface's, moved by ``t``
        away from the enclosed side (towards the point on the other side)."""
        p = as_points(points)
        if len(p) == 0:
            return np.zeros((0, 3))
        q = np.asarray(self.base.closest_points(p), dtype=np.float64)
        return offset_closest(p, q, self.enclosed_side(p), self.thickness)

    def unsigned_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """``|signed_distance|`` (n,), model units."""
        return np.abs(self.signed_distance(points))

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: the surface's bounds grown by the thickness."""
        b = np.asarray(self.base.bounds, dtype=np.float64)
        return np.stack([b[0] - self.thickness, b[1] + self.thickness])

    def transformed(self, rotation: ArrayLike, translation: ArrayLike) -> Geometry:
        """This solid moved rigidly (a :class:`~shapedb.geometry.base.Transformed` wrapper:
        the side mask belongs to this grid)."""
        return Transformed(self, rotation, translation)

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """The solid's field at every cell centre of ``grid``, ``grid.shape`` float32."""
        return Geometry.grid_sdf(self, grid)
