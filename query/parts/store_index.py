"""The part index of a store: opened (loaded, brought up to date or built) and kept up to date
by the store's commits.

One :class:`query.parts.index.PartIndex` per :class:`shapedb.config.part.PartConfig`, under
``<store>/parts/<fingerprint>/``, cached in-process per store and configuration. A new
store version adds the new shapes (featurised from the store's balls) and tombstones the
deleted ones; a build reads and featurises the store a batch of shapes at a time.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import threading
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.parts.index import FEATURE_BATCH, PARTS_DIR, PartIndex, read_part_config
from query.search.index import keep_beside
from query.search.versioned import POINTER
from shapedb.config.part import PartConfig
from shapedb.errors import StoreError

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["open_parts_index", "on_commit", "forget"]

log = logging.getLogger(__name__)

_CACHE: dict[tuple[str, str], PartIndex] = {}
_LOCK = threading.Lock()


def _graphs_from_store(
    db: StoreHandle, ids: NDArray[np.int64], cfg: PartConfig
) -> list[tuple[Any, Any]]:
    """(radii, edges) of each stored shape ``ids`` (ascending), read in one go.

    The edges are the stored contact graph's when ``cfg.contact_tol_cells`` is 0, and
    otherwise found again from the balls at that tolerance (:func:`part_graph`).
    """
    from shapedb.mdbd.graph import contact_edges

    if not len(ids):
        return []
    balls = db.store.balls(ids.tolist())
    bs, r = balls.column("shape_id").to_numpy(), balls.column("r").to_numpy()
    ends = np.r_[ids, np.iinfo(np.int64).max]
    b_ptr = np.asarray(np.searchsorted(bs, ends), np.int64)
    if cfg.contact_tol_cells > 0:
        c = np.stack([balls.column(a).to_numpy() for a in ("x", "y", "z")], 1)
        spacing = db.store.shapes(["spacing"], ids=ids.tolist()).column("spacing").to_numpy()
        out = []
        for g in range(len(ids)):
            lo, hi = b_ptr[g], b_ptr[g + 1]
            tol = cfg.contact_tol_cells * float(spacing[g])
            out.append((r[lo:hi], contact_edges(c[lo:hi], r[lo:hi], tol).astype(np.int64)))
        return out
    edges = db.store.edges(ids.tolist())
    es = edges.column("shape_id").to_numpy()
    e = np.stack([edges.column("i").to_numpy(), edges.column("j").to_numpy()], 1)
    e_ptr = np.asarray(np.searchsorted(es, ends), np.int64)
    return [(r[b_ptr[g] : b_ptr[g + 1]], e[e_ptr[g] : e_ptr[g + 1]]) for g in range(len(ids))]


def _build(
    db: StoreHandle, ids: NDArray[np.int64], cfg: PartConfig, root: Path, params: dict[str, Any]
) -> PartIndex:
    """A fresh index of the shapes ``ids``, read and featurised a batch at a time, each
    batch's rows spilled to a scratch directory under ``root`` where it can be written."""
    batches = (
        (ids[b : b + FEATURE_BATCH], _graphs_from_store(db, ids[b : b + FEATURE_BATCH], cfg))
        for b in range(0, len(ids), FEATURE_BATCH)
    )
    scratch = root / f".tmp-build-{uuid.uuid4().hex[:12]}"
    spill: Path | None = scratch
    try:
        scratch.mkdir(parents=True)
    except OSError:
        spill = None  # a store the process may not write: the rows stay in memory
    try:
        index = PartIndex(cfg, **params).fit_batches(batches, spill=spill)
        keep_beside(index, root, db.store.version, "part index")  # links the spilled rows
    finally:
        if spill is not None:
            shutil.rmtree(spill, ignore_errors=True)
    return index


def open_parts_index(
    db: StoreHandle, config: PartConfig | None = None, *, rebuild: bool = False, **params: Any
) -> PartIndex:
    """The store's part index for ``config``, loaded, brought up to date, or built.

    Parameters
    ----------
    db : shapedb.Database
        Uses ``db.store`` (``path``, ``version``, ``ids()``, ``balls()``, ``edges()``).
    config : PartConfig, optional
        Neighbourhood range and kernel; one index per distinct config.
    rebuild : bool
        Build from scratch.
    **params
        :class:`PartIndex` settings for a (re)build.

    Returns
    -------
    PartIndex
        Reflecting ``db.store.version``; cached in-process.
    """
    cfg = config if config is not None else PartConfig()
    store = db.store
    root = Path(os.fspath(store.path)) / PARTS_DIR / cfg.fingerprint
    key = (os.fspath(store.path), cfg.fingerprint)
    with _LOCK:
        version = store.version
        index = None if rebuild else _CACHE.get(key)
        if index is not None and index.version_ == version:
            return index
        if index is None and not rebuild and (root / POINTER).exists():
            try:
                index = PartIndex.load(root)
            except StoreError as exc:
                log.warning("rebuilding the part index: %s", exc)
        if index is not None and index.version_ == version:
            _CACHE[key] = index
            return index
        ids = np.asarray(store.ids(), np.int64)
        if index is None:
            index = _build(db, ids, cfg, root, params)
            action = "built"
        else:
            have = index.shapes_[index.alive_]
            gone = np.setdiff1d(have, ids)
            new = np.setdiff1d(ids, have)
            if len(gone):
                index.remove(gone)
            if len(new):
                index.add(new, _graphs_from_store(db, new, cfg))
            action = f"updated (+{len(new)}, -{len(gone)})"
        keep_beside(index, root, version, "part index")
        log.info("part index %s at store version %s: %r", action, version, index)
        _CACHE[key] = index
        return index


def on_commit(db: StoreHandle, *args: Any, **kwargs: Any) -> None:
    """Commit hook: bring every part index already built for this store up to date."""
    base = Path(os.fspath(db.store.path)) / PARTS_DIR
    if not base.is_dir():
        return
    for sub in base.iterdir():
        if (sub / POINTER).exists():
            try:
                cfg = read_part_config(json.loads((sub / POINTER).read_text())["config"])
            except (OSError, ValueError, KeyError, TypeError) as exc:
                log.warning("skipping part index %s: %s", sub, exc)
                continue
            open_parts_index(db, cfg)


def forget(db: StoreHandle) -> None:
    """Drop the part indexes this process keeps for ``db``'s store (as a new process)."""
    path = os.fspath(db.store.path)
    for key in [k for k in _CACHE if k[0] == path]:
        _CACHE.pop(key, None)
