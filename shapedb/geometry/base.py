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

__all__ = ["Geometry", "Grid", "Transformed", "offset_closest"]


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

    def mask_at(self, mask: NDArray[np.bool_], points: ArrayLike) -> NDArray[np.bool_]:
        """(n,) bool: ``mask`` (this grid's shape) at each point's nearest cell; False off the grid."""
        p = as_points(points)
        ijk = np.rint((p - self.origin) / self.spacing).astype(np.int64)
        on = np.all((ijk >= 0) & (ijk < np.asarray(self.shape)), axis=1)
        out = np.zeros(len(p), dtype=bool)
        i = ijk[on]
        out[on] = mask[i[:, 0], i[:, 1], i[:, 2]]
        return out


class Geometry(ABC):
    """A solid, seen only through distance and point membership.

    Subclasses set ``representation`` ("mesh", "pointcloud", "voxels", "implicit",
    "brep") and implement :attr:`bounds` and :meth:`signed_distance`; they override
    :meth:`grid_sdf` when the whole grid can be evaluated faster than point by point.
    """

    representation: ClassVar[str] = "abstract"

    @property
    def surface_sampling(self) -> float:
        """Typical spacing of the samples the boundary is known from, model units.

        0.0 for representations whose boundary is exact (meshes, voxel grids, implicit
        functions, B-reps); point clouds report their median sample spacing. The
        descriptor uses it to correct the measured bias of sparse samples.
        """
        return 0.0

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

    def unsigned_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Distance (n,) of points (n, 3) to the boundary, without the sign.

        The default is ``abs(signed_distance)``; representations whose sign is the
        expensive part (meshes, point clouds: winding numbers) override it. The
        decomposition's refinement takes the sign from the grid where the grid is
        unambiguous and only asks for this.
        """
        return np.abs(self.signed_distance(points))

    def closest_points(self, points: ArrayLike) -> NDArray[np.float64]:
        """Boundary points (n, 3) nearest to points (n, 3), model units.

        The default follows the distance gradient, ``p - D(p) grad D(p)``, with
        central differences of :meth:`signed_distance` (one batched call of 7n
        points), one-sided ones on the medial axis where central ones cancel; so
        ``|p - q| = |D(p)|`` always and q is a nearest boundary point for exact
        distances.
        Representations that know their surface override it.
        """
        p = as_points(points)
        if len(p) == 0:
            return np.zeros((0, 3))
        eps = 1e-4 * float(np.ptp(self.bounds, axis=0).max())
        offsets = np.concatenate([np.zeros((1, 3)), eps * np.eye(3), -eps * np.eye(3)])
        d = self.signed_distance((p[:, None, :] + offsets[None]).reshape(-1, 3)).reshape(-1, 7)
        grad = (d[:, 1:4] - d[:, 4:7]) / (2 * eps)
        norm = np.linalg.norm(grad, axis=1, keepdims=True)
        # On the medial axis central differences cancel (a ridge of D): a one-sided
        # difference still points to one of the equally near boundary points.
        ridge = norm[:, 0] < 0.5
        if ridge.any():
            grad[ridge] = (d[ridge, 1:4] - d[ridge, :1]) / eps
            norm = np.linalg.norm(grad, axis=1, keepdims=True)
        grad = np.divide(grad, norm, out=np.zeros_like(grad), where=norm > 0)
        return p - d[:, :1] * grad

    def transformed(self, rotation: ArrayLike, translation: ArrayLike) -> Geometry:
        """This solid mapped by ``x -> rotation @ x + translation`` (a rigid motion).

        The default wraps it in :class:`Transformed`, which maps query points back;
        representations override it to move their own data instead (faster queries,
        fast :meth:`grid_sdf`).
        """
        return Transformed(self, rotation, translation)

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """Signed distance at every cell centre of ``grid``: ``grid.shape`` float32.

        The default evaluates :meth:`signed_distance` in chunks; representations
        override it with something faster (distance transforms, narrow bands).
        """
        pts = grid.points()
        out = np.empty(len(pts), dtype=np.float32)
        step = 1 << 18
        for s in range(0, len(pts), step):
            out[s : s + step] = self.signed_distance(pts[s : s + step])
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


def rigid(rotation: ArrayLike, translation: ArrayLike) -> tuple[NDArray, NDArray]:
    """Validate a rigid motion: (3, 3) orthogonal rotation, (3,) translation, finite."""
    R = np.asarray(rotation, dtype=np.float64)
    t = np.asarray(translation, dtype=np.float64)
    if R.shape != (3, 3) or t.shape != (3,):
        raise ValueError(f"need a (3, 3) rotation and a (3,) translation, got {R.shape}, {t.shape}")
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        raise NonFiniteGeometryError("rotation and translation must be finite")
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6):
        raise ValueError("rotation is not orthogonal (R^T R != I)")
    return R, t


class Transformed(Geometry):
    """Any :class:`Geometry` moved rigidly: ``x -> rotation @ x + translation``.

    Queries map the points back into the child's frame (distances are preserved by
    rigid motions); :meth:`grid_sdf` is the pointwise default, so representations
    with a fast grid evaluation should override :meth:`Geometry.transformed` instead.

    Parameters
    ----------
    child : Geometry
        The solid in its own frame.
    rotation : (3, 3) float
        Orthogonal matrix.
    translation : (3,) float
        Offset, model units.
    """

    child: Geometry
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]

    def __init__(self, child: Geometry, rotation: ArrayLike, translation: ArrayLike) -> None:
        R, t = rigid(rotation, translation)
        if isinstance(child, Transformed):  # compose instead of nesting
            R, t, child = R @ child.rotation, R @ child.translation + t, child.child
        self.child, self.rotation, self.translation = child, R, t
        self.representation = child.representation  # type: ignore[misc]

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float: box around the moved corners of the child's box."""
        lo, hi = self.child.bounds
        corners = np.array(
            [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        moved = corners @ self.rotation.T + self.translation
        return np.stack([moved.min(axis=0), moved.max(axis=0)])

    def _back(self, points: ArrayLike) -> NDArray[np.float64]:
        return (as_points(points) - self.translation) @ self.rotation

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distance (n,) of points (n, 3), positive inside."""
        return self.child.signed_distance(self._back(points))

    def unsigned_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Distance (n,) of points (n, 3) to the boundary."""
        return self.child.unsigned_distance(self._back(points))

    def closest_points(self, points: ArrayLike) -> NDArray[np.float64]:
        """Nearest boundary points (n, 3)."""
        return self.child.closest_points(self._back(points)) @ self.rotation.T + self.translation

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Point-membership classification (n,) bool."""
        return self.child.contains(self._back(points))


def offset_closest(
    points: NDArray[np.float64],
    closest: NDArray[np.float64],
    inward: NDArray[np.bool_],
    distance: float,
) -> NDArray[np.float64]:
    """Closest points (n, 3) of a surface offset by ``distance``: ``closest`` moved that far
    towards ``points``, or away from them where ``inward`` (points inside the offset solid).

    A point exactly on the surface has no direction and keeps its closest point.
    """
    v = points - closest
    n = np.linalg.norm(v, axis=1)
    sign = np.where(inward, -1.0, 1.0)
    unit = v / np.maximum(n, 1e-300)[:, None] * sign[:, None]
    unit[n <= 0] = 0.0
    return closest + distance * unit
