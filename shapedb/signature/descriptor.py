"""shapedb's default shape descriptor: distributions over the whole decomposition.

The default similarity (``KernelConfig(method="mdbd")``); the paper's Eq. 1-3 kernel
stays available as ``method="paper"``. How it compares with the paper's kernel and
the baselines, and how each version was chosen, is measured in ``docs/results.md``
("Retrieval"); the blocks tried and dropped are in ``docs/studies.md``.

Everything is computed from the balls and their contact graph only, so it stays
representation-agnostic. Lengths are divided by ``s = (sum r_i^3)^(1/3)`` (scale
invariance without hinging on one ball); balls count by their volume fraction
``v_i = r_i^3 / sum r^3``, so the many small balls, whose number depends on the
resolution and the ball budget, carry little. 1-D distributions are stored as
cumulative histograms times the bin width, so that L1 between them is the 1-D
Wasserstein (earth mover's) distance: small shifts of a value move the distance
a little instead of jumping between bins. Centre distances are rotation invariant.

Blocks (each divided by its typical distance, then weighted)

=================  ====  ======================================================
block              dim   content
=================  ====  ======================================================
``radius``         30    CDF of log2(r / s), volume-weighted
``d2c``            40    CDF of centre-pair distances / s (D2 on balls)
``d2c_mean``       30    CDF of centre-pair distances / their weighted mean
``d1c``            30    CDF of centre distances from the volume centroid, / s
``inertia``        3     sqrt of the sorted eigenvalues of the balls' second moments, / s
``walk``           90    CDFs of log2 of the paper's walk averages at t = 1, 3, 10 (w = 0.9)
``paper``          64    Eq. 1 with flat weights: n_r = 32, t = 20, w = 0.7, la = lb = 1
``paper_sorted``   64    the same with its walk averages sorted in decreasing order
``geodesic``       48    CDF of geodesic centre-pair distances / s (see below)
``geodesic_mean``  30    CDF of geodesic centre-pair distances / their weighted mean
``union``          128   spherical-harmonic energies of the ball union (version 5;
                         :mod:`shapedb.signature.union`: 16 shells x degrees 0-7)
=================  ====  ======================================================

Geodesic distances run along the contact graph, each edge as long as the distance
between its balls' centres (Dijkstra from the 400 largest balls): the inner distance
of the ball union, which an articulation (a bent limb) does not change. A pair in two
components of the graph counts as three times its straight distance apart.

The whole vector is compared with plain L1 (what the faiss index and the SQL
macros compute) and scaled so that a typical pair of unrelated shapes is at
distance ln(10), i.e. has similarity exp(-d) of about 0.1 with ``lam = 1``.

Versions (``DescriptorConfig.version``; a store records the version its features were
computed with, and refuses to mix them). Weights and typical distances per version
are :data:`LAYOUTS`:

* **7** (opt-in): version 4 plus the ``views`` block (:mod:`shapedb.signature.union_views`,
  weight 8): what the ball union looks like from outside, for collections of rigid
  objects. Weight chosen on the validation splits of the rigid sets
  (``python -m bench.union_select --block views``); not the default because, like
  version 5, it costs the jointed figures (a pose changes the silhouettes).
* **6** (opt-in): version 4 without the pose blocks ``d2c_mean`` and ``inertia``
  (:data:`POSE_BLOCKS`): the shape of the centre-distance distribution relative to
  its mean, and the balls' principal extents, follow the pose of a jointed shape
  more than the shape, so without them a scan of a person finds its person rather
  than another person in its pose (``python -m bench.studies.cloud_weights``).
* **5** (opt-in): version 4 plus the ``union`` block (:mod:`shapedb.signature.union`, weight 4):
  where the balls' volume lies around its centroid, at the scale of the parts. Chosen
  on the validation splits (``python -m bench.union_select``); not the default because
  it costs the jointed figures (docs/results.md, docs/studies.md).
* **4** (default): version 3 with ``paper_sorted`` (weight 6) instead of ``paper``:
  sorted, the walk averages no longer depend on which of two near-equal balls the
  packing listed first.
* **3**: version 2 plus ``geodesic`` (weight 2) and ``geodesic_mean`` (1).
* **2**: radius 4, d2c 1, d2c_mean 2, inertia 2, walk 2, paper 8 (no d1c).
* **1**: radius, d2c_mean, d1c, walk 1 each; inertia, paper 2.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from shapedb.mdbd.graph import ContactGraph
from shapedb.signature.union import BANDS, SHELLS, union_features
from shapedb.signature.union_views import view_dim, view_features

__all__ = ["describe", "dim", "DIM", "BLOCKS", "LAYOUTS", "POSE_BLOCKS", "VERSION"]

FloatArray = NDArray[np.float64]

_LOG_BINS = np.linspace(-7.0, 0.5, 31)
_MEAN_BINS = np.linspace(0.0, 3.0, 31)
_DIST_BINS = np.linspace(0.0, 4.0, 41)
_D1_BINS = _DIST_BINS[:31] * 0.75
_WALK_BINS = np.linspace(-12.0, 0.5, 31)
_WALK_STEPS = (1, 3, 10)
_PAIR_LIMIT = 400  # centre pairs among the 400 largest balls (volume-weighted anyway)
_GEO_BINS = np.linspace(0.0, 6.0, 49)
_GEO_MEAN_BINS = np.linspace(0.0, 3.0, 31)
#: A pair in two components of the contact graph counts as this many times its
#: straight distance apart.
_DISCONNECTED = 3.0

Layout = tuple[tuple[str, int, float, float], ...]

#: Typical distance and weight of version 4's ``paper_sorted`` block.
PAPER_SORTED_TYPICAL = 3.791
PAPER_SORTED_WEIGHT = 6.0
#: Walk averages of balls whose radii are within this fraction of the previous
#: ball's are sorted together (1: all of them; smaller values are what
#: ``python -m bench.studies.select_descriptors --sorted-walks`` compares).
WALK_TIE = 1.0

#: Per version, (name, dimension, typical L1 distance, weight) of each block.
#: Typical distances are the geometric means over the three validation sets of the
#: median pairwise distance (``bench/studies/select_descriptors.py``; versions 2 and 3
#: with the current engine); weights are the selected combination.
_VERSION_2: Layout = (
    ("radius", 30, 0.290, 4.0),
    ("d2c", 40, 0.255, 1.0),
    ("d2c_mean", 30, 0.0712, 2.0),
    ("inertia", 3, 0.604, 2.0),
    ("walk", 90, 0.950, 2.0),
    ("paper", 64, 4.461, 8.0),
)
LAYOUTS: dict[int, Layout] = {
    1: (
        ("radius", 30, 0.244, 1.0),
        ("d2c_mean", 30, 0.0631, 1.0),
        ("d1c", 30, 0.208, 1.0),
        ("inertia", 3, 0.614, 2.0),
        ("walk", 90, 0.886, 1.0),
        ("paper", 64, 3.955, 2.0),
    ),
    2: _VERSION_2,
    3: _VERSION_2 + (("geodesic", 48, 0.383, 2.0), ("geodesic_mean", 30, 0.0752, 1.0)),
    4: tuple(
        ("paper_sorted", 64, PAPER_SORTED_TYPICAL, PAPER_SORTED_WEIGHT) if b[0] == "paper" else b
        for b in _VERSION_2
    )
    + (("geodesic", 48, 0.383, 2.0), ("geodesic_mean", 30, 0.0752, 1.0)),
}
#: Typical distance and weight of version 5's ``union`` block (:mod:`shapedb.signature.union`).
UNION_TYPICAL = 5.069
UNION_WEIGHT = 4.0
LAYOUTS[5] = LAYOUTS[4] + (("union", SHELLS * BANDS, UNION_TYPICAL, UNION_WEIGHT),)
#: Typical distance and weight of version 7's ``views`` block (:mod:`shapedb.signature.union_views`).
VIEWS_TYPICAL = 4.722
VIEWS_WEIGHT = 8.0
LAYOUTS[7] = LAYOUTS[4] + (("views", view_dim(), VIEWS_TYPICAL, VIEWS_WEIGHT),)
#: Blocks that tell poses apart more than shapes: version 6 leaves them out.
POSE_BLOCKS = ("d2c_mean", "inertia")
LAYOUTS[6] = tuple(b for b in LAYOUTS[4] if b[0] not in POSE_BLOCKS)
#: The default version (``DescriptorConfig().version``).
VERSION: int = 4
BLOCKS: Layout = LAYOUTS[VERSION]


def dim(version: int = VERSION) -> int:
    """Length of the descriptor of ``version``."""
    return sum(b[1] for b in LAYOUTS[version])


DIM: int = dim(VERSION)


def _cdf(values: FloatArray, weights: FloatArray, edges: FloatArray) -> FloatArray:
    h, _ = np.histogram(np.clip(values, edges[0], edges[-1]), bins=edges, weights=weights)
    total = h.sum()
    c = np.cumsum(h) / total if total > 0 else np.zeros(len(h))
    return c * (edges[1] - edges[0])


def _transition(g: ContactGraph) -> sp.csr_matrix:
    return sp.csr_matrix(g.transition())


def _walk_blocks(g: ContactGraph, p0: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The ``walk`` CDFs (t = 1, 3, 10; w = 0.9) and the flat-weight Eq. 1 vector.

    The Eq. 1 vector is ``[p0_1..p0_32, P_1..P_32]`` over the 32 largest balls (zeros
    past the last ball).
    """
    a = _transition(g)
    # walk CDFs
    p, acc, cdfs = p0.copy(), np.zeros_like(p0), []
    for k in range(1, max(_WALK_STEPS) + 1):
        p = a @ p
        acc += 0.9**k * p
        if k in _WALK_STEPS:
            cdfs.append(_cdf(np.log2(np.maximum(acc / k, 1e-6)), v, _WALK_BINS))
    # Eq. 1 with flat weights (n_r = 32, t = 20, w = 0.7)
    n_r, t, w = 32, 20, 0.7
    p, acc = p0.copy(), np.zeros_like(p0)
    for k in range(1, t + 1):
        p = a @ p
        acc += w**k * p
    paper = np.zeros(2 * n_r)
    m = min(n_r, len(p0))
    paper[:m] = p0[:m]
    paper[n_r : n_r + m] = acc[:m] / t
    return np.concatenate(cdfs), paper


