"""The shells of each model's field inside (the cells the field vector reads), cached.

:func:`shells` gives a split's models (those :func:`bench.support.cached.load` has, in its order)
the shell cells of the inside of their MDBD field (:func:`model_inside`: the field of
:func:`shapedb.mdbd.decomposition.prepare_field`, its inside by :func:`shapedb.geometry.inside.field_inside`), with the cell edge, the volume centroid, the inside
cell count and the field's CPU seconds: what :func:`shapedb.signature.field_vector.field_vector`
reads. Cached under ``$SHAPEDB_BENCH_CACHE/field_depth`` keyed by the model's cache key of
:func:`bench.common.cache_path` (the older engines of :data:`bench.support.cached.ENGINE_COMMITS`
are read too) and :data:`VERSION`; :func:`fill` computes what the cache lacks.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import cache_path
from bench.sets.datasets import CACHE_DIR, Dataset
from bench.support.cached import ENGINE_COMMITS
from shapedb.config.core import MDBDConfig
from shapedb.geometry.inside import Inside

__all__ = ["VERSION", "FOLDER", "fill", "shells", "model_inside", "as_inside"]

#: Bump when the cached shells change.
VERSION = "v1"
FOLDER = CACHE_DIR / "field_depth"


def model_inside(model: Any) -> tuple[Inside, float]:
    """A bench model's field inside (as ``decompose(keep_inside=True)`` keeps it) and the
    CPU seconds of its field, at the default :class:`MDBDConfig`."""
    from bench.common import variant_geometry
    from shapedb.geometry.inside import field_inside
    from shapedb.mdbd.decomposition import prepare_field

    cfg = MDBDConfig()
    c0 = time.process_time()
    prep = prepare_field(variant_geometry(model, "mesh", cfg), cfg)
    inside = field_inside(prep.F, prep.grid, prep.frame, prep.scale)
    return inside, time.process_time() - c0


def as_inside(z: Any) -> Inside:
    """The :class:`shapedb.geometry.inside.Inside` of a cached shell (:func:`shells`' dicts)."""
    return Inside(shell=np.asarray(z["shell"], np.float64), cell=float(z["cell"]),
                  centroid=np.asarray(z["centroid"], np.float64), count=int(z["count"]))  # fmt: skip


def _paths(model: Any) -> list[Path]:
    """Today's cache path of a model's shell, then those of the older engines
    (:data:`bench.support.cached.ENGINE_COMMITS`, whose fields are today's)."""
    cfg = MDBDConfig()
    keys = [cache_path(model, "mesh", cfg).stem]
    keys += [cache_path(model, "mesh", cfg, engine_commit=c).stem for c in ENGINE_COMMITS]
    return [FOLDER / f"{k}_{VERSION}.npz" for k in keys]


def _path(model: Any) -> Path:
    """The model's cached shell if any engine's exists, else today's path."""
    paths = _paths(model)
    return next((p for p in paths if p.exists()), paths[0])


def _compute(args: tuple[Any, str]) -> str | None:
    """Worker: the model's field and its inside's shell, written to ``path``."""
    model, path = args
    try:
        inside, field_cpu = model_inside(model)
        tmp = f"{path}.{os.getpid()}.tmp.npz"
        np.savez_compressed(
            tmp, shell=inside.shell.astype(np.float32), cell=np.float64(inside.cell),
            centroid=inside.centroid, count=np.int64(inside.count),
            field_cpu=np.float64(field_cpu),
        )  # fmt: skip
        Path(tmp).replace(path)
    except Exception as exc:  # noqa: BLE001 - reported per model, the run goes on
        return f"{model.name}: {type(exc).__name__}: {exc}"
    return None


def fill(ds: Dataset, *, workers: int = 2) -> None:
    """Compute the shells the cache lacks for ``ds``'s models."""
    from concurrent.futures import ProcessPoolExecutor

    FOLDER.mkdir(parents=True, exist_ok=True)
    todo = [(m, str(_path(m))) for m in ds.models if not _path(m).exists()]
    if not todo:
        return
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for err in pool.map(_compute, todo, chunksize=2):
            if err:
                print(f"  failed {err}", flush=True)
    print(f"  {len(todo)} shells computed ({time.perf_counter() - t0:.0f} s)", flush=True)


def shells(ds: Dataset, *, workers: int = 2) -> list[dict[str, Any]]:
    """Per model of ``ds``: its cached shell (``shell`` (s, 3), ``cell``, ``centroid``,
    ``count``, ``field_cpu``), computing what the cache lacks."""
    fill(ds, workers=workers)
    out = []
    for m in ds.models:
        p = _path(m)
        if not p.exists():
            raise ValueError(f"no field shell for {m.name}")
        with np.load(p) as z:
            out.append({k: np.asarray(z[k]) for k in z.files})
    return out
