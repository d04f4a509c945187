"""The store's feature index (:class:`query.search.feature_index.FeatureIndex`), kept in
step with the store.

On disk (:func:`open_index`) the index lives in ``<store>/index/``: a pointer file
``current.json`` (replaced atomically) naming a directory ``v<version>-<token>/``
with ``faiss.index``, ``ids.npy``, ``features.npy``, ``alive.npy`` and ``segs.npy``.
The pointer records the store version and the ``shapes`` segment files the index
reflects; when the store has moved on, only the segments it has not read are read
(:mod:`query.search.index_segments`): new ids are added, changed and deleted ones
tombstoned, and the index is rebuilt from its own live vectors when it is flat with
tombstones, HNSW and a fifth dead, or ``"auto"`` and of the other size
(:meth:`FeatureIndex.settle`). It is written again only once the changes since the saved
copy pass :data:`_RESAVE_FRACTION` of it; a new process loads the saved copy and reads
the few newer segments. A store the process cannot write keeps it in memory (one
warning each time it would be written).
"""

from __future__ import annotations

import logging
import os
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.search import field_rows, index_segments
from query.search.feature_index import FeatureIndex
from query.search.versioned import POINTER
from shapedb.errors import ConfigError, StoreError

if TYPE_CHECKING:
    from query.learn.metric import LearnedMetric
    from shapedb.config.core import Config
    from shapedb.store.handle import StoreHandle

__all__ = [
    "FeatureIndex", "open_index", "build_index", "on_commit", "keep_beside", "forget", "INDEX_DIR"
]  # fmt: skip

log = logging.getLogger(__name__)

INDEX_DIR = "index"
#: Where the index over the shapes' sparse-view features lives (stores with views).
VIEW_INDEX_DIR = "index_view"
#: An update is written to disk once the changes since the saved index pass this fraction
#: of it (as the field vector index: below it a new process re-reads those few segments).
_RESAVE_FRACTION = 0.02


# ------------------------------------------------------------------ store glue
_CACHE: dict[str, tuple[Config, FeatureIndex]] = {}
_LOCK = threading.Lock()


def _store_key(db: StoreHandle) -> str:
    return os.fspath(db.store.path)


def open_index(
    db: StoreHandle,
    *,
    kind: str | None = None,
    rebuild: bool = False,
    view: bool = False,
    metric: LearnedMetric | None = None,
    **params: Any,
) -> FeatureIndex:
    """The store's feature index, loaded, updated to the store's version, or built.

    Parameters
    ----------
    db : shapedb.Database
        Uses ``db.store`` (``path``, ``version``; the segments its manifest lists are
        read through :mod:`query.search.field_rows`) and ``db.config``.
    kind : {"auto", "flat", "hnsw"}, optional
        Force an index type (rebuilding if the current one differs).
    rebuild : bool
        Rebuild from scratch even when up to date.
    view : bool
        The index over the shapes' sparse-view features (each shape's own feature
        where it has no view; :mod:`shapedb.geometry.view`), kept in ``<store>/index_view/``.
    metric : LearnedMetric, optional
        Weigh the distance by a learned metric (:mod:`query.learn.metric`): an index of its
        own, kept in ``<store>/index_metric_<digest>/`` (``index_view_metric_...``
        for views) and brought up to date lazily, at its next search. The identity
        metric is the plain index.
    **params
        Other :class:`FeatureIndex` settings for a (re)build.

    Returns
    -------
    FeatureIndex
        Up to date with ``db.store.version`` (or a later one); cached in-process per
        store path. An update reads only the segments the index has not read.
    """
    store = db.store
    root = Path(_store_key(db))
    config = db.config
    w, suffix = _weights(config, metric)
    key = _store_key(db) + ("#view" if view else "") + suffix
    directory = root / ((VIEW_INDEX_DIR if view else INDEX_DIR) + suffix)
    with _LOCK:
        version = store.version
        cached = None if rebuild else _CACHE.get(key)
        shared = False  # whether ``index`` is the cached one, which searches may be using
        if cached is not None and cached[0] == config and kind in (None, cached[1].kind):
            if cached[1].version_ == version:
                return cached[1]
            index: FeatureIndex | None = cached[1]
            shared = True
        else:
            index = None if rebuild else _load(directory)
        if index is not None and (
            index.weights_.shape != w.shape
            or not np.allclose(index.weights_, w, rtol=1e-12, atol=0)
            or kind not in (None, index.kind)
        ):
            index = None  # kernel configuration or requested type changed
        if index is None or index.version_ != version:
            settings = {**params, "kind": kind or params.get("kind", "auto")}
            base = index

            def bring(snap: field_rows.Snapshot) -> tuple[FeatureIndex, str]:
                return _brought_to(base, shared, snap, w, view=view, settings=settings)

            index, action = field_rows.consistent(db, bring)
            if action in ("built", "rebuilt") or index.unsaved_ > _RESAVE_FRACTION * len(
                index.ids_
            ):
                keep_beside(index, directory, index.version_ or 0, "feature index")
            log.info("feature index %s at store version %s: %r", action, version, index)
        _CACHE[key] = (config, index)
        return index


