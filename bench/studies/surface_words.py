"""Surface words beside the stage: the codebook, and the fusion's offset and weight.

``python -m bench.studies.surface_words --write-codebook`` trains the codebook the product
ships (:data:`shapedb.signature.surface_words.CODEBOOK_FILE`): faiss k-means of
:data:`~shapedb.signature.surface_words.WORDS` words over the FPFH features of every mesh
of the rigid families' validation splits (:data:`RIGID`), seeded.

``python -m bench.studies.surface_words`` (the stores of ``bench.quality``, built or
cached) ranks each split's meshes three ways: by the stage without the words
(``StageTuning.word_weight`` 0), by the words alone (chi-square of the stored
histograms), and by the two fused over whole rankings as
:mod:`query.search.word_fusion` fuses a query's candidates, for every offset and weight
of :data:`OFFSETS` x :data:`WEIGHTS`. The setting with the highest validation objective
(mean of NN, 1-T and DCG over the rigid families) whose rigid families lose no NN is
the product's (``StageTuning.word_offset``, ``word_weight``); the jointed families are
reported fused too, though the stage's pose gate keeps the words from them. Written to
``bench/results/studies/surface_words.json``; the product's own figures are
``python -m bench.quality``'s. ``--cost`` measures what the words cost at ingest and in a
search (``surface_words_cost.json``); ``--mixed`` the web and figures validation meshes in one
store, each family's queries among all its shapes (``surface_words_mixed.json``).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "RIGID", "JOINTED", "OFFSETS", "WEIGHTS", "fused", "cost", "mixed", "write_codebook", "main",
]  # fmt: skip

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "surface_words.json"
#: Rigid families (the codebook's and the fusion's choice) and jointed ones.
RIGID = ("web", "generic", "enclosures", "capod", "parts")
JOINTED = ("figures", "people")
#: The fusion's grid (offsets of ranks from 0).
OFFSETS = (2.0, 4.0, 11.0, 31.0)
WEIGHTS = (0.25, 0.5, 0.75, 1.0, 1.5)


def fused(stage: NDArray[np.float64], words: NDArray[np.float64], offset: float,
          weight: float) -> NDArray[np.float64]:  # fmt: skip
    """Similarity (n, n) fusing two 0-based rank matrices as the stage fuses a row."""
    return 1.0 / (offset + stage) + weight / (offset + words)


def _ranks(distance: NDArray[np.float64]) -> NDArray[np.float64]:
    d = np.array(distance, dtype=np.float64, copy=True)
    np.fill_diagonal(d, np.inf)
    return np.argsort(np.argsort(d, axis=1, kind="stable"), axis=1).astype(np.float64)


def _stage_ranks(db: Any, names: list[str], *, words: bool = False) -> NDArray[np.float64]:
    """(n, n) 0-based ranks of each shape's others as the stage orders them, without the
    words (``words`` False) or as the product does."""
    from query.search.tuning import PRODUCT, tuned

    column = {name: j for j, name in enumerate(names)}
    ranks = np.full((len(names), len(names)), np.inf)
    with tuned(PRODUCT if words else replace(PRODUCT, word_weight=0.0)):
        for i, name in enumerate(names):
            r = 0
            for hit in db.search(name, k=len(names)):
                if hit.name != name and hit.name in column:
                    ranks[i, column[hit.name]] = r
                    r += 1
    return ranks


def _stored_words(db: Any, names: list[str]) -> NDArray[np.float64]:
    t = db.sql("SELECT name, surface_words FROM shapes").to_pylist()
    got = {r["name"]: r["surface_words"] for r in t}
    return np.array([got[n] for n in names], dtype=np.float64)


def _scores(similarity: NDArray[np.float64], labels: NDArray[Any]) -> list[float]:
    from query.evaluate import retrieval_scores

    s = retrieval_scores(np.where(np.isfinite(similarity), similarity, np.nan), labels)
    return [round(float(getattr(s, k)), 4) for k in ("nn", "first_tier", "dcg")]


def write_codebook() -> Path:
    """Train the codebook on the rigid validation splits and write the product's file."""
    from bench.quality import family_split
    from bench.sets.datasets import mesh_arrays
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.signature.surface_words import (
        CODEBOOK_FILE,
        surface_features,
        surface_points,
        train_codebook,
    )

    features = []
    for name in RIGID:
        for m in family_split(name, "validation").models:
            mesh = TriangleMesh(*mesh_arrays(m), name=m.name)
            features.append(surface_features(surface_points(mesh, 0.0)))
    np.save(CODEBOOK_FILE, train_codebook(features))
    return CODEBOOK_FILE


