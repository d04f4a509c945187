"""Every tunable parameter of shapedb, in frozen, typed dataclasses, one per concern.

A :class:`Config` composes the settings that determine a store's records:

* :class:`MDBDConfig`: the decomposition and its contact graph;
* :class:`KernelConfig`: the paper's Eq. 1-3 random-walk kernel and the feature method;
* :class:`DescriptorConfig`: the version of shapedb's own descriptor (method "mdbd");
* :class:`CloudConfig`: what a store keeps for sparse point clouds (views, reconstructions);
* :class:`RerankConfig` (module :mod:`shapedb.config.rerank`): whether a search re-ranks
  the candidates of the index (the stage's numbers are not options:
  :mod:`query.search.tuning`);
* :class:`LightFieldConfig` (module :mod:`shapedb.config.lightfield`): the light fields
  stored per record;
* :class:`FieldVectorConfig` (module :mod:`shapedb.config.field_vector`): the field vector
  (depth buffers and spherical harmonics of the field's inside) stored per record;
* :class:`SurfaceWordsConfig` (module :mod:`shapedb.config.surface_words`): the surface
  words (local surface features over a fixed codebook) stored per record.

:class:`shapedb.config.part.PartConfig` (substructure matching) embeds a :class:`KernelConfig`
of its own.

A :class:`Config` is stored with every record and in every store manifest, so a store
always knows how it was built, and a query computed with another configuration is
refused. Configurations written by older versions of shapedb (other layouts, fewer
fields) are read through :mod:`shapedb.config.migrations`, the only module that knows them.

On the command line and in :func:`shapedb.connect` every setting is one flat option
(:data:`OPTIONS`): the field's name, except ``descriptor`` for
``DescriptorConfig.version``, ``rerank`` for :class:`RerankConfig`,
``lf_<field>`` for the light field section and ``fv_<field>`` for
:class:`FieldVectorConfig` (:class:`SurfaceWordsConfig` has none: a new store keeps the
words, an older one reads without them).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, TypeVar

from shapedb.config import migrations
from shapedb.config.checks import build_section, check, is_int
from shapedb.config.field_vector import FieldVectorConfig, product_field_vector
from shapedb.config.lightfield import LightFieldConfig, product_light_field
from shapedb.config.rerank import RerankConfig
from shapedb.config.surface_words import SurfaceWordsConfig, product_surface_words
from shapedb.errors import ConfigError

__all__ = [
    "MDBDConfig",
    "KernelConfig",
    "DescriptorConfig",
    "CloudConfig",
    "LightFieldConfig",
    "FieldVectorConfig",
    "SurfaceWordsConfig",
    "RerankConfig",
    "Config",
    "OPTIONS",
    "with_options",
    "parse_options",
]

_C = TypeVar("_C")


_check = check
_is_int = is_int


@dataclass(frozen=True)
class MDBDConfig:
    """Parameters of the decomposition and of its contact graph.

    Attributes
    ----------
    resolution : int
        Grid cells along the longest side of the padded bounding box, in [8, 1024].
    n_balls : int
        Maximum number of balls (the paper's n), in [1, 100000].
    min_radius_cells : float
        Stop when the largest remaining ball is smaller than this, in grid cells.
    padding_cells : int
        Empty cells added around the bounding box on every side.
    contact_tol_cells : float
        Two balls are in contact when the gap between them, |ci - cj| - ri - rj,
        is at most this many grid cells (tied to the grid spacing so that it is scale
        invariant; the paper used an absolute 0.05 on normalised models).
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
        (6-neighbours), count as tied: a ridge or plateau of the distance field (see
        ``tie_rule`` for which of its cells is taken). Separate local maxima are never
        tied. The cell taken is within ``tie_cells / 4`` of the maximum on that ridge;
        a tie spans at most a quarter of the current maximum and never reaches below
        ``min_radius_cells``. 0 is the paper's plain argmax. In [0, 4].
    tie_rule : {"middle", "first"}
        Which tied cell of a ridge the packing takes: "middle" the cell nearest the
        centroid of the whole ridge (independent of the frame's axis signs; a limb's,
        shaft's or hole's first ball lies at its middle; a ridge whose centroid falls
        between two cells is decided by rounding); "first" the smallest flat (C-order)
        index, i.e. one end of the ridge along the frame's first axis.
    sheet_cells : float
        Triangle meshes in which no ball fits (sheets, flat or thinner than the grid
        models), and open meshes made largely of sheets, are decomposed dilated by
        this many grid cells (:mod:`shapedb.geometry.sheet`); 0 turns it off (such models then
        fail). Closed meshes in which a ball fits are never dilated whole.
    sheet_rule : {"enclosed", "local", "whole"}
        ``"enclosed"`` (the default): the solid of a triangle mesh that is not closed
        (some edge not used twice in opposite directions once cleaned and oriented:
        open walls, single-sided sheets, soups) is what a flood from outside the grid
        cannot reach plus every point within ``sheet_cells`` of its surface
        (:mod:`shapedb.geometry.enclosed`), whatever its faces' orientation; a closed
        mesh, whose inside the winding number gives exactly, and every other
        representation follow ``"local"``. ``"local"`` (stores written before the
        enclosed solid): a triangle mesh not dilated whole whose sheet cells (surface
        cells with no inside nearby: sheets and parts thinner than the grid) are at
        least 1 % of its surface cells is dilated by ``sheet_cells`` near them only
        (:func:`shapedb.geometry.sheet.sheet_region`), so the wings of an airplane with
        a closed fuselage get a solid. ``"whole"``: only the whole-model rule (stores
        written before the field, whose sheets in such models had no inside).
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
    sheet_rule: str = "enclosed"

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
            self.sheet_rule in ("enclosed", "local", "whole"),
            "sheet_rule",
            self.sheet_rule,
            "must be 'enclosed', 'local' or 'whole'",
        )
        _check(
            self.tie_rule in ("first", "middle"),
            "tie_rule",
            self.tie_rule,
            "must be 'middle' or 'first'",
        )


