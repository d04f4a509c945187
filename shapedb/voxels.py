"""Voxel grids: a solid given as a boolean occupancy array.

The signed distance is the exact Euclidean distance transform
(``scipy.ndimage.distance_transform_edt``) of the occupancy, on both sides, with the
*half-cell convention*: the boundary of the solid lies midway between an occupied
and an empty cell centre, so

* inside (occupied) cells: ``sdf = edt_to_nearest_empty_centre - pitch / 2``;
* outside (empty) cells: ``sdf = -(edt_to_nearest_occupied_centre - pitch / 2)``.

A cell next to the boundary therefore has ``|sdf| = pitch / 2``, the distance from
its centre to the shared face. The occupancy is padded with one empty layer so
that cells on the array border see the outside. :meth:`VoxelGrid.signed_distance`
interpolates this field trilinearly (beyond the array it adds the distance to the
array's box, so points far away stay negative and roughly right).
"""

from __future__ import annotations

import logging
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapedb.errors import EmptyGeometryError, InvalidShapeError, NonFiniteGeometryError
from shapedb.geometry import Geometry, Grid, as_points

__all__ = ["VoxelGrid"]

logger = logging.getLogger(__name__)


class VoxelGrid(Geometry):
    """A solid made of occupied cubic cells.

    Parameters
    ----------
    occupancy : (nx, ny, nz) bool
        True where the cell belongs to the solid.
    origin : (3,) float
        Centre of cell (0, 0, 0), model units.
    pitch : float
        Edge length of one cell, model units.
    name : str, optional
        Used in error messages.

    Raises
    ------
    EmptyGeometryError
        No occupied cell (or an empty array).
    NonFiniteGeometryError
        Non-finite origin or pitch.
    InvalidShapeError
        Occupancy not 3-D, origin not (3,), pitch not positive.
    """

    representation = "voxels"

    def __init__(
        self,
        occupancy: ArrayLike,
        origin: ArrayLike = (0.0, 0.0, 0.0),
        pitch: float = 1.0,
        *,
        name: str | None = None,
    ) -> None:
        self.name = name
        occ = np.asarray(occupancy)
        if occ.ndim != 3:
            raise InvalidShapeError(
                f"occupancy must be a 3-D array (nx, ny, nz), got shape {occ.shape}", source=name
            )
        if occ.dtype != bool:
            if not np.issubdtype(occ.dtype, np.number):
                raise InvalidShapeError(
                    f"occupancy must be boolean or numeric, got {occ.dtype}", source=name
                )
            occ = occ != 0
        if occ.size == 0 or not occ.any():
            raise EmptyGeometryError(
                f"voxel grid of shape {occ.shape} has no occupied cell", source=name
            )
        o = np.asarray(origin, dtype=np.float64)
        if o.shape != (3,):
            raise InvalidShapeError(f"origin must have shape (3,), got {o.shape}", source=name)
        if not (np.all(np.isfinite(o)) and np.isfinite(pitch)):
            raise NonFiniteGeometryError(
                f"origin {o.tolist()} and pitch {pitch} must be finite", source=name
            )
        if not pitch > 0:
            raise InvalidShapeError(f"pitch must be positive, got {pitch}", source=name)
        self._occupancy = np.ascontiguousarray(occ)
        self.origin = o
        self.pitch = float(pitch)

    @property
    def occupancy(self) -> NDArray[np.bool_]:
        """(nx, ny, nz) bool: the occupancy (read-only view)."""
        out = self._occupancy.view()
        out.flags.writeable = False
        return out

    @property
    def grid(self) -> Grid:
        """The voxels' own :class:`Grid` (cell centres)."""
        shape = self._occupancy.shape
        return Grid(origin=self.origin, spacing=self.pitch, shape=(shape[0], shape[1], shape[2]))

    @cached_property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: box around the occupied cells (faces, not centres)."""
        idx = np.argwhere(self._occupancy)
        lo = self.origin + (idx.min(0) - 0.5) * self.pitch
        hi = self.origin + (idx.max(0) + 0.5) * self.pitch
        return np.stack([lo, hi])

    @cached_property
    def sdf(self) -> NDArray[np.float64]:
        """(nx, ny, nz) float64: signed distance at the cell centres, model units."""
        return _edt_sdf(self._occupancy, self.pitch)

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distance (n,) of points (n, 3), model units, positive inside.

        Trilinear interpolation of :attr:`sdf`; outside the array, the value at the
        nearest point of the array's box minus the distance to it.
        """
        p = as_points(points)
        if len(p) == 0:
            return np.zeros(0)
        shape = np.asarray(self._occupancy.shape)
        u = (p - self.origin) / self.pitch
        uc = np.clip(u, 0, shape - 1)
        beyond = np.linalg.norm(u - uc, axis=1) * self.pitch
        vals = ndimage.map_coordinates(self.sdf, uc.T, order=1, mode="nearest")
        return vals - beyond

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """Signed distance at every cell centre of ``grid``, ``grid.shape`` float32.

        When ``grid`` is aligned with the voxels (same spacing, integer offset) and
        holds every occupied cell, this is the exact EDT on ``grid`` itself;
        otherwise the trilinear interpolation of :meth:`signed_distance`.
        """
        shift = (self.origin - grid.origin) / grid.spacing
        if np.isclose(grid.spacing, self.pitch, rtol=1e-9) and np.allclose(
            shift, np.rint(shift), atol=1e-6
        ):
            idx = np.argwhere(self._occupancy) + np.rint(shift).astype(np.int64)
            if np.all(idx >= 0) and np.all(idx < np.asarray(grid.shape)):
                occ = np.zeros(grid.shape, dtype=bool)
                occ[idx[:, 0], idx[:, 1], idx[:, 2]] = True
                return _edt_sdf(occ, grid.spacing).astype(np.float32)
        logger.debug("voxel grid %s: target grid not aligned, interpolating", self.name)
        return super().grid_sdf(grid)


def _edt_sdf(occ: NDArray[np.bool_], pitch: float) -> NDArray[np.float64]:
    """Half-cell-convention signed EDT of an occupancy array, model units."""
    pad = np.pad(occ, 1, constant_values=False)
    inside = ndimage.distance_transform_edt(pad)
    outside = ndimage.distance_transform_edt(~pad)
    field = np.where(pad, inside - 0.5, -(outside - 0.5)) * pitch
    return field[1:-1, 1:-1, 1:-1]