def cost(family: str = "web", split: str = "validation", models: int = 20) -> dict[str, float]:
    """What the words cost in the split's store: at ingest (their share of each record's
    build time, median), in a search by stored id (median ms with and without them, 3 x
    ``models`` searches interleaved) and in a search by a mesh (the words' seconds against
    the whole search's, median over ``models`` meshes)."""
    import time

    from bench.quality import family_split
    from bench.sets.datasets import mesh_arrays
    from bench.support.product_stores import split_store
    from query.search.tuning import PRODUCT, tuned
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.signature.surface_words import surface_points, surface_words

    ds = family_split(family, split)
    db = split_store(ds, {})
    rows = db.sql("SELECT build_seconds, timings FROM shapes").to_pylist()
    share = [dict(r["timings"])["surface_words"] / r["build_seconds"] for r in rows]
    names = [m.name for m in ds.models[:models]]
    on, off = [], []
    for _ in range(3):
        for name in names:
            t = time.perf_counter()
            db.search(name, k=10)
            on.append(time.perf_counter() - t)
            with tuned(replace(PRODUCT, word_weight=0.0)):
                t = time.perf_counter()
                db.search(name, k=10)
                off.append(time.perf_counter() - t)
    words, whole = [], []
    for m in ds.models[:models]:
        mesh = TriangleMesh(*mesh_arrays(m), name=m.name)
        t = time.perf_counter()
        surface_words(surface_points(mesh, 0.0))
        words.append(time.perf_counter() - t)
        t = time.perf_counter()
        db.search(mesh, k=10)
        whole.append(time.perf_counter() - t)
    return {
        "ingest_share_median": round(float(np.median(share)), 3),
        "search_by_id_ms_with": round(1e3 * float(np.median(on)), 2),
        "search_by_id_ms_without": round(1e3 * float(np.median(off)), 2),
        "mesh_query_words_s": round(float(np.median(words)), 3),
        "mesh_query_s": round(float(np.median(whole)), 3),
    }


def mixed(
    families: Sequence[str] = ("web", "figures"), split: str = "validation"
) -> dict[str, Any]:
    """The families' meshes in one store (labels kept apart by family): each family's NN /
    1-T / DCG among all the store's shapes, by the stage without and with the words."""
    from bench.quality import family_split
    from bench.sets.datasets import Dataset
    from bench.support.product_stores import split_store

    parts = {name: family_split(name, split) for name in families}
    models = tuple(replace(m, label=f"{name}:{m.label}") for name, ds in parts.items()
                   for m in ds.models)  # fmt: skip
    ds = Dataset("+".join(families), models)
    db = split_store(ds, {})
    names = [m.name for m in models]
    labels = np.asarray(ds.labels)
    out: dict[str, Any] = {}
    for way, words in (("without the words", False), ("default", True)):
        ranks = _stage_ranks(db, names, words=words)
        for name in families:
            # the family's queries, ranked among the whole store (the others unlabelled:
            # never queries, never relevant)
            mine = np.array([lab if lab.startswith(f"{name}:") else None for lab in labels])
            out.setdefault(name, {})[way] = _scores(-ranks, mine)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    from bench.quality import family_split
    from bench.support.product_stores import split_store
    from shapedb.signature.surface_words import words_distance

    ap = argparse.ArgumentParser(prog="python -m bench.studies.surface_words", description=__doc__)
    ap.add_argument("--write-codebook", action="store_true", help="train and write the codebook")
    ap.add_argument("--families", nargs="+", default=list(RIGID + JOINTED))
    ap.add_argument("--cost", action="store_true", help="measure the words' cost only")
    ap.add_argument("--mixed", action="store_true", help="web and figures in one store only")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    if args.write_codebook:
        print(f"wrote {write_codebook()}")
        return 0
    if args.mixed:
        measured = mixed()
        print(json.dumps(measured, indent=1))
        args.out.with_name("surface_words_mixed.json").write_text(json.dumps(measured, indent=1))
        return 0
    if args.cost:
        measured = cost()
        print(json.dumps(measured, indent=1))
        out = args.out.with_name("surface_words_cost.json")
        out.write_text(json.dumps(measured, indent=1))
        return 0
    rows: dict[str, dict[str, Any]] = {"validation": {}, "test": {}}
    for split, found in rows.items():
        for name in args.families:
            ds = family_split(name, split)
            db = split_store(ds, {})
            names = [m.name for m in ds.models]
            h = _stored_words(db, names)
            words = np.stack([words_distance(x, h) for x in h])
            found[name] = {"stage": _stage_ranks(db, names), "words": _ranks(words),
                           "labels": np.asarray(ds.labels)}  # fmt: skip
            print(f"  {split} {name}: {len(names)} shapes", flush=True)
    rigid = [n for n in args.families if n in RIGID]
    val = rows["validation"]
    base = {n: _scores(-val[n]["stage"], val[n]["labels"]) for n in rigid}
    grid = {}
    for o in OFFSETS:
        for w in WEIGHTS:
            s = {n: _scores(fused(val[n]["stage"], val[n]["words"], o, w), val[n]["labels"])
                 for n in rigid}  # fmt: skip
            worst = min(s[n][0] - base[n][0] for n in rigid)
            grid[(o, w)] = (float(np.mean([np.mean(v) for v in s.values()])), worst)
    allowed = {k: v for k, v in grid.items() if v[1] >= 0} or grid
    offset, weight = max(allowed, key=lambda k: allowed[k][0])
    result: dict[str, Any] = {
        "offset": offset, "weight": weight,
        "validation_grid": {f"{o},{w}": [round(v[0], 4), round(v[1], 4)]
                            for (o, w), v in grid.items()},
    }  # fmt: skip
    print(f"chosen on validation: offset {offset}, weight {weight}")
    print(f"{'split':10s} {'family':11s} {'stage':>22s} {'words':>22s} {'fused':>22s}")
    for split, found in rows.items():
        result[split] = {}
        for name, row in found.items():
            lab = row["labels"]
            out = {"stage": _scores(-row["stage"], lab), "words": _scores(-row["words"], lab),
                   "fused": _scores(fused(row["stage"], row["words"], offset, weight), lab)}  # fmt: skip
            result[split][name] = out
            cells = [" / ".join(f"{v:.3f}" for v in out[k]) for k in ("stage", "words", "fused")]
            print(f"{split:10s} {name:11s} {cells[0]:>22s} {cells[1]:>22s} {cells[2]:>22s}",
                  flush=True)  # fmt: skip
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
