"""The bench's settings of the re-ranking stage: what a store keeps, and the stage's numbers.

A store keeps only its :class:`shapedb.config.core.Config` (whether it re-ranks, its light
fields); the stage's numbers are a :class:`query.search.tuning.StageTuning`
(:data:`query.search.tuning.PRODUCT` by default). The studies name settings as flat
``key=value`` pairs, as the options they once were: :func:`split_settings` sends each to
its place (``lf_<field>`` of :class:`~query.search.tuning.StageTuning` and
``rerank_candidates`` to the tuning, the light fields' specification fields to
``Config.light_field``, the rest to :meth:`Config.with_options`).

``lf_power``, the exponent of the overlap gate the stage had before the spread ceiling
(always 0 in the product, and gone from the library), lives on here for the studies that
measure the settings of that time: :class:`OverlapFusion`. So does ``lf_typical``, the
former unit 18.03 of the light field distance alone (no field vectors) in the local spread
and the shared-neighbour term, where the product now divides by ``light_field_unit``
(20.67, which keeps its gate at its ceiling but moves the shared-neighbour term a little):
:class:`LegacyTuning`, for the studies' settings of that time (their ceilings are in that
unit). The bench reads it through :func:`unit_of` (its statistics,
:mod:`bench.support.stores`) and :func:`configure` (a setting's units are its ``typical``
on a store without field vectors); the product's :data:`~query.search.tuning.PRODUCT` has
none.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from query.search.field_fusion import FieldFusion
from query.search.rerank_lightfield import LightFieldFusion
from query.search.tuning import PRODUCT, StageTuning
from shapedb.config.core import OPTIONS, Config
from shapedb.errors import ConfigError

__all__ = [
    "TUNING_FIELDS",
    "LEGACY_TYPICAL",
    "LegacyTuning",
    "unit_of",
    "at_unit",
    "Setting",
    "OverlapFusion",
    "parse_value",
    "with_light_field",
    "split_settings",
    "configure",
]

Floats = NDArray[np.float64]
Bools = NDArray[np.bool_]

#: The retired ``typical``: the geometric mean over the six validation sets of the median
#: light field distance (the spread's unit before ``StageTuning.light_field_unit``).
LEGACY_TYPICAL = 18.03


@dataclasses.dataclass(frozen=True)
class LegacyTuning(StageTuning):
    """The stage's numbers with the retired unit of the light field distance alone.

    On a store without field vectors the local spread and the shared-neighbour term
    divide the light field distance by ``typical`` instead of ``light_field_unit`` (as the
    stage did before); a store that fuses the field vectors keeps ``scale``, which
    reproduces the former fusion exactly (:mod:`query.search.tuning`).

    Attributes
    ----------
    typical : float
        The unit of the light field distance alone (> 0).
    """

    typical: float = LEGACY_TYPICAL

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.typical <= 0:
            raise ConfigError("LegacyTuning.typical must be > 0")


#: The fields of :class:`StageTuning`, and the retired one of :class:`LegacyTuning`.
TUNING_FIELDS = tuple(f.name for f in dataclasses.fields(LegacyTuning))
#: The retired fields (:class:`LegacyTuning`'s own).
_RETIRED = ("typical",)


def unit_of(tuning: Any, stage: Any = None) -> float:
    """The unit of the stage's distance in the spread and the shared-neighbour term.

    ``stage`` (a :class:`bench.support.field_vectors.FieldStage`, or None) fusing the
    field vectors: its ``scale``; else ``tuning``'s ``typical`` when it has one
    (:class:`LegacyTuning`), else its ``light_field_unit``.
    """
    if stage is not None and stage.fuses:
        return float(stage.scale)
    return float(getattr(tuning, "typical", tuning.light_field_unit))


def at_unit(tuning: Any, stage: Any = None) -> Any:
    """``tuning`` with both units, ``scale`` and ``light_field_unit``, set to :func:`unit_of`
    (so the product's scorer reads it whether its configuration fuses or not; itself when
    both already are). ``tuning``: a :class:`StageTuning` or a namespace of its fields.
    """
    unit = unit_of(tuning, stage)
    if unit == tuning.scale == tuning.light_field_unit:
        return tuning
    units = {"scale": unit, "light_field_unit": unit}
    if dataclasses.is_dataclass(tuning):
        return dataclasses.replace(tuning, **units)
    return type(tuning)(**{**vars(tuning), **units})


def parse_value(text: str) -> Any:
    """A ``key=value`` pair's value: an int, a float, a bool (``true``/``false``) or the text."""
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    if text.replace(".", "", 1).lstrip("-").isdigit():
        return float(text) if "." in text else int(text)
    return text


