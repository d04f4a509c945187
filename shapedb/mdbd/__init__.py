"""The Maximal Disjoint Ball Decomposition and its contact graph.

:func:`decompose` packs disjoint balls on a solid's field (greedy packing, then off-grid
refinement, in the solid's canonical frame) and returns a :class:`Decomposition` whose
:class:`ContactGraph` links the balls that touch (paper, section 2.2).
"""

from __future__ import annotations

from shapedb.mdbd.decomposition import Decomposition, decompose
from shapedb.mdbd.graph import ContactGraph, contact_edges

__all__ = [
    "Decomposition",
    "decompose",
    "ContactGraph",
    "contact_edges",
]
