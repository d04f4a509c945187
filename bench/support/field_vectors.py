"""The field vectors of the ``"lightfield"`` stage, in the gate bench: fused distance, union candidates.

Usage (from the repository root)::

    export SHAPEDB_BENCH_CACHE=/work/bench_cache
    nice -n 5 python -m bench.studies.field_choice --split validation     # the scales (medians)
    nice -n 5 python -m bench.studies.field_choice --choose               # the choice on validation

The product's stage: each record keeps a *field vector*, the depth buffer
descriptor of its field's inside (Vranic: 438 floats at 64 px, ``k`` 8) followed by the
spherical-harmonic energies of the same inside (Kazhdan, on an angle grid: 32 shells x
16 bands). The stage's distance between two shapes is

    ``l + alpha * b + gamma * h``

(``l`` the light field distance, ``b`` and ``h`` the L1 distances of the depth and the
harmonic parts; ``alpha`` and ``gamma`` the fields ``field_depth_weight`` and
``field_harmonic_weight`` of :class:`query.search.tuning.StageTuning`, its unit ``scale``),
and its candidates are version 4's ``K`` nearest followed by those of the ``K2`` nearest
by the L1 distance of the scaled vectors ``[alpha * depth, gamma * harmonic]``
(``field_candidates``) that are not among them, in the stored distance's order.

The research chose weights ``a`` and ``c`` of the three distances each over a fixed scale
(``m_l``, ``m_b``, ``m_h``: their medians), the distance
``m_l * (l / m_l + a * b / m_b + c * h / m_h) / (1 + a + c)``. The distance above is that
one times ``1 + a + c`` with ``alpha = a * m_l / m_b`` and ``gamma = c * m_l / m_h``, in the
unit ``scale = (1 + a + c) * m_l`` (:meth:`FieldStage.at_scales`): the research's settings
(:data:`WEIGHTS`, :data:`SCALES`) are turned into the stage's that way.

:func:`fuse` turns a :class:`bench.support.stores.Split` into that stage's split (its
light field distance replaced by the fused one, the scaled vectors' distance kept for
the candidates); :class:`bench.support.stores.Store` takes the union. The vectors of
the bench models (:func:`shapedb.signature.field_vector.field_vector`) come from the field
shells cached by :mod:`bench.support.field_shells`
(``$SHAPEDB_BENCH_CACHE/field_depth``, computed by :func:`bench.support.field_shells.fill` when missing) and are cached under
``$SHAPEDB_BENCH_CACHE/field_vectors``. :func:`analytic_distance` gives the analytic
stores of :mod:`bench.studies.gate_checks` the same fused distance, so the analytic chain is
checked on it. The choice of the scales, the weights and ``K2`` on validation is
:mod:`bench.studies.field_choice`.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.sets.datasets import CACHE_DIR
from bench.support.cached import load, model_key
from bench.support.field_shells import as_inside

#: A :class:`bench.support.stores.Split` (that module imports this one).
Split = Any

FloatArray = NDArray[np.float64]
FOLDER = CACHE_DIR / "field_vectors"
#: Bump when the cached vectors change.
VERSION = "v1"
#: Floats of the depth buffer descriptor (64 px, ``k`` 8) at the head of a field vector.
DEPTH_DIM = 438
#: Floats of the harmonic energies (32 shells x 16 bands) after it.
HARMONIC_DIM = 32 * 16


#: The research's weights ``a`` and ``c`` of the depth and the harmonic distances: the
#: field vector choice on validation (python -m bench.studies.field_choice).
WEIGHTS = (0.25, 0.25)
#: The research's scales ``m_l``, ``m_b``, ``m_h``: the three distances' medians over each
#: validation set's off-diagonal pairs, then the median of the six sets.
SCALES = (20.67, 6.045, 2.168)


@dataclasses.dataclass(frozen=True)
class FieldStage:
    """The field vectors' part of the stage (the fields of ``StageTuning``).

    Attributes
    ----------
    depth_weight, harmonic_weight : float
        ``alpha`` and ``gamma``, >= 0 (light field units per unit of ``b`` and ``h``).
    scale : float
        The fused distance's unit in the spread and the shared-neighbour term, > 0.
    candidates : int
        ``K2``, the field vectors' nearest added to version 4's ``K``; 0: none.
    """

    depth_weight: float = 0.5
    harmonic_weight: float = 0.5
    scale: float = 1.0
    candidates: int = 100

    @property
    def fuses(self) -> bool:
        """Whether the distance is not the light field's alone."""
        return self.depth_weight > 0 or self.harmonic_weight > 0

    @classmethod
    def at_scales(cls, a: float, c: float, light_field_scale: float, depth_scale: float,
                  harmonic_scale: float, candidates: int = 100) -> FieldStage:  # fmt: skip
        """The stage of the research's weights ``a``, ``c`` at scales ``m_l``, ``m_b``,
        ``m_h`` (> 0): ``alpha = a * m_l / m_b``, ``gamma = c * m_l / m_h``, ``scale = (1 +
        a + c) * m_l`` (the module docstring)."""
        ml, mb, mh = light_field_scale, depth_scale, harmonic_scale
        return cls(a * ml / mb, c * ml / mh, (1.0 + a + c) * ml, candidates)

    @classmethod
    def of(cls, fusion: Any) -> FieldStage | None:
        """The stage of a ``StageTuning`` (None when it has no field vectors)."""
        names = {"depth_weight": "field_depth_weight",
                 "harmonic_weight": "field_harmonic_weight",
                 "scale": "scale", "candidates": "field_candidates"}  # fmt: skip
        if not all(hasattr(fusion, v) for v in names.values()):
            return None
        got = cls(**{k: getattr(fusion, v) for k, v in names.items()})
        return got if got.fuses or got.candidates > 0 else None

    def short(self) -> str:
        """The stage in a few characters."""
        return (f"alpha {self.depth_weight:.4g} gamma {self.harmonic_weight:.4g} "
                f"K2 {self.candidates} scale {self.scale:.4g}")  # fmt: skip


