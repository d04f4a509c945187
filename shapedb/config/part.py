"""Parameters of part search and substructure matching: :class:`PartConfig`.

A part index is built with one (its fingerprint names the index's folder); it embeds a
:class:`~shapedb.config.core.KernelConfig` of its own, the paper's Eq. 1-3 kernel on a
neighbourhood subgraph. Older layouts read through :mod:`shapedb.config.migrations`.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

from shapedb.config import migrations
from shapedb.config.checks import build_section
from shapedb.config.checks import check as _check
from shapedb.config.core import KernelConfig
from shapedb.errors import ConfigError

__all__ = ["PartConfig"]


def _part_kernel() -> KernelConfig:
    return KernelConfig(n_r=10, method="paper")


@dataclass(frozen=True)
class PartConfig:
    """Parameters of substructure matching (paper, section 3.3: K = 2, n_r = 10).

    A part is the neighbourhood subgraph G[N(v, K)] of a node v; it is compared with
    the Eq. 1-3 kernel computed on that subgraph alone (its own largest ball, its own
    random walk), extended by the size and centre blocks.

    Attributes
    ----------
    hops : int
        Neighbourhood range K: nodes within ``hops`` contact edges of v, in [0, 64].
    kernel : KernelConfig
        The part's Eq. 1-3 kernel (method "paper"; default n_r = 10 as in the paper,
        the other fields as :class:`KernelConfig`'s).
    size : float
        Weight of the *size block* appended to the paper's Eq. 1 vector: ``r_i / R``
        of the part's n_r largest balls, ``R`` the largest ball of the whole shape
        (the paper's node attribute r/r1 with the shape's r1), weighted
        ``size * la^i``. Eq. 1 on a subgraph alone normalises by the subgraph's own
        largest ball, so every lone ball (one-node neighbourhood) has the same Eq. 1
        vector; the size block tells them apart by their size relative to the shape.
        0 with ``centre = 0`` gives the paper's vector alone (length 2 n_r). In [0, 100].
    centre : float
        Weight of the *centre block*: ``[r_v / r1, r_v / R]`` of the centre node v of
        N(v, K) (r1 the part's largest ball); 0 leaves it out. In [0, 100].
    contact_tol_cells : float
        Balls closer than this many grid cells are neighbours in a part's graph:
        part matching rebuilds the contacts from the balls
        (:func:`shapedb.signature.subgraph.part_graph`); 0 takes the decomposition's own
        contact graph (``MDBDConfig.contact_tol_cells``). In [0, 8].
    """

    hops: int = 2
    kernel: KernelConfig = field(default_factory=_part_kernel)
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
        _check(
            isinstance(self.kernel, KernelConfig) and self.kernel.method == "paper",
            "kernel",
            self.kernel,
            "must be a KernelConfig of method 'paper' (a part's Eq. 1-3 kernel)",
        )
        _check(0.0 <= self.size <= 100.0, "size", self.size, "must be in [0, 100]")
        _check(0.0 <= self.centre <= 100.0, "centre", self.centre, "must be in [0, 100]")
        _check(
            0.0 <= self.contact_tol_cells <= 8.0,
            "contact_tol_cells",
            self.contact_tol_cells,
            "must be in [0, 8] grid cells (0: the decomposition's own contact graph)",
        )

    @property
    def dim(self) -> int:
        """Length of a part's Eq. 1 vector, 2 * n_r (without the size and centre blocks)."""
        return 2 * self.kernel.n_r

    def with_options(self, **options: Any) -> PartConfig:
        """A copy with some fields changed; kernel fields (``n_r``, ``la``...) go to ``kernel``.

        Raises
        ------
        ConfigError
            For an unknown name or a value out of range.
        """
        own = {f.name for f in fields(PartConfig)} - {"kernel"}
        kernel_names = {f.name for f in fields(KernelConfig)} - {"method"}
        unknown = set(options) - own - kernel_names
        if unknown:
            raise ConfigError(f"unknown part option(s): {sorted(unknown)}")
        if not options:
            return self
        kernel = replace(self.kernel, **{k: v for k, v in options.items() if k in kernel_names})
        return replace(self, kernel=kernel, **{k: v for k, v in options.items() if k in own})

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable dict; ``kernel`` nested."""
        return {**asdict(self), "layout": migrations.PART_LAYOUT}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PartConfig:
        """Inverse of :meth:`to_dict`, also for every layout stored by older versions.

        Raises
        ------
        ConfigError
            When ``data`` has unknown keys or values out of range.
        """
        current = migrations.upgrade_part_config(data)
        kernel = build_section(KernelConfig, current.pop("kernel", {}))
        return build_section(PartConfig, {**current, "kernel": kernel})

    @property
    def fingerprint(self) -> str:
        """Short hash of every parameter (names a part index built with this config)."""
        text = json.dumps(migrations.part_fingerprint_fields(asdict(self)), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]