@dataclass(frozen=True)
class KernelConfig:
    """The paper's Eq. 1-3 random-walk graph kernel, and which feature vector to compare.

    Attributes
    ----------
    n_r : int
        Representative nodes: the n_r largest balls, in [1, 4096].
    t : int
        Random-walk steps, in [1, 1000].
    w : float
        Decay of the walk average, P_i = (1/t) sum_k w^k p_i^k, in (0, 1].
    la, lb : float
        Geometric weights of Eq. 2 on the initial attributes and on the walk
        averages, in (0, 1].
    lam : float
        Scale of Eq. 3, k = exp(-lam * d), > 0.
    method : {"mdbd", "paper"}
        The feature vector: "mdbd" is shapedb's descriptor over the whole
        decomposition (:mod:`shapedb.signature.descriptor`, of ``DescriptorConfig.version``;
        ``n_r, t, w, la, lb`` are then unused); "paper" is the paper's Eq. 1 vector
        with Eq. 2 weights. Both are compared with a weighted L1 distance and turned
        into a similarity by Eq. 3.
    """

    n_r: int = 32
    t: int = 10
    w: float = 0.9
    la: float = 0.75
    lb: float = 0.75
    lam: float = 1.0
    method: str = "mdbd"

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


#: The length of each version of shapedb's descriptor: ``dim(version)`` of
#: :mod:`shapedb.signature.descriptor` (a test holds the two equal; the configuration sits
#: below the descriptor it names, so it keeps the sizes, not the layouts).
DESCRIPTOR_DIMS: dict[int, int] = {1: 247, 2: 257, 3: 335, 4: 335, 5: 463, 6: 302, 7: 591}
#: The versions of shapedb's descriptor.
DESCRIPTOR_VERSIONS: tuple[int, ...] = tuple(DESCRIPTOR_DIMS)