def with_light_field(config: Config, **fields: Any) -> Config:
    """``config`` with ``fields`` of its ``light_field`` set (flat ``lf_`` options or not)."""
    flat = {f"lf_{k}": v for k, v in fields.items() if f"lf_{k}" in OPTIONS}
    spec = {k: v for k, v in fields.items() if f"lf_{k}" not in OPTIONS}
    out = config.with_options(**flat) if flat else config
    if spec:
        out = dataclasses.replace(out, light_field=dataclasses.replace(out.light_field, **spec))
    return out


def split_settings(settings: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(options, tuning)``: flat settings split into :meth:`Config.with_options`'s (with
    the light fields' specification fields as ``lf_<field>``) and the stage's.

    ``lf_<field>`` of a :class:`StageTuning` field, ``lf_typical``
    (:class:`LegacyTuning`'s), ``lf_power`` and ``rerank_candidates`` (as ``candidates``)
    go to the stage's.
    """
    options: dict[str, Any] = {}
    tuning: dict[str, Any] = {}
    for key, value in settings.items():
        name = key[3:] if key.startswith("lf_") else None
        if key == "rerank_candidates":
            tuning["candidates"] = value
        elif name in TUNING_FIELDS or name == "power":
            tuning[name] = value
        else:
            options[key] = value
    return options, tuning


class OverlapFusion(LightFieldFusion):
    """The light field stage with the overlap gate it had before the spread ceiling.

    ``g(q)`` is the product's times ``(|A ∩ B| / m) ** power``, ``A`` and ``B`` the query's
    ``m = min(neighbours, others)`` nearest other candidates by the stored distance and by
    the light field distance (ties in list order), as the stage computed it then.
    """

    def __init__(self, config: Config, *, tuning: StageTuning = PRODUCT, power: float) -> None:
        super().__init__(config, tuning=tuning)
        self.power = float(power)

    def gate(self, d4: Floats, dl: Floats, own: Bools, spreads: Floats | None) -> float:
        """``g(q)``: the product's gate times the overlap to the power ``power``."""
        g = super().gate(d4, dl, own, spreads)
        others = np.flatnonzero(~own)
        if self.power <= 0 or not len(others):
            return g
        others = others[np.argsort(d4[others], kind="stable")]
        m = min(self.tuning.neighbours, len(others))
        b = others[np.argsort(dl[others], kind="stable")[:m]]
        return float((len(np.intersect1d(others[:m], b)) / m) ** self.power * g)


@dataclasses.dataclass(frozen=True)
class Setting:
    """A setting of a study: what the store keeps, the stage's numbers, the overlap gate."""

    config: Config
    tuning: StageTuning = PRODUCT
    power: float = 0.0

    def scorer(self) -> LightFieldFusion | None:
        """The stage of this setting (None: the store does not re-rank)."""
        if self.config.rerank.scorer == "none":
            return None
        if self.power > 0:
            return OverlapFusion(self.config, tuning=self.tuning, power=self.power)
        return LightFieldFusion(self.config, tuning=self.tuning)


def configure(
    config: Config, settings: Mapping[str, Any], tuning: StageTuning = PRODUCT
) -> Setting:
    """``config`` and ``tuning`` with the flat ``settings`` applied (:func:`split_settings`).

    With ``lf_typical``, a :class:`LegacyTuning` whose units are ``typical`` when the
    configuration fuses nothing (so the product's scorer, its stored statistics and
    :func:`query.search.tuning.tuned` all read that unit).
    """
    options, changes = split_settings(settings)
    power = float(changes.pop("power", 0.0))
    flat = {k: v for k, v in options.items() if not k.startswith("lf_") or k in OPTIONS}
    spec = {k[3:]: v for k, v in options.items() if k not in flat}
    out = config.with_options(**flat) if flat else config
    if spec:
        out = with_light_field(out, **spec)
    if any(k in changes for k in _RETIRED):
        now = {f.name: getattr(tuning, f.name) for f in dataclasses.fields(tuning)}
        legacy = LegacyTuning(**{**now, **changes})
        fused = FieldFusion.from_config(out, legacy).active
        return Setting(out, legacy if fused else at_unit(legacy), power)
    return Setting(out, dataclasses.replace(tuning, **changes) if changes else tuning, power)
