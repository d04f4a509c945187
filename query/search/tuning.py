"""The re-ranking stage's tuned numbers, in one place: :data:`PRODUCT` is what every search uses.

These are not options: no user has a reason to turn them, and a store does not keep them
(a store keeps only whether its searches re-rank, ``RerankConfig.scorer``). Each number
was chosen on the validation splits of the bench's sets (CAPOD, jointed figures, machined
parts, the web-like generic and web sets, people) by the objective the comment names, and
its figures on the test splits are in docs/results.md; the research that chose them is
under ``bench/studies/``. A study varies them by passing another :class:`StageTuning` to
the stage (``LightFieldFusion(config, tuning=replace(PRODUCT, weight=4.0))``), or runs a
whole store's searches and commits under another with :func:`tuned`.

The stage (:mod:`query.search.rerank_lightfield`): among a query's candidates, with
``rank_d`` and ``rank_l`` each candidate's rank by the stored distance ``d`` and by the
light field distance ``l``, the fused distance is ``-(1 / (offset + rank_d) + weight *
g(q) / (offset + rank_l))``, ``g(q)`` the product of the spread ceiling (the store's
pooled local statistic of the query's candidates) and the contrast floor (how far the
stored vector already sets the nearest apart); the field vectors are fused into ``l``
(``l + alpha * b + gamma * h``, in light field units), their index adds candidates, and
candidates that share the query's nearest neighbours rise, by the light field where the gate
is open and by the stored distance among the candidates in every row (``rank_d``).
:class:`StageTuning`'s attributes name each part.

One unit turns the stage's light field distance into the local spread's and the
shared-neighbour term's: ``scale`` for the fused distance, ``light_field_unit`` for the
light field distance alone (a store without field vectors: older configurations). A
store with field vectors ranks exactly as before these two units (the former fusion's
weights and scales, and the unit 18.03 of its spread, are in the attributes' comments);
one without keeps its gate exactly, and its shared-neighbour term moves slightly (its
unit was 18.03, now 20.67).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, fields

from shapedb.errors import ConfigError

__all__ = ["StageTuning", "PRODUCT", "active", "tuned"]


@dataclass(frozen=True)
class StageTuning:
    """The numbers of the light field re-ranking stage (:data:`PRODUCT`: the defaults).

    Attributes
    ----------
    candidates : int
        K, the index's nearest candidates the stage re-ranks.
    weight : float
        Weight of the light field's rank term at ``g = 1``.
    neighbours : int
        Size of the query's neighbourhood the contrast reads.
    ceiling, ramp : float
        The gate's spread ceiling: ``clip((ceiling - s_q) / ramp, 0, 1)``.
    offset : float
        Rank offset of the reciprocal rank fusion.
    spread_candidates : int
        Nearest others a shape's local spread is measured over.
    pool, pool_quantile : int, float
        ``s_q`` is the ``pool_quantile`` of the stored local statistics of the query's
        first ``pool`` candidates.
    contrast_floor, contrast_ramp, contrast_depth : float, float, int
        The contrast floor ``clip((t_q - floor) / ramp, 0, 1)``, ``t_q`` the median ``d`` of
        the query's ``neighbours`` nearest others over ``d`` of its ``contrast_depth``-th.
    ratio_weight, ratio_candidates : float, int
        The ratio's share of the local statistic, and the others it is taken among.
    field_depth_weight, field_harmonic_weight : float
        ``alpha`` and ``gamma``: the fused distance is ``l + alpha * b + gamma * h``
        (light field units), ``b`` and ``h`` the field vectors' depth and harmonic L1
        distances (:mod:`query.search.field_fusion`).
    scale, light_field_unit : float
        The unit of the stage's fused distance, and of the light field distance alone (a
        store without field vectors), in a shape's local spread and in the
        shared-neighbour term (> 0; :meth:`unit`).
    field_candidates : int
        Candidates the field vector index adds to the index's K.
    shared_neighbours, shared_weight : int, float
        ``k`` and ``beta`` of the shared-neighbour term (0: off).
    descriptor_shared_weight : float
        ``beta`` of the stored distance's shared-neighbour term among the candidates
        (:mod:`query.search.candidate_neighbours`; 0: off).
    word_offset, word_weight : float
        The last fusion's rank offset and the surface words' weight
        (:mod:`query.search.word_fusion`; weight 0: off).
    proxy : bool
        A point cloud on the whole path ranks as its proxy does
        (:mod:`query.search.cloud_proxy`): the stored shape nearest to it by light fields
        among its first ``candidates``. False: by its own stage row (studies).
    """

    # K: the index's 100 nearest, re-ranked (the stage's candidates since it was introduced;
    # the adaptive and light field stages were both chosen at K = 100 on validation).
    candidates: int = 100
    # Weight, local statistic (spread over the 3 nearest others, ratio share 0.2 among the
    # 100 nearest), pool (the query's 30 first candidates, at their lower quartile), spread
    # ceiling 0.17 and ramp 0.034, contrast ramp 0.2: the best validation objective of the
    # 2,304 settings of the gate's ratio grid that keep both margins (jointed sets shut,
    # rigid ones open): python -m bench.studies.lightfield_gate --split validation --grid ratio
    weight: float = 8.0
    spread_candidates: int = 3
    ratio_weight: float = 0.2
    ratio_candidates: int = 100
    pool: int = 30
    pool_quantile: float = 0.25
    # The ceiling and ramp: that grid's 0.17 and 0.034 in the spread's units (``scale``,
    # ``light_field_unit``), i.e. times (18.03 / 20.67) ** 0.8 (the former spread unit over
    # the former light field scale, to the spread's share 1 - 0.2).
    ceiling: float = 0.1523958432880074
    ramp: float = 0.030479168657601478
    contrast_ramp: float = 0.2
    # Rank offset 60 and the contrast's 5 nearest: the first light field stage's grid on
    # validation (offset 20 gains about one web query on test with a perfect gate, not kept).
    offset: float = 60.0
    neighbours: int = 5
    # The contrast floor 0.2 over depth 20: the highest objective of their grid with the
    # shared-neighbour term on: python -m bench.studies.lightfield_gate --contrast-grid
    contrast_floor: float = 0.2
    contrast_depth: int = 20
    # The field vectors fused into the light field distance, and their index's 200 nearest
    # added to the candidates: the field vector choice on validation (python -m
    # bench.studies.field_choice) chose weights 0.25 and 0.25 at the former scales (the
    # distances' medians over each validation set's off-diagonal pairs, median of the six
    # sets: light field 20.67, depth 6.045, harmonic 2.168); alpha = 0.25 * 20.67 / 6.045
    # and gamma = 0.25 * 20.67 / 2.168 are that fusion times 1 + 0.25 + 0.25.
    field_depth_weight: float = 0.8548387096774195
    field_harmonic_weight: float = 2.383533210332103
    field_candidates: int = 200
    # The fused distance's unit: (1 + 0.25 + 0.25) * 20.67, the former light field scale
    # at the former weights.
    scale: float = 31.005
    # The light field distance's unit where nothing is fused: the former light field scale
    # (its median over each validation set's off-diagonal pairs, median of the six sets), so
    # such a store's gate is exactly the former one (its spread unit was 18.03, the geometric
    # mean of the sets' medians, at the ceiling 0.17); its shared-neighbour term's unit was
    # 18.03 too, so that term moves a little (beta as if times 20.67 / 18.03).
    light_field_unit: float = 20.67
    # Shared neighbours k 6: the highest objective of 3, 4, 5, 6 and 8 on validation splits
    # whose classes are as large as the test splits' (python -m bench.studies.class_size;
    # on the splits' own validation, classes half as large, k 3 wins). Beta 1.6: the highest
    # objective of its grid on validation (python -m bench.studies.lightfield_gate --shared-grid).
    shared_neighbours: int = 6
    shared_weight: float = 1.6
    # The stored distance's shared-neighbour term among the candidates, k as above: beta 0.2,
    # the highest validation objective of 0.1, 0.2, 0.3, 0.4, 0.6, 0.8 and 1.6 (0.8183; off,
    # 0.8105: python -m bench.studies.stage_parts, "no stored-distance neighbours").
    descriptor_shared_weight: float = 0.2
    # The surface words fused last, offset 4 (ranks from 0) and weight 0.75: the highest
    # validation objective of the rigid families over offsets 2-31 and weights 0.25-1.5, no
    # family losing NN (python -m bench.studies.surface_words).
    word_offset: float = 4.0
    word_weight: float = 0.75
    # The proxy: validation clouds (even, vertex, fall-off) of CAPOD, parts, enclosures and
    # generic models find their class more often (NN 0.762-0.979 -> 0.786-1.000; parts
    # level), whether the store holds the cloud's model or not, except the enclosures'
    # fall-off clouds without their models (0.778 -> 0.694): python -m bench.studies.cloud_proxy.
    proxy: bool = True

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type == "bool":
                if not isinstance(value, bool):
                    raise ConfigError(f"StageTuning.{f.name} must be True or False, got {value!r}")
                continue
            integer = isinstance(value, int) and not isinstance(value, bool)
            ok = integer if f.type == "int" else integer or isinstance(value, float)
            if not ok or not 0 <= value < float("inf"):
                kind = "an integer" if f.type == "int" else "a finite number"
                raise ConfigError(f"StageTuning.{f.name} must be {kind} >= 0, got {value!r}")
        for name in ("candidates", "neighbours", "spread_candidates", "ratio_candidates"):
            if getattr(self, name) < 1:
                raise ConfigError(f"StageTuning.{name} must be >= 1")
        for name in ("ramp", "offset", "contrast_ramp", "scale", "light_field_unit", "word_offset"):
            if getattr(self, name) <= 0:
                raise ConfigError(f"StageTuning.{name} must be > 0")
        if self.contrast_depth < 2 or self.pool_quantile > 1 or self.ratio_weight > 1:
            raise ConfigError(
                "StageTuning: contrast_depth must be >= 2, pool_quantile and ratio_weight <= 1"
            )

    def unit(self, fused: bool) -> float:
        """The unit of the stage's distance: ``scale`` when ``fused``, else
        ``light_field_unit``."""
        return float(self.scale if fused else self.light_field_unit)

    @property
    def shares_neighbours(self) -> bool:
        """Whether the shared-neighbour term is on (``k > 0`` and ``beta > 0``)."""
        return self.shared_neighbours > 0 and self.shared_weight > 0


#: What every search uses.
PRODUCT = StageTuning()


_ACTIVE: list[StageTuning] = [PRODUCT]
_LOCK = threading.Lock()


def active() -> StageTuning:
    """The numbers a store's searches and commits use now: :data:`PRODUCT` but inside
    :func:`tuned`."""
    return _ACTIVE[-1]


@contextmanager
def tuned(tuning: StageTuning) -> Iterator[StageTuning]:
    """Run a block's searches and commits with ``tuning`` instead of :data:`PRODUCT`.

    For studies and tests that compare settings of the stage on one store (the side
    tables are keyed by the numbers they were computed with, so they never mix).
    Process-wide: not for concurrent searches that want different numbers.
    """
    with _LOCK:
        _ACTIVE.append(tuning)
    try:
        yield tuning
    finally:
        with _LOCK:
            _ACTIVE.remove(tuning)
