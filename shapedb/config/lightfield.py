"""Configuration of the balls' light fields and of the ``"lightfield"`` re-ranking scorer.

Two sections of :class:`shapedb.config.core.Config` (re-exported from :mod:`shapedb.config.core`):

* :class:`LightFieldConfig` (``Config.light_field``): the light field descriptor of a
  ball union (:mod:`shapedb.signature.lightfield`); a store whose ``RerankConfig.scorer`` is
  ``"lightfield"`` stores each record's light fields under it;
* :class:`LightFieldFusionConfig` (``Config.lf_fusion``): how the ``"lightfield"``
  scorer (:mod:`query.search.rerank_lightfield`) fuses the light field distance with the
  stored vector's distance.

Flat options (``connect(path, **options)``, ``--set``) are ``lf_<field>`` for both.
"""

from __future__ import annotations

from dataclasses import dataclass

from shapedb.config.checks import check as _check
from shapedb.config.checks import is_int as _is_int

__all__ = [
    "LightFieldConfig",
    "LightFieldFusionConfig",
    "SOURCES",
    "CENTRES",
    "product_light_field",
    "product_light_field_fusion",
    "PRODUCT_SCALES",
]

#: What a light field can see (``LightFieldConfig.source``).
SOURCES = ("balls", "field")
#: About which point the field's inside is seen (``LightFieldConfig.centre``).
CENTRES = ("volume", "surface")


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


def product_light_field() -> LightFieldConfig:
    """The light fields a new store keeps: 3 light fields of 128 px, silhouettes only, of
    the inside of the decomposition's field (``source="field"``) seen about the mean of
    its shell cells (``centre="surface"``); with ``lf_source=balls``, of the packing
    continued to 2048 balls."""
    return LightFieldConfig(
        n_fields=3, resolution=128, depth_weight=0.0, n_balls=2048, source="field",
        centre="surface",
    )  # fmt: skip