# --------------------------------------------------------------------------------------
# The vectors of the bench models
# --------------------------------------------------------------------------------------


def _describer() -> tuple[Callable[[dict[str, Any]], NDArray[np.float32]], bytes]:
    """The product's field vector of a cached shell
    (:func:`shapedb.signature.field_vector.field_vector`) and its code (for the cache key)."""
    from shapedb.config.field_vector import FieldVectorConfig
    from shapedb.signature import field_vector as fd

    cfg = FieldVectorConfig(enabled=True)

    def product(z: dict[str, Any]) -> NDArray[np.float32]:
        return np.asarray(fd.field_vector(as_inside(z), cfg), np.float32)

    return product, Path(fd.__file__).read_bytes() + repr(cfg).encode()


def set_vectors(name: str, split: str) -> NDArray[np.float32]:
    """(n, 950) float32 field vectors of a set's split (its models in :func:`load`'s order).

    Read from the cache, else computed from the study's cached shells (computing the
    shells the cache lacks).
    """
    from bench.support.field_shells import shells

    ds, _ = load(name, split)
    fn, code = _describer()
    keys = "\n".join(model_key(m) for m in ds.models)
    key = hashlib.sha256(code + VERSION.encode() + keys.encode()).hexdigest()[:16]
    path = FOLDER / f"{name}_{split}_{key}.npy"
    if path.exists():
        return np.load(path)
    t = time.perf_counter()
    out = np.stack([fn(z) for z in shells(ds)]).astype(np.float32)
    if out.shape[1] != DEPTH_DIM + HARMONIC_DIM:
        raise ValueError(f"{name} {split}: field vectors of {out.shape[1]} floats")
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, out)
    print(f"  {name} {split}: {len(out)} field vectors ({time.perf_counter() - t:.0f} s)",
          flush=True)  # fmt: skip
    return out


