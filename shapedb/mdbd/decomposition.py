"""Maximal Disjoint Ball Decomposition (MDBD) of a solid given by a :class:`Geometry`.

The paper's construction (section 2.1): compute the signed distance field ``D`` of
the solid once, on a grid; then repeatedly take the grid maximum ``c = argmax D``,
``r = D(c)``, record the ball ``(c, r)`` and remove it from the solid, which on the
field is ``D(p) <- min(D(p), |p - c| - r)``. Stop after ``n_balls`` balls or when
the largest remaining ball is smaller than ``min_radius_cells`` cells.

Three things make it fast and accurate:

* **Block maxima** (:mod:`shapedb.mdbd.packing`, the greedy loop :func:`pack_balls`): the
  argmax and the carving touch only the blocks of cells a ball can change, compiled
  with numba, and agree with the plain-numpy reference :func:`_decompose_naive`.
* **Off-grid refinement** (``MDBDConfig.refine``, :mod:`shapedb.mdbd.refine`). Each
  ball is moved off its grid cell, within one cell, to where it can grow largest
  against the representation's own distance; its radius is exact, so balls are
  inside the solid and pairwise disjoint according to that distance.
* **Canonical frame** (``MDBDConfig.canonical_frame``, :mod:`shapedb.mdbd.frame`). The
  solid's centroid and principal axes: exact moments of a mesh's triangles or a
  cloud's points, the child's frame for a moved copy, else two coarse passes. The
  fine grid is laid in that frame, with ``resolution`` cells along the longest
  principal extent, and the geometry is queried in it (meshes are rebuilt on
  their local vertices in units of that extent, see :func:`_local_copy`). A
  similarity transform of a mesh or a cloud therefore gives the same
  decomposition up to rounding (the greedy packing is chaotic: a frame off by
  0.001 degree already changes its tail). Centres are returned in model
  coordinates and the frame in :attr:`Decomposition.frame`. Where the moments do
  not determine the frame (isotropic or rotationally symmetric solids), ties
  between equally good balls are still broken by the grid, and a generic rotation
  of such a solid can change the decomposition (not its leading radii).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from shapedb.config.core import MDBDConfig, with_options
from shapedb.errors import ConfigError, DegenerateGeometryError, InvalidShapeError
from shapedb.geometry.base import Geometry, Grid
from shapedb.geometry.sheet import LocallyThickened, Thickened, needs_thickening, sheet_region
from shapedb.mdbd.frame import canonical_frame, frame_grid
from shapedb.mdbd.packing import pack_balls

if TYPE_CHECKING:
    from shapedb.geometry.inside import Inside
    from shapedb.mdbd.graph import ContactGraph

__all__ = ["Decomposition", "PreparedField", "decompose", "pack_balls", "prepare_field"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Decomposition:
    """A truncated MDBD: balls sorted by decreasing radius, and their contacts.

    Attributes
    ----------
    centers : (n, 3) float64
        Ball centres, model units.
    radii : (n,) float64
        Ball radii, non-increasing, model units.
    edges : (m, 2) int32
        Contact-graph edges (i < j), rows sorted lexicographically.
    spacing : float
        Grid cell size used to compute the decomposition, model units.
    bounds : (2, 3) float64
        Bounding box of the source geometry.
    config : MDBDConfig
        Parameters it was computed with.
    representation : str
        Representation of the source ("mesh", "pointcloud", "voxels", "implicit", "brep").
    sampling : float
        Typical spacing of the samples the source's boundary was known from, model
        units (:attr:`shapedb.geometry.base.Geometry.surface_sampling`); 0.0 for exact
        boundaries.
    timings : dict[str, float]
        Seconds per stage: "frame" (coarse pass), "sdf", "decompose" (the loop,
        refinement included), "refine" (its share), "graph"; "inside" with
        ``keep_inside``.
    frame : (4, 4) float64
        Homogeneous map from the grid's frame to model coordinates (rotation whose
        columns are the principal axes, and the centroid); identity without the
        canonical frame.
    tail_centers : (t, 3) float64
        Balls the packing found after its ``n_balls`` (``decompose(tail_balls=...)``),
        model units, sorted by decreasing radius; (0, 3) without a tail. They are not
        part of the decomposition (no contact edges, no feature): only the light
        fields of a longer packing read them.
    tail_radii : (t,) float64
        Their radii, non-increasing, model units.
    inside : Inside or None
        The inside of the field the balls were packed in (its shell of cells, model
        units; :mod:`shapedb.geometry.inside`) with ``decompose(keep_inside=True)``, else None.
        In memory only, like the tail: only the light fields of the field
        (``LightFieldConfig.source="field"``) read it.
    """

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    edges: NDArray[np.int32]
    spacing: float
    bounds: NDArray[np.float64]
    config: MDBDConfig = field(default_factory=MDBDConfig)
    representation: str = "unknown"
    sampling: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    frame: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    tail_centers: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    tail_radii: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    inside: Inside | None = None

    @property
    def n_balls(self) -> int:
        """Number of balls n."""
        return int(len(self.radii))

    def longer_packing(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The balls followed by the tail: ((n + t, 3) centres, (n + t,) radii), model units."""
        if len(self.tail_radii) == 0:
            return self.centers, self.radii
        return (
            np.vstack([self.centers, self.tail_centers]),
            np.concatenate([self.radii, self.tail_radii]),
        )

    @cached_property
    def graph(self) -> ContactGraph:
        """The contact graph of the balls."""
        from shapedb.mdbd.graph import ContactGraph

        return ContactGraph(self.centers, self.radii, self.edges)


