"""The typed configuration a store is built with, and how older stores' read today.

:class:`Config` composes one frozen section per concern (the decomposition, the kernel,
the descriptor's version, sparse clouds, whether searches re-rank, the light fields,
field vectors and surface words kept per record); it is stored with every record, so a store knows how it
was built. :mod:`shapedb.config.migrations` is the one place that reads older layouts.
"""

from __future__ import annotations

from shapedb.config.core import (
    OPTIONS,
    CloudConfig,
    Config,
    DescriptorConfig,
    FieldVectorConfig,
    KernelConfig,
    LightFieldConfig,
    MDBDConfig,
    RerankConfig,
    SurfaceWordsConfig,
    parse_options,
)
from shapedb.config.part import PartConfig

__all__ = [
    "Config",
    "MDBDConfig",
    "KernelConfig",
    "DescriptorConfig",
    "CloudConfig",
    "RerankConfig",
    "LightFieldConfig",
    "FieldVectorConfig",
    "SurfaceWordsConfig",
    "PartConfig",
    "OPTIONS",
    "parse_options",
]
