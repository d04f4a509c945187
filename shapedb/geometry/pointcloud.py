"""Point clouds: a solid known only through (possibly sparse, uneven) surface samples.

Distance is the distance to the *splats* of the samples: each sample stands for a
disc in its tangent plane (normal: the oriented normal below) whose area is the
sample's area ``a_i`` (the same areas the winding number uses), radius
``sqrt(a_i / pi)``; the distance of a point is its smallest distance to the discs of
its ``SPLAT_NEIGHBOURS`` nearest samples, and :meth:`closest_points` returns the
closest point on that disc. The distance to the nearest sample alone overestimates
the distance to the underlying surface (the nearest sample is offset sideways from
the true closest point); a fixed correction for the mean offset (``sqrt(d^2 - r^2)``,
``r = SPACING_CORRECTION * rho_k``, still used outside the solid where only the sign
matters) centres the median but leaves the scatter, which the splats narrow
(``docs/results.md``, "Across representations").

The sign is the hard part. Poisson reconstruction and fixed-width shells leak on
sparse clouds (the paper queries a random 20 % of a mesh's vertices), and point
winding numbers need consistently oriented normals. :class:`PointCloud` therefore:

1. estimates the local sample spacing ``rho_i`` (distance to the k-th neighbour);
2. builds an *adaptive shell* on an orientation grid: a cell is wall when it is
   within ``shell * rho_i`` of its nearest sample ``i`` (at least ``1.5`` cells), so
   sparse regions get thick walls and gaps close; the *exterior* is the part of the
   non-wall cells connected to the grid border (flood fill);
3. estimates normals by local PCA (or takes the given ones) and orients each one
   towards its nearest exterior cell; normals nearly tangent to that direction
   take the orientation of their well-oriented neighbours;
4. classifies points with the point-cloud generalised winding number (libigl
   ``fast_winding_number``; point areas: the smaller of ``pi * rho_k^2 / k`` and the
   area of the neighbourhood's ellipse, so that samples along a thin leg or in
   anisotropic rings do not count as wide patches): inside where
   ``w > 0.5``. Unlike the flood fill, the winding number does not need the shell
   to be closed, and it is smooth away from the samples, so :meth:`grid_sdf` uses
   the same narrow band / closest-point propagation / coarse-to-fine machinery as
   :class:`shapedb.geometry.mesh.TriangleMesh` (see :mod:`shapedb.geometry._meshing`).

If normals are given they are used as they are, except that they are all flipped
when most of them point away from the exterior.
"""

from __future__ import annotations

import logging
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage

from shapedb.errors import (
    DegenerateGeometryError,
    EmptyGeometryError,
    InvalidShapeError,
    NonFiniteGeometryError,
)
from shapedb.geometry._meshing import (
    cell_band,
    coarse_to_fine_inside,
    propagate_closest,
    refine_closest,
)
from shapedb.geometry.base import Geometry, Grid, as_points

__all__ = ["DISTANCES", "PointCloud"]

logger = logging.getLogger(__name__)

#: Fewest distinct points accepted.
MIN_POINTS = 10
#: Nearest samples whose splats (discs of their area in their tangent plane) are
#: searched for the distance to the surface; 4-16 measure the same.
SPLAT_NEIGHBOURS = 8
#: Sideways offset of the nearest sample from the closest surface point, in units of
#: its spacing (distance to the k-th neighbour); see the module docstring.
SPACING_CORRECTION = 0.3
#: Fraction of kNN edges with unexplained opposite normals (see
#: ``PointCloud._unexplained``) above which exterior votes are replaced by the
#: orientation propagated along the surface (chosen on CAPOD's clouds with
#: ``python -m bench.studies.agreement``; ``docs/results.md``).
UNEXPLAINED_SWITCH = 0.06
#: Calibration of the ellipse estimate of a sample's area (see ``PointCloud.areas``):
#: ``4 pi sqrt(l1 l2) / k`` of the k-neighbourhood falls short of the true area per
#: sample by a factor 1.19-1.33 on uniform random samples of a sphere, a box and a torus
#: (500-8,000 samples); the isotropic ``pi rho_k^2 / k`` is within 3 % there.
ELLIPSE_AREA = 1.2
#: Distance estimators :meth:`PointCloud.unsigned_distance` offers (see its docstring).
DISTANCES = ("splat", "nearest", "sphere")
#: Query-point x sample pairs up to which winding numbers are summed directly.
_DIRECT_WINDING_PAIRS = 200_000


