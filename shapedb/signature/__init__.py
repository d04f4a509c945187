"""What a decomposition is compared by: its signatures and their distances.

shapedb's descriptor (distributions over the balls and the contact graph), the paper's
Eq. 1-3 kernel, the light fields (silhouettes) of the packed solid, its field vector
(depth buffers and spherical harmonics), and the Eq. 1 features of neighbourhood
subgraphs that part search indexes.
"""

from __future__ import annotations

from shapedb.signature.descriptor import describe
from shapedb.signature.field_vector import decomposition_field_vector
from shapedb.signature.kernel import distance, features, features_batch, weights
from shapedb.signature.lightfield import decomposition_light_field, light_field_distance
from shapedb.signature.subgraph import neighbourhood_features, neighbourhoods

__all__ = [
    "describe",
    "features",
    "features_batch",
    "weights",
    "distance",
    "decomposition_light_field",
    "light_field_distance",
    "decomposition_field_vector",
    "neighbourhoods",
    "neighbourhood_features",
]