@dataclass(frozen=True)
class DescriptorConfig:
    """Which version of shapedb's descriptor (:mod:`shapedb.signature.descriptor`) method "mdbd" uses.

    Attributes
    ----------
    version : int
        A key of :data:`shapedb.signature.descriptor.LAYOUTS`. Stored with every record, so that
        a store never mixes versions; ignored by method "paper".
    """

    version: int = 4

    def __post_init__(self) -> None:
        _check(
            _is_int(self.version) and self.version in DESCRIPTOR_VERSIONS,
            "descriptor",
            self.version,
            f"must be one of {list(DESCRIPTOR_VERSIONS)} (see shapedb.signature.descriptor)",
        )


@dataclass(frozen=True)
class CloudConfig:
    """What a store keeps, besides each shape's own feature, to compare sparse point clouds.

    Attributes
    ----------
    view_cells : float
        0 stores one feature per shape. A positive value, in [2, 16], also stores for
        every shape that is not itself a sparse point cloud the feature of a *sparse
        view*: a point cloud drawn uniformly on its surface, one sample per
        ``view_cells`` grid cells of spacing (:mod:`shapedb.geometry.view`). Sparse point-cloud
        queries and records are then also compared with views; ingest then costs one
        point-cloud decomposition more per dense shape.
    reconstruct : bool
        True: every sparse point cloud, stored or queried, also has the feature of its
        screened Poisson reconstruction (:mod:`shapedb.mdbd.reconstruct`), compared with
        dense shapes' own features; dense shapes pay nothing.
    reconstruct_depth : int
        Octree depth of the reconstructions' Poisson solve (2^depth cells along the
        cloud's box at the finest level), in [4, 12]. Default 7 (chosen on the
        validation splits, ``docs/results.md``, "Across representations"); stores that do not record it read 8.
    """

    view_cells: float = 0.0
    reconstruct: bool = True
    reconstruct_depth: int = 7

    def __post_init__(self) -> None:
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
            _is_int(self.reconstruct_depth) and 4 <= self.reconstruct_depth <= 12,
            "reconstruct_depth",
            self.reconstruct_depth,
            "must be an integer in [4, 12]",
        )


#: The sections of a :class:`Config`, by attribute name.
_SECTIONS: dict[str, type] = {
    "mdbd": MDBDConfig,
    "kernel": KernelConfig,
    "descriptor": DescriptorConfig,
    "cloud": CloudConfig,
    "rerank": RerankConfig,
    "light_field": LightFieldConfig,
    "field_vector": FieldVectorConfig,
    "surface_words": SurfaceWordsConfig,
}


def _option(section: str, name: str) -> str:
    if section == "descriptor":
        return "descriptor"
    if section == "rerank":
        return "rerank"
    if section == "light_field":
        return f"lf_{name}"
    if section == "field_vector":
        return f"fv_{name}"
    return name


#: Fields of the per-record signatures that are their specification, not a user's choice:
#: the light field descriptor's (Zernike order, Fourier coefficients, angles, seed, and the
#: fills and depth terms its studies tried) and the field vector's resolutions. A store
#: keeps them (it knows how its records were built) and a study may set them on the
#: section's dataclass, but they are not flat options.
SPECIFICATION: dict[str, tuple[str, ...]] = {
    "light_field": (
        "zernike_order", "fourier", "angles", "fourier_weight", "depth_weight", "seed",
        "edges", "dilate_px", "close_px", "framing",
    ),
    "field_vector": (
        "depth_resolution", "depth_frequencies", "harmonic_shells", "harmonic_bands",
        "harmonic_angles",
    ),
    "surface_words": ("enabled", "view_words"),
}  # fmt: skip