def l1(x: NDArray[np.float32]) -> FloatArray:
    """(n, n) float64 L1 distances of float32 rows (chunked)."""
    x64 = np.asarray(x, np.float64)
    out = np.empty((len(x64), len(x64)))
    for lo in range(0, len(x64), 64):
        out[lo : lo + 64] = np.abs(x64[lo : lo + 64, None, :] - x64[None, :, :]).sum(-1)
    return out


def parts(vectors: NDArray[np.float32]) -> tuple[FloatArray, FloatArray]:
    """(n, n) L1 distances of the depth parts and of the harmonic parts of the vectors."""
    return l1(vectors[:, :DEPTH_DIM]), l1(vectors[:, DEPTH_DIM:])


def off_median(d: FloatArray) -> float:
    """The median off-diagonal entry of a square matrix."""
    return float(np.median(d[~np.eye(len(d), dtype=bool)]))


# --------------------------------------------------------------------------------------
# The stage's split
# --------------------------------------------------------------------------------------


def fuse(split: Split, names: Sequence[str], stage: FieldStage) -> Split:
    """``split`` as the stage sees it: a shallow copy with ``dl`` the fused distance, ``dv``
    the L1 distance of the scaled field vectors and ``stage`` set (``light`` keeps the
    light field distance)."""
    import copy

    b, h = split_parts(split, names)
    out = copy.copy(split)
    light = split.light
    out.light = light
    out.dl = light + stage.depth_weight * b + stage.harmonic_weight * h
    out.dv = scaled_distance(split, names, stage)
    out.stage = stage
    return out


_PARTS: dict[tuple[str, tuple[str, ...]], tuple[FloatArray, FloatArray]] = {}


def split_parts(split: Split, names: Sequence[str]) -> tuple[FloatArray, FloatArray]:
    """(n, n) ``b`` and ``h`` over the split's shapes (its sets in ``names``' order), kept."""
    key = (split.split, tuple(names))
    if key not in _PARTS:
        v = np.concatenate([set_vectors(n, split.split) for n in names])
        if len(v) != len(split.labels):
            raise ValueError(f"{len(v)} field vectors for {len(split.labels)} shapes")
        _PARTS[key] = parts(v)
    return _PARTS[key]


def scaled_distance(split: Split, names: Sequence[str], stage: FieldStage) -> FloatArray:
    """(n, n) L1 of ``[alpha * depth, gamma * harmonic]`` as float32 vectors (the index's)."""
    v = np.concatenate([set_vectors(n, split.split) for n in names]).astype(np.float64)
    x = np.concatenate([stage.depth_weight * v[:, :DEPTH_DIM],
                        stage.harmonic_weight * v[:, DEPTH_DIM:]], 1)  # fmt: skip
    return l1(x.astype(np.float32))


def union_order(order: NDArray[np.int64], dv: FloatArray, k: int, k2: int) -> tuple[
        NDArray[np.int64], NDArray[np.int64]]:  # fmt: skip
    """Each query's list: version 4's ``k`` then the ``k2`` nearest by ``dv`` not among them.

    Parameters
    ----------
    order : (n, n) int
        Each row's positions by the stored distance (ties by id).
    dv : (n, n) float
        The scaled field vectors' L1 distances.

    Returns
    -------
    (n, n) int64, (n,) int64
        Each row's positions, the union first in the stored distance's order, then the
        rest in that order; and the size of each row's union.
    """
    n = len(order)
    rows = np.arange(n)[:, None]
    inside = np.zeros((n, n), bool)
    inside[rows, order[:, :k]] = True
    if k2 > 0:
        near = np.lexsort((np.broadcast_to(np.arange(n), (n, n)), dv), axis=-1)[:, :k2]
        inside[rows, near] = True
    first = np.argsort(~np.take_along_axis(inside, order, 1), axis=1, kind="stable")
    return np.take_along_axis(order, first, 1), inside.sum(1)


