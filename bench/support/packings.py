"""Decompositions continued past their balls (the light fields of a longer packing), cached.

:func:`longer` gives a split's models (those :func:`bench.support.cached.load` has) decomposed as
ingest does in a store whose ``LightFieldConfig.n_balls`` exceeds ``MDBDConfig.n_balls``:
``shapedb.mdbd.decomposition.decompose(tail_balls=...)``, the decomposition's balls then the tail (each
part by decreasing radius). Cached under ``$SHAPEDB_BENCH_CACHE/lightfield_pack`` (keyed by
the model, the default MDBD configuration, the engine's code and the tail; the older
engines of :data:`bench.support.cached.ENGINE_COMMITS` are read too).
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import Balls, cache_path, variant_geometry
from bench.sets.datasets import CACHE_DIR, Dataset
from bench.support.cached import ENGINE_COMMITS, load
from shapedb.config.core import MDBDConfig

__all__ = ["longer"]


def _decompose_longer(args: tuple[Any, int, str]) -> str | None:
    """Worker: decompose ``model`` with ``tail`` tail balls; write its balls and tail."""
    from shapedb.mdbd.decomposition import decompose

    model, tail, path = args
    try:
        cfg = MDBDConfig()
        d = decompose(variant_geometry(model, "mesh", cfg), config=cfg, tail_balls=tail)
        c, r = d.longer_packing()
        tmp = f"{path}.{os.getpid()}.tmp.npz"
        np.savez_compressed(tmp, centers=c, radii=r, main=np.int64(d.n_balls),
                            spacing=np.float64(d.spacing))  # fmt: skip
        Path(tmp).replace(path)
    except Exception as exc:  # noqa: BLE001 - reported per model, the run goes on
        return f"{model.name}: {type(exc).__name__}: {exc}"
    return None


def _path(folder: Path, model: Any, tail: int) -> Path:
    """Today's cache path of a model's longer packing, else an older engine's that exists
    (:data:`bench.support.cached.ENGINE_COMMITS`: engines whose balls today's reproduce)."""
    cfg = MDBDConfig()
    keys = [cache_path(model, "mesh", cfg)]
    keys += [cache_path(model, "mesh", cfg, engine_commit=c) for c in ENGINE_COMMITS]
    paths = [folder / f"{k.stem}_t{tail}.npz" for k in keys]
    return next((p for p in paths if p.exists()), paths[0])


def longer(
    name: str, split: str, tail: int, *, workers: int = 2, within: int = 0
) -> tuple[Dataset, list[Balls], list[int]]:
    """A split's models (those cached today) with the decomposition's balls then ``tail``
    more (radius order inside each part), cached under ``$SHAPEDB_BENCH_CACHE/lightfield_pack``;
    and each model's number of decomposition balls.

    ``within`` > ``tail``: the first ``tail`` tail balls (by radius) of the packing
    continued for ``within`` (one decomposition serves several lengths; near-ties of the
    greedy order can make a few balls differ from a packing stopped at ``tail``).
    """
    from concurrent.futures import ProcessPoolExecutor

    keep_tail = tail
    tail = max(tail, within)

    ds, _ = load(name, split)
    folder = CACHE_DIR / "lightfield_pack"
    folder.mkdir(parents=True, exist_ok=True)
    paths = [_path(folder, m, tail) for m in ds.models]
    todo = [(m, tail, str(p)) for m, p in zip(ds.models, paths, strict=True) if not p.exists()]
    if todo:
        t0 = time.perf_counter()
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for err in pool.map(_decompose_longer, todo, chunksize=4):
                if err:
                    print(f"  failed {err}")
        print(f"  {name} {split}: {len(todo)} decomposed with {tail} tail balls "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)  # fmt: skip
    keep, balls, main = [], [], []
    for i, p in enumerate(paths):
        if p.exists():
            with np.load(p) as z:
                k = int(z["main"]) + keep_tail
                keep.append(i)
                balls.append(Balls(z["centers"][:k], z["radii"][:k], np.zeros((0, 2), np.int64),
                                   float(z["spacing"]), 0.0))  # fmt: skip
                main.append(int(z["main"]))
    return Dataset(ds.name, tuple(ds.models[i] for i in keep)), balls, main


def light_field_balls(
    name: str, split: str, ds: Dataset, balls: list[Any], config: Any, *, within: int = 0
) -> list[Any]:
    """The balls a store of ``config`` renders each model's light fields from.

    ``balls`` (a split's cached decompositions, in ``ds``'s order) themselves when
    ``config.light_field_tail`` is 0; else each model's packing continued as ingest
    continues it (:func:`longer`, ``within`` as there, in total balls), the model's own
    balls where that failed.
    """
    tail = int(config.light_field_tail)
    if not tail:
        return list(balls)
    got, more, _ = longer(name, split, tail, within=max(within - config.mdbd.n_balls, 0))
    by = dict(zip((m.name for m in got.models), more, strict=True))
    return [by.get(m.name, b) for m, b in zip(ds.models, balls, strict=True)]
