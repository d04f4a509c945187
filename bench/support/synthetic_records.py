"""Store records made fast from a few hundred real ones, for the scale benchmark.

A real store's records (its decompositions, Eq. 1 descriptors, light fields, field
vectors and surface words) are the seeds. Synthetic record ``i`` is made from one seed ``a`` and a second
seed ``b`` of the same label (any seed when unlabelled):

* **balls**: ``a``'s centres moved by N(0, 3 % of ``a``'s mean radius) per coordinate, its
  radii scaled by exp(N(0, 0.05)) (kept in decreasing order), and between 0 and 10 % of
  its balls left out with their contact edges (the rest renumbered): real-shaped
  packings with varying ball counts;
* **descriptor, light fields, field vector** (and the sparse view's descriptor when the
  seed has one): ``(1 - t) a + t b`` with ``t ~ U(0, 0.3)``, each number then scaled by
  ``1 + N(0, 0.02)``: neighbours that vary continuously within a class instead of
  exact copies of 200 points;
* **surface words**: ``(1 - t) a + t b`` with the same ``t``, no noise (still a histogram);
* name ``syn-<i>-<a's name>``, ``a``'s label, a unique content hash, the store's config.

Nothing here decomposes or renders: a record costs tens of microseconds to make, so the
benchmark's time goes to the product's own write path.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from shapedb.mdbd.decomposition import Decomposition
from shapedb.store.schema import ShapeRecord

__all__ = ["RecordMaker"]

#: Per-coordinate centre noise, as a share of the seed's mean radius.
CENTRE_NOISE = 0.03
#: Standard deviation of the log of the radius scale.
RADIUS_NOISE = 0.05
#: At most this share of a seed's balls is left out.
MAX_DROPPED = 0.10
#: Largest weight of the second seed in the mixed vectors.
MAX_MIX = 0.3
#: Relative noise on every number of the mixed vectors.
VECTOR_NOISE = 0.02


def _mix(
    rng: np.random.Generator, a: NDArray[np.float32] | None, b: NDArray[np.float32] | None, t: float
) -> NDArray[np.float32] | None:
    if a is None:
        return None
    a = np.asarray(a, np.float32)
    if b is None or np.shape(b) != a.shape:
        b = a
    mixed = (1.0 - t) * a + t * np.asarray(b, np.float32)
    return (mixed * (1.0 + VECTOR_NOISE * rng.standard_normal(a.shape))).astype(np.float32)


def _mix_histograms(
    a: NDArray[np.float32] | None, b: NDArray[np.float32] | None, t: float
) -> NDArray[np.float32] | None:
    """The two histograms mixed, still summing to 1 (no noise: a histogram stays one)."""
    if a is None:
        return None
    if b is None or np.shape(b) != np.shape(a):
        b = a
    return ((1.0 - t) * np.asarray(a, np.float32) + t * np.asarray(b, np.float32)).astype(
        np.float32
    )


def _balls(rng: np.random.Generator, d: Decomposition) -> Decomposition:
    n = d.n_balls
    radii = np.asarray(d.radii, np.float64) * np.exp(RADIUS_NOISE * rng.standard_normal(n))
    centres = np.asarray(d.centers, np.float64) + rng.normal(
        0.0, CENTRE_NOISE * float(np.mean(d.radii)), (n, 3)
    )
    drop = int(rng.integers(0, int(MAX_DROPPED * n) + 1))
    keep = np.ones(n, bool)
    if drop and n > drop + 1:
        keep[rng.choice(np.arange(1, n), drop, replace=False)] = False
    new = np.cumsum(keep) - 1
    edges = np.asarray(d.edges, np.int64).reshape(-1, 2)
    edges = new[edges[keep[edges].all(axis=1)]].astype(np.int32)
    order = np.argsort(-radii[keep], kind="stable")  # radii stay in decreasing order
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    edges = np.sort(rank[edges], axis=1).astype(np.int32)
    return replace(
        d,
        centers=centres[keep][order],
        radii=radii[keep][order],
        edges=edges[np.lexsort((edges[:, 1], edges[:, 0]))] if len(edges) else edges,
        tail_centers=np.zeros((0, 3)),
        tail_radii=np.zeros(0),
        inside=None,
    )


class RecordMaker:
    """Makes synthetic records from seed records (see the module docstring).

    Parameters
    ----------
    seeds : sequence of ShapeRecord
        Real records, all of one store's configuration.
    seed : int
        Random seed; record ``i`` depends only on it and ``i``.
    """

    def __init__(self, seeds: Sequence[ShapeRecord], seed: int = 0) -> None:
        if not seeds:
            raise ValueError("RecordMaker needs at least one seed record")
        self.seeds = list(seeds)
        self.seed = int(seed)
        by_label: dict[str | None, list[int]] = defaultdict(list)
        for k, r in enumerate(self.seeds):
            by_label[r.label].append(k)
        self._partners = [by_label[r.label] for r in self.seeds]

    def make(self, i: int) -> ShapeRecord:
        """Synthetic record number ``i`` (no id: the store assigns it)."""
        rng = np.random.default_rng([self.seed, int(i)])
        k = int(rng.integers(len(self.seeds)))
        a, partners = self.seeds[k], self._partners[k]
        b = self.seeds[partners[int(rng.integers(len(partners)))]]
        t = float(rng.uniform(0.0, MAX_MIX))
        feature = _mix(rng, a.feature, b.feature, t)
        assert feature is not None
        return replace(
            a,
            id=None,
            name=f"syn-{int(i):07d}-{a.name}",
            content_hash=f"synthetic-{self.seed}-{int(i)}",
            source=None,
            decomposition=_balls(rng, a.decomposition),
            feature=feature,
            view_feature=_mix(rng, a.view_feature, b.view_feature, t),
            light_field=_mix(rng, a.light_field, b.light_field, t),
            field_vector=_mix(rng, a.field_vector, b.field_vector, t),
            surface_words=_mix_histograms(a.surface_words, b.surface_words, t),
        )

    def batch(self, start: int, count: int) -> list[ShapeRecord]:
        """Records ``start`` .. ``start + count - 1``."""
        return [self.make(i) for i in range(int(start), int(start) + int(count))]