# --------------------------------------------------------------------------------------
# The analytic stores on the same distance
# --------------------------------------------------------------------------------------


def analytic_vectors(shapes: Sequence[tuple[str, Any]], config: Any) -> NDArray[np.float32]:
    """(n, 950) field vectors of analytic shapes decomposed under ``config`` (their inside)."""
    from shapedb.mdbd.decomposition import decompose

    fn, _ = _describer()
    out = []
    for _, shape in shapes:
        inside = decompose(shape, config=config.mdbd, keep_inside=True).inside
        assert inside is not None, "decompose(keep_inside=True) keeps the inside"
        out.append(fn({"shell": inside.shell, "cell": inside.cell,
                       "centroid": inside.centroid, "count": inside.count}))  # fmt: skip
    return np.stack(out)


def analytic_distance(db: Any, shapes: Sequence[tuple[str, Any]], stage: FieldStage) -> Callable[
        [int, NDArray[np.int64], FloatArray], FloatArray]:  # fmt: skip
    """The fused distance of an analytic store (:func:`bench.studies.gate_checks.analytic_stores`):
    ``f(query id, candidate ids, light field distances)``, for
    :func:`bench.studies.gate_checks.analytic_gates`'s ``distance``."""
    v = analytic_vectors(shapes, db.config)
    t = db.store.shapes(["id", "name"])
    pos = {int(i): [s for s, _ in shapes].index(n)
           for i, n in zip(t.column("id").to_pylist(), t.column("name").to_pylist(), strict=True)}  # fmt: skip
    alpha, gamma = stage.depth_weight, stage.harmonic_weight

    def f(q: int, ids: NDArray[np.int64], dl: FloatArray) -> FloatArray:
        x = v[pos[int(q)]].astype(np.float64)
        y = v[[pos[int(i)] for i in ids]].astype(np.float64)
        b = np.abs(y[:, :DEPTH_DIM] - x[:DEPTH_DIM]).sum(1)
        h = np.abs(y[:, DEPTH_DIM:] - x[DEPTH_DIM:]).sum(1)
        return dl + alpha * b + gamma * h

    return f


# --------------------------------------------------------------------------------------
# The stage of a run, and the choice on validation
# --------------------------------------------------------------------------------------

#: The choice on validation (docs/results.md, "The field vectors in the stage"): the stage
#: of ``--field-vectors`` when the product's fusion is off (its gate: ``contrast_ramp`` 0.05).
CHOSEN = FieldStage.at_scales(*WEIGHTS, *SCALES, 200)


def stage_of(args: argparse.Namespace) -> FieldStage | None:
    """The field stage a gate bench run asks for (None: the light field alone).

    ``--no-field-vectors``: None. No flag: the product's (:data:`query.search.tuning.PRODUCT`'s
    fields, None while it has none). ``--field-vectors`` or any ``--fv-*``: the
    product's stage (:data:`CHOSEN` while it is off) with those values replaced;
    ``--fv-weights`` (``a``, ``c``) and ``--fv-scales`` (``m_l``, ``m_b``, ``m_h``) are the
    research's, the other at :data:`WEIGHTS` or :data:`SCALES` (:meth:`FieldStage.at_scales`).
    """
    from query.search.tuning import PRODUCT

    product = FieldStage.of(PRODUCT)
    on = getattr(args, "field_vectors", None)
    given = {k: getattr(args, k, None) for k in ("fv_weights", "fv_scales", "fv_candidates")}
    if on is False or (on is None and all(v is None for v in given.values())):
        return None if on is False else product
    stage = product or CHOSEN
    if given["fv_weights"] is not None or given["fv_scales"] is not None:
        a, c = given["fv_weights"] or WEIGHTS
        ml, mb, mh = given["fv_scales"] or SCALES
        stage = FieldStage.at_scales(a, c, ml, mb, mh, stage.candidates)
    if given["fv_candidates"] is not None:
        stage = dataclasses.replace(stage, candidates=int(given["fv_candidates"]))
    return stage
