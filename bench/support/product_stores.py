"""Stores of the bench's sets built through the product's own ingest, cached, and their scores.

:func:`split_store` ingests a set's split (meshes) into a store of its own with
:meth:`query.database.Database.ingest` and the options given (the default store
when none), and keeps it under ``$SHAPEDB_BENCH_CACHE/stores``, keyed by the split's
models, the resolved configuration and the code of ``shapedb/`` and ``ingest/`` (docstrings
and comments left out), so that a second run only scores. :func:`store_scores` scores a
store as its searches rank (:meth:`Database.evaluate`).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bench.common import code_digest
from bench.sets.datasets import CACHE_DIR, Dataset, mesh_arrays

__all__ = ["STORES_DIR", "store_key", "split_store", "store_scores"]

STORES_DIR = CACHE_DIR / "stores"

_REPO = Path(__file__).resolve().parents[2]


def store_key(ds: Dataset, options: Mapping[str, Any]) -> str:
    """A digest (16 hex) of the split's models, the store's whole configuration (the defaults
    with ``options``) and the code of ``shapedb/`` and ``ingest/`` but its configuration
    module (a changed default changes the configuration, which is in the key)."""
    from shapedb.config.core import Config

    config = Config().with_options(**options).to_dict()
    files = [*_REPO.joinpath("shapedb").rglob("*.py"), *_REPO.joinpath("ingest").rglob("*.py")]
    code = code_digest([f for f in files if f.parent.name != "config"])
    text = json.dumps([[m.source for m in ds.models], config, code], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def split_store(ds: Dataset, options: Mapping[str, Any], *, workers: int = 2) -> Any:
    """The split's meshes in a store with ``options`` (flat store options), built or cached.

    Returns the open :class:`query.database.Database`. A store left half-built by an
    interrupted run is completed (the ingest skips the shapes it already holds).
    """
    import shapedb
    from shapedb.geometry.mesh import TriangleMesh

    path = STORES_DIR / f"{ds.name}_{store_key(ds, options)}"
    done = path / "built.json"
    if done.exists():
        return shapedb.connect(path, create=False)
    t = time.perf_counter()
    db = shapedb.connect(path, **options)
    items = [(m.name, m.label, TriangleMesh(*mesh_arrays(m), name=m.name)) for m in ds.models]
    report = db.ingest(items, workers=workers, progress=False)
    seconds = time.perf_counter() - t
    failed = len(report.failed)
    done.write_text(json.dumps({"models": len(ds), "failed": failed, "seconds": seconds}))
    print(
        f"  {ds.name}: {len(report.ingested)} ingested, {failed} failed, {seconds:.0f} s",
        flush=True,
    )
    return db


def store_scores(db: Any) -> dict[str, Any]:
    """NN / 1-T / 2-T / DCG of a store as its searches rank, with its per-class NN."""
    s = db.evaluate()
    return {
        "nn": s.nn,
        "first_tier": s.first_tier,
        "second_tier": s.second_tier,
        "dcg": s.dcg,
        "queries": s.queries,
        "per_class_nn": {k: v["nn"] for k, v in s.per_class.items()},
    }