@dataclass(frozen=True)
class LightFieldFusionConfig:
    """The ``"lightfield"`` scorer: a reciprocal rank fusion gated by the store and contrast.

    Among a query's candidates (the store's ``RerankConfig.candidates`` nearest by the
    stored distance ``d``; the query itself, when stored, among them), with ``rank_d``
    and ``rank_l`` each candidate's rank (0 first) by ``d`` and by the light field
    distance ``l`` (:func:`shapedb.signature.lightfield.light_field_distance`), the scorer's
    distance is ``-(1 / (offset + rank_d) + weight * g(q) / (offset + rank_l))``, with
    ``g(q)`` the product of three factors, each 1 when switched off:

    * the overlap ``(|A ∩ B| / neighbours) ** power`` of the query's ``neighbours``
      nearest candidates by ``d`` and by ``l`` (itself left out; ``power`` 0: off);
    * the ceiling ``clip((ceiling - s_q) / ramp, 0, 1)`` (``ceiling`` 0: off) on the
      shapes' *local statistic* ``spread ** (1 - b) * ratio ** b`` (``b =
      ratio_weight``). A shape's *spread* is the median of ``l / typical`` over the median
      of ``d / c`` among its ``spread_candidates`` nearest others by ``d`` (``c = ln(10) /
      (sum of the descriptor's block weights)``, version 4's calibrated units): high where
      near neighbours by the stored vector look unlike (jointed subjects in other poses).
      Its *ratio* is the median ``l`` of those neighbours over the median of the
      ``spread_candidates`` smallest ``l`` among its ``ratio_candidates`` nearest others
      by ``d``: scale-free, near 1 where the light field's nearest are about as near as
      the stored distance's, high where the light field finds other shapes much nearer
      (other subjects in the same pose). With ``pool > 0``, ``s_q`` is the
      ``pool_quantile`` (0.5: the median) of the stored local statistics of the query's
      first ``pool`` candidates (the query itself among them when stored; kept per store
      version with the index, :mod:`query.search.lightfield_spread`); with ``pool`` 0, the
      query's own local statistic;
    * the contrast floor ``clip((t_q - contrast_floor) / contrast_ramp, 0, 1)``
      (``contrast_floor`` 0: off), ``t_q`` the median ``d`` of the query's
      ``neighbours`` nearest others over ``d`` of its ``contrast_depth``-th nearest
      other (the last when fewer): low where the stored vector already sets the
      nearest apart, and the light field is kept out.

    The defaults are those chosen on the validation splits (docs/results.md, "A gate
    with a margin (issue 25)"); stores written before ``pool`` and the
    contrast read ``pool`` 0 and ``contrast_floor`` 0, stores written before the ratio
    read ``ratio_weight`` 0 and ``pool_quantile`` 0.5 (:mod:`shapedb.config.migrations`), and
    their stored weight, power, ceiling and spread candidates.

    Attributes
    ----------
    weight : float
        Weight of the light field's rank term at ``g = 1``, in [0, 1000].
    neighbours : int
        Size of the neighbourhoods of the overlap and of the contrast, in [1, 1000].
    power : float
        Exponent of the overlap, in [0, 8]; 0: the overlap does not count.
    ceiling : float
        The spread ``s_q`` above which the term is off; 0 disables the ceiling. In [0, 10].
    ramp : float
        Width of the fade below the ceiling, in (0, 10].
    typical : float
        Typical light field distance (median over the validation sets), > 0.
    offset : float
        Rank offset of the reciprocal rank fusion, > 0.
    spread_candidates : int
        Nearest others a local spread is measured over, in [1, 100000].
    pool : int
        Candidates whose stored local statistics make ``s_q``, in [0, 100000]; 0: the
        query's own local statistic, taken among its candidates (at most
        ``RerankConfig.candidates - 1`` others, also for the ratio).
    contrast_floor : float
        The contrast ``t_q`` below which the term is off; 0 disables it. In [0, 1].
    contrast_ramp : float
        Width of the fade above the floor, in (0, 1].
    contrast_depth : int
        Rank of the far candidate of the contrast, in [2, 100000].
    ratio_weight : float
        ``b``, the ratio's share of the local statistic (in the log), in [0, 1]; 0: the
        local spread alone, 1: the ratio alone (``typical`` and the calibration unused).
    ratio_candidates : int
        Nearest others by ``d`` among which the ratio takes the light field's nearest, in
        [1, 100000] (at least ``spread_candidates`` are taken).
    pool_quantile : float
        Quantile of the pooled statistics that makes ``s_q``, in [0, 1]; 0.5: the median.
    field_depth_weight : float
        ``a``: weight of the field vectors' depth buffer distance in the fused light field
        distance ``m_l * (l / m_l + a * b / m_b + c * h / m_h) / (1 + a + c)`` (``b``, ``h``:
        L1 distances of the depth and harmonic parts of the stored field vectors,
        :func:`shapedb.signature.field_vector.field_vector_parts`), which replaces ``l``
        everywhere the scorer reads it, in [0, 1000]. Read only by stores that keep field
        vectors (:attr:`shapedb.config.core.Config.stores_field_vectors`); 0 with
        ``field_harmonic_weight`` 0: ``l`` alone (the default, and stores written before).
    field_harmonic_weight : float
        ``c``: weight of the harmonic distance ``h`` in the fused distance, in [0, 1000].
    light_field_scale : float
        ``m_l``: the light field distance's fixed scale (a typical value), > 0.
    field_depth_scale : float
        ``m_b``: the depth buffer distance's fixed scale, > 0.
    field_harmonic_scale : float
        ``m_h``: the harmonic distance's fixed scale, > 0.
    field_candidates : int
        K2: the candidates of the stage are the union of the stored vector's ``candidates``
        nearest and the K2 nearest by the L1 distance of the scaled field vectors
        ``[depth / m_b, harmonic / m_h]``, in [0, 100000]; 0: the stored vector's alone
        (the default, and stores written before). Read only by stores that keep field
        vectors.
    shared_neighbours : int
        ``k`` of the shared-neighbour term, in [0, 50]; 0: the term is off (the default,
        and stores written before). With ``k > 0`` and ``shared_weight > 0`` the light
        field's rank ``rank_l`` ranks the candidates by ``l / m_l - beta * S(q, x)``
        instead of ``l`` (``m_l``: ``light_field_scale`` when the field vectors are fused
        into ``l``, else ``typical``), where ``S(q, x) = |({q} ∪ N_k(q)) ∩ ({x} ∪
        N_k(x))| / (k + 1)``: ``N_k(q)`` the query's ``k`` nearest other candidates by
        ``l``, ``N_k(x)`` the stored shape's ``k`` nearest others among its own stage
        candidates (a per-store-version table, :mod:`query.search.lightfield_neighbours`); an
        outside query matches no stored id. The gate and its statistics read ``l``
        alone, and the first result among the query's other candidates stays the one
        without the term.
    shared_weight : float
        ``beta``, the weight of ``S`` against ``l / m_l``, in [0, 100]; 0: the term is off.
    """

    weight: float = 8.0
    neighbours: int = 5
    power: float = 0.0
    ceiling: float = 0.17
    ramp: float = 0.034
    typical: float = 18.03
    offset: float = 60.0
    spread_candidates: int = 3
    pool: int = 30
    contrast_floor: float = 0.3
    contrast_ramp: float = 0.2
    contrast_depth: int = 30
    ratio_weight: float = 0.2
    ratio_candidates: int = 100
    pool_quantile: float = 0.25
    field_depth_weight: float = 0.0
    field_harmonic_weight: float = 0.0
    light_field_scale: float = 1.0
    field_depth_scale: float = 1.0
    field_harmonic_scale: float = 1.0
    field_candidates: int = 0
    shared_neighbours: int = 0
    shared_weight: float = 0.0

    def __post_init__(self) -> None:
        def number(v: object) -> bool:
            return isinstance(v, (int, float)) and not isinstance(v, bool) and v == v

        ok = number(self.weight) and 0.0 <= self.weight <= 1000.0
        _check(ok, "lf_weight", self.weight, "must be a number in [0, 1000]")
        ok = _is_int(self.neighbours) and 1 <= self.neighbours <= 1000
        _check(ok, "lf_neighbours", self.neighbours, "must be an integer in [1, 1000]")
        ok = number(self.power) and 0.0 <= self.power <= 8.0
        _check(ok, "lf_power", self.power, "must be a number in [0, 8]")
        ok = number(self.ceiling) and 0.0 <= self.ceiling <= 10.0
        _check(ok, "lf_ceiling", self.ceiling, "must be a number in [0, 10]")
        ok = number(self.ramp) and 0.0 < self.ramp <= 10.0
        _check(ok, "lf_ramp", self.ramp, "must be a number in (0, 10]")
        ok = number(self.typical) and 0.0 < self.typical < float("inf")
        _check(ok, "lf_typical", self.typical, "must be a finite number > 0")
        ok = number(self.offset) and 0.0 < self.offset < float("inf")
        _check(ok, "lf_offset", self.offset, "must be a finite number > 0")
        ok = _is_int(self.spread_candidates) and 1 <= self.spread_candidates <= 100_000
        _check(
            ok, "lf_spread_candidates", self.spread_candidates, "must be an integer in [1, 100000]"
        )
        ok = _is_int(self.pool) and 0 <= self.pool <= 100_000
        _check(ok, "lf_pool", self.pool, "must be an integer in [0, 100000]")
        ok = number(self.contrast_floor) and 0.0 <= self.contrast_floor <= 1.0
        _check(ok, "lf_contrast_floor", self.contrast_floor, "must be a number in [0, 1]")
        ok = number(self.contrast_ramp) and 0.0 < self.contrast_ramp <= 1.0
        _check(ok, "lf_contrast_ramp", self.contrast_ramp, "must be a number in (0, 1]")
        ok = _is_int(self.contrast_depth) and 2 <= self.contrast_depth <= 100_000
        _check(ok, "lf_contrast_depth", self.contrast_depth, "must be an integer in [2, 100000]")
        ok = number(self.ratio_weight) and 0.0 <= self.ratio_weight <= 1.0
        _check(ok, "lf_ratio_weight", self.ratio_weight, "must be a number in [0, 1]")
        ok = _is_int(self.ratio_candidates) and 1 <= self.ratio_candidates <= 100_000
        _check(
            ok, "lf_ratio_candidates", self.ratio_candidates, "must be an integer in [1, 100000]"
        )
        ok = number(self.pool_quantile) and 0.0 <= self.pool_quantile <= 1.0
        _check(ok, "lf_pool_quantile", self.pool_quantile, "must be a number in [0, 1]")
        for name in ("field_depth_weight", "field_harmonic_weight"):
            v = getattr(self, name)
            ok = number(v) and 0.0 <= v <= 1000.0
            _check(ok, f"lf_{name}", v, "must be a number in [0, 1000]")
        for name in ("light_field_scale", "field_depth_scale", "field_harmonic_scale"):
            v = getattr(self, name)
            ok = number(v) and 0.0 < v < float("inf")
            _check(ok, f"lf_{name}", v, "must be a finite number > 0")
        ok = _is_int(self.field_candidates) and 0 <= self.field_candidates <= 100_000
        _check(
            ok, "lf_field_candidates", self.field_candidates, "must be an integer in [0, 100000]"
        )
        ok = _is_int(self.shared_neighbours) and 0 <= self.shared_neighbours <= 50
        _check(ok, "lf_shared_neighbours", self.shared_neighbours, "must be an integer in [0, 50]")
        ok = number(self.shared_weight) and 0.0 <= self.shared_weight <= 100.0
        _check(ok, "lf_shared_weight", self.shared_weight, "must be a number in [0, 100]")

    @property
    def shares_neighbours(self) -> bool:
        """Whether the shared-neighbour term is on (``k > 0`` and ``beta > 0``)."""
        return self.shared_neighbours > 0 and self.shared_weight > 0


