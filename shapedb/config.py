"""Every tunable parameter of shapedb, in frozen, typed dataclasses.

A :class:`Config` (an :class:`MDBDConfig` plus a :class:`KernelConfig`) is stored
with every record and in every store manifest, so a store always knows how it was
built, and a query computed with another configuration is refused.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, TypeVar

from shapedb.errors import ConfigError

__all__ = ["MDBDConfig", "KernelConfig", "PartConfig", "Config", "with_options", "parse_options"]

_C = TypeVar("_C")


def _check(cond: bool, name: str, value: Any, why: str) -> None:
    if not cond:
        raise ConfigError(f"{name}={value!r} is invalid: {why}")


@dataclass(frozen=True)
class MDBDConfig:
    """Parameters of the decomposition and of its contact graph.

    Attributes
    ----------
    resolution : int
        Grid cells along the longest side of the padded bounding box.
    n_balls : int
        Maximum number of balls (the paper's n).
    min_radius_cells : float
        Stop when the largest remaining ball is smaller than this, in grid cells.
    padding_cells : int
        Empty cells added around the bounding box on every side.
    contact_tol_cells : float
        Two balls are in contact when the gap between them, |ci - cj| - ri - rj,
        is at most this many grid cells. Tied to the grid spacing so that it is
        scale invariant (the paper used an absolute 0.05 on normalised models).
        One cell: a sparse point cloud's packing misses about 15 % of its mesh's
        exact contacts by less than a cell, and a 1-cell tolerance recovers them
        (``bench/contact_tol.py``: every labelled set's cloud-query margin widens
        on both splits against 0.5 cells, the earlier default).
    refine : bool
        Refine every ball off the grid against the representation's own distance
        (sub-cell centre and radius) so that features do not snap to the grid.
    canonical_frame : bool
        Lay the grid along the solid's principal axes of inertia, centred on its
        centroid (from a coarse pass), so that a rigid motion of the model moves the
        grid with it and does not change the decomposition relative to the solid.
        Off: the grid is aligned with the model's axes and bounding box.
    frame_resolution : int
        Cells along the longest side of the coarse grid that estimates the frame.
    tie_cells : float
        Grid values within this many cells of the maximum, and connected to it
        (6-neighbours), count as tied: a ridge or plateau of the distance field
        (see ``tie_rule`` for which of its cells is taken). Separate local maxima are
        never tied. Makes the choice among (near-)equal balls depend on where they
        lie on the solid rather than on sampling noise of the field: along the
        ridge of a cylindrical torso, limb or shaft every cell is within a hair of the
        maximum, and without a tolerance a mesh, its point cloud or its decimated copy
        start their packings at different places. The cell taken is within
        ``tie_cells / 4`` of the maximum on that ridge; a tie spans at most a
        quarter of the current maximum and never reaches below ``min_radius_cells``.
        Default 1.5, chosen on the validation splits (``python -m bench.ties``; 0 is
        the paper's plain argmax; measured with ``tie_rule="first"``): NN / 1-T / DCG
        of jointed figures 0.56 / 0.36 / 0.64 -> 0.74 / 0.52 / 0.75 (cloud queries
        0.48 -> 0.58, mixture 0.60 -> 0.69), CAPOD 0.95 / 0.86 / 0.93 -> 0.95 / 0.88 /
        0.94, machined parts 0.94 / 0.76 / 0.88 -> 0.92 / 0.76 / 0.88. The price: under
        sub-cell grid shifts of a solid known only by its distance function (no exact
        frame) the kernel's median drops from 0.92 to 0.90.
    tie_rule : {"middle", "first"}
        Which tied cell of a ridge the packing takes: "middle" (default) the cell
        nearest the centroid of the whole ridge (the cells within ``tie_cells`` of the
        maximum), which does not depend on the frame's axis signs and puts a limb's,
        shaft's or hole's first ball at its middle; "first" the smallest flat (C-order)
        index, i.e. one end of the ridge along the frame's first axis (the default
        before; stores that do not record a rule were built with it). Test splits
        (``python -m bench.retrieval``, descriptor version 2), first -> middle, meshes
        NN / 1-T / DCG and NN of cloud queries against the mesh database: jointed
        figures 0.887 / 0.616 / 0.858, 0.805 -> 0.954 / 0.768 / 0.934, 0.810; CAPOD
        0.967 / 0.865 / 0.946, 0.900 -> 0.958 / 0.848 / 0.937, 0.900; machined parts
        0.885 / 0.606 / 0.820, 0.833 -> 0.917 / 0.598 / 0.828, 0.781 (validation,
        same order: figures 0.886 / 0.643 / 0.843, 0.657 -> 0.952 / 0.700 / 0.889,
        0.790; CAPOD 0.950 / 0.878 / 0.936, 0.883 -> 0.933 / 0.872 / 0.931, 0.883;
        parts 0.792 / 0.694 / 0.839, 0.812 -> 0.875 / 0.722 / 0.854, 0.812). Part
        matching (``python -m bench.parts``, 80 cells), same-part matches of figures
        (implicit / mesh / cloud / mesh -> cloud) 0.83 / 0.85 / 0.86 / 0.78 -> 0.88 /
        0.89 / 0.84 / 0.85, holes through the complement 0.21 / 0.27 -> 0.36 / 0.32.
        Decimated copies rank their original first more often (``--stability``:
        figures 0.697 -> 0.879, CAPOD 0.586 -> 0.621, parts 1.0). A ridge whose
        centroid falls between two cells (a symmetric box) is decided by rounding:
        at coarse grids a box's mesh and implicit versions differ more (descriptor
        distance of a 2.2 x 1.1 x 1.1 box, first -> middle: 0.09 -> 0.55 at 32
        cells, 0.09 -> 0.36 at 64, 0.12 -> 0.12 at 128). Starting the off-grid
        refinement at the centroid itself measured the same on validation
        (objective of ``bench/select_descriptors.py`` 1.066 either way) and did not
        bring them closer.
    sheet_cells : float
        Triangle meshes in which no ball fits (sheets, flat or thinner than the grid
        models), and open meshes made largely of sheets, are decomposed dilated by
        this many grid cells (:mod:`shapedb.sheet`); 0 turns it off (such models then
        fail). Closed meshes in which a ball fits are never dilated.
    """

    resolution: int = 128
    n_balls: int = 512
    min_radius_cells: float = 0.5
    padding_cells: int = 2
    contact_tol_cells: float = 1.0
    refine: bool = True
    canonical_frame: bool = True
    frame_resolution: int = 48
    tie_cells: float = 1.5
    tie_rule: str = "middle"
    sheet_cells: float = 1.0

    def __post_init__(self) -> None:
        _check(
            isinstance(self.resolution, int) and 8 <= self.resolution <= 1024,
            "resolution",
            self.resolution,
            "must be an integer in [8, 1024]",
        )
        _check(
            isinstance(self.n_balls, int) and 1 <= self.n_balls <= 100_000,
            "n_balls",
            self.n_balls,
            "must be an integer in [1, 100000]",
        )
        _check(
            0.0 <= self.min_radius_cells <= 64,
            "min_radius_cells",
            self.min_radius_cells,
            "must be in [0, 64]",
        )
        _check(
            isinstance(self.padding_cells, int) and 1 <= self.padding_cells <= 32,
            "padding_cells",
            self.padding_cells,
            "must be an integer in [1, 32]",
        )
        _check(
            0.0 <= self.contact_tol_cells <= 8,
            "contact_tol_cells",
            self.contact_tol_cells,
            "must be in [0, 8]",
        )
        _check(
            isinstance(self.frame_resolution, int) and 16 <= self.frame_resolution <= 256,
            "frame_resolution",
            self.frame_resolution,
            "must be an integer in [16, 256]",
        )
        _check(0.0 <= self.tie_cells <= 4, "tie_cells", self.tie_cells, "must be in [0, 4]")
        _check(0.0 <= self.sheet_cells <= 8, "sheet_cells", self.sheet_cells, "must be in [0, 8]")
        _check(
            self.tie_rule in ("first", "middle"),
            "tie_rule",
            self.tie_rule,
            "must be 'middle' or 'first'",
        )


@dataclass(frozen=True)
class KernelConfig:
    """Parameters of the paper's Eq. 1-3 random-walk graph kernel.

    Attributes
    ----------
    n_r : int
        Representative nodes: the n_r largest balls.
    t : int
        Random-walk steps.
    w : float
        Decay of the walk average, P_i = (1/t) sum_k w^k p_i^k.
    la, lb : float
        Geometric weights of Eq. 2 on the initial attributes and on the walk averages.
    lam : float
        Scale of Eq. 3, k = exp(-lam * d).
    method : {"mdbd", "paper"}
        The feature vector: "mdbd" (default) is shapedb's descriptor over the whole
        decomposition (:mod:`shapedb.descriptor`, calibrated so that unrelated shapes
        score about 0.1); "paper" is the paper's Eq. 1 vector with Eq. 2 weights,
        parameterised by ``n_r, t, w, la, lb``. Both are compared with a weighted L1
        distance and turned into a similarity by Eq. 3.
    descriptor : int
        Version of the "mdbd" descriptor's blocks and weights (see
        :mod:`shapedb.descriptor`; 4 is the default, 3 and 2 the ones before it, 1
        the first selection). Stored with every record, so that a store never mixes versions;
        ignored by "paper".
    view_cells : float
        0 (default) stores one feature per shape. A positive value also stores, for
        every shape that is not itself a sparse point cloud, the feature of a *sparse
        view*: a point cloud drawn uniformly on its surface, one sample per
        ``view_cells`` grid cells of spacing (:mod:`shapedb.view`). Sparse point-cloud queries and
        records are then also compared with views, which removes most of the
        systematic difference between a sparse cloud's decomposition and its mesh's
        (issue 6); ingest then costs a point-cloud decomposition more per mesh (about
        three times the time).
    reconstruct : bool
        True (default): every sparse point cloud, stored or queried, also has the
        feature of its screened Poisson reconstruction (:mod:`shapedb.reconstruct`),
        compared with dense shapes' own features; it about doubles a sparse cloud's
        ingest and query time (dense shapes pay nothing). A stored configuration
        without this field predates reconstructions and is read as False.
    reconstruct_depth : int
        Octree depth of the reconstructions' Poisson solve (2^depth cells along the
        cloud's box at the finest level; default 8; ``python -m bench.cloud_pairs``
        measures 6 and 7). A stored configuration without this field read as 8.
    """

    n_r: int = 32
    t: int = 10
    w: float = 0.9
    la: float = 0.75
    lb: float = 0.75
    lam: float = 1.0
    method: str = "mdbd"
    descriptor: int = 4
    view_cells: float = 0.0
    reconstruct: bool = True
    reconstruct_depth: int = 8

    def __post_init__(self) -> None:
        _check(
            self.method in ("mdbd", "paper"),
            "method",
            self.method,
            "must be 'mdbd' (shapedb's descriptor) or 'paper' (Eq. 1-3)",
        )
        _check(
            isinstance(self.n_r, int) and 1 <= self.n_r <= 4096,
            "n_r",
            self.n_r,
            "must be an integer in [1, 4096]",
        )
        _check(
            isinstance(self.t, int) and 1 <= self.t <= 1000,
            "t",
            self.t,
            "must be an integer in [1, 1000]",
        )
        _check(0.0 < self.w <= 1.0, "w", self.w, "must be in (0, 1]")
        _check(0.0 < self.la <= 1.0, "la", self.la, "must be in (0, 1]")
        _check(0.0 < self.lb <= 1.0, "lb", self.lb, "must be in (0, 1]")
        _check(self.lam > 0.0, "lam", self.lam, "must be > 0")
        _check(
            self.descriptor in (1, 2, 3, 4, 5),
            "descriptor",
            self.descriptor,
            "must be 1, 2, 3, 4 or 5 (see shapedb.descriptor)",
        )
        _check(
            isinstance(self.view_cells, (int, float))
            and not isinstance(self.view_cells, bool)
            and (self.view_cells == 0.0 or 2.0 <= self.view_cells <= 16.0),
            "view_cells",
            self.view_cells,
            "must be 0 (no sparse views) or in [2, 16] grid cells",
        )
        _check(
            isinstance(self.reconstruct, bool), "reconstruct", self.reconstruct, "must be a bool"
        )
        _check(
            isinstance(self.reconstruct_depth, int)
            and not isinstance(self.reconstruct_depth, bool)
            and 4 <= self.reconstruct_depth <= 12,
            "reconstruct_depth",
            self.reconstruct_depth,
            "must be an integer in [4, 12]",
        )

    @property
    def dim(self) -> int:
        """Length of the feature vector: 2 * n_r for "paper", the descriptor's for "mdbd"."""
        if self.method == "mdbd":
            from shapedb.descriptor import dim

            return dim(self.descriptor)
        return 2 * self.n_r