def _brought_to(
    base: FeatureIndex | None,
    shared: bool,
    snap: field_rows.Snapshot,
    w: NDArray[np.float64],
    *,
    view: bool,
    settings: dict[str, Any],
) -> tuple[FeatureIndex, str]:
    """``base`` at the snapshot (a copy first when it is ``shared`` and its rows change),
    or a fresh build; with what was done: "built", "unchanged", "updated" or "rebuilt"."""
    if base is None:
        index, action = index_segments.build(FeatureIndex(**settings), snap, w, view=view), "built"
    elif base.segments_ == snap.files:  # no shape changed (a commit of failures only)
        index, action = base, "unchanged"
    else:
        index = base.copy() if shared else base
        index_segments.catch_up(index, snap, view=view)
        action = index.settle()
    index.version_ = snap.version
    return index, action


def keep_beside(index: Any, directory: Path, version: int, what: str) -> None:
    """Save a derived index beside its store; a store the process may not write (read-only
    media, another user's files) keeps it in memory only, with one warning."""
    try:
        index.save(directory, version=version)
    except OSError as exc:
        log.warning("%s kept in memory only: cannot write %s (%s)", what, directory, exc.strerror)


def _weights(config: Any, metric: LearnedMetric | None) -> tuple[NDArray[np.float64], str]:
    """The distance's per-number weights (the kernel's, times a learned metric's) and the
    suffix of the metric's own index directory ("" for the plain index)."""
    from shapedb.signature.kernel import weights

    w = np.asarray(weights(config), dtype=np.float64)
    if metric is None or not metric.learned:
        return w, ""
    if metric.dim != w.shape[0]:
        raise ConfigError(
            f"the metric weighs {metric.dim}-long vectors, the store's are {w.shape[0]}",
            source="metric",
        )
    return w * metric.dim_weights(), f"_metric_{metric.digest}"


def _load(root: Path) -> FeatureIndex | None:
    if not (root / POINTER).exists():
        return None
    try:
        return FeatureIndex.load(root)
    except StoreError as exc:
        log.warning("rebuilding the feature index: %s", exc)
        return None


def build_index(db: StoreHandle, *, kind: str = "auto", **params: Any) -> FeatureIndex:
    """Rebuild the store's index from scratch with the given settings."""
    return open_index(db, kind=kind, rebuild=True, **params)


def on_commit(db: StoreHandle, *args: Any, **kwargs: Any) -> None:
    """Store commit hook (entry point ``on_commit``): update an existing index.

    Only an index that was already built is updated (incrementally when possible);
    a store that was never searched gets its index lazily on the first search, and
    the indexes of learned metrics are updated at their next search.
    """
    for view, directory in ((False, INDEX_DIR), (True, VIEW_INDEX_DIR)):
        key = _store_key(db) + ("#view" if view else "")
        if key in _CACHE or (Path(_store_key(db)) / directory / POINTER).exists():
            open_index(db, view=view)


def forget(db: StoreHandle) -> None:
    """Drop the feature indexes this process keeps for ``db``'s store (as a new process)."""
    root = _store_key(db)
    for key in [k for k in _CACHE if k == root or k.startswith(root + "#")]:
        _CACHE.pop(key, None)
