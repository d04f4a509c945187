"""Choose and measure the adaptive re-ranking stage (the study's own) through the index.

Usage (from the repository root)::

    python -m bench.studies.rerank_select                      # validation, six sets, the k x p x w x K grid
    python -m bench.studies.rerank_select --grid ratio --out bench/results/studies/rerank_select_validation_ratio.json
    python -m bench.studies.rerank_select --split test --setting 10 1 16 100 0.35 --lfd   # k p w K ratio
    python -m bench.studies.rerank_select --cost               # per-query search time, with and without

For each set's split (meshes, decompositions at the defaults from the bench cache), the
descriptors of versions 4 and 7 are computed from the balls (cached on disk by
decomposition and descriptor code), a flat :class:`query.search.index.FeatureIndex` is built
over the stored vectors (ids 0..n-1), and every shape queries it through
:func:`query.search.rerank.search` with ``k = n`` (the product's search path: faiss
candidates, exact re-ranking, the stage). Rows: version 4 (the index over v4
vectors), version 7 (over v7 vectors, no stage), the views block alone (an index over
that block), and the adaptive stage over version 7's vectors for each setting of the
grid (:class:`bench.studies.adaptive_rerank.AdaptiveFusion`, passed as the scorer). The
ranking of each query (itself left out) is scored with the PSB measures.

The chosen setting is the best objective (mean over the sets of (NN + 1-T + DCG) / 3)
among those with no set's NN, 1-T or DCG more than two queries' worth below version 4
(the "two-queries rule"); the table also says whether it beats version 4's objective
on every set. ``--lfd`` adds the light field descriptor (:mod:`bench.support.lightfield`,
meshes; descriptors cached). ``--cost`` times the search of a store of the web
validation shapes (version 7) with the stage and without it, queries interleaved: the
store's index through :func:`query.search.rerank.search`, the stage passed as its scorer
(the adaptive stage is no store's any more, so ``db.search`` cannot run it); and scores
the store with ``db.evaluate`` (the v7 web row of the validation table) and the stage
through the same path (the web row of its setting).
Written to bench/results/studies/rerank_select_<split>.json (``rerank_cost.json``).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import decompose_all, format_table, retrieval_scores, write_json
from bench.sets.datasets import CACHE_DIR, Dataset, articulated, capod, generic, parts, people, web
from bench.studies.adaptive_rerank import AdaptiveFusion, AdaptiveSettings, block_slice
from bench.support.lightfield import lfd_matrix
from query.search import rerank
from query.search.index import FeatureIndex
from shapedb.config.core import Config, MDBDConfig

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
SETS = ("web", "generic", "capod", "articulated", "parts", "people")
#: The grid of the adaptive stage: neighbours k, power p, weight w, candidates K.
GRID = {"neighbours": (5, 10, 20), "power": (1.0, 2.0), "weight": (4.0, 8.0, 16.0),
        "candidates": (50, 100, 200), "ratio": (0.0,)}  # fmt: skip
#: The grid of ``--grid ratio``: the spread ceiling beside the overlap gate.
RATIO_GRID = {"neighbours": (5, 10), "power": (0.0, 1.0, 2.0), "weight": (8.0, 16.0, 24.0, 32.0),
              "candidates": (100,), "ratio": (0.0, 0.35, 0.4)}  # fmt: skip
#: An engine whose cached decompositions the test splits fall back on (bench.studies.union_select).
OLDER_ENGINE = "b95b2be"
_MEASURES = ("nn", "first_tier", "dcg")
_QUERY_CHUNK = 32


def _makers() -> dict[str, Any]:
    return {
        "web": web, "generic": generic, "capod": capod, "articulated": articulated,
        "parts": parts, "people": lambda: people(extra_validation=12),
    }  # fmt: skip


def _digest(*modules: str) -> str:
    root = Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for m in modules:
        h.update((root / m).read_bytes())
    return h.hexdigest()[:12]


def descriptors(
    ds: Dataset, version: int, workers: int, split: str
) -> tuple[np.ndarray, np.ndarray]:
    """Stored vectors of ``version`` for the split's meshes: (kept indices (n,), (n, d))."""
    from bench.support.features import kernel_features

    balls = decompose_all(ds.models, "mesh", MDBDConfig(), workers=workers)
    keep = np.array([i for i, b in enumerate(balls) if b is not None], np.int64)
    code = _digest(
        "shapedb/signature/descriptor.py",
        "shapedb/signature/union_views.py",
        "shapedb/signature/union.py",
    )
    path = CACHE_DIR / "descriptors" / f"{ds.name}_{split}_{version}_{code}.npz"
    names = np.array([ds.models[i].name for i in keep])
    if path.exists():
        got = np.load(path)
        if np.array_equal(got["names"], names):
            return keep, got["x"]
    x = kernel_features([balls[i] for i in keep], Config().with_options(descriptor=version))  # type: ignore[misc]
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, names=names, x=x)
    return keep, x


