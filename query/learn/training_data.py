"""Labelled training data of the classifiers, free of torch.

Stratified splits and folds of labels, the contact graphs and descriptors of stored
shapes read back in bulk from the store's Arrow tables, and the training-curve plot.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from shapedb.config.core import Config

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "stratified_split",
    "stratified_folds",
    "StoredGraph",
    "stored_graphs",
    "stored_features",
    "plot_history",
]


def stratified_split(
    labels: Sequence[Any] | NDArray[Any], fractions: Sequence[float], *, seed: int = 0
) -> list[NDArray[np.int64]]:
    """Split indices into parts with the given fractions, class by class.

    Parameters
    ----------
    labels : (n,) sequence
    fractions : sequence of float summing to 1, e.g. (0.7, 0.15, 0.15)
    seed : int

    Returns
    -------
    list of (n_k,) int64 index arrays, one per fraction (every class with at least
    ``len(fractions)`` members has at least one member in each part).
    """
    y = np.asarray(labels)
    rng = np.random.default_rng(seed)
    parts: list[list[int]] = [[] for _ in fractions]
    cum = np.cumsum(fractions) / float(np.sum(fractions))
    for c in sorted(set(y.tolist()), key=str):
        idx = rng.permutation(np.flatnonzero(y == c))
        n = len(idx)
        cuts = [int(round(f * n)) for f in cum[:-1]]
        if n >= len(fractions):  # keep each part non-empty
            for k in range(len(cuts)):
                cuts[k] = min(max(cuts[k], k + 1), n - (len(cuts) - k))
        bounds = [0, *cuts, n]
        for k in range(len(fractions)):
            parts[k].extend(idx[bounds[k] : bounds[k + 1]].tolist())
    return [np.sort(np.asarray(p, dtype=np.int64)) for p in parts]


def stratified_folds(
    labels: Sequence[Any] | NDArray[Any], k: int, *, seed: int = 0
) -> list[NDArray[np.int64]]:
    """``k`` disjoint validation folds covering every index, stratified by class.

    Parameters
    ----------
    labels : (n,) sequence
    k : int
        Number of folds, at least 2.
    seed : int

    Returns
    -------
    list of k (n_f,) int64 index arrays (each class with at least k members has at
    least one member in every fold).
    """
    if k < 2:
        raise ValueError(f"k={k} is invalid: need at least 2 folds")
    return stratified_split(labels, [1.0 / k] * k, seed=seed)


@dataclass(frozen=True, eq=False)
class StoredGraph:
    """A contact graph read back from the store's ``balls`` and ``edges`` tables.

    Attributes
    ----------
    centers : (n, 3) float64
    radii : (n,) float64
    edges : (m, 2) int32
    name : str
    config : Config
    """

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    edges: NDArray[np.int32]
    name: str
    config: Config


def stored_graphs(db: StoreHandle, ids: Sequence[int]) -> list[StoredGraph]:
    """The contact graphs of stored shapes, read in bulk from the Arrow tables.

    Parameters
    ----------
    db : StoreHandle
    ids : sequence of int, length k

    Returns
    -------
    list of k :class:`StoredGraph`, in the order of ``ids``
    """
    store = db.store
    config = db.config
    ids = [int(i) for i in ids]
    shapes = store.shapes(["id", "name"], ids=ids)
    names = dict(
        zip(shapes.column("id").to_pylist(), shapes.column("name").to_pylist(), strict=True)
    )
    balls, edges = store.balls(ids), store.edges(ids)  # sorted by shape id
    b_id = balls.column("shape_id").to_numpy()
    xyzr = np.column_stack([balls.column(c).to_numpy() for c in ("x", "y", "z", "r")])
    e_id = edges.column("shape_id").to_numpy()
    ij = np.column_stack([edges.column("i").to_numpy(), edges.column("j").to_numpy()])
    out = []
    for sid in ids:
        b0, b1 = np.searchsorted(b_id, [sid, sid + 1])
        e0, e1 = np.searchsorted(e_id, [sid, sid + 1])
        out.append(
            StoredGraph(
                centers=xyzr[b0:b1, :3].astype(np.float64),
                radii=xyzr[b0:b1, 3].astype(np.float64),
                edges=ij[e0:e1].astype(np.int32),
                name=str(names.get(sid, sid)),
                config=config,
            )
        )
    return out


def plot_history(
    history: dict[str, list[float]], path: str | os.PathLike[str], *, title: str = ""
) -> Path:
    """Training curve (loss and accuracy, train and validation) as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epochs = np.arange(1, len(history["loss"]) + 1)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    ax1.plot(epochs, history["loss"], label="train")
    ax1.plot(epochs, history["val_loss"], label="validation")
    ax1.set(xlabel="epoch", ylabel="cross-entropy", title="loss")
    ax2.plot(epochs, history["accuracy"], label="train")
    ax2.plot(epochs, history["val_accuracy"], label="validation")
    ax2.set(xlabel="epoch", ylabel="accuracy", title="accuracy", ylim=(0, 1.02))
    for ax in (ax1, ax2):
        ax.legend()
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def stored_features(db: StoreHandle, ids: Sequence[int]) -> NDArray[np.float64]:
    """The stored descriptors (the store's ``feature`` column) of shapes, in bulk.

    Parameters
    ----------
    db : StoreHandle
    ids : sequence of int, length k

    Returns
    -------
    (k, d) float64, row i the feature of ``ids[i]``; d = ``KernelConfig.dim``.
    """
    store = db.store
    all_ids, matrix = store.features()
    order = np.argsort(all_ids, kind="stable")
    want = np.asarray([int(i) for i in ids], dtype=np.int64)
    pos = order[np.searchsorted(all_ids[order], want)] if len(want) else want
    return np.asarray(matrix[pos], dtype=np.float64).reshape(len(want), -1)
