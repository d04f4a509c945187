"""Maximal Disjoint Ball Decomposition (MDBD) of a solid given by a :class:`Geometry`.

(Contract stub written first so that downstream work can start; the helper that owns
this module fills in :func:`decompose`.)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from shapedb.config import MDBDConfig

if TYPE_CHECKING:
    from shapedb.graph import ContactGraph

__all__ = ["Decomposition", "decompose"]


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
    timings : dict[str, float]
        Seconds per stage ("sdf", "decompose", "graph").
    """

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    edges: NDArray[np.int32]
    spacing: float
    bounds: NDArray[np.float64]
    config: MDBDConfig = field(default_factory=MDBDConfig)
    representation: str = "unknown"
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def n_balls(self) -> int:
        """Number of balls n."""
        return int(len(self.radii))

    @cached_property
    def graph(self) -> ContactGraph:
        """The contact graph of the balls."""
        from shapedb.graph import ContactGraph

        return ContactGraph(self.centers, self.radii, self.edges)


def decompose(geometry, *, config: MDBDConfig | None = None, **options):  # type: ignore[no-untyped-def]
    raise NotImplementedError("being written")