def ranking_scores(
    index: FeatureIndex,
    x: np.ndarray,
    labels: np.ndarray,
    config: Config,
    scorer: rerank.Scorer | None = None,
) -> dict[str, float]:
    """PSB measures of every shape querying ``index`` through :func:`query.search.rerank.search`
    (re-ranked by ``scorer``; None: the index's order)."""
    n = len(x)
    ids = np.arange(n)
    ranks = np.empty((n, n))
    for lo in range(0, n, _QUERY_CHUNK):
        q = slice(lo, min(lo + _QUERY_CHUNK, n))
        got, _ = rerank.search(index, x[q], n, config=config, query_ids=ids[q], scorer=scorer)
        np.put_along_axis(ranks[q], got, np.broadcast_to(np.arange(n, dtype=float), got.shape), 1)
    return retrieval_scores(-ranks, labels)


def _index(x: np.ndarray) -> FeatureIndex:
    return FeatureIndex(kind="flat").fit(np.arange(len(x)), x, np.ones(x.shape[1]))


def _setting(cfg: dict[str, Any]) -> str:
    return (f"k={cfg['neighbours']} p={cfg['power']:g} w={cfg['weight']:g} K={cfg['candidates']}"
            f" r={cfg['ratio']:g}")  # fmt: skip


def _objective(entry: dict[str, Any], sets: Sequence[str]) -> float:
    return float(np.mean([sum(entry[s][m] for m in _MEASURES) / 3 for s in sets]))


def _passes(entry: dict[str, Any], base: dict[str, Any], sizes: dict[str, int]) -> bool:
    return all(entry[s][m] >= base[s][m] - 2.0 / sizes[s] - 1e-12 for s in sizes for m in _MEASURES)


def _beats(entry: dict[str, Any], base: dict[str, Any], sets: Sequence[str]) -> bool:
    return all(_objective(entry, [s]) > _objective(base, [s]) for s in sets)


