"""Scans, samplings and cropped halves of a split's models searched against its meshes' store.

:func:`query_geometry` makes a model's query of one kind (:data:`QUERY_KINDS`) from its
mesh with :mod:`bench.sets.scans`, seeded by the model's name and the kind. Clouds are
:class:`shapedb.geometry.pointcloud.PointCloud`, cropped halves
:class:`shapedb.geometry.mesh.TriangleMesh`. :func:`kind_scores` searches every model's
query with ``db.search(query, k=len(store))`` against the store of the split's meshes,
drops the model's own mesh from the hits, and scores the ranked lists as the
leave-one-out evaluation does (NN / 1-T / 2-T / DCG), with the searches' median wall
time and, when the hits carry a ``path``, how often each path was taken.
"""

from __future__ import annotations

import inspect
import time
from collections import Counter
from typing import Any

import numpy as np

from bench.common import retrieval_scores
from bench.sets.datasets import Dataset, Model, mesh_arrays, min_cloud_points, stable_seed

__all__ = ["QUERY_KINDS", "TOP_RECORDED", "query_geometry", "search_options", "kind_scores"]

#: Query kinds; ``mesh`` is the stored mesh itself (the leave-one-out baseline).
QUERY_KINDS = ("mesh", "even", "vertex", "falloff", "one-sided", "cropped")
#: Hits per query written out (``top``), for reading which shapes a query found.
TOP_RECORDED = 10


def query_geometry(model: Model, kind: str) -> Any:
    """The model's query of ``kind`` (one of :data:`QUERY_KINDS`), from its mesh.

    Raises
    ------
    ValueError
        An unknown kind.
    """
    from bench.sets import scans
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.geometry.pointcloud import PointCloud

    v, f = mesh_arrays(model)
    seed = stable_seed(model.name, kind)
    name = f"{model.name}~{kind}"
    if kind == "mesh":
        return TriangleMesh(v, f, name=name)
    if kind == "cropped":
        return TriangleMesh(*scans.cropped_mesh(v, f, seed=seed), name=name)
    if kind == "even":
        points = scans.even_cloud(v, f, seed=seed)
    elif kind == "vertex":
        points = scans.vertex_cloud(v, f, seed=seed, min_points=min_cloud_points(model))
    elif kind == "falloff":
        points = scans.falloff_cloud(v, f, seed=seed)
    elif kind == "one-sided":
        points = scans.one_sided_scan(v, f, seed=seed)
    else:
        raise ValueError(f"query kind {kind!r}: expected one of {', '.join(QUERY_KINDS)}")
    return PointCloud(points, name=name)


def search_options(db: Any, partial: bool | None) -> dict[str, Any]:
    """Keyword arguments of ``db.search`` for ``partial`` (None: let the search decide).

    ``partial`` is always passed when ``db.search`` takes it; when it does not, None
    passes nothing and True / False stop the run (``SystemExit``).
    """
    if "partial" in inspect.signature(db.search).parameters:
        return {"partial": partial}
    if partial is None:
        return {}
    raise SystemExit(
        "--partial on/off: this product's Database.search takes no 'partial' argument yet "
        "(use --partial auto)"
    )


def _rank_row(hits: Any, own: str, column: dict[str, int], n: int) -> np.ndarray:
    """A similarity row (n,) from ranked hits: ``-rank``, unranked and own shapes NaN."""
    row = np.full(n, np.nan)
    rank = 0
    for hit in hits:
        j = column.get(hit.name)
        if j is None or hit.name == own:
            continue
        row[j] = -float(rank)
        rank += 1
    return row


def kind_scores(db: Any, ds: Dataset, kind: str, *, partial: bool | None = None) -> dict[str, Any]:
    """NN / 1-T / 2-T / DCG of the split's ``kind`` queries searched against ``db``.

    Parameters
    ----------
    db : query.database.Database
        The store of ``ds``'s meshes (its shape names are the models' names).
    ds : Dataset
        The split; every model queries once.
    kind : str
        One of :data:`QUERY_KINDS` but ``mesh`` (the baseline is ``db.evaluate``).
    partial : bool or None
        ``db.search``'s ``partial`` (:func:`search_options`).

    Returns
    -------
    dict
        ``nn``, ``first_tier``, ``second_tier``, ``dcg`` (in [0, 1]), ``queries``,
        ``failed`` (queries the product refused: scored with their own class ranked
        last), ``median_ms`` of the searches, ``paths`` (``{path: count}`` of the
        first hits' ``path``, empty when hits carry none) and ``top`` (per query
        model, the first :data:`TOP_RECORDED` names it was scored on, its own left out)
        and ``errors`` (per failed query model, the product's one-line error).
    """
    from shapedb.errors import ShapeDBError

    options = search_options(db, partial)
    names = [m.name for m in ds.models]
    column = {name: j for j, name in enumerate(names)}
    labels = np.asarray(ds.labels)
    n, k = len(names), len(db.store)
    sim = np.full((n, n), np.nan)
    times: list[float] = []
    paths: Counter[str] = Counter()
    top: dict[str, list[str]] = {}
    errors: dict[str, str] = {}
    for i, model in enumerate(ds.models):
        try:
            query = query_geometry(model, kind)
            t = time.perf_counter()
            hits = db.search(query, k=k, **options)
            times.append(1e3 * (time.perf_counter() - t))
        except (ShapeDBError, ValueError) as e:
            errors[model.name] = f"{type(e).__name__}: {e}"
            sim[i] = np.where(labels == labels[i], -1.0, 0.0)
            continue
        path = getattr(hits[0], "path", None) if hits else None
        if path is not None:
            paths[str(path)] += 1
        sim[i] = _rank_row(hits, model.name, column, n)
        ranked = [h.name for h in hits if h.name != model.name]
        top[model.name] = ranked[:TOP_RECORDED]
    s = retrieval_scores(sim, labels)
    return {
        **{m: s[m] for m in ("nn", "first_tier", "second_tier", "dcg")},
        "queries": n,
        "failed": len(errors),
        "median_ms": float(np.median(times)) if times else None,
        "paths": dict(paths),
        "top": top,
        "errors": errors,
    }
