"""A point cloud ranks as its proxy does: the stored shape its light fields find nearest.

A sparse cloud's decomposition packs the solid its samples enclose, which the stored
decomposition of its model (a mesh's enclosed solid, decomposed from the mesh) matches
less closely than two meshes' match; the stage's terms read from that decomposition
(its stored distance, field vectors and neighbourhoods) then cost a cloud what they
earn a mesh. Its light fields, drawn from its points
(:func:`shapedb.signature.lightfield.cloud_light_field`), find its model, or a shape of
its class, about as often as a mesh's own light fields do.

So the engine (:mod:`query.search.engine`) ranks a point cloud whose light fields come
from its points in two steps: :func:`proxies` takes, among the cloud's first ``K``
re-ranked results (``StageTuning.candidates``), the stored shape nearest to it by light
field distance, its *proxy*; the stored shapes are then ranked as a search for the
proxy ranks them (the proxy first), each hit keeping its stored distance to the cloud's
own feature. The proxy is the cloud's own model when the store holds it, else the
shape that looks most like it. Where the proxy's own search shuts the stage's spread
gate (jointed subjects, whose silhouettes do not tell one subject's poses from
another's) the cloud keeps its own row, ranked with its reconstruction as before.

A cloud so ranked needs no Poisson reconstruction (the engine skips it: no validation
query's results changed without it), which cuts its cost by about a third. The view path of one-sided
scans does not use a proxy (its nearest view names the right class too rarely).

Measured on the validation splits (even, vertex and scanner fall-off clouds through
``db.search``), NN before -> with the proxy. The store holds the cloud's mesh (left out
of the hits): CAPOD 0.950 / 0.950 / 0.850 -> 1.000 / 1.000 / 0.967, parts 0.979 each
way, enclosures 0.774 / 0.762 / 0.690 -> 0.821 / 0.821 / 0.786, generic 0.929 / 0.940 /
0.857 -> 0.978 / 0.984 / 0.907. It does not (every other model of a class stored, the
rest querying; ``python -m bench.studies.cloud_proxy``): CAPOD 0.800 / 0.800 / 0.767 ->
0.933 / 0.967 / 0.867 (meshes 0.967), parts 0.958 / 0.958 / 0.917 -> 0.958 each (0.958),
enclosures 0.778 each -> 0.806 / 0.833 / 0.694 (0.861), generic 0.910 / 0.923 / 0.808 ->
0.987 / 0.987 / 0.885 (0.974).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from query.search.rerank_lightfield import COLUMN

__all__ = ["proxies"]


def proxies(
    light_fields: NDArray[np.float64], candidates: NDArray[np.int64], arrays: Any
) -> NDArray[np.int64]:
    """Each query's proxy: the candidate nearest to it by light field distance.

    Parameters
    ----------
    light_fields : (q, fields, 10, d) float64
        The queries' light fields (a cloud's drawn from its points).
    candidates : (q, c) int64
        Each query's candidate ids, -1 pads.
    arrays : ArrayReader
        The store's per-record arrays (:func:`query.search.rerank_lightfield.stored_arrays`),
        read for the candidates' light fields.

    Returns
    -------
    (q,) int64
        The proxy's id, -1 where a query has no light fields or no candidate has any
        (ties: the first in list order).
    """
    from shapedb.signature.lightfield import light_field_distance

    lf = np.asarray(light_fields, np.float64)
    cand = np.asarray(candidates, np.int64)
    out = np.full(len(cand), -1, np.int64)
    for row in range(len(cand)):
        ids = cand[row][cand[row] >= 0]
        if not len(ids) or not np.all(np.isfinite(lf[row])):
            continue
        stored = arrays(COLUMN, ids)
        if stored is None:
            continue
        stored = np.asarray(stored, np.float64)
        known = np.all(np.isfinite(stored.reshape(len(ids), -1)), axis=1)
        if not known.any():
            continue
        d = light_field_distance(lf[row][None], stored[known])[0]
        out[row] = int(ids[known][int(np.argmin(d))])
    return out