def _sorted_walks(paper: FloatArray, tie: float | None = None) -> FloatArray:
    """The Eq. 1 vector with its walk averages ``P_i`` sorted in decreasing order.

    ``p0`` (radii over r1) is sorted already; sorting ``P`` too makes the vector blind
    to which of two near-equal balls came first, a swap that the packing's chaos
    makes often and that otherwise exchanges two of its entries. ``P`` is sorted
    within runs of balls each within ``tie`` (default :data:`WALK_TIE`) of the
    previous one's radius; ``tie = 1`` sorts it whole.
    """
    n_r = len(paper) // 2
    p0, walks = paper[:n_r], paper[n_r:]
    tie = WALK_TIE if tie is None else tie
    brk = np.concatenate([[False], p0[1:] < p0[:-1] * (1.0 - tie)])
    group = np.cumsum(brk)
    return np.concatenate([p0, walks[np.lexsort((-walks, group))]])


def _geodesics(g: ContactGraph, m: int) -> FloatArray:
    """(m, m) distances along the contact graph between the ``m`` largest balls.

    Each edge is as long as the distance between its balls' centres; pairs in two
    components get ``_DISCONNECTED`` times their straight distance.
    """
    from scipy.sparse import csgraph

    c, e, n = np.asarray(g.centers, dtype=np.float64), g.edges, g.n_nodes
    length = np.linalg.norm(c[e[:, 0]] - c[e[:, 1]], axis=1)
    a = sp.csr_matrix((length, (e[:, 0], e[:, 1])), shape=(n, n))
    d = csgraph.dijkstra(a, directed=False, indices=np.arange(m))[:, :m]
    far = ~np.isfinite(d)
    if far.any():
        straight = np.linalg.norm(c[:m, None, :] - c[None, :m, :], axis=2)
        d[far] = _DISCONNECTED * straight[far]
    return d


