"""Corpus part search at scale: p50/p99 latency and recall against brute force.

For each store size (default 1e3 and 1e4 shapes) a real store is built
(``shapedb.connect`` + ``Database.commit``) of synthetic contact graphs: random
geometric ball graphs of 512 balls (centres in a randomly stretched box, radii
decreasing as a power law with a random exponent, each ball touching its 3 nearest
neighbours), so 512 neighbourhood subgraphs per shape. Then:

* the part index is built (:func:`query.parts.store_index.open_parts_index`: features of
  every node, faiss IVF above 5e5 vectors) and its build time reported;
* queries are parts of *noisy copies* of stored shapes (radii x (1 + 2% noise), not
  stored), so the exact answer is not trivially a distance-0 hit;
* ``query.parts.match.match(db, graph, node=v, k=10)`` is timed end to end (part
  feature, index search with exact re-rank, names and node sets);
* the baseline, timed in the same run, is brute force: the exact Eq. 2 scan of the
  query against every stored neighbourhood feature (numpy, ``PartIndex.exact_search``),
  i.e. Algorithm 1 against every shape with all features precomputed;
* recall@10: a returned shape counts when its distance is within the exact 10th
  (ties tolerated, as in faiss contrib).

Each store is searched with the default part vector (``PartConfig()``: Eq. 1 plus
the size and centre blocks, 32 values) and, in the same run on the same store and queries, with
the paper's vector alone (``size=0``, 20 values, as measured before the size block),
so the cost of the extra block is a ratio measured under the same load.

Run ``python -m bench.substructure`` (about 10 minutes on 2 cores, most of it
building the 1e4 store). Prints a table and writes ``bench/results/substructure.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import os
import platform
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from bench.common import format_table, write_json
from shapedb.config.core import Config
from shapedb.config.part import PartConfig
from shapedb.mdbd.decomposition import Decomposition
from shapedb.mdbd.graph import ContactGraph
from shapedb.signature.kernel import features
from shapedb.store.schema import ShapeRecord

logger = logging.getLogger(__name__)

RESULTS = Path(__file__).resolve().parent / "results"
CONFIG = Config().with_options(resolution=64, n_balls=512)


def ball_graph(seed: int, n: int = 512) -> tuple[NDArray, NDArray, NDArray]:
    """A random geometric ball graph: centres (n, 3), radii (n,) decreasing, edges (m, 2)."""
    rng = np.random.default_rng([5, seed])
    c = rng.random((n, 3)) * rng.uniform(0.3, 1.0, 3)
    alpha = rng.uniform(0.3, 0.9)
    r = 0.1 * np.arange(1, n + 1) ** -alpha * rng.uniform(0.9, 1.1, n)
    r = -np.sort(-r)
    _, nb = cKDTree(c).query(c, k=4)
    e = np.stack([np.repeat(np.arange(n), 3), nb[:, 1:].ravel()], 1)
    e = np.unique(np.sort(e, axis=1), axis=0)
    return c, r, e


def record(seed: int, n: int) -> ShapeRecord:
    c, r, e = ball_graph(seed, n)
    dec = Decomposition(
        centers=c,
        radii=r,
        edges=e.astype(np.int32),
        spacing=0.01,
        bounds=np.stack([c.min(0), c.max(0)]),
        config=CONFIG.mdbd,
        representation="implicit",
    )
    feat = features(ContactGraph(c, r, e), CONFIG.kernel).astype(np.float32)
    return ShapeRecord(
        name=f"g{seed:06d}",
        decomposition=dec,
        feature=feat,
        config=CONFIG,
        content_hash=hashlib.sha256(f"g{seed}".encode()).hexdigest(),
        representation="implicit",
        label=f"a{int(10 * (seed % 7))}",
    )


def build_store(path: Path, n_shapes: int, n_balls: int) -> Any:
    import query.database as database

    db = database.connect(path, config=CONFIG)
    batch = 500
    for s in range(0, n_shapes, batch):
        db.commit([record(i, n_balls) for i in range(s, min(n_shapes, s + batch))])
    return db


#: Part settings measured: the default, and the paper's vector alone (the baseline).
#: The synthetic graphs are not packings (their edges join nearest neighbours, not
#: tangent balls), so part matching takes their stored edges (``contact_tol_cells=0``)
#: instead of finding contacts again from the balls.
PARTS = {
    "default": PartConfig(contact_tol_cells=0.0),
    "paper": PartConfig(size=0.0, centre=0.0, contact_tol_cells=0.0),
}


def run(
    n_shapes: int, n_queries: int, n_balls: int, root: Path, parts: Sequence[str] = ("default",)
) -> list[dict[str, Any]]:
    t0 = time.perf_counter()
    db = build_store(root / f"store{n_shapes}", n_shapes, n_balls)
    t_store = time.perf_counter() - t0
    return [run_config(db, n_shapes, n_queries, n_balls, t_store, p) for p in parts]


def run_config(
    db: Any, n_shapes: int, n_queries: int, n_balls: int, t_store: float, part: str
) -> dict[str, Any]:
    from query.parts.match import match, part_feature
    from query.parts.store_index import open_parts_index

    cfg = PARTS[part]
    t0 = time.perf_counter()
    index = open_parts_index(db, cfg)
    t_index = time.perf_counter() - t0
    logger.info("%d shapes: store %.1f s, part index %.1f s: %r", n_shapes, t_store, t_index, index)
    rng = np.random.default_rng(1)
    lat, base, recall = [], [], []
    match(db, ContactGraph(*ball_graph(0, n_balls)), node=0, k=10, config=cfg)  # warm up
    for _ in range(n_queries):
        sid = int(rng.integers(n_shapes))
        c, r, e = ball_graph(sid, n_balls)
        r = -np.sort(-r * (1 + 0.02 * rng.standard_normal(len(r))))
        g = ContactGraph(c, r, e)
        v = int(rng.integers(n_balls))
        t = time.perf_counter()
        hits = match(db, g, node=v, k=10, config=cfg)
        lat.append(time.perf_counter() - t)
        feat, _ = part_feature(g, v, cfg)
        t = time.perf_counter()
        ex_ids, _, ex_d = index.exact_search(feat, 10)
        base.append(time.perf_counter() - t)
        kth = ex_d[-1] + 1e-9
        recall.append(np.mean([h.distance <= kth for h in hits]) if len(hits) == 10 else 0.0)
    ms = 1e3 * np.asarray(lat)
    bms = 1e3 * np.asarray(base)
    return {
        "part": part,
        "dim": int(index.features_.shape[1]),
        "shapes": n_shapes,
        "vectors": index.n_vectors,
        "index_kind": index.kind_,
        "store_build_s": t_store,
        "index_build_s": t_index,
        "queries": n_queries,
        "p50_ms": float(np.percentile(ms, 50)),
        "p99_ms": float(np.percentile(ms, 99)),
        "brute_p50_ms": float(np.percentile(bms, 50)),
        "brute_p99_ms": float(np.percentile(bms, 99)),
        "recall_at_10": float(np.mean(recall)),
    }


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--queries", type=int, default=100)
    ap.add_argument("--n-balls", type=int, default=512)
    ap.add_argument("--parts", nargs="+", default=["default", "paper"], choices=sorted(PARTS))
    ap.add_argument("--out", type=Path, default=RESULTS / "substructure.json")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    rows, out = [], []
    with tempfile.TemporaryDirectory(prefix="shapedb-bench-") as tmp:
        for n in args.sizes:
            for r in run(n, args.queries, args.n_balls, Path(tmp), args.parts):
                out.append(r)
                rows.append(
                    [
                        n,
                        r["part"],
                        r["dim"],
                        r["vectors"],
                        r["index_kind"],
                        r["index_build_s"],
                        r["p50_ms"],
                        r["p99_ms"],
                        r["brute_p50_ms"],
                        r["brute_p99_ms"],
                        r["recall_at_10"],
                    ]
                )
    logger.info(
        "\n%s",
        format_table(
            f"Corpus part search, k=10, {args.n_balls}-ball graphs, K=2, n_r=10 "
            f"({os.cpu_count()} cores, load {os.getloadavg()[0]:.1f})",
            [
                "shapes",
                "part",
                "dim",
                "vectors",
                "index",
                "build s",
                "p50 ms",
                "p99 ms",
                "brute p50",
                "brute p99",
                "recall@10",
            ],
            rows,
        ),
    )
    write_json(
        args.out,
        {
            "machine": platform.platform(),
            "cores": os.cpu_count(),
            "load_avg": os.getloadavg(),
            "runs": out,
        },
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