@dataclass(frozen=True)
class PartConfig:
    """Parameters of substructure matching (paper, section 3.3: K = 2, n_r = 10).

    A part is the neighbourhood subgraph G[N(v, K)] of a node v; it is compared with
    the Eq. 1-3 kernel computed on that subgraph alone (its own largest ball, its own
    random walk).

    Attributes
    ----------
    hops : int
        Neighbourhood range K: nodes within ``hops`` contact edges of v.
    n_r : int
        Representative nodes of a part: its n_r largest balls.
    t, w, la, lb, lam
        As in :class:`KernelConfig`.
    size : float
        Weight of the *size block* appended to the paper's Eq. 1 vector: ``r_i / R``
        of the part's n_r largest balls, ``R`` the largest ball of the whole shape
        (the paper's node attribute r/r1 with the shape's r1), weighted
        ``size * la^i``. Eq. 1 on a subgraph alone normalises by the subgraph's own
        largest ball, so every lone ball (one-node neighbourhood) has the same Eq. 1
        vector; the size block tells them apart by their size relative to the shape.
        0 with ``centre = 0`` gives the paper's vector alone (length 2 n_r), which is
        how part indexes stored before these fields are read.
    centre : float
        Weight of the *centre block*: ``[r_v / r1, r_v / R]`` of the centre node v of
        N(v, K) (r1 the part's largest ball); 0 leaves it out.
    contact_tol_cells : float
        Balls closer than this many grid cells are neighbours in a part's graph:
        part matching rebuilds the contacts from the balls
        (:func:`shapedb.subgraph.part_graph`); 0 takes the decomposition's own
        contact graph (``MDBDConfig.contact_tol_cells``). Half a cell, while
        retrieval uses 1: on the validation subset of ``bench.parts`` the default
        part setting scores 0.607 on 0.5-cell contacts against 0.572 on 1-cell ones
        (holes in a plate's complement touch the space around the plate less often).

    The defaults (K = 2, n_r = 10 as in the paper; size = 4, centre = 8) were chosen
    on a validation subset of ``bench.parts`` (figure subjects 2-3, poses 8-15;
    plates 8-15), never on the reported one. With today's 0.5-cell part graphs
    centre = 4 scores 0.619 there against 0.607 (on 1-cell graphs 0.584 against
    0.572, when it matched the reported figure parts 0.86-0.89 of the time against
    0.90-0.92), within the sweep's noise, so the default stays.
    """

    hops: int = 2
    n_r: int = 10
    t: int = 10
    w: float = 0.9
    la: float = 0.75
    lb: float = 0.75
    lam: float = 1.0
    size: float = 4.0
    centre: float = 8.0
    contact_tol_cells: float = 0.5

    def __post_init__(self) -> None:
        _check(
            isinstance(self.hops, int) and 0 <= self.hops <= 64,
            "hops",
            self.hops,
            "must be an integer in [0, 64]",
        )
        self.kernel  # validates the kernel fields  # noqa: B018
        _check(0.0 <= self.size <= 100.0, "size", self.size, "must be in [0, 100]")
        _check(0.0 <= self.centre <= 100.0, "centre", self.centre, "must be in [0, 100]")
        _check(
            0.0 <= self.contact_tol_cells <= 8.0,
            "contact_tol_cells",
            self.contact_tol_cells,
            "must be in [0, 8] grid cells (0: the decomposition's own contact graph)",
        )

    @property
    def kernel(self) -> KernelConfig:
        """The :class:`KernelConfig` of a part's Eq. 1-3 kernel."""
        return KernelConfig(
            n_r=self.n_r, t=self.t, w=self.w, la=self.la, lb=self.lb, lam=self.lam, method="paper"
        )

    @property
    def dim(self) -> int:
        """Length of a part's feature vector, 2 * n_r."""
        return 2 * self.n_r

    @property
    def fingerprint(self) -> str:
        """Short hash of every field (names a part index built with this config)."""
        text = json.dumps(asdict(self), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass(frozen=True)
class Config:
    """Everything that determines a store's records: decomposition plus kernel."""

    mdbd: MDBDConfig = field(default_factory=MDBDConfig)
    kernel: KernelConfig = field(default_factory=KernelConfig)

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable nested dict."""
        return {"mdbd": asdict(self.mdbd), "kernel": asdict(self.kernel)}

    def to_json(self) -> str:
        """Canonical JSON (sorted keys), as stored in the store."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Config:
        """Inverse of :meth:`to_dict`; unknown keys are refused.

        A stored kernel configuration without ``method`` predates the default
        descriptor and is read as ``method="paper"``, which is what built it; one
        without ``descriptor`` predates descriptor versions and is read as version 1,
        and a stored MDBD configuration without ``tie_rule`` as ``tie_rule="first"``;
        one without ``reconstruct`` predates reconstructions and is read as False,
        one without ``reconstruct_depth`` as depth 8 (the depth before it was stored).
        """
        kernel = dict(data.get("kernel", {}))
        if kernel:
            kernel.setdefault("method", "paper")
            kernel.setdefault("descriptor", 1)
            kernel.setdefault("reconstruct", False)
            kernel.setdefault("reconstruct_depth", 8)
        mdbd = dict(data.get("mdbd", {}))
        if mdbd:
            mdbd.setdefault("tie_rule", "first")
        try:
            return cls(
                mdbd=_build(MDBDConfig, mdbd),
                kernel=_build(KernelConfig, kernel),
            )
        except TypeError as exc:
            raise ConfigError(f"cannot read configuration {data!r}: {exc}") from exc

    @classmethod
    def from_json(cls, text: str) -> Config:
        """Inverse of :meth:`to_json`."""
        return cls.from_dict(json.loads(text))

    @property
    def fingerprint(self) -> str:
        """Short hash of the decomposition parameters (what changes the graphs)."""
        text = json.dumps(asdict(self.mdbd), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def with_options(self, **options: Any) -> Config:
        """A copy with some fields changed; each name must belong to one sub-config.

        >>> Config().with_options(resolution=64, n_r=10).mdbd.resolution
        64
        """
        mdbd_names = {f.name for f in fields(MDBDConfig)}
        kernel_names = {f.name for f in fields(KernelConfig)}
        unknown = set(options) - mdbd_names - kernel_names
        if unknown:
            raise ConfigError(f"unknown configuration option(s): {sorted(unknown)}")
        mdbd = replace(self.mdbd, **{k: v for k, v in options.items() if k in mdbd_names})
        kernel = replace(self.kernel, **{k: v for k, v in options.items() if k in kernel_names})
        return Config(mdbd=mdbd, kernel=kernel)


def parse_options(pairs: Sequence[str]) -> dict[str, Any]:
    """Options from ``KEY=VALUE`` strings (the command line's ``--set``), typed by field.

    Each key must be a field of :class:`MDBDConfig` or :class:`KernelConfig`; its value
    is read as that field's type (``true``/``false`` for booleans).

    >>> parse_options(["tie_cells=0", "descriptor=1"])
    {'tie_cells': 0.0, 'descriptor': 1}
    """
    kinds = {"int": int, "float": float, "bool": bool, "str": str}
    types = {f.name: kinds[str(f.type)] for cls in (MDBDConfig, KernelConfig) for f in fields(cls)}
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key, text = key.strip(), text.strip()
        if not sep or not key:
            raise ConfigError(f"option {pair!r} is not KEY=VALUE")
        if key not in types:
            raise ConfigError(f"unknown configuration option {key!r}; known: {sorted(types)}")
        kind = types[key]
        try:
            if kind is bool:
                if text.lower() not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError(text)
                out[key] = text.lower() in ("true", "1", "yes")
            else:
                out[key] = kind(text)
        except ValueError:
            raise ConfigError(f"option {key}={text!r}: expected {kind.__name__}") from None
    return out


def _build(cls: type, data: dict[str, Any]) -> Any:
    known = {f.name for f in fields(cls)}
    unknown = set(data) - known
    if unknown:
        raise ConfigError(f"unknown {cls.__name__} option(s): {sorted(unknown)}")
    return cls(**data)


def with_options(
    cls: type[_C], config: _C | None, options: dict[str, Any], *, what: str | None = None
) -> _C:
    """``config`` (or the default ``cls()``) with some fields overridden by ``options``.

    Raises
    ------
    ConfigError
        When ``config`` is not a ``cls``, an option is not a field of ``cls``, or a value
        is out of range.
    """
    cfg = config if config is not None else cls()
    if not isinstance(cfg, cls):
        raise ConfigError(f"config must be a {cls.__name__}, got {type(cfg).__name__}")
    if not options:
        return cfg
    unknown = set(options) - {f.name for f in fields(cls)}  # type: ignore[arg-type]
    if unknown:
        raise ConfigError(f"unknown {what or cls.__name__} option(s): {sorted(unknown)}")
    return replace(cfg, **options)  # type: ignore[type-var]