# -- compiled block-max field ----------------------------------------------------------
def _resolve_config(config: MDBDConfig | None, options: dict[str, Any]) -> MDBDConfig:
    return with_options(MDBDConfig, config, options, what="MDBD")


@dataclass(frozen=True)
class PreparedField:
    """What :func:`prepare_field` returns: the geometry in the grid's frame, the grid and its field."""

    local: Geometry  # the geometry in the grid's frame, in units of ``scale``
    grid: Grid
    F: NDArray[np.float32]
    frame: NDArray[np.float64]  # (4, 4) local -> model (rotation and centroid)
    timings: dict[str, float]
    scale: float = 1.0  # model units per local unit


def _local_copy(
    geometry: Geometry, V: NDArray[np.float64], c: NDArray[np.float64], extent: float
) -> tuple[Geometry, float]:
    """The geometry in the frame (rotation ``V`` (3, 3), centroid ``c`` (3,)), and its unit.

    A mesh is rebuilt on its vertices in the local frame, divided by its principal
    ``extent`` (model units), rather than moved: its query structures (open3d's
    scene) work in float32, so a moved copy would query the model's own float32
    coordinates, whose rounding depends on the model's pose and size and is enough
    (~1e-7 relative) to flip ties of the greedy packing. Rebuilt, a model and its
    rotated, moved or scaled copy query the same local coordinates (to float64
    rounding). It costs nothing extra when the model itself is never queried.
    Other representations are moved (:meth:`Geometry.transformed`), unit 1.
    """
    from shapedb.geometry.mesh import TriangleMesh

    if isinstance(geometry, TriangleMesh) and extent > 0:
        v = np.asarray(geometry.vertices, dtype=np.float64)
        local = TriangleMesh((v - c) @ V / extent, np.asarray(geometry.faces), name=geometry.name)
        return local, extent
    return geometry.transformed(V.T, -V.T @ c), 1.0


