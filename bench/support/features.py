"""Feature matrices and distances shared by the benchmarks and the studies.

The paper's Eq. 1 vectors of many decompositions, each sparse cloud's kept
reconstruction, plain L1 distance matrices, the even seeded split of a set into
clouds and meshes, and the subset of a set whose decompositions all succeeded.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import Balls, decompose_all, recon_variant
from bench.sets.datasets import Dataset, stable_seed
from shapedb import kernel
from shapedb.config.core import Config, KernelConfig, MDBDConfig
from shapedb.mdbd.reconstruct import volumes_agree

__all__ = ["complete", "kernel_features", "l1_matrix", "mixture_mask", "reconstructions"]

FloatArray = NDArray[np.float64]


def l1_matrix(a: FloatArray, b: FloatArray) -> FloatArray:
    """L1 distances between the rows of ``a`` (n, d) and ``b`` (m, d): (n, m)."""
    out = np.empty((len(a), len(b)))
    for i in range(len(a)):
        out[i] = np.abs(b - a[i]).sum(axis=1)
    return out


def kernel_features(balls: Sequence[Balls], config: KernelConfig | Config) -> FloatArray:
    """Feature vectors pre-multiplied by their weights, so that plain L1 is the distance.

    :func:`shapedb.signature.kernel.features` times :func:`shapedb.signature.kernel.weights` of ``config``
    (the paper's Eq. 1 and 2, or shapedb's descriptor): (n, d).
    """
    w = np.asarray(kernel.weights(config))
    return np.stack([np.asarray(kernel.features(b.decomposition(), config)) * w for b in balls])


def mixture_mask(names: Sequence[str]) -> NDArray[np.bool_]:
    """An even, seeded split of the models into point clouds (True) and meshes."""
    n = len(names)
    mask = np.zeros(n, dtype=bool)
    mask[np.random.default_rng(stable_seed("mixture", n)).permutation(n)[: n // 2]] = True
    return mask


def reconstructions(
    models: Sequence[Any],
    clouds: list[Balls | None],
    mdbd: MDBDConfig,
    *,
    workers: int = 2,
    variant: str | None = None,
) -> list[Balls | None]:
    """Each cloud's kept reconstruction (:mod:`shapedb.mdbd.reconstruct`), else the cloud itself.

    ``variant``: the reconstructions' decomposition variant (default: the paper
    cloud's at a default store's Poisson depth, :func:`bench.common.recon_variant`).

    The cloud itself adds no comparison to the nearest-of rule (``query.search.engine``).
    """
    found = decompose_all(models, variant or recon_variant(), mdbd, workers=workers)
    return [
        r if r is not None and c is not None and volumes_agree(c.radii, r.radii) else c
        for r, c in zip(found, clouds, strict=True)
    ]


def complete(ds: Dataset, *lists: list[Balls | None]) -> tuple[Dataset, list[list[Balls]]]:
    """The models of ``ds`` whose entries in every list are not None, and those lists.

    Prints how many models were left out (a decomposition failed).
    """
    keep = [i for i in range(len(ds)) if all(lst[i] is not None for lst in lists)]
    if len(keep) < len(ds):
        print(f"  {len(ds) - len(keep)} model(s) left out (a decomposition failed)")
    sub = Dataset(ds.name, tuple(ds.models[i] for i in keep))
    return sub, [[lst[i] for i in keep] for lst in lists]  # type: ignore[misc]