def select(args: argparse.Namespace) -> dict[str, Any]:
    """Score the rows on every set; returns the JSON written."""
    if args.split == "test":
        from bench.studies.union_select import read_older_cache

        read_older_cache(OLDER_ENGINE)
    data = {}
    for name in args.datasets:
        ds = _makers()[name]().split(args.split)
        keep, v4 = descriptors(ds, 4, args.workers, args.split)
        keep7, v7 = descriptors(ds, 7, args.workers, args.split)
        assert np.array_equal(keep, keep7)
        if len(keep) < len(ds):
            print(f"  {name}: {len(ds) - len(keep)} model(s) left out (decomposition failed)")
        data[name] = {"labels": ds.labels[keep], "v4": v4, "v7": v7, "ds": ds, "keep": keep,
                      "index7": _index(v7)}  # fmt: skip
        print(f"  {name}: {len(keep)} models", flush=True)
    views = block_slice(Config().with_options(descriptor=7), "views")
    grid = RATIO_GRID if args.grid == "ratio" else GRID
    settings = [dict(zip(grid, c, strict=True)) for c in itertools.product(*grid.values())]
    if args.setting:
        settings = [dict(zip(GRID, args.setting, strict=True))]
        settings[0] = {k: type(GRID[k][0])(v) for k, v in settings[0].items()}
    table: list[dict[str, Any]] = []
    fixed = [("v4", None), ("v7", None), ("views alone", None)]
    for label, _ in fixed + [(None, s) for s in settings]:
        setting = None if label else settings[len(table) - len(fixed)]
        entry: dict[str, Any] = {"row": label or _setting(setting), "setting": setting}
        t0 = time.perf_counter()
        for name, d in data.items():
            if label == "v4":
                s = ranking_scores(_index(d["v4"]), d["v4"], d["labels"], Config())
            elif label == "v7":
                s = ranking_scores(
                    _index(d["v7"]), d["v7"], d["labels"], Config().with_options(descriptor=7)
                )
            elif label == "views alone":
                xv = np.ascontiguousarray(d["v7"][:, views])
                s = ranking_scores(_index(xv), xv, d["labels"], Config())
            else:
                cfg = Config().with_options(descriptor=7, rerank="none")
                stage = AdaptiveFusion(cfg, AdaptiveSettings(**setting))  # type: ignore[arg-type]
                s = ranking_scores(d["index7"], d["v7"], d["labels"], cfg, stage)
            entry[name] = s
        entry["objective"] = _objective(entry, list(data))
        table.append(entry)
        print(f"  {entry['row']:28s} " + "  ".join(
            f"{n[:5]} {entry[n]['nn']:.3f}/{entry[n]['first_tier']:.3f}/{entry[n]['dcg']:.3f}" for n in data
        ) + f"  obj {entry['objective']:.4f} ({time.perf_counter() - t0:.1f} s)", flush=True)  # fmt: skip
    if args.lfd:
        entry = {"row": "light field descriptor (meshes)", "setting": None}
        for name, d in data.items():
            t0 = time.perf_counter()
            dist = lfd_matrix(d["ds"])[np.ix_(d["keep"], d["keep"])]
            entry[name] = retrieval_scores(-dist, d["labels"])
            print(f"  LFD {name}: {time.perf_counter() - t0:.0f} s", flush=True)
        entry["objective"] = _objective(entry, list(data))
        table.append(entry)
    base = table[0]
    sizes = {n: len(d["labels"]) for n, d in data.items()}
    candidates = [e for e in table if e["setting"] is not None]
    passing = [e for e in candidates if _passes(e, base, sizes)]
    chosen = max(passing, key=lambda e: e["objective"]) if passing else None
    for e in table:
        e["passes_two_queries_rule"] = _passes(e, base, sizes) if e is not base else None
        e["beats_v4_on_every_set"] = _beats(e, base, list(data)) if e is not base else None
    rows = [
        [e["row"], *(f"{e[n]['nn']:.3f} / {e[n]['first_tier']:.3f} / {e[n]['dcg']:.3f}" for n in data),
         f"{e['objective']:.4f}", {True: "yes", False: "no", None: "-"}[e["passes_two_queries_rule"]]]
        for e in table if e["setting"] is None or e is chosen or len(settings) <= 4
    ]  # fmt: skip
    print()
    print(format_table(
        f"re-ranking stage, {args.split} splits (NN / 1-T / DCG), through query.search.rerank.search",
        ("row", *data, "objective", "2-query rule"), rows,
    ))  # fmt: skip
    print(f"passing settings: {len(passing)} of {len(candidates)}; chosen: "
          f"{chosen['row'] if chosen else None}; beats v4 on every set: "
          f"{chosen['beats_v4_on_every_set'] if chosen else None}")  # fmt: skip
    return {"split": args.split, "sizes": sizes, "table": table,
            "chosen": chosen["setting"] if chosen else None}  # fmt: skip