#: ``(m_l, m_b, m_h)`` of :func:`product_light_field_fusion`: the medians of the light field
#: distance (the field's, 3 x 128 px), the depth buffer L1 and the harmonic L1 of the default
#: field vector over each validation set's off-diagonal pairs, then the median of the six sets.
PRODUCT_SCALES = (20.67, 6.045, 2.168)


def product_light_field_fusion() -> LightFieldFusionConfig:
    """The fusion a new store's ``"lightfield"`` scorer uses: the defaults of
    :class:`LightFieldFusionConfig` with the field vectors fused into the light field
    distance (weights 0.25 and 0.25, the scales :data:`PRODUCT_SCALES`), their index's 200
    nearest added to the candidates. Chosen on the validation splits (docs/results.md, "The
    field vectors in the stage: the choice and the rows"). The shared-neighbour term at
    ``k`` 3, ``beta`` 1.6, the highest objective of its grid on the validation splits with
    the field seen about its surface (docs/results.md, "The field seen about its surface,
    and shared neighbours"). The gate's contrast at floor 0.2, ramp 0.2, depth 20, the
    highest objective of its grid with that term on (docs/results.md, "The gate's contrast
    with the shared neighbours")."""
    return LightFieldFusionConfig(
        field_depth_weight=0.25,
        field_harmonic_weight=0.25,
        light_field_scale=PRODUCT_SCALES[0],
        field_depth_scale=PRODUCT_SCALES[1],
        field_harmonic_scale=PRODUCT_SCALES[2],
        field_candidates=200,
        contrast_floor=0.2,
        contrast_ramp=0.2,
        contrast_depth=20,
        shared_neighbours=3,
        shared_weight=1.6,
    )
