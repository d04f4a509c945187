"""Implicit solids: signed distance functions, analytic primitives and CSG.

An :class:`Implicit` is a :class:`~shapedb.geometry.base.Geometry` given directly by
its signed distance function ``f(points (n, 3)) -> (n,)``, positive inside and in
model units. Analytic primitives (:class:`Sphere`, :class:`Box`, :class:`Capsule`,
:class:`Cylinder`, :class:`Torus`) have exact distances. They combine with
constructive solid geometry::

    part = (Box([0, 0, 0], [4, 2, 1]) - Cylinder([0, 0, -1], [0, 0, 1], 0.4)) | Sphere([2, 0, 0], 1)

and move with :meth:`Implicit.translate`, :meth:`Implicit.rotate` and
:meth:`Implicit.scale`, which return new geometry (rigid motions and uniform
scaling keep distances exact).

Exactness of CSG (positive inside): ``Intersection`` (min) and ``Difference``
(min with the negated subtrahend) are exact *inside* the result and a lower bound
of the distance outside; ``Union`` (max) is exact *outside* and only a lower bound
inside, wherever the nearest boundary point of one operand lies inside another
operand (near the junctions of the parts). A lower bound inside is conservative
for the decomposition: balls stay inside, but near junctions they can be smaller
than on an exact representation (e.g. a mesh of the same solid).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.errors import (
    ConfigError,
    DegenerateGeometryError,
    InvalidShapeError,
    NonFiniteGeometryError,
)
from shapedb.geometry.base import Geometry, Grid, as_points

__all__ = [
    "Implicit",
    "Sphere",
    "Box",
    "Capsule",
    "Cylinder",
    "Torus",
    "Union",
    "Intersection",
    "Difference",
    "Transformed",
]

SDF = Callable[[NDArray[np.float64]], Any]


def _vector(value: ArrayLike, name: str) -> NDArray[np.float64]:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,):
        raise InvalidShapeError(f"{name} must be a 3-vector, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise NonFiniteGeometryError(f"{name} is not finite: {v.tolist()}")
    return v


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not np.isfinite(v):
        raise NonFiniteGeometryError(f"{name} is not finite: {v}")
    if v <= 0:
        raise DegenerateGeometryError(f"{name} must be > 0, got {v}")
    return v


def _unit(value: ArrayLike, name: str) -> NDArray[np.float64]:
    v = _vector(value, name)
    n = float(np.linalg.norm(v))
    if n == 0:
        raise DegenerateGeometryError(f"{name} must be a non-zero vector")
    return v / n


class Implicit(Geometry):
    """A solid given by its signed distance function.

    Parameters
    ----------
    fn : callable
        ``fn(points)`` with points (n, 3) float64 returns (n,) signed distances,
        positive inside, model units. It should be a true distance (1-Lipschitz);
        a lower bound inside is acceptable (balls then stay inside but may be
        smaller than maximal).
    bounds : (2, 3) float
        Minimum and maximum corner of a box containing the solid.
    name : str, optional
        Used in error messages and ``repr``.
    """

    representation = "implicit"
    # Built-in subclasses compute their distances themselves and need no output check
    # when nested inside CSG; a user's function is checked at every call.
    _trusted = False

    def __init__(self, fn: SDF, bounds: ArrayLike, *, name: str | None = None) -> None:
        if not callable(fn):
            raise InvalidShapeError(f"fn must be callable, got {type(fn).__name__}")
        self._fn = fn
        self._bounds = self._check_bounds(bounds)
        self.name = name or getattr(fn, "__name__", type(self).__name__)

    @staticmethod
    def _check_bounds(bounds: ArrayLike) -> NDArray[np.float64]:
        b = np.asarray(bounds, dtype=np.float64)
        if b.shape != (2, 3):
            raise InvalidShapeError(f"bounds must have shape (2, 3), got {b.shape}")
        if not np.all(np.isfinite(b)):
            raise NonFiniteGeometryError(f"bounds are not finite: {b.tolist()}")
        if np.any(b[1] < b[0]):
            raise InvalidShapeError(f"bounds minimum exceeds maximum: {b.tolist()}")
        b.setflags(write=False)
        return b

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float: minimum and maximum corner, model units."""
        return self._bounds

    def __repr__(self) -> str:
        lo, hi = np.round(self.bounds, 4).tolist()
        label = "" if self.name == type(self).__name__ else f" {self.name!r}"
        return f"<{type(self).__name__}{label} bounds={lo}..{hi}>"

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Raw distances of validated points p (n, 3); subclasses override."""
        return np.asarray(self._fn(p), dtype=np.float64)

    def _nested(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distances of already validated points, as used by CSG and transforms."""
        return self._evaluate(p) if self._trusted else self.signed_distance(p)

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distance (n,) float64 of points (n, 3), positive inside.

        Raises
        ------
        InvalidShapeError
            If the function returns the wrong shape.
        NonFiniteGeometryError
            If it returns NaN or infinity.
        """
        p = as_points(points)
        d = self._evaluate(p)
        if d.shape != (len(p),):
            raise InvalidShapeError(
                f"signed distance function returned shape {d.shape} for {len(p)} points; "
                f"expected ({len(p)},)",
                source=self.name,
            )
        if not np.all(np.isfinite(d)):
            bad = int(np.count_nonzero(~np.isfinite(d)))
            raise NonFiniteGeometryError(
                f"signed distance function returned {bad} non-finite value(s)", source=self.name
            )
        return d

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """Signed distance at every cell centre of ``grid``: ``grid.shape`` float32.

        Evaluated slab by slab (a few x-planes at a time) to bound memory.
        """
        x, y, z = grid.axes()
        out = np.empty(grid.shape, dtype=np.float32)
        plane = len(y) * len(z)
        step = max(1, (1 << 18) // plane)
        yy, zz = np.meshgrid(y, z, indexing="ij")
        yz = np.stack([yy.ravel(), zz.ravel()], axis=1)
        for s in range(0, len(x), step):
            xs = x[s : s + step]
            pts = np.empty((len(xs) * plane, 3))
            pts[:, 0] = np.repeat(xs, plane)
            pts[:, 1:] = np.tile(yz, (len(xs), 1))
            out[s : s + step] = self.signed_distance(pts).reshape(len(xs), len(y), len(z))
        return out

    # -- transformations -------------------------------------------------------------
    def translate(self, offset: ArrayLike) -> Implicit:
        """This solid moved by ``offset`` (3,), model units."""
        return Transformed(self, translation=_vector(offset, "offset"))

    def rotate(self, matrix: ArrayLike, *, center: ArrayLike | None = None) -> Implicit:
        """This solid rotated by the orthogonal 3x3 ``matrix`` about ``center`` (3,).

        ``center`` defaults to the origin. Reflections (det = -1) are allowed.
        """
        R = np.asarray(matrix, dtype=np.float64)
        if R.shape != (3, 3) or not np.all(np.isfinite(R)):
            raise ConfigError(f"rotation matrix must be a finite 3x3 array, got shape {R.shape}")
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6):
            raise ConfigError("rotation matrix is not orthogonal (R^T R != I)")
        c = np.zeros(3) if center is None else _vector(center, "center")
        return Transformed(self, rotation=R, translation=c - R @ c)

    def transformed(self, rotation: ArrayLike, translation: ArrayLike) -> Implicit:
        """This solid mapped by ``x -> rotation @ x + translation`` (a rigid motion)."""
        return self.rotate(rotation).translate(translation)

    def scale(self, factor: float, *, center: ArrayLike | None = None) -> Implicit:
        """This solid scaled uniformly by ``factor`` > 0 about ``center`` (3,), default origin."""
        s = float(factor)
        if not (np.isfinite(s) and s > 0):
            raise ConfigError(f"scale factor must be finite and > 0, got {factor!r}")
        c = np.zeros(3) if center is None else _vector(center, "center")
        return Transformed(self, scale=s, translation=c - s * c)

    # -- CSG operators ---------------------------------------------------------------
    def __or__(self, other: Implicit) -> Implicit:
        return Union(self, other)

    def __and__(self, other: Implicit) -> Implicit:
        return Intersection(self, other)

    def __sub__(self, other: Implicit) -> Implicit:
        return Difference(self, other)


# -- primitives ------------------------------------------------------------------------
class Sphere(Implicit):
    """Ball of ``radius`` > 0 about ``center`` (3,); exact distance."""

    _trusted = True

    def __init__(self, center: ArrayLike, radius: float) -> None:
        self.center = _vector(center, "center")
        self.radius = _positive(radius, "radius")
        r = self.radius
        super().__init__(self._evaluate, [self.center - r, self.center + r], name="Sphere")

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.radius - np.linalg.norm(p - self.center, axis=1)


class Box(Implicit):
    """Axis-aligned box with ``center`` (3,) and edge lengths ``size`` (3,); exact distance."""

    _trusted = True

    def __init__(self, center: ArrayLike, size: ArrayLike) -> None:
        self.center = _vector(center, "center")
        size_ = _vector(size, "size")
        if np.any(size_ <= 0):
            raise DegenerateGeometryError(f"box size must be > 0, got {size_.tolist()}")
        self.half = 0.5 * size_
        super().__init__(
            self._evaluate, [self.center - self.half, self.center + self.half], name="Box"
        )

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        q = np.abs(p - self.center) - self.half
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        inside = np.minimum(q.max(axis=1), 0.0)
        return -(outside + inside)


def _segment_frame(
    a: NDArray[np.float64], b: NDArray[np.float64], name: str
) -> tuple[NDArray[np.float64], float]:
    axis = b - a
    length = float(np.linalg.norm(axis))
    if length == 0:
        raise DegenerateGeometryError(f"{name}: endpoints a and b coincide")
    return axis / length, length


class Capsule(Implicit):
    """Points within ``radius`` of the segment from ``a`` (3,) to ``b`` (3,); exact distance.

    ``a == b`` gives a sphere.
    """

    _trusted = True

    def __init__(self, a: ArrayLike, b: ArrayLike, radius: float) -> None:
        self.a = _vector(a, "a")
        self.b = _vector(b, "b")
        self.radius = _positive(radius, "radius")
        r = self.radius
        lo = np.minimum(self.a, self.b) - r
        hi = np.maximum(self.a, self.b) + r
        super().__init__(self._evaluate, [lo, hi], name="Capsule")

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        ab = self.b - self.a
        ab2 = float(ab @ ab)
        pa = p - self.a
        t = np.clip(pa @ ab / ab2, 0.0, 1.0) if ab2 > 0 else np.zeros(len(p))
        return self.radius - np.linalg.norm(pa - t[:, None] * ab, axis=1)


class Cylinder(Implicit):
    """Solid capped cylinder of ``radius`` with axis from ``a`` (3,) to ``b`` (3,); exact."""

    _trusted = True

    def __init__(self, a: ArrayLike, b: ArrayLike, radius: float) -> None:
        self.a = _vector(a, "a")
        self.b = _vector(b, "b")
        self.radius = _positive(radius, "radius")
        self.axis, self.length = _segment_frame(self.a, self.b, "Cylinder")
        # Exact AABB of the end discs: half-extent radius * sqrt(1 - axis_k^2).
        ext = self.radius * np.sqrt(np.clip(1.0 - self.axis**2, 0.0, 1.0))
        lo = np.minimum(self.a, self.b) - ext
        hi = np.maximum(self.a, self.b) + ext
        super().__init__(self._evaluate, [lo, hi], name="Cylinder")

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        mid = 0.5 * (self.a + self.b)
        q = p - mid
        h = q @ self.axis
        rho = np.linalg.norm(q - h[:, None] * self.axis, axis=1)
        dr = rho - self.radius
        dz = np.abs(h) - 0.5 * self.length
        outside = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0))
        inside = np.minimum(np.maximum(dr, dz), 0.0)
        return -(outside + inside)


class Torus(Implicit):
    """Solid torus: points within ``minor`` of the circle of radius ``major`` about ``center``.

    Parameters
    ----------
    center : (3,) float
        Centre of the ring.
    major, minor : float
        Ring and tube radii, ``0 < minor < major``.
    axis : (3,) float
        Normal of the ring's plane, default z.
    """

    _trusted = True

    def __init__(
        self, center: ArrayLike, major: float, minor: float, axis: ArrayLike = (0.0, 0.0, 1.0)
    ) -> None:
        self.center = _vector(center, "center")
        self.major = _positive(major, "major")
        self.minor = _positive(minor, "minor")
        if self.minor >= self.major:
            raise DegenerateGeometryError(
                f"torus minor radius {self.minor} must be smaller than major radius {self.major}"
            )
        self.axis = _unit(axis, "axis")
        ext = self.major * np.sqrt(np.clip(1.0 - self.axis**2, 0.0, 1.0)) + self.minor
        super().__init__(self._evaluate, [self.center - ext, self.center + ext], name="Torus")

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        q = p - self.center
        h = q @ self.axis
        rho = np.linalg.norm(q - h[:, None] * self.axis, axis=1)
        return self.minor - np.hypot(rho - self.major, h)


# -- CSG -------------------------------------------------------------------------------
def _operands(children: tuple[Implicit, ...], name: str, minimum: int) -> tuple[Implicit, ...]:
    flat: list[Implicit] = []
    for c in children:
        if not isinstance(c, Implicit):
            raise InvalidShapeError(f"{name} operands must be Implicit, got {type(c).__name__}")
        # Flatten nested operations of the same kind: (a | b) | c -> Union(a, b, c).
        same = type(c).__name__ == name and name != "Difference"
        flat.extend(getattr(c, "children", (c,)) if same else (c,))
    if len(flat) < minimum:
        raise InvalidShapeError(f"{name} needs at least {minimum} operand(s), got {len(flat)}")
    return tuple(flat)


class Union(Implicit):
    """Union of solids: max of the distances (exact outside, a lower bound inside)."""

    _trusted = True

    def __init__(self, *children: Implicit) -> None:
        self.children = _operands(children, "Union", 1)
        b = np.stack([c.bounds for c in self.children])
        super().__init__(self._evaluate, [b[:, 0].min(axis=0), b[:, 1].max(axis=0)], name="Union")

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        out = self.children[0]._nested(p)
        if len(p) == 0:
            return out
        pmin, pmax = p.min(axis=0), p.max(axis=0)
        for c in self.children[1:]:
            lo, hi = c.bounds
            # Whole-batch cull: every point is at least `gap` outside the child's box,
            # so the child's distance is <= -gap and cannot raise the max.
            gap = float(np.linalg.norm(np.maximum(np.maximum(lo - pmax, pmin - hi), 0.0)))
            if gap > 0 and gap >= float(np.abs(out).max()):
                continue
            np.maximum(out, _culled(c, p, out), out=out)
        return out


def _culled(child: Implicit, p: NDArray[np.float64], current: NDArray[np.float64]) -> NDArray:
    """Child's distance where it can change ``max(current, child)``, a lower bound elsewhere.

    Outside the child's box the child's distance is at most minus the distance ``gap``
    to the box, so it cannot exceed ``current`` when ``gap >= |current|``; there
    ``-gap`` (which does not change the max) is returned without evaluating the child.
    """
    lo, hi = child.bounds
    gap = np.linalg.norm(np.maximum(np.maximum(lo - p, p - hi), 0.0), axis=1)
    need = gap < np.abs(current) + 1e-12
    if need.all():
        return child._nested(p)
    out = -gap
    if need.any():
        out[need] = child._nested(p[need])
    return out


class Intersection(Implicit):
    """Intersection of solids: min of the distances (exact inside, a lower bound outside)."""

    _trusted = True

    def __init__(self, *children: Implicit) -> None:
        self.children = _operands(children, "Intersection", 1)
        b = np.stack([c.bounds for c in self.children])
        lo, hi = b[:, 0].max(axis=0), b[:, 1].min(axis=0)
        if np.any(hi < lo):
            raise DegenerateGeometryError("intersection is empty: the operands' boxes are disjoint")
        super().__init__(self._evaluate, [lo, hi], name="Intersection")

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        out = self.children[0]._nested(p)
        for c in self.children[1:]:
            np.minimum(out, c._nested(p), out=out)
        return out


class Difference(Implicit):
    """``base`` minus the union of ``tools``: min(base, -tool) (exact inside)."""

    _trusted = True

    def __init__(self, base: Implicit, *tools: Implicit) -> None:
        self.children = _operands((base, *tools), "Difference", 2)
        super().__init__(self._evaluate, base.bounds, name="Difference")

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        out = self.children[0]._nested(p)
        for c in self.children[1:]:
            # A tool changes min(out, -tool) only at points inside the solid so far
            # whose distance to the tool is below their depth: near the tool's box.
            lo, hi = c.bounds
            reach = np.maximum(out, 0.0)[:, None]
            near = (out > 0) & np.all((p >= lo - reach) & (p <= hi + reach), axis=1)
            if near.all():
                np.minimum(out, -c._nested(p), out=out)
            elif near.any():
                out[near] = np.minimum(out[near], -c._nested(p[near]))
        return out


class Transformed(Implicit):
    """``child`` mapped by x -> scale * rotation @ x + translation (distances stay exact)."""

    _trusted = True
    child: Implicit
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    factor: float

    def __init__(
        self,
        child: Implicit,
        *,
        rotation: ArrayLike | None = None,
        translation: ArrayLike | None = None,
        scale: float = 1.0,
    ) -> None:
        R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        t = np.zeros(3) if translation is None else _vector(translation, "translation")
        s = float(scale)
        if isinstance(child, Transformed):  # compose instead of nesting
            R, t, s = R @ child.rotation, s * (R @ child.translation) + t, s * child.factor
            child = child.child
        self.child, self.rotation, self.translation, self.factor = child, R, t, s
        lo, hi = child.bounds
        corners = np.array(
            [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        moved = s * corners @ R.T + t
        super().__init__(
            self._evaluate,
            [moved.min(axis=0), moved.max(axis=0)],
            name=f"Transformed({child.name})",
        )

    def _evaluate(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        local = (p - self.translation) @ self.rotation / self.factor
        return self.factor * self.child._nested(local)