def describe(g: ContactGraph, version: int = VERSION) -> FloatArray:
    """The default descriptor of a contact graph: (dim(version),) float64, compared with L1.

    Parameters
    ----------
    g : ContactGraph
        Balls (centres (n, 3), radii (n,), model units) and contacts; nodes must be
        sorted by decreasing radius (as every Decomposition is).
    version : int
        Descriptor version (a key of :data:`LAYOUTS`).
    """
    layout = LAYOUTS[version]
    out = np.zeros(dim(version))
    r = np.asarray(g.radii, dtype=np.float64)
    if len(r) == 0 or not r[0] > 0:
        return out
    names = {b[0] for b in layout}
    c = np.asarray(g.centers, dtype=np.float64)
    vol = r**3
    v = vol / vol.sum()
    s = float(np.cbrt(vol.sum()))
    centroid = v @ c
    x = c - centroid

    blocks: dict[str, FloatArray] = {}
    blocks["radius"] = _cdf(np.log2(r / s), v, _LOG_BINS)
    cl, vl = c[:_PAIR_LIMIT], v[:_PAIR_LIMIT]
    i, j = np.triu_indices(len(cl), 1)
    d = np.linalg.norm(cl[i] - cl[j], axis=1)
    w = vl[i] * vl[j]
    if "d2c" in names:
        blocks["d2c"] = _cdf(d / s, w, _DIST_BINS)
    mean = float((d * w).sum() / max(w.sum(), 1e-300))
    blocks["d2c_mean"] = _cdf(d / max(mean, 1e-300), w, _MEAN_BINS)
    if "d1c" in names:
        blocks["d1c"] = _cdf(np.linalg.norm(x, axis=1) / s, v, _D1_BINS)
    moments = (x * v[:, None]).T @ x + np.eye(3) * float((0.2 * r**2 * v).sum())
    ev = np.sort(np.linalg.eigvalsh(moments))[::-1]
    blocks["inertia"] = np.sqrt(np.maximum(ev, 0.0)) / s
    blocks["walk"], blocks["paper"] = _walk_blocks(g, r / r[0], v)
    if "paper_sorted" in names:
        blocks["paper_sorted"] = _sorted_walks(blocks["paper"])
    if "geodesic" in names:
        gd = _geodesics(g, len(cl))[i, j]
        blocks["geodesic"] = _cdf(gd / s, w, _GEO_BINS)
        gmean = float((gd * w).sum() / max(w.sum(), 1e-300))
        blocks["geodesic_mean"] = _cdf(gd / max(gmean, 1e-300), w, _GEO_MEAN_BINS)

    if "union" in names:
        blocks["union"] = union_features(c, r)
    if "views" in names:
        blocks["views"] = view_features(c, r)

    calibration = np.log(10.0) / sum(b[3] for b in layout)
    at = 0
    for name, size, typical, weight in layout:
        out[at : at + size] = blocks[name] * (weight / typical * calibration)
        at += size
    return out
