"""Configuration of the field vector each record stores: :class:`FieldVectorConfig`.

A section of :class:`shapedb.config.core.Config` (``Config.field_vector``, re-exported from
:mod:`shapedb.config.core`); flat options ``fv_<field>`` (``--set fv_enabled=false``). The
vector itself is :func:`shapedb.signature.field_vector.field_vector`: the depth buffer
descriptor and the spherical-harmonic energies of the inside of the field the MDBD packs
(:mod:`shapedb.geometry.inside`), concatenated.
"""

from __future__ import annotations

from dataclasses import dataclass

from shapedb.config.checks import check as _check
from shapedb.config.checks import is_int as _is_int

__all__ = ["FieldVectorConfig", "product_field_vector"]


@dataclass(frozen=True)
class FieldVectorConfig:
    """The field vector of a record (:mod:`shapedb.signature.field_vector`).

    The vector is read from the inside of the decomposition's field, which a store keeps
    in memory at ingest only when its light fields are those of the field
    (:attr:`shapedb.config.core.Config.light_field_inside`); ingest computes and stores it when
    :attr:`shapedb.config.core.Config.stores_field_vectors` (``enabled`` and such a store).

    Attributes
    ----------
    enabled : bool
        Store each record's field vector (the ``field_vector`` column). False: none
        (stores written before the section read False).
    depth_resolution : int
        Pixels along each side of the depth buffer descriptor's six orthographic depth
        images, in [8, 512].
    depth_frequencies : int
        Fourier coefficients of each depth image kept: ``0 <= u, v`` with ``u + v <=
        depth_frequencies``, in [1, depth_resolution // 2].
    harmonic_shells : int
        Concentric spheres (rings of distance to the volume centroid, up to twice the
        mean distance) of the spherical-harmonic energies, in [1, 256].
    harmonic_bands : int
        Harmonic degrees ``l < harmonic_bands`` per sphere, in [1, 32].
    harmonic_angles : int
        Polar cells of the angle grid the directions are snapped to (twice as many in
        azimuth), in [8, 128].
    """

    enabled: bool = False
    depth_resolution: int = 64
    depth_frequencies: int = 8
    harmonic_shells: int = 32
    harmonic_bands: int = 16
    harmonic_angles: int = 64

    def __post_init__(self) -> None:
        _check(isinstance(self.enabled, bool), "fv_enabled", self.enabled, "must be true or false")
        ok = _is_int(self.depth_resolution) and 8 <= self.depth_resolution <= 512
        _check(ok, "fv_depth_resolution", self.depth_resolution, "must be an integer in [8, 512]")
        ok = _is_int(self.depth_frequencies) and 1 <= self.depth_frequencies <= (
            self.depth_resolution // 2
        )
        _check(
            ok,
            "fv_depth_frequencies",
            self.depth_frequencies,
            "must be an integer in [1, fv_depth_resolution // 2]",
        )
        ok = _is_int(self.harmonic_shells) and 1 <= self.harmonic_shells <= 256
        _check(ok, "fv_harmonic_shells", self.harmonic_shells, "must be an integer in [1, 256]")
        ok = _is_int(self.harmonic_bands) and 1 <= self.harmonic_bands <= 32
        _check(ok, "fv_harmonic_bands", self.harmonic_bands, "must be an integer in [1, 32]")
        ok = _is_int(self.harmonic_angles) and 8 <= self.harmonic_angles <= 128
        _check(ok, "fv_harmonic_angles", self.harmonic_angles, "must be an integer in [8, 128]")


def product_field_vector() -> FieldVectorConfig:
    """The field vector a new store keeps: enabled, 64 px depth images with frequencies up
    to 8 (438 numbers), 32 spheres x 16 degrees of harmonic energies on a 64 x 128 angle
    grid (512 numbers)."""
    return FieldVectorConfig(enabled=True)
