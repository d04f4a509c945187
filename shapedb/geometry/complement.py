"""The complement of a solid within its bounding box (optionally padded), as a :class:`Geometry`.

MDBD fills a solid with balls, so its contact graph sees protrusions (bosses, ribs,
limbs) but not concavities: a hole is only an absence of balls. The paper names
concave features as future work. Decomposing the *complement* turns them around:
inside the box ``B`` (the solid's bounding box grown by ``padding``), the region
``B \\ solid`` is a solid whose convex features are the holes, slots and pockets of
the original, so the same MDBD, graph and kernel find and match them.

The signed distance (positive inside) is the CSG intersection of the box with the
solid's outside::

    sdf_c(p) = min(-sdf(p), sdf_box(p))

exact inside the complement wherever ``sdf`` is (as for any CSG intersection). The
whole-grid evaluation reuses the solid's own fast :meth:`Geometry.grid_sdf`.

>>> from shapedb.examples import part
>>> from shapedb.mdbd.decomposition import decompose
>>> holes = decompose(Complement(part("plate", 0)), resolution=96)   # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.errors import ConfigError, InvalidShapeError
from shapedb.geometry.base import Geometry, Grid, as_points

__all__ = ["Complement", "box_sdf"]


def box_sdf(
    points: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64]
) -> NDArray:
    """Exact signed distance (n,) of points (n, 3) to the box [lo, hi], positive inside."""
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    q = np.abs(points - c) - h
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(q.max(axis=1), 0.0)
    return -(outside + inside)


class Complement(Geometry):
    """The region of the (optionally padded) bounding box of ``solid`` outside it.

    Parameters
    ----------
    solid : Geometry
        Any representation.
    padding : float
        Margin added to the bounding box on every side, as a fraction of its
        longest side. The default 0 keeps the exact box, so the complement is the
        stock minus the part (the machining "removal volume"): each through hole or
        slot is a component of its own, open onto the box faces, instead of hanging
        off slabs of air around the part (padding measured in ``docs/studies.md``).
        A solid that fills its box has an empty complement.

    Attributes
    ----------
    solid : Geometry
        The original solid.
    box : (2, 3) float64
        The padded box, which is also :attr:`bounds`.
    """

    def __init__(self, solid: Geometry, *, padding: float = 0.0) -> None:
        if not isinstance(solid, Geometry):
            raise InvalidShapeError(f"the complement needs a Geometry, got {type(solid).__name__}")
        p = float(padding)
        if not (np.isfinite(p) and 0.0 <= p <= 1.0):
            raise ConfigError(f"padding must be in [0, 1], got {padding!r}", source=repr(solid))
        self.solid = solid
        self.padding = p
        b = np.asarray(solid.bounds, dtype=np.float64)
        margin = p * float((b[1] - b[0]).max())
        self.box = np.stack([b[0] - margin, b[1] + margin])
        self.box.setflags(write=False)
        self.name = f"complement({getattr(solid, 'name', type(solid).__name__)})"

    @property
    def representation(self) -> str:  # type: ignore[override]
        """The solid's representation (the distance comes from it)."""
        return str(self.solid.representation)

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float: the padded box."""
        return self.box

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """``min(-sdf(p), sdf_box(p))`` (n,) float64 for points (n, 3), positive inside."""
        p = as_points(points)
        inside_box = box_sdf(p, self.box[0], self.box[1])
        return np.minimum(-np.asarray(self.solid.signed_distance(p), np.float64), inside_box)

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """The complement's distance on ``grid`` (``grid.shape`` float32), from the
        solid's own whole-grid evaluation and the box's exact distance."""
        f = -np.asarray(self.solid.grid_sdf(grid), dtype=np.float32)
        x, y, z = grid.axes()
        lo, hi = self.box
        # box distance is separable per axis only outside; evaluate it slab by slab
        yy, zz = np.meshgrid(y, z, indexing="ij")
        yz = np.stack([yy.ravel(), zz.ravel()], axis=1)
        for i, xi in enumerate(x):
            pts = np.column_stack([np.full(len(yz), xi), yz])
            b = box_sdf(pts, lo, hi).reshape(len(y), len(z)).astype(np.float32)
            np.minimum(f[i], b, out=f[i])
        return f

    def __repr__(self) -> str:
        lo, hi = np.round(self.box, 4).tolist()
        return f"<Complement of {self.solid!r} box={lo}..{hi}>"
