"""The one interface the decomposition needs from a representation, and the grid.

The paper's point is that MDBD needs only a distance query and point-membership
classification. In shapedb that is :class:`Geometry`: a bounding box, a signed
distance query (positive inside, negative outside) and a fast evaluation of that
distance on a regular :class:`Grid`. Every representation (triangle mesh, point
cloud, voxel grid, implicit function, CAD solid) implements it; nothing downstream
looks at the representation itself.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.errors import DegenerateGeometryError, NonFiniteGeometryError

__all__ = ["Geometry", "Grid"]


@dataclass(frozen=True)
class Grid:
    """A regular grid of cell centres.

    Attributes
    ----------
    origin : (3,) float
        Centre of cell (0, 0, 0), in model units.
    spacing : float
        Edge length of one cubic cell, in model units.
    shape : (3,) int
        Number of cells along x, y, z.
    """

    origin: NDArray[np.float64]
    spacing: float
    shape: tuple[int, int, int]

    @classmethod
    def fit(cls, bounds: ArrayLike, *, resolution: int = 128, padding: int = 2) -> Grid:
        """Grid covering ``bounds`` with ``resolution`` cells along the longest side.

        Parameters
        ----------
        bounds : (2, 3) float
            Minimum and maximum corner of the solid.
        resolution : int
            Cells along the longest side of the box, padding included.
        padding : int
            Empty cells added on every side, so the outside is always sampled.
        """
        b = np.asarray(bounds, dtype=np.float64).reshape(2, 3)
        if not np.all(np.isfinite(b)):
            raise NonFiniteGeometryError(f"bounds are not finite: {b.tolist()}")
        extent = b[1] - b[0]
        longest = float(extent.max())
        if not longest > 0:
            raise DegenerateGeometryError(f"bounding box has zero size: {b.tolist()}")
        inner = max(resolution - 2 * padding, 1)
        spacing = longest / inner
        counts = np.maximum(np.ceil(extent / spacing - 1e-9).astype(np.int64), 1) + 2 * padding
        centre = 0.5 * (b[0] + b[1])
        origin = centre - 0.5 * (counts - 1) * spacing
        shape = (int(counts[0]), int(counts[1]), int(counts[2]))
        return cls(origin=origin, spacing=float(spacing), shape=shape)

    @property
    def size(self) -> int:
        """Total number of cells."""
        return int(np.prod(self.shape))

    def axes(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Cell-centre coordinates along x, y and z: three 1-D arrays."""
        return tuple(  # type: ignore[return-value]
            self.origin[k] + self.spacing * np.arange(self.shape[k]) for k in range(3)
        )

    def points(self, dtype: type = np.float64) -> NDArray:
        """All cell centres, (size, 3), in C order (x slowest, z fastest)."""
        x, y, z = self.axes()
        g = np.stack(np.meshgrid(x, y, z, indexing="ij"), axis=-1)
        return g.reshape(-1, 3).astype(dtype, copy=False)

    def to_index(self, points: ArrayLike) -> NDArray[np.int64]:
        """Nearest cell index (n, 3) of points (n, 3), clipped to the grid."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        ijk = np.rint((p - self.origin) / self.spacing).astype(np.int64)
        return np.clip(ijk, 0, np.asarray(self.shape) - 1)

    def to_point(self, ijk: ArrayLike) -> NDArray[np.float64]:
        """Centres (n, 3) of cells with (possibly fractional) indices ijk (n, 3)."""
        return self.origin + self.spacing * np.asarray(ijk, dtype=np.float64).reshape(-1, 3)


class Geometry(ABC):
    """A solid, seen only through distance and point membership.

    Subclasses set ``representation`` ("mesh", "pointcloud", "voxels", "implicit",
    "brep") and implement :attr:`bounds` and :meth:`signed_distance`; they override
    :meth:`grid_sdf` when the whole grid can be evaluated faster than point by point.
    """

    representation: ClassVar[str] = "abstract"

    @property
    @abstractmethod
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float: minimum and maximum corner of the solid, model units."""

    @abstractmethod
    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distance of points (n, 3) to the boundary: (n,) float, positive inside.

        This is the precise query used to refine balls off the grid; it should be
        as exact as the representation allows.
        """

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Point-membership classification: (n,) bool, True inside."""
        return self.signed_distance(points) > 0

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """Signed distance at every cell centre of ``grid``: ``grid.shape`` float32.

        The default evaluates :meth:`signed_distance` in chunks; representations
        override it with something faster (distance transforms, narrow bands).
        """
        pts = grid.points()
        out = np.empty(len(pts), dtype=np.float32)
        step = 1 << 18
        for s in range(0, len(pts), step):
            out[s:s + step] = self.signed_distance(pts[s:s + step])
        return out.reshape(grid.shape)

    def __repr__(self) -> str:
        lo, hi = np.round(self.bounds, 4).tolist()
        return f"<{type(self).__name__} bounds={lo}..{hi}>"


def as_points(points: ArrayLike, *, name: str = "points") -> NDArray[np.float64]:
    """Validate and return an (n, 3) float64 array of finite points."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        p = p.reshape(-1, 3) if p.size % 3 == 0 and p.ndim <= 2 else p
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3), got {np.shape(points)}")
    return p
