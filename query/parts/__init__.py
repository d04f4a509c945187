"""Part search: the index of every node's neighbourhood subgraph and Algorithm 1.

``db.match`` calls :func:`query.parts.match.match`, which finds stored parts like a part
of the query through :class:`PartIndex` and the paper's substructure matching.
"""

from __future__ import annotations

from query.parts.index import PartIndex
from query.parts.match import PartGeometry, match_pairs, part_geometry
from query.parts.store_index import open_parts_index

__all__ = [
    "PartIndex",
    "open_parts_index",
    "PartGeometry",
    "match_pairs",
    "part_geometry",
]