def prepare_field(geometry: Geometry, cfg: MDBDConfig) -> PreparedField:
    """The stages before the packing: canonical frame, local copy, grid and its SDF.

    :func:`decompose` is ``prepare_field`` then :func:`pack_balls` on its field;
    the two are public so that a profiler can time them apart (``bench/mdbd.py``).

    Raises
    ------
    InvalidShapeError
        ``geometry`` is not a :class:`shapedb.geometry.base.Geometry`.
    """
    if not isinstance(geometry, Geometry):
        raise InvalidShapeError(
            f"decompose needs a shapedb Geometry, got {type(geometry).__name__}"
        )
    timings: dict[str, float] = {}
    frame = np.eye(4)
    local = geometry
    scale = 1.0
    found = None
    if cfg.canonical_frame:
        t0 = time.perf_counter()
        found = canonical_frame(geometry, cfg)
        timings["frame"] = time.perf_counter() - t0
    if found is not None:
        V, c, lo, hi, hc = found
        frame[:3, :3], frame[:3, 3] = V, c
        t0 = time.perf_counter()
        local, scale = _local_copy(geometry, V, c, float((hi - lo).max()))
        grid = frame_grid(lo / scale, hi / scale, 0.5 * hc / scale, cfg)
        timings["frame"] += time.perf_counter() - t0
    else:
        grid = Grid.fit(geometry.bounds, resolution=cfg.resolution, padding=cfg.padding_cells)
    from shapedb.geometry.mesh import TriangleMesh

    t0 = time.perf_counter()
    thickness = cfg.sheet_cells * grid.spacing
    enclosing = cfg.sheet_rule == "enclosed" and cfg.sheet_cells > 0
    if enclosing and isinstance(local, TriangleMesh) and not local.closed:
        local, F = local.enclosed_solid(grid, thickness)
        timings["sdf"] = time.perf_counter() - t0
        return PreparedField(local, grid, F, frame, timings, scale)
    F = np.ascontiguousarray(local.grid_sdf(grid), dtype=np.float32)
    if F.shape != grid.shape:
        raise InvalidShapeError(
            f"grid_sdf returned shape {F.shape}, expected {grid.shape}", source=repr(geometry)
        )
    if cfg.sheet_cells > 0 and needs_thickening(
        local, F, grid.spacing, cfg.min_radius_cells * grid.spacing
    ):
        local = Thickened(local, thickness)
        F += np.float32(thickness)
    elif cfg.sheet_cells > 0 and cfg.sheet_rule in ("local", "enclosed"):
        region = sheet_region(local, F, grid.spacing, thickness)
        if region is not None:
            local = LocallyThickened(local, thickness, grid, region)
            F += np.float32(thickness) * region
    timings["sdf"] = time.perf_counter() - t0
    return PreparedField(local, grid, F, frame, timings, scale)


