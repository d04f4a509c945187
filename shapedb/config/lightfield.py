"""Configuration of the light fields a store keeps per record: :class:`LightFieldConfig`.

A section of :class:`shapedb.config.core.Config` (``Config.light_field``): the light field
descriptor (:mod:`shapedb.signature.lightfield`); a store whose ``RerankConfig.scorer`` is
``"lightfield"`` stores each record's light fields under it. The class's defaults are the
published descriptor's (10 light fields of 64 px); a new store keeps
:func:`product_light_field`'s. How the stage fuses them is not configuration
(:mod:`query.search.tuning`). Flat options (``--set``) are ``lf_<field>``.
"""

from __future__ import annotations

from dataclasses import dataclass

from shapedb.config.checks import check as _check
from shapedb.config.checks import is_int as _is_int

__all__ = [
    "LightFieldConfig",
    "SOURCES",
    "CENTRES",
    "FRAMINGS",
    "product_light_field",
]

#: What a light field can see (``LightFieldConfig.source``).
SOURCES = ("balls", "field")
#: About which point the field's inside is seen (``LightFieldConfig.centre``).
CENTRES = ("volume", "surface")
#: How each silhouette is framed (:attr:`LightFieldConfig.framing`).
FRAMINGS = ("view", "sphere")


@dataclass(frozen=True)
class LightFieldConfig:
    """Light fields of a shape (:mod:`shapedb.signature.lightfield`, Chen et al. 2003).

    Attributes
    ----------
    n_fields : int
        Light fields (dodecahedra turned in fixed ways), 1-10; each is 10 views.
    resolution : int
        Image side, pixels, in [16, 256]; the image spans the unit disc.
    zernike_order : int
        Largest Zernike order, in [2, 16] (order 10: 36 magnitudes per image).
    fourier : int
        Fourier descriptors of the silhouette's centroid distance, 0 to ``angles // 2``.
    angles : int
        Samples of the centroid distance around the contour, >= 8.
    fourier_weight : float
        Weight of the Fourier block against the Zernike block, >= 0.
    depth_weight : float
        0: silhouettes only. Positive: each view also has the Zernike magnitudes of its
        two depth images (front and back, combined as their sum and absolute
        difference), times this weight (ball unions only).
    seed : int
        Seed of the light fields' turns.
    edges : bool
        Fill the silhouettes from the contact graph: each contact edge also covers the
        convex hull of its two balls (which closes the gap between touching balls).
    dilate_px : float
        Every ball's disc grows by this many pixels, in [0, 8].
    close_px : int
        Morphological closing of every silhouette by a disc of this many pixels, in [0, 8].
    n_balls : int
        Balls of the packing the light fields are rendered from, 0 or in [1, 100000].
        0, or at most ``MDBDConfig.n_balls``: the decomposition's balls. More: the
        greedy packing continues past the decomposition's balls on the same field,
        without off-grid refinement, up to this many balls in all
        (:func:`shapedb.mdbd.decomposition.decompose`'s ``tail_balls``, :attr:`Config.light_field_tail`);
        the decomposition, its contact graph and its feature stay those of
        ``MDBDConfig.n_balls``. Read only with ``source="balls"``.
    source : str
        What the light fields see. ``"balls"``: the union of the packing's balls (the
        decomposition's, or the longer packing of ``n_balls``). ``"field"``: the inside
        of the signed field the MDBD packs (every cell where it is >= 0, each a ball of
        half a cell, :mod:`shapedb.geometry.inside`), which keeps the sheets thinner than the
        smallest ball; ``decompose(keep_inside=True)`` keeps it in memory
        (:attr:`Config.light_field_inside`). Both are normalised alike: about the
        solid's volume centroid (for the field, see ``centre``), the farthest far side on
        the unit sphere.
    centre : str
        The point the field's inside is seen about (``source="field"`` only; a ball
        union is always seen about its volume centroid). ``"volume"``: the centroid of
        all the inside cells. ``"surface"``: the mean of the shell cells (the surface as
        the grid sees it, as a mesh light field descriptor centres on its surface), which
        a thin sheet or wall pulls as much as a bulky part of the same area.
    framing : str
        How each silhouette is framed (:func:`shapedb.signature.lightfield.render_discs`).
        ``"view"``: about its own bounding box's centre, scaled by its light field's
        largest reach from those centres, as the published descriptor frames them.
        ``"sphere"``: every view spans the unit disc about the 3-D centre (``centre``).
    """

    n_fields: int = 10
    resolution: int = 64
    zernike_order: int = 10
    fourier: int = 10
    angles: int = 64
    fourier_weight: float = 1.0
    depth_weight: float = 0.0
    seed: int = 0
    edges: bool = False
    dilate_px: float = 0.0
    close_px: int = 0
    n_balls: int = 0
    source: str = "balls"
    centre: str = "volume"
    framing: str = "view"

    def __post_init__(self) -> None:
        ints = {"n_fields": (1, 10), "resolution": (16, 256), "zernike_order": (2, 16)}
        for name, (lo, hi) in ints.items():
            v = getattr(self, name)
            _check(
                _is_int(v) and lo <= v <= hi, f"lf_{name}", v, f"must be an integer in [{lo}, {hi}]"
            )
        _check(_is_int(self.angles) and self.angles >= 8, "lf_angles", self.angles, "must be >= 8")
        _check(
            _is_int(self.fourier) and 0 <= self.fourier <= self.angles // 2,
            "lf_fourier", self.fourier, "must be an integer in [0, lf_angles // 2]",
        )  # fmt: skip
        for name in ("fourier_weight", "depth_weight"):
            v = getattr(self, name)
            _check(isinstance(v, (int, float)) and v >= 0, f"lf_{name}", v, "must be a number >= 0")
        _check(_is_int(self.seed), "lf_seed", self.seed, "must be an integer")
        _check(isinstance(self.edges, bool), "lf_edges", self.edges, "must be true or false")
        ok = isinstance(self.dilate_px, (int, float)) and 0 <= self.dilate_px <= 8
        _check(ok, "lf_dilate_px", self.dilate_px, "must be a number in [0, 8]")
        ok = _is_int(self.close_px) and 0 <= self.close_px <= 8
        _check(ok, "lf_close_px", self.close_px, "must be an integer in [0, 8]")
        ok = _is_int(self.n_balls) and 0 <= self.n_balls <= 100_000
        _check(ok, "lf_n_balls", self.n_balls, "must be an integer in [0, 100000]")
        ok = isinstance(self.source, str) and self.source in SOURCES
        _check(ok, "lf_source", self.source, f"must be one of {', '.join(SOURCES)}")
        ok = isinstance(self.centre, str) and self.centre in CENTRES
        _check(ok, "lf_centre", self.centre, f"must be one of {', '.join(CENTRES)}")
        ok = isinstance(self.framing, str) and self.framing in FRAMINGS
        _check(ok, "lf_framing", self.framing, f"must be one of {', '.join(FRAMINGS)}")


def product_light_field() -> LightFieldConfig:
    """The light fields a new store keeps: 3 light fields of 128 px, silhouettes only, of
    the inside of the decomposition's field (``source="field"``) seen about the mean of
    its shell cells (``centre="surface"``), each silhouette framed about its own centroid
    (``framing="view"``); with ``lf_source=balls``, of the packing continued to 2048 balls."""
    return LightFieldConfig(
        n_fields=3, resolution=128, depth_weight=0.0, n_balls=2048, source="field",
        centre="surface",
    )  # fmt: skip
