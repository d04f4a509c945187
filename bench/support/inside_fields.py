"""Light fields of the inside of each model's field (``LightFieldConfig.source="field"``), cached.

:func:`light_fields` gives a split's models (those :func:`bench.support.cached.load` has, in its
order) their light fields as a store with ``source="field"`` keeps them: the field of
:func:`shapedb.mdbd.decomposition.prepare_field` (as ``decompose`` computes it), its inside
(:func:`shapedb.geometry.inside.field_inside`) rendered by :func:`shapedb.geometry.inside.inside_light_field`.
Each model is computed once, at two renderings from which every configuration the
benches ask for is cut: 10 light fields at 64 px with the depth images (depth weight 1)
and 10 light fields at 128 px, silhouettes only. Fewer light fields are the first ones
(:func:`shapedb.signature.lightfield.field_rotations` draws the same turns first), and another
depth weight rescales the depth block. Other Zernike orders, Fourier settings, seeds
or fills are not cached (a ``ValueError``). The renderings about the volume centroid
(``LightFieldConfig.centre="volume"``) are computed from the model's field; those about
the shell's mean (``"surface"``) from its cached shell (:mod:`bench.support.field_shells`), in
files of their own that record their centre.

Cached under ``$SHAPEDB_BENCH_CACHE/lightfield_inside``, keyed by the model's cache key
of :func:`bench.common.cache_path` (model, MDBD configuration, engine code; the older
engines of :data:`bench.support.cached.ENGINE_COMMITS` are read too) and :data:`VERSION`, with
the CPU seconds of the field and of the rendering. Fill a split's cache with::

    nice -n 5 python -m bench.support.inside_fields --split validation --datasets web generic
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import cache_path
from bench.sets.datasets import CACHE_DIR, Dataset
from bench.support.cached import CHOICES, ENGINE_COMMITS, load
from bench.support.field_shells import as_inside, model_inside, shells
from shapedb.config.core import LightFieldConfig, MDBDConfig

__all__ = ["VERSION", "light_fields", "fill", "cut"]

#: Bump when the rendering of the cached light fields changes.
VERSION = "v1"
FOLDER = CACHE_DIR / "lightfield_inside"
_BASE = LightFieldConfig(n_fields=10, resolution=64)


def _paths(model: Any, centre: str = "volume") -> list[Path]:
    """Today's cache path of a model's renderings about ``centre``, then those of the
    older engines."""
    cfg = MDBDConfig()
    keys = [cache_path(model, "mesh", cfg).stem]
    keys += [cache_path(model, "mesh", cfg, engine_commit=c).stem for c in ENGINE_COMMITS]
    tail = "" if centre == "volume" else f"_{centre}"
    return [FOLDER / f"{k}_{VERSION}{tail}.npz" for k in keys]


def _render(inside: Any, centre: str, path: str, **extra: Any) -> None:
    """Both renderings of an inside about ``centre``, written to ``path`` atomically."""
    from shapedb.signature.lightfield import inside_light_field

    base = replace(_BASE, centre=centre)
    c1 = time.process_time()
    lf64 = inside_light_field(inside, replace(base, depth_weight=1.0))
    c2 = time.process_time()
    lf128 = inside_light_field(inside, replace(base, resolution=128))
    c3 = time.process_time()
    tmp = f"{path}.{os.getpid()}.tmp.npz"
    np.savez_compressed(
        tmp, lf64=lf64, lf128=lf128, shell=np.int64(len(inside.shell)),
        count=np.int64(inside.count), render64_cpu=np.float64(c2 - c1),
        render128_cpu=np.float64(c3 - c2), centre=np.str_(centre), **extra,
    )  # fmt: skip
    Path(tmp).replace(path)


def _compute(args: tuple[Any, str]) -> str | None:
    """Worker: the model's field, its inside and both renderings about the volume
    centroid; written to ``path``."""
    model, path = args
    try:
        inside, field_cpu = model_inside(model)
        _render(inside, "volume", path, field_cpu=np.float64(field_cpu))
    except Exception as exc:  # noqa: BLE001 - reported per model, the run goes on
        return f"{model.name}: {type(exc).__name__}: {exc}"
    return None


def _compute_shell(args: tuple[Any, dict[str, Any], str, str]) -> str | None:
    """Worker: both renderings of a cached shell about ``centre``; written to ``path``."""
    name, z, centre, path = args
    try:
        _render(as_inside(z), centre, path, field_cpu=np.float64(z["field_cpu"]))
    except Exception as exc:  # noqa: BLE001 - reported per model, the run goes on
        return f"{name}: {type(exc).__name__}: {exc}"
    return None


def fill(name: str, split: str, *, workers: int = 2, centre: str = "volume") -> Dataset:
    """Compute what the cache lacks for a split's models (those :func:`load` has), about
    ``centre`` (``LightFieldConfig.centre``)."""
    from concurrent.futures import ProcessPoolExecutor

    ds, _ = load(name, split)
    FOLDER.mkdir(parents=True, exist_ok=True)
    missing = [i for i, m in enumerate(ds.models)
               if not any(p.exists() for p in _paths(m, centre))]  # fmt: skip
    if not missing:
        return ds
    t0 = time.perf_counter()
    if centre == "volume":
        fn: Any = _compute
        todo: list[Any] = [(ds.models[i], str(_paths(ds.models[i])[0])) for i in missing]
    else:  # from the cached shells (computing those the shell cache lacks)
        got = shells(ds, workers=workers)
        fn = _compute_shell
        todo = [(ds.models[i].name, got[i], centre, str(_paths(ds.models[i], centre)[0]))
                for i in missing]  # fmt: skip
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for err in pool.map(fn, todo, chunksize=2):
            if err:
                print(f"  failed {err}", flush=True)
    print(f"  {name} {split}: {len(todo)} fields rendered about the {centre} centre "
          f"({time.perf_counter() - t0:.0f} s)", flush=True)  # fmt: skip
    return ds


def cut(z: Any, config: LightFieldConfig) -> NDArray[np.float32]:
    """The light fields of ``config`` cut from a cached model's two renderings.

    Raises
    ------
    ValueError
        If ``config`` differs from the cached renderings in anything but ``n_fields``,
        ``resolution`` (64 or 128), ``depth_weight`` (64 px only) and the fills, or sees
        the field about another centre (renderings without a recorded centre are the
        volume centroid's).
    """
    fixed = ("zernike_order", "fourier", "angles", "fourier_weight", "seed", "dilate_px",
             "close_px")  # fmt: skip
    if any(getattr(config, f) != getattr(_BASE, f) for f in fixed):
        raise ValueError(f"light fields of {config} are not cached")
    centre = str(z["centre"]) if "centre" in z else "volume"
    if config.centre != centre:
        raise ValueError(f"light fields of {config} are not cached (rendered about the {centre})")
    k = config.n_fields
    if config.resolution == 128 and config.depth_weight == 0:
        return np.asarray(z["lf128"][:k])
    if config.resolution != 64:
        raise ValueError(f"light fields of {config} are not cached (resolution)")
    lf = np.asarray(z["lf64"][:k])
    zern = sum(1 for n in range(config.zernike_order + 1) for _ in range(n % 2, n + 1, 2))
    head = zern + config.fourier
    if config.depth_weight == 0:
        return np.ascontiguousarray(lf[..., :head])
    out = lf.copy()
    out[..., head:] *= np.float32(config.depth_weight)
    return out


def light_fields(
    name: str, split: str, ds: Dataset, config: LightFieldConfig, *, workers: int = 2
) -> NDArray[np.float32]:
    """(n, n_fields, 10, dim) the field-source light fields of ``ds``'s models (a split of
    ``name`` as :func:`load` gives it), computing what the cache lacks.

    Raises
    ------
    ValueError
        If a model's field could not be computed, or ``config`` is not cached (:func:`cut`).
    """
    centre = config.centre
    found = [next((p for p in _paths(m, centre) if p.exists()), None) for m in ds.models]
    if any(p is None for p in found):
        fill(name, split, workers=workers, centre=centre)
        found = [next((p for p in _paths(m, centre) if p.exists()), None) for m in ds.models]
    rows = []
    for m, p in zip(ds.models, found, strict=True):
        if p is None:
            raise ValueError(f"{name} {split}: no field light field for {m.name}")
        with np.load(p) as z:
            rows.append(cut(z, config))
    return np.stack(rows)


def cpu(name: str, split: str, ds: Dataset) -> dict[str, float]:
    """Median CPU seconds per model of the cached field, renderings, shell and inside cells."""
    keys = ("field_cpu", "render64_cpu", "render128_cpu", "shell", "count")
    got: dict[str, list[float]] = {k: [] for k in keys}
    for m in ds.models:
        p = next((p for p in _paths(m) if p.exists()), None)
        if p is not None:
            with np.load(p) as z:
                for k in keys:
                    got[k].append(float(z[k]))
    return {k: float(np.median(v)) if v else float("nan") for k, v in got.items()}


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point: fill the cache of the named sets' splits."""
    ap = argparse.ArgumentParser(prog="python -m bench.support.inside_fields")
    ap.add_argument("--split", nargs="+", default=["validation"], choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=["web"], choices=CHOICES)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--centre",
        default="surface",
        choices=["volume", "surface"],
        help="the centre the field is seen about (LightFieldConfig.centre)",
    )
    args = ap.parse_args(argv)
    for split in args.split:
        for name in args.datasets:
            if name in ("webplus",) and split != "test":
                continue
            ds = fill(name, split, workers=args.workers, centre=args.centre)
            print(f"{name} {split}: {len(ds)} models, medians {cpu(name, split, ds)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