def _finish(
    geometry: Geometry,
    prep: PreparedField,
    cfg: MDBDConfig,
    centers: NDArray[np.float64],
    radii: NDArray[np.float64],
    timings: dict[str, float],
    tail: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    inside: Inside | None = None,
) -> Decomposition:
    from shapedb.mdbd.graph import contact_edges

    grid = prep.grid
    if len(radii) == 0:
        raise DegenerateGeometryError(
            f"no ball of radius >= {cfg.min_radius_cells} cell(s) fits inside the solid at "
            f"resolution {cfg.resolution} (cell {prep.scale * grid.spacing:.4g}); the solid is thinner "
            "than the grid: increase resolution",
            source=repr(geometry),
        )

    def to_model(
        c: NDArray[np.float64], r: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        order = np.argsort(-r, kind="stable")
        c, r = prep.scale * c[order], prep.scale * r[order]
        return c @ prep.frame[:3, :3].T + prep.frame[:3, 3], r  # back to model coordinates

    centers, radii = to_model(centers, radii)
    tail_centers, tail_radii = (
        to_model(*tail) if tail is not None else (np.zeros((0, 3)), np.zeros(0))
    )
    spacing = prep.scale * grid.spacing
    t0 = time.perf_counter()
    edges = contact_edges(centers, radii, cfg.contact_tol_cells * spacing)
    timings["graph"] = time.perf_counter() - t0
    return Decomposition(
        centers=centers,
        radii=radii,
        edges=edges,
        spacing=float(spacing),
        bounds=np.asarray(geometry.bounds, dtype=np.float64).copy(),
        config=cfg,
        representation=str(getattr(geometry, "representation", "unknown")),
        sampling=float(getattr(geometry, "surface_sampling", 0.0)),
        timings=timings,
        frame=prep.frame,
        tail_centers=tail_centers,
        tail_radii=tail_radii,
        inside=inside,
    )


def _run(
    geometry: Geometry, cfg: MDBDConfig, *, naive: bool, tail: int = 0, keep_inside: bool = False
) -> Decomposition:
    prep = prepare_field(geometry, cfg)
    inside = None
    if keep_inside:  # before the packing carves the field
        from shapedb.geometry.inside import field_inside

        t0 = time.perf_counter()
        inside = field_inside(prep.F, prep.grid, prep.frame, prep.scale)
        prep.timings["inside"] = time.perf_counter() - t0
    stats: dict[str, float] = {}
    t0 = time.perf_counter()
    centers, radii = pack_balls(
        prep.local, prep.grid, prep.F, cfg, naive=naive, stats=stats, tail=tail
    )
    timings = dict(prep.timings)
    timings["decompose"] = time.perf_counter() - t0
    timings["refine"] = stats["refine"]
    main = int(stats["main"])
    rest = (centers[main:], radii[main:]) if tail > 0 else None
    return _finish(geometry, prep, cfg, centers[:main], radii[:main], timings, rest, inside)


def decompose(
    geometry: Geometry,
    *,
    config: MDBDConfig | None = None,
    tail_balls: int = 0,
    keep_inside: bool = False,
    **options: Any,
) -> Decomposition:
    """Truncated MDBD of ``geometry``, with its contact graph.

    Parameters
    ----------
    geometry : Geometry
        Any representation (mesh, point cloud, voxels, implicit...).
    config : MDBDConfig, optional
        Parameters; defaults to ``MDBDConfig()``.
    tail_balls : int, optional
        Continue the greedy packing past ``n_balls`` for at most this many balls,
        without off-grid refinement, kept apart in ``tail_centers`` / ``tail_radii``
        (the light fields of a longer packing, ``LightFieldConfig.n_balls``). The
        decomposition's own balls are those of ``tail_balls=0``. Default 0.
    keep_inside : bool, optional
        Keep the inside of the field the balls are packed in
        (:attr:`Decomposition.inside`, the light fields of ``source="field"``); it
        changes nothing else. Default False.
    **options
        Overrides of ``config`` fields, e.g. ``resolution=64, n_balls=256``.

    Returns
    -------
    Decomposition
        Balls sorted by decreasing radius (centres in model coordinates); ``edges``
        index that order.

    Raises
    ------
    ConfigError
        For unknown or out-of-range options.
    DegenerateGeometryError
        When no ball of the minimum radius fits inside the solid.
    """
    cfg = _resolve_config(config, options)
    if isinstance(tail_balls, bool) or not isinstance(tail_balls, int) or tail_balls < 0:
        raise ConfigError(f"tail_balls={tail_balls!r}: must be an integer >= 0")
    if not isinstance(keep_inside, bool):
        raise ConfigError(f"keep_inside={keep_inside!r}: must be true or false")
    out = _run(geometry, cfg, naive=False, tail=tail_balls, keep_inside=keep_inside)
    logger.debug("decomposed %r: %d balls, timings %s", geometry, out.n_balls, out.timings)
    return out


def _decompose_naive(
    geometry: Geometry, *, config: MDBDConfig | None = None, **options: Any
) -> Decomposition:
    """Reference implementation: full-grid argmax and full-grid update, plain numpy.

    Same results as :func:`decompose` (same frame, tie-breaking and refinement);
    used by the tests and as the baseline of ``bench/mdbd.py``.
    """
    return _run(geometry, _resolve_config(config, options), naive=True)