#: Every flat option (``connect(path, **options)``, ``--set KEY=VALUE``) and the
#: ``(section, field)`` of :class:`Config` it sets: a field's own name, except
#: ``descriptor`` for ``DescriptorConfig.version``, ``rerank`` for ``RerankConfig.scorer``,
#: ``lf_<field>`` for the light field section and ``fv_<field>`` for the field vector's.
OPTIONS: dict[str, tuple[str, str]] = {
    _option(section, f.name): (section, f.name)
    for section, cls in _SECTIONS.items()
    for f in fields(cls)
    if f.name not in SPECIFICATION.get(section, ())
}


@dataclass(frozen=True)
class Config:
    """Everything that determines a store's records, one section per concern.

    Attributes
    ----------
    mdbd : MDBDConfig
        The decomposition (its fields alone make :attr:`fingerprint`).
    kernel : KernelConfig
        The feature method and the paper's kernel.
    descriptor : DescriptorConfig
        The version of the "mdbd" descriptor.
    cloud : CloudConfig
        Sparse views and reconstructions of sparse point clouds.
    rerank : RerankConfig
        Whether a search re-ranks the index's candidates. ``scorer="lightfield"`` is also
        the switch that makes ingest store each record's light fields (the
        ``light_field`` column).
    light_field : LightFieldConfig
        The light fields stored per record when the scorer is ``"lightfield"``
        (:func:`~shapedb.config.lightfield.product_light_field`: 3 light fields of 128 px,
        silhouettes only, of the field's inside seen about its surface).
    field_vector : FieldVectorConfig
        The field vector stored per record when :attr:`stores_field_vectors`.
    surface_words : SurfaceWordsConfig
        The surface words stored per record when :attr:`stores_surface_words`.
    """

    mdbd: MDBDConfig = field(default_factory=MDBDConfig)
    kernel: KernelConfig = field(default_factory=KernelConfig)
    descriptor: DescriptorConfig = field(default_factory=DescriptorConfig)
    cloud: CloudConfig = field(default_factory=CloudConfig)
    rerank: RerankConfig = field(default_factory=RerankConfig)
    light_field: LightFieldConfig = field(default_factory=product_light_field)
    field_vector: FieldVectorConfig = field(default_factory=product_field_vector)
    surface_words: SurfaceWordsConfig = field(default_factory=product_surface_words)

    @property
    def stores_light_fields(self) -> bool:
        """Whether ingest computes and stores each record's light fields (the switch)."""
        return self.rerank.scorer == "lightfield"

    @property
    def light_field_tail(self) -> int:
        """Balls the packing continues for past the decomposition's, for the light fields only.

        ``LightFieldConfig.n_balls - MDBDConfig.n_balls`` when the store keeps light
        fields of the balls (``source="balls"``) and that is positive, else 0
        (``tail_balls`` of :func:`shapedb.mdbd.decomposition.decompose`).
        """
        if not self.stores_light_fields or self.light_field.source != "balls":
            return 0
        return max(0, self.light_field.n_balls - self.mdbd.n_balls)

    @property
    def light_field_inside(self) -> bool:
        """Whether the store's light fields are those of the field's inside.

        True when the store keeps light fields and ``LightFieldConfig.source`` is
        ``"field"`` (``keep_inside`` of :func:`shapedb.mdbd.decomposition.decompose`).
        """
        return self.stores_light_fields and self.light_field.source == "field"

    @property
    def stores_field_vectors(self) -> bool:
        """Whether ingest computes and stores each record's field vector (``field_vector``).

        True when ``FieldVectorConfig.enabled`` and the store keeps the light fields of
        the field's inside (:attr:`light_field_inside`: the inside the vector is read
        from is then at hand).
        """
        return self.field_vector.enabled and self.light_field_inside

    @property
    def stores_surface_words(self) -> bool:
        """Whether ingest computes and stores each record's surface words (``surface_words``).

        True when ``SurfaceWordsConfig.enabled`` and the store keeps light fields (its
        searches run the ``"lightfield"`` stage, which fuses the words).
        """
        return self.surface_words.enabled and self.stores_light_fields

    @property
    def stores_view_words(self) -> bool:
        """Whether ingest computes and stores each record's view words (``view_words``):
        ``SurfaceWordsConfig.view_words`` in a store that keeps surface words."""
        return self.surface_words.view_words and self.stores_surface_words

    @property
    def dim(self) -> int:
        """Length of the feature vector: the descriptor's for "mdbd", 2 * n_r for "paper"."""
        if self.kernel.method == "mdbd":
            return DESCRIPTOR_DIMS[self.descriptor.version]
        return 2 * self.kernel.n_r

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable nested dict: one dict per section, and ``layout``."""
        out: dict[str, Any] = {name: asdict(getattr(self, name)) for name in _SECTIONS}
        out["layout"] = migrations.LAYOUT
        return out

    def to_json(self) -> str:
        """Canonical JSON (sorted keys), as stored in the store."""
        return json.dumps(self.to_dict(), sort_keys=True)

    def options(self) -> dict[str, Any]:
        """Every setting as a flat option (:data:`OPTIONS`), e.g. ``{"resolution": 128, ...}``."""
        return {name: getattr(getattr(self, s), f) for name, (s, f) in OPTIONS.items()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Config:
        """Inverse of :meth:`to_dict`, also for every layout stored by older versions.

        Older layouts and fields a stored configuration predates are read as what
        built it (:func:`shapedb.config.migrations.upgrade_config`); a section not stored at
        all takes today's defaults.

        Raises
        ------
        ConfigError
            When ``data`` has unknown keys or values out of range.
        """
        current = migrations.upgrade_config(data)
        unknown = set(current) - set(_SECTIONS)
        if unknown:
            raise ConfigError(
                f"cannot read configuration {dict(data)!r}: unknown {sorted(unknown)}"
            )
        return cls(
            **{name: build_section(_SECTIONS[name], section) for name, section in current.items()}
        )

    @classmethod
    def from_json(cls, text: str) -> Config:
        """Inverse of :meth:`to_json`."""
        return cls.from_dict(json.loads(text))

    @property
    def fingerprint(self) -> str:
        """Short hash of the decomposition parameters (what changes the graphs)."""
        text = json.dumps(migrations.mdbd_fingerprint_fields(asdict(self.mdbd)), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def with_options(self, **options: Any) -> Config:
        """A copy with some settings changed, by flat option name (:data:`OPTIONS`).

        >>> Config().with_options(resolution=64, n_r=10, descriptor=3).descriptor.version
        3

        Raises
        ------
        ConfigError
            For an unknown option or a value out of range.
        """
        unknown = set(options) - set(OPTIONS)
        if unknown:
            raise ConfigError(f"unknown configuration option(s): {sorted(unknown)}")
        changes: dict[str, dict[str, Any]] = {}
        for name, value in options.items():
            section, name_in_section = OPTIONS[name]
            changes.setdefault(section, {})[name_in_section] = value
        return replace(
            self,
            **{section: replace(getattr(self, section), **kw) for section, kw in changes.items()},
        )


def parse_options(pairs: Sequence[str]) -> dict[str, Any]:
    """Options from ``KEY=VALUE`` strings (the command line's ``--set``), typed by field.

    Each key must be a flat option (:data:`OPTIONS`); its value is read as that field's
    type (``true``/``false`` for booleans).

    >>> parse_options(["tie_cells=0", "descriptor=1"])
    {'tie_cells': 0.0, 'descriptor': 1}

    Raises
    ------
    ConfigError
        For a pair that is not ``KEY=VALUE``, an unknown key, or a value of the wrong type.
    """
    kinds = {"int": int, "float": float, "bool": bool, "str": str}
    types = {
        name: kinds[str(next(f.type for f in fields(_SECTIONS[s]) if f.name == attr))]
        for name, (s, attr) in OPTIONS.items()
    }
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
