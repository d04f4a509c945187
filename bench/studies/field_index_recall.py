"""Recall and cost of the field vector index's HNSW proposals (:mod:`query.search.field_index`).

Usage (from the repository root)::

    nice -n 5 python -m bench.studies.field_index_recall                 # 10^5 vectors
    nice -n 5 python -m bench.studies.field_index_recall --n 20000 --oversample 1 2 4

Synthetic clustered vectors shaped like the scaled field vectors (950 floats): ``n / 200``
uniform random centres, each point its centre plus Gaussian noise of a per-cluster
spread in [0.05, 0.3]. The index (``FieldIndex``, above ``SCAN_MAX`` its HNSW graph
``IndexHNSWFlat(d, HNSW_M, METRIC_L1)``, here whatever ``n``) is built once and timed; then, for queries near
random stored points, the recall@k (its ids as a set) of the graph's proposals and of the re-ranked results
against the exact L1 scan, at each proposal factor (``OVERSAMPLE``), and the seconds per
query of a search and of the exact scan. Written to
bench/results/studies/field_index_recall_<n>_efc<ef_construction>.json.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import query.search.field_index as field_index
from bench.common import format_table, write_json
from query.search.field_index import FieldIndex

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


def clustered(n: int, d: int, seed: int) -> np.ndarray:
    """(n, d) float32 points around n / 200 random centres."""
    rng = np.random.default_rng(seed)
    n_centres = max(n // 200, 10)
    centres = rng.random((n_centres, d)).astype(np.float32)
    spread = rng.uniform(0.05, 0.3, n_centres).astype(np.float32)
    label = rng.integers(0, n_centres, n)
    x = np.empty((n, d), np.float32)
    for lo in range(0, n, 8192):
        c = label[lo : lo + 8192]
        noise = rng.standard_normal((len(c), d), dtype=np.float32)
        x[lo : lo + 8192] = centres[c] + spread[c, None] * noise
    return x


def run(
    n: int, d: int, k: int, n_queries: int, factors: Sequence[int], seed: int
) -> dict[str, Any]:
    """Build the index over ``n`` clustered vectors and measure each proposal factor."""
    x = clustered(n, d, seed)
    rng = np.random.default_rng(seed + 1)
    queries = x[rng.choice(n, n_queries, replace=False)]
    queries = queries + 0.05 * rng.standard_normal(queries.shape, dtype=np.float32)
    field_index.SCAN_MAX = 0  # the graph proposes whatever n
    index = FieldIndex(np.arange(n), x)
    started = time.perf_counter()
    index.settle()  # above SCAN_MAX: builds the graph
    build = time.perf_counter() - started
    started = time.perf_counter()
    exact = []
    for q in queries:  # float32 differences, float64 sums: the order up to rounding
        dist = np.abs(x - q).sum(axis=1, dtype=np.float64)
        exact.append(np.lexsort((np.arange(n), dist))[:k])
    scan = (time.perf_counter() - started) / n_queries
    rows = []
    for factor in factors:
        field_index.OVERSAMPLE = factor
        proposed = index.propose(queries, k)
        started = time.perf_counter()
        found = np.vstack([index.search(q[None], k)[0] for q in queries.astype(np.float64)])
        per_query = (time.perf_counter() - started) / n_queries
        rows.append(
            {
                "oversample": factor,
                "proposals": factor * (k + 16),
                "recall_proposals": float(
                    np.mean([np.isin(e, p).mean() for e, p in zip(exact, proposed, strict=True)])
                ),
                "recall_results": float(
                    np.mean([np.isin(e, f).mean() for e, f in zip(exact, found, strict=True)])
                ),
                "search_seconds": per_query,
            }
        )
    return {
        "n": n, "d": d, "k": k, "queries": n_queries, "hnsw_m": field_index.HNSW_M,
        "ef_construction": field_index.EF_CONSTRUCTION,
        "approximate": index.approximate, "build_seconds": build,
        "exact_scan_seconds": scan, "factors": rows,
    }  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench.studies.field_index_recall", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--n", type=int, default=100_000)
    parser.add_argument("--d", type=int, default=950)
    parser.add_argument("--k", type=int, default=200)
    parser.add_argument("--queries", type=int, default=40)
    parser.add_argument("--oversample", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--ef-construction", type=int, default=field_index.EF_CONSTRUCTION)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    field_index.EF_CONSTRUCTION = args.ef_construction
    out = run(args.n, args.d, args.k, args.queries, args.oversample, args.seed)
    title = (
        f"n={out['n']} d={out['d']} k={out['k']}: graph built in {out['build_seconds']:.1f} s, "
        f"exact scan {out['exact_scan_seconds']:.3f} s/query"
    )
    columns = ["oversample", "proposals", "recall_proposals", "recall_results", "search_seconds"]
    print(format_table(title, columns, [[r[c] for c in columns] for r in out["factors"]]))
    write_json(RESULTS / f"field_index_recall_{args.n}_efc{args.ef_construction}.json", out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