def cost(args: argparse.Namespace, repeats: int = 3) -> dict[str, Any]:
    """Median per-query search seconds with and without the stage, one store, same run."""
    import tempfile

    import shapedb
    from query.search.index import open_index
    from shapedb.store.schema import ShapeRecord

    ds = web().split("validation")
    balls = decompose_all(ds.models, "mesh", MDBDConfig(), workers=args.workers)
    keep, v7 = descriptors(ds, 7, args.workers, "validation")
    setting = dict(zip(GRID, args.setting or (10, 0.0, 16.0, 100, 0.35), strict=True))
    setting = {k: type(GRID[k][0])(v) for k, v in setting.items()}
    out: dict[str, Any] = {"models": len(keep), "setting": setting}
    cfg = Config().with_options(descriptor=7, rerank="none")
    stages = {"without": None, "with": AdaptiveFusion(cfg, AdaptiveSettings(**setting))}  # type: ignore[arg-type]
    with tempfile.TemporaryDirectory() as tmp:
        db = shapedb.connect(Path(tmp) / "v7", config=cfg)
        db.commit([
            ShapeRecord(name=ds.models[i].name, decomposition=balls[i].decomposition(),  # type: ignore[union-attr]
                        feature=v7[j].astype(np.float32), config=cfg,
                        content_hash=hashlib.sha256(ds.models[i].name.encode()).hexdigest(),
                        representation="mesh", label=ds.models[i].label)
            for j, i in enumerate(keep)
        ])  # fmt: skip
        index = open_index(db)
        got = db.evaluate()  # the store without the stage, as db.search ranks
        out["evaluate_without"] = {m: float(getattr(got, m)) for m in _MEASURES}
        x = np.asarray(index.features_, np.float64)
        out["evaluate_with"] = ranking_scores(_index(v7), v7, ds.labels[keep], cfg, stages["with"])
        for label, e in (("without", out["evaluate_without"]), ("with", out["evaluate_with"])):
            print(f"  stage {label}: NN / 1-T / DCG "
                  f"{e['nn']:.3f} / {e['first_tier']:.3f} / {e['dcg']:.3f}")  # fmt: skip
        ids = [int(i) for i in db.store.features()[0]]
        times: dict[str, list[float]] = {"with": [], "without": []}
        for _ in range(repeats):
            for sid in ids:  # interleaved, so load changes hit both alike
                q = x[index.lookup(np.array([sid]))]
                for label, stage in stages.items():
                    t = time.perf_counter()
                    rerank.search(index, q, 10, config=cfg, query_ids=np.array([sid]),
                                  scorer=stage)  # fmt: skip
                    times[label].append(time.perf_counter() - t)
    med = {k: float(np.median(v)) for k, v in times.items()}
    out.update({f"median_s_{k}": v for k, v in med.items()})
    out["ratio"] = med["with"] / med["without"]
    print(format_table(
        f"search per query, k = 10, {len(ids)} stored web shapes (v7), {repeats} x {len(ids)} queries",
        ("stage", "median ms", "ratio"),
        [["none", f"{med['without'] * 1e3:.2f}", "1.00"],
         [f"adaptive ({_setting(setting)})", f"{med['with'] * 1e3:.2f}", f"{out['ratio']:.2f}"]],
    ))  # fmt: skip
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.rerank_select", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--datasets", nargs="+", default=list(SETS), choices=SETS)
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--setting", nargs=5,
                    metavar=("K_NEIGHBOURS", "POWER", "WEIGHT", "CANDIDATES", "RATIO"),
                    help="one setting instead of the grid")  # fmt: skip
    ap.add_argument("--grid", default="overlap", choices=["overlap", "ratio"],
                    help="overlap: k x p x w x K (ratio off); ratio: with the spread ceiling")  # fmt: skip
    ap.add_argument("--lfd", action="store_true", help="add the light field descriptor's row")
    ap.add_argument(
        "--cost", action="store_true", help="only time the search with and without the stage"
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.cost:
        write_json(args.out or RESULTS / "rerank_cost.json", cost(args))
        return 0
    result = select(args)
    out = args.out or RESULTS / f"rerank_select_{args.split}.json"
    write_json(out, result)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