def _corrected(d: NDArray[np.floating], rho: NDArray[np.floating]) -> NDArray[np.floating]:
    """Surface distance estimated from nearest-sample distance ``d`` and spacing ``rho``."""
    r = SPACING_CORRECTION * rho
    return np.maximum(np.sqrt(np.maximum(d * d - r * r, 0.0)), 0.5 * d)


class PointCloud(Geometry):
    """A solid sampled on its boundary by points, with or without normals.

    Parameters
    ----------
    points : (n, 3) float
        Surface samples, model units; duplicates are dropped.
    normals : (n, 3) float, optional
        Outward normals (need not be unit length). Estimated when omitted.
    name : str, optional
        Used in error messages.
    k : int
        Neighbours used for spacing, areas and normal estimation.
    shell : float
        Wall radius of the adaptive shell, in units of the local spacing.
    orient_resolution : int
        Cells along the longest side of the grid used to find the exterior.
    distance : str
        The distance estimator (one of :data:`DISTANCES`; see
        :meth:`unsigned_distance`), used by every query and by :meth:`grid_sdf`.

    Raises
    ------
    EmptyGeometryError
        No points.
    NonFiniteGeometryError
        NaN or infinite coordinates.
    DegenerateGeometryError
        Fewer than ``MIN_POINTS`` distinct points, or all points on a plane.
    InvalidShapeError
        Wrong array shapes, or normals not matching the points.
    """

    representation = "pointcloud"

    def __init__(
        self,
        points: ArrayLike,
        normals: ArrayLike | None = None,
        *,
        name: str | None = None,
        k: int = 10,
        shell: float = 1.5,
        orient_resolution: int = 96,
        distance: str = "splat",
    ) -> None:
        self.name = name
        if distance not in DISTANCES:
            raise InvalidShapeError(
                f"distance={distance!r} is unknown; choose from {DISTANCES}", source=name
            )
        self.distance = distance
        p = np.asarray(points)
        if p.size == 0:
            raise EmptyGeometryError("point cloud has no points", source=name)
        if p.ndim != 2 or p.shape[1] != 3:
            raise InvalidShapeError(f"points must have shape (n, 3), got {p.shape}", source=name)
        if not np.issubdtype(p.dtype, np.number) or np.iscomplexobj(p):
            raise InvalidShapeError(f"points must be real numbers, got {p.dtype}", source=name)
        p = np.asarray(p, dtype=np.float64)
        if not np.all(np.isfinite(p)):
            bad = int((~np.isfinite(p)).any(axis=1).sum())
            raise NonFiniteGeometryError(
                f"{bad} of {len(p)} points have NaN or infinite coordinates", source=name
            )
        n = None
        if normals is not None:
            n = np.asarray(normals, dtype=np.float64)
            if n.shape != p.shape:
                raise InvalidShapeError(
                    f"normals must have the shape of points {p.shape}, got {n.shape}", source=name
                )
            if not np.all(np.isfinite(n)):
                raise NonFiniteGeometryError("normals contain NaN or inf", source=name)
        p, first = np.unique(p, axis=0, return_index=True)
        if len(p) < MIN_POINTS:
            raise DegenerateGeometryError(
                f"point cloud has {len(p)} distinct points; at least {MIN_POINTS} are needed "
                "to enclose a volume",
                source=name,
            )
        sv = np.linalg.svd(p[:: max(1, len(p) // 20000)] - p.mean(0), compute_uv=False)
        if sv[2] <= 1e-9 * sv[0]:
            raise DegenerateGeometryError("all points lie on a plane or a line", source=name)
        if k < 3 or shell <= 0 or orient_resolution < 16:
            raise InvalidShapeError(
                f"need k >= 3, shell > 0, orient_resolution >= 16; got {k}, {shell}, "
                f"{orient_resolution}",
                source=name,
            )
        self._points = np.ascontiguousarray(p)
        self._given_normals = None if n is None else np.ascontiguousarray(n[first])
        self.k = int(min(k, len(p) - 1))
        self.shell = float(shell)
        self.orient_resolution = int(orient_resolution)

    # ------------------------------------------------------------------ basics
    @property
    def points(self) -> NDArray[np.float64]:
        """(n, 3) float64: the distinct points (read-only view)."""
        out = self._points.view()
        out.flags.writeable = False
        return out

    @cached_property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float64: corners of the box around the points."""
        return np.stack([self._points.min(0), self._points.max(0)])

    @cached_property
    def _tree(self) -> Any:
        from scipy.spatial import cKDTree

        return cKDTree(self._points)

    @cached_property
    def spacing(self) -> NDArray[np.float64]:
        """(n,) float64: distance of each point to its k-th nearest neighbour."""
        d, _ = self._tree.query(self._points, k=self.k + 1)
        return np.maximum(d[:, -1], 1e-12)

    @property
    def surface_sampling(self) -> float:
        """Median distance of a point to its k-th nearest neighbour, model units."""
        return float(np.median(self.spacing))

    @cached_property
    def _local_pca(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Covariance of each sample's neighbourhood (itself and its k nearest).

        Returns eigenvalues (n, 3), ascending, in squared model units, and the
        eigenvectors (n, 3, 3) as columns.
        """
        nb = np.concatenate([np.arange(len(self._points))[:, None], self._neighbours], axis=1)
        q = self._points[nb] - self._points[nb].mean(1, keepdims=True)
        lam, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", q, q) / nb.shape[1])
        return lam, vecs

    @cached_property
    def areas(self) -> NDArray[np.float64]:
        """(n,) float64: surface area represented by each point, squared model units.

        The smaller of the isotropic estimate ``pi rho_k^2 / k`` and the area of the
        neighbourhood's ellipse, ``ELLIPSE_AREA * 4 pi sqrt(l1 l2) / k`` (``l1, l2``
        the two largest variances of the k-neighbourhood). Both are unbiased on
        uniform samples of a surface; where the samples are anisotropic (rings of
        vertices) or lie along a curve (a leg or a wire thinner than the sample
        spacing) the isotropic disc counts the spacing along the curve as a width,
        and such samples gave the winding number blobs of spurious volume.
        """
        lam = self._local_pca[0]
        iso = np.pi * self.spacing**2 / self.k
        ellipse = ELLIPSE_AREA * 4.0 * np.pi * np.sqrt(np.clip(lam[:, 1] * lam[:, 2], 0, None))
        return np.minimum(ellipse / self.k, iso)

    # ------------------------------------------------------------------ orientation
    def _pca_normals(self) -> NDArray[np.float64]:
        return self._local_pca[1][:, :, 0]

    @cached_property
    def _shell(self) -> tuple[Grid, NDArray[np.bool_], NDArray[np.bool_]]:
        """(grid, wall, exterior) of the adaptive shell on the orientation grid."""
        reach = self.shell * np.minimum(self.spacing, 4 * np.median(self.spacing))
        b = self.bounds + np.array([[-1.0], [1.0]]) * reach.max()  # the wall stays inside
        grid = Grid.fit(b, resolution=self.orient_resolution, padding=2)
        h = grid.spacing
        band = cell_band((self._points - grid.origin) / h, grid.shape, dilate=2)
        cells = grid.to_point(np.argwhere(band))
        _, nearest = self._tree.query(cells)
        dist, owner = propagate_closest(band, (self._points[nearest] - grid.origin) / h)
        radius = np.maximum(reach / h, 1.5)
        wall = dist <= radius[nearest[owner]]
        labels, _ = ndimage.label(~wall)
        border = np.unique(
            np.concatenate(
                [labels[[0, -1]].ravel(), labels[:, [0, -1]].ravel(), labels[:, :, [0, -1]].ravel()]
            )
        )
        exterior = np.isin(labels, border[border > 0])
        logger.debug(
            "point cloud %s: exterior %.1f%% of %s orientation grid, wall %.1f%%",
            self.name,
            100 * exterior.mean(),
            grid.shape,
            100 * wall.mean(),
        )
        return grid, wall, exterior

    @cached_property
    def _exterior_direction(self) -> NDArray[np.float64]:
        """(n, 3): unit vector from each point to its nearest exterior cell."""
        grid, _, exterior = self._shell
        ind = ndimage.distance_transform_edt(~exterior, return_distances=False, return_indices=True)
        ijk = grid.to_index(self._points)
        target = ind[:, ijk[:, 0], ijk[:, 1], ijk[:, 2]].T
        v = grid.to_point(target) - self._points
        return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)

    @cached_property
    def _neighbours(self) -> NDArray[np.intp]:
        """(n, k) int: the k nearest other samples of each sample."""
        _, nb = self._tree.query(self._points, k=self.k + 1)
        return np.asarray(nb[:, 1:])

    @cached_property
    def _pca(self) -> NDArray[np.float64]:
        """(n, 3) float64: unoriented unit normals from local PCA."""
        return self._pca_normals()

    def _exterior_orientation(self) -> NDArray[np.float64]:
        """(n,) signs of the PCA normals from exterior votes.

        Each normal is turned towards its nearest exterior cell; normals nearly
        tangent to that direction (``|cos| < 0.3``) take the orientation of their
        well-oriented neighbours.
        """
        n = self._pca
        dot = np.einsum("ij,ij->i", n, self._exterior_direction)
        sign = np.where(dot < 0, -1.0, 1.0)
        unsure = np.abs(dot) < 0.3
        if unsure.any() and not unsure.all():
            nb = self._neighbours
            for _ in range(8):
                idx = np.flatnonzero(unsure)
                m = n[nb[idx]] * (sign[nb[idx]] * ~unsure[nb[idx]])[..., None]
                vote = np.sign(np.einsum("mkj,mj->m", m, n[idx] * sign[idx, None]))
                fixed = vote != 0
                sign[idx[fixed]] *= vote[fixed]
                unsure[idx[fixed]] = False
                if not unsure.any():
                    break
        return sign

    def _propagated_orientation(self) -> NDArray[np.float64]:
        """(n,) signs of the PCA normals propagated along the surface, like the mesh's.

        Hoppe et al. (1992): a minimum spanning tree over the kNN edges with weights
        ``1 - |n_i . n_j|`` (plus 1 for edges whose offset along the normals exceeds
        half their length: across a wall or a sharp edge) carries the sign from one
        sample to the next; each tree (connected part of the cloud) is then flipped
        so that its signed volume ``sum a_i (p_i - c) . n_i`` is positive, as
        :class:`shapedb.geometry.mesh.TriangleMesh` does per edge-connected component.
        """
        from scipy import sparse
        from scipy.sparse import csgraph

        n, p = self._pca, self._points
        size, nb = len(n), self._neighbours
        i = np.repeat(np.arange(size), nb.shape[1])
        j = nb.ravel()
        d = p[j] - p[i]
        offset = np.abs(np.einsum("ij,ij->i", d, n[i])) + np.abs(np.einsum("ij,ij->i", d, n[j]))
        across = offset > np.linalg.norm(d, axis=1)  # mean offset above half the length
        w = 1.0 - np.abs(np.einsum("ij,ij->i", n[i], n[j])) + across + 1e-6
        g = sparse.coo_matrix((w, (i, j)), shape=(size, size)).tocsr()
        tree = csgraph.minimum_spanning_tree(g.maximum(g.T)).tocoo()
        ncomp, label = csgraph.connected_components(tree, directed=False)
        roots = np.unique(label, return_index=True)[1]
        # one breadth-first traversal from a virtual node joined to every tree's root
        rows = np.r_[tree.row, np.full(ncomp, size)]
        cols = np.r_[tree.col, roots]
        g2 = sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(size + 1, size + 1))
        _, pred = csgraph.breadth_first_order(g2.tocsr(), size, directed=False)
        parent = np.asarray(pred[:size], dtype=np.intp)
        top = parent == size
        parent[top] = np.flatnonzero(top)
        sign = np.where(np.einsum("ij,ij->i", n, n[parent]) < 0, -1.0, 1.0)
        while True:  # pointer jumping: product of the relative signs up to the root
            sign = sign * sign[parent]
            up = parent[parent]
            if np.array_equal(up, parent):
                break
            parent = up
        vol = np.bincount(
            label, weights=self.areas * np.einsum("ij,ij->i", p - p.mean(0), n * sign[:, None])
        )
        return sign * np.where(vol[label] < 0, -1.0, 1.0)

    def _unexplained(self, sign: NDArray[np.float64]) -> float:
        """Fraction of kNN edges whose oriented normals disagree for no geometric reason.

        Neighbours with opposite normals (``n_i . n_j < -0.5``) are explained when
        they face away from each other (two sides of a plate thinner than the sample
        spacing) or towards each other (two walls of a narrow gap); otherwise
        (coplanar, or one in front of the other) the orientation is locally random, as exterior votes are on a single open sheet
        that the exterior reaches from both sides.
        """
        n, p, nb = self._pca * sign[:, None], self._points, self._neighbours
        i = np.repeat(np.arange(len(n)), nb.shape[1])
        j = nb.ravel()
        d = p[j] - p[i]
        a = np.einsum("ij,ij->i", d, n[i])  # > 0: j lies in front of i
        b = np.einsum("ij,ij->i", d, n[j])  # < 0: i lies in front of j
        apart = (a < 0) & (b > 0)
        facing = (a > 0) & (b < 0)
        opposite = np.einsum("ij,ij->i", n[i], n[j]) < -0.5
        return float(np.mean(opposite & ~apart & ~facing))

    @cached_property
    def normals(self) -> NDArray[np.float64]:
        """(n, 3) float64: unit outward normals (given, or estimated and oriented).

        Estimated normals are oriented by exterior votes, unless more than
        ``UNEXPLAINED_SWITCH`` of the kNN edges then disagree for no geometric
        reason (open single sheets: chairs, pianos, some cars); such clouds take
        the orientation propagated along the surface (consistent, like the mesh's).
        """
        if self._given_normals is not None:
            n = self._given_normals / np.maximum(
                np.linalg.norm(self._given_normals, axis=1, keepdims=True), 1e-300
            )
            if np.sum(np.einsum("ij,ij->i", n, self._exterior_direction)) < 0:
                logger.warning("point cloud %s: given normals point inwards; flipped", self.name)
                n = -n
            return n
        sign = self._exterior_orientation()
        unexplained = self._unexplained(sign)
        if unexplained > UNEXPLAINED_SWITCH:
            sign = self._propagated_orientation()
        logger.debug(
            "point cloud %s: %.3f of the kNN edges inconsistent under exterior votes: %s",
            self.name,
            unexplained,
            "propagated" if unexplained > UNEXPLAINED_SWITCH else "voted",
        )
        return self._pca * sign[:, None]

    # ------------------------------------------------------------------ queries
    def winding_number(self, points: ArrayLike) -> NDArray[np.float64]:
        """Point-cloud generalised winding number (n,) of points (n, 3).

        ``sum_i a_i (p_i - q) . n_i / (4 pi |p_i - q|^3)``; summed directly for a
        few query points (the refinement asks for 1-7 at a time), else by libigl's
        Barnes-Hut approximation, whose tree costs milliseconds to build per call.
        """
        import igl

        q = np.ascontiguousarray(as_points(points))
        if len(q) == 0:
            return np.zeros(0)
        if len(q) * len(self._points) <= _DIRECT_WINDING_PAIRS:
            return self._direct_winding_number(q)
        return np.asarray(
            igl.fast_winding_number(self._points, self.normals, self.areas, q), dtype=np.float64
        )

    @cached_property
    def _dipoles(self) -> tuple[NDArray[np.float64], ...]:
        """The direct sum's per-sample terms, about the samples' centroid: centre (3,),
        centred samples (n, 3), their squared norms (n,), ``p . n`` (n,), ``a / 4 pi`` (n,)."""
        centre = self._points.mean(axis=0)
        p = self._points - centre
        return (
            centre,
            p,
            np.einsum("ij,ij->i", p, p),
            np.einsum("ij,ij->i", p, self.normals),
            self.areas / (4.0 * np.pi),
        )

    def _direct_winding_number(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """The winding number of query points q (m, 3) summed over every sample.

        Written with matrix products (``|p - q|^2 = |p|^2 + |q|^2 - 2 p . q`` and
        ``(p - q) . n = p . n - q . n``, about the centroid) instead of an (m, n, 3)
        difference array: the refinement's queries of 1-7 points cost a sixth. A query
        point within ``1e-12`` of the cloud's extent of a sample gets no term from it (the
        term is 0 / 0 there).
        """
        centre, p, p2, pn, weight = self._dipoles
        q = q - centre
        r2 = p2[None, :] + np.einsum("ij,ij->i", q, q)[:, None] - 2.0 * (q @ p.T)
        dot = pn[None, :] - q @ self.normals.T
        tiny = (1e-12 * float(np.sqrt(p2.max()))) ** 2
        far = r2 > tiny
        r2 = np.where(far, r2, 1.0)
        return np.asarray(np.where(far, weight * dot / (r2 * np.sqrt(r2)), 0.0).sum(axis=1))

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Point-membership classification (n,) bool: ``winding number > 0.5``.

        Unlike a mesh's ``|winding number|``: the normals are oriented outwards, and the
        magnitude would add specks of inside beside single sheets, whose samples' signs
        are a coin toss (docs/studies.md, "Point clouds").
        """
        return self.winding_number(points) > 0.5

    def _splat(self, p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Closest points (n, 3) on the nearest splats of points p (n, 3), and distances (n,)."""
        k = int(min(SPLAT_NEIGHBOURS, len(self._points)))
        _, idx = self._tree.query(p, k=k)
        idx = np.asarray(idx).reshape(len(p), k)
        s = self._points[idx]  # (n, k, 3)
        n = self.normals[idx]
        v = p[:, None, :] - s
        along = np.einsum("nkj,nkj->nk", v, n)
        lateral = v - along[..., None] * n
        size = np.linalg.norm(lateral, axis=2)
        disc = self._splat_radius[idx]
        over = np.maximum(size - disc, 0.0)
        d = np.sqrt(along * along + over * over)
        best = np.argmin(d, axis=1)
        rows = np.arange(len(p))
        keep = (disc[rows, best] / np.maximum(size[rows, best], 1e-300)).clip(max=1.0)
        q = s[rows, best] + lateral[rows, best] * keep[:, None]
        return q, d[rows, best]

    @cached_property
    def _splat_radius(self) -> NDArray[np.float64]:
        """(n,) float64: radius of each sample's splat, the disc of its area."""
        return np.sqrt(self.areas / np.pi)

    def closest_points(self, points: ArrayLike) -> NDArray[np.float64]:
        """Estimated closest surface points (n, 3) of points (n, 3), model units.

        The closest point on the nearest splat (see the module docstring).
        """
        p = as_points(points)
        if len(p) == 0:
            return np.zeros((0, 3))
        return self._splat(p)[0]

    def transformed(self, rotation: ArrayLike, translation: ArrayLike) -> PointCloud:
        """This cloud moved by ``x -> rotation @ x + translation`` (a rigid motion).

        Given normals move along. Estimated ones do not: their orientation is voted on
        an axis-aligned grid, so the copy estimates its own, and a cloud decomposes
        alike whether or not its normals were asked for first.
        """
        from shapedb.geometry.base import rigid

        R, t = rigid(rotation, translation)
        out = object.__new__(PointCloud)
        out.name, out.k, out.shell = self.name, self.k, self.shell
        out.orient_resolution = self.orient_resolution
        out.distance = self.distance
        out._points = np.ascontiguousarray(self._points @ R.T + t)
        given = self._given_normals
        out._given_normals = None if given is None else np.ascontiguousarray(given @ R.T)
        if "spacing" in self.__dict__:
            out.__dict__["spacing"] = self.spacing
        return out

    def unsigned_distance(
        self, points: ArrayLike, *, distance: str | None = None
    ) -> NDArray[np.float64]:
        """Estimated distance (n,) of points (n, 3) to the surface, model units.

        ``distance`` (default: the cloud's own, :attr:`distance`) picks the estimator:
        ``"splat"`` the nearest splat (see the module docstring); ``"nearest"`` the
        nearest sample; ``"sphere"`` the nearer of the splat and the local sphere
        fitted to the samples around the splat's closest point
        (:func:`shapedb.geometry.surface_fit.sphere_distance`).

        Raises
        ------
        InvalidShapeError
            ``distance`` is not one of :data:`DISTANCES`.
        """
        p = as_points(points)
        if len(p) == 0:
            return np.zeros(0)
        return self._distance(p, self.distance if distance is None else distance)

    def _distance(self, p: NDArray[np.float64], distance: str) -> NDArray[np.float64]:
        """Distances (n,) of points p (n, 3) by the estimator ``distance``."""
        if distance == "nearest":
            return np.asarray(self._tree.query(p)[0], dtype=np.float64)
        if distance not in DISTANCES:
            raise InvalidShapeError(
                f"distance={distance!r} is unknown; choose from {DISTANCES}", source=self.name
            )
        q, d = self._splat(p)
        if distance == "splat":
            return d
        from shapedb.geometry.surface_fit import sphere_distance

        return np.minimum(
            d, sphere_distance(p, q, self._points, self.normals, self.spacing, self._tree)
        )

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distance (n,) of points (n, 3), model units, positive inside."""
        p = as_points(points)
        d = self.unsigned_distance(p)
        return np.where(self.contains(p), d, -d)

    def grid_sdf(self, grid: Grid) -> NDArray[np.float32]:
        """Signed distance at every cell centre, ``grid.shape`` float32, model units."""
        h = grid.spacing
        band = cell_band((self._points - grid.origin) / h, grid.shape, dilate=2)
        if not band.any():
            return super().grid_sdf(grid)
        _, nearest = self._tree.query(grid.to_point(np.argwhere(band)))
        closest = (self._points[nearest] - grid.origin) / h
        dist, owner = propagate_closest(band, closest)
        # the sampled surface may pass up to about half a sample gap closer than the
        # nearest sample: widen the safety margin of the nearest-node inheritance
        margin = 0.5 + 0.5 * float(np.median(self.spacing)) / h
        inside = coarse_to_fine_inside(grid, dist, self.winding_number, near=1.0, margin=margin)
        refine_closest(dist, owner, closest, inside & ~band)
        rho = (self.spacing / h).astype(np.float32)[nearest[owner]]
        dist = _corrected(dist, rho) * np.float32(h)
        # inside, where MDBD puts its balls, the distance to the splats
        cells = np.argwhere(inside)
        dist[inside] = self._distance(grid.to_point(cells), self.distance)
        return np.where(inside, dist, -dist).astype(np.float32, copy=False)
