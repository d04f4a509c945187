"""Retrieval at scale: the faiss index + exact re-rank against numpy brute force.

For each size (default 1e4, 1e5, 1e6 stored vectors) this builds a
:class:`query.search.index.FeatureIndex` (``kind="auto"``: flat below 50 000 vectors, HNSW
above) over synthetic Eq. 1 vectors shaped like real ones (sorted, decreasing
radius ratios in (0, 1] followed by walk averages; d = 2 * n_r with the default
KernelConfig), and measures, with a numpy brute-force baseline in the same run:

* recall@10 of the index (faiss candidates + exact Eq. 2 re-rank) against the
  exact ranking (a result counts when its distance is within the exact 10th);
* p50 / p99 latency of single k=10 queries (one query per call);
* build time and memory (resident-set growth and size on disk).

With ``--store-sizes`` it also times ``query.search.engine.search`` end to end on a real
store (synthetic records committed through ``Store.commit``), i.e. including the
version check, id lookup and Hit construction; and in a store with sparse views
(``view_cells=4``, a tenth of the shapes sparse), where a sparse query searches two
indexes and merges them.

Run ``python -m bench.query`` (all sizes) or ``--sizes 10000 100000`` for a quicker
run (about 1.5 minutes). The full run took 13 to 15 minutes on 2 cores shared with
other jobs (load average 12 to 16), 11 of them building the HNSW graph of 1e6 vectors;
expect it to be several times faster on an idle machine. Prints a table and writes
``bench/results/query.json`` (with the load average at the start and the end).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from query.search.index import FeatureIndex
from shapedb.config.core import CloudConfig, Config, KernelConfig
from shapedb.signature.kernel import weights

log = logging.getLogger("bench.query")

RESULTS = Path(__file__).parent / "results" / "query.json"


def synthetic_features(n: int, n_r: int, seed: int, *, chunk: int = 100_000) -> NDArray[np.float32]:
    """(n, 2 n_r) float32 vectors shaped like Eq. 1 features (see module docstring)."""
    rng = np.random.default_rng(seed)
    out = np.empty((n, 2 * n_r), np.float32)
    i = np.arange(n_r)
    for lo in range(0, n, chunk):
        m = min(chunk, n - lo)
        alpha = rng.uniform(0.01, 0.3, (m, 1))
        beta = rng.uniform(0.5, 1.5, (m, 1))
        r = np.exp(-alpha * i**beta) * (1 + 0.05 * rng.standard_normal((m, n_r)))
        r = -np.sort(-np.clip(r, 1e-3, None), axis=1)
        r /= r[:, :1]
        nb = rng.integers(0, n_r, (m, n_r, 3))
        mean_nb = np.take_along_axis(np.repeat(r[:, :, None], 3, 2), nb, 1).mean(2)
        walk = rng.uniform(0.5, 0.7, (m, 1)) * (0.5 * r + 0.5 * mean_nb)
        out[lo : lo + m, :n_r] = r
        out[lo : lo + m, n_r:] = walk
    return out


def synthetic_descriptors(
    n: int, version: int, seed: int, *, chunk: int = 100_000
) -> NDArray[np.float32]:
    """(n, dim(version)) float32 vectors shaped like :func:`shapedb.signature.descriptor.describe`'s.

    Each distribution block is the cumulative histogram of a random two-bump density
    over its bins (smooth and of few parameters, as real ones are), ``inertia`` three
    sorted positive values, ``paper`` :func:`synthetic_features`; each block is then
    scaled, as ``describe`` scales it, so that its median pairwise L1 is its weight
    times the calibration (unrelated shapes at about ln 10 in all).
    """
    from shapedb.signature.descriptor import LAYOUTS

    layout = LAYOUTS[version]
    calibration = np.log(10.0) / sum(b[3] for b in layout)
    rng = np.random.default_rng(seed)

    def cdfs(m: int, size: int) -> NDArray[np.float64]:
        x = np.linspace(0.0, 1.0, size)
        mu = rng.uniform(0.1, 0.9, (m, 2, 1))
        sd = rng.uniform(0.03, 0.25, (m, 2, 1))
        a = rng.uniform(0.0, 1.0, (m, 1))
        pdf = a * np.exp(-0.5 * ((x - mu[:, 0]) / sd[:, 0]) ** 2) + (1 - a) * np.exp(
            -0.5 * ((x - mu[:, 1]) / sd[:, 1]) ** 2
        )
        c = np.cumsum(pdf, axis=1)
        return c / c[:, -1:]

    def block(m: int, name: str, size: int) -> NDArray[np.float64]:
        if name == "inertia":
            return -np.sort(-np.exp(rng.normal(-1.0, 0.5, (m, size))), axis=1)
        if name == "paper":
            return synthetic_features(m, size // 2, int(rng.integers(2**31))).astype(np.float64)
        if name == "walk":
            return np.concatenate([cdfs(m, size // 3) for _ in range(3)], axis=1)
        return cdfs(m, size)

    scale = {}
    for name, size, _, weight in layout:  # median pairwise L1 of each block, from a sample
        b = block(400, name, size)
        d = np.abs(b[:200] - b[200:]).sum(axis=1)
        scale[name] = weight * calibration / float(np.median(d))
    out = np.empty((n, sum(b[1] for b in layout)), np.float32)
    for lo in range(0, n, chunk):
        m = min(chunk, n - lo)
        out[lo : lo + m] = np.concatenate(
            [block(m, name, size) * scale[name] for name, size, _, _ in layout], axis=1
        )
    return out


def synthetic_vectors(n: int, config: Config | KernelConfig, seed: int) -> NDArray[np.float32]:
    """Synthetic feature vectors of ``config``'s method and length, (n, Config.dim).

    A :class:`KernelConfig` alone stands for ``Config(kernel=config)`` (today's descriptor).
    """
    full = config if isinstance(config, Config) else Config(kernel=config)
    if full.kernel.method == "paper":
        return synthetic_features(n, full.kernel.n_r, seed)
    return synthetic_descriptors(n, full.descriptor.version, seed)


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def brute_force(
    x: NDArray[np.float32], q: NDArray[np.float64], w: NDArray[np.float64], k: int
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The numpy baseline: exact Eq. 2 of one query against every row, top k by (d, id)."""
    d = np.abs(x - q.astype(np.float32)) @ w.astype(np.float32)  # float32 scan
    part = np.argpartition(d, k + 16)[: k + 16]
    exact = np.abs(x[part].astype(np.float64) - q) @ w  # float64 re-rank of the head
    order = np.lexsort((part, exact))[:k]
    return part[order], exact[order]


def exact_topk(
    x: NDArray[np.float32], q: NDArray[np.float64], w: NDArray[np.float64], k: int
) -> NDArray[np.float64]:
    """Exact Eq. 2 distances of the k nearest rows of each query: (nq, k) float64."""
    import faiss

    flat = faiss.IndexFlat(x.shape[1], faiss.METRIC_L1)
    flat.add(np.ascontiguousarray(x * w.astype(np.float32)))
    _, cand = flat.search(np.ascontiguousarray((q * w).astype(np.float32)), 128)
    exact = np.abs(x[cand].astype(np.float64) - q[:, None, :]) @ w
    return np.sort(exact, axis=1)[:, :k]


def _percentiles(seconds: list[float]) -> tuple[float, float]:
    a = np.asarray(seconds) * 1e3
    return float(np.percentile(a, 50)), float(np.percentile(a, 99))


def run_size(
    n: int,
    *,
    n_queries: int,
    n_latency: int,
    n_baseline: int,
    seed: int = 0,
    config: KernelConfig | None = None,
) -> dict[str, Any]:
    """All measures for one size; returns one JSON row."""
    config = config or KernelConfig()
    w = weights(config)
    t0 = time.perf_counter()
    x = synthetic_vectors(n, config, seed)
    log.info("n=%d: generated in %.1f s", n, time.perf_counter() - t0)
    ids = np.arange(n, dtype=np.int64)
    queries = synthetic_vectors(max(n_queries, n_latency), config, seed + 1).astype(np.float64)

    rss0 = _rss_mb()
    t0 = time.perf_counter()
    index = FeatureIndex(kind="auto").fit(ids, x, w)
    build = time.perf_counter() - t0
    rss_index = _rss_mb() - rss0
    with tempfile.TemporaryDirectory() as tmp:
        index.save(tmp, version=0)
        disk = sum(f.stat().st_size for f in Path(tmp).rglob("*") if f.is_file()) / 2**20
    log.info("n=%d: built %s index in %.1f s", n, index.kind_, build)

    # single-query latency first (before numpy's BLAS threads are woken up)
    k = 10
    lat = []
    for j in range(n_latency):
        t0 = time.perf_counter()
        index.search(queries[j], k)
        lat.append(time.perf_counter() - t0)

    # exact ground truth: faiss flat L1 (batched) + float64 Eq. 2 re-rank of 128 candidates
    ref_d = exact_topk(x, queries[:n_queries], w, k)
    got, got_d = index.search(queries[:n_queries], k)
    recall = float(np.mean(got_d <= ref_d[:, -1:] * (1 + 1e-12) + 1e-15))

    # numpy brute-force baseline (one query per call), checked against the ground truth
    base_lat, base_hits = [], 0
    for j in range(n_baseline):
        t0 = time.perf_counter()
        _, bd = brute_force(x, queries[j], w, k)
        base_lat.append(time.perf_counter() - t0)
        base_hits += int(np.sum(bd <= ref_d[j, -1] * (1 + 1e-12) + 1e-15))
    p50, p99 = _percentiles(lat)
    b50, b99 = _percentiles(base_lat)
    row = {
        "n": n,
        "kind": index.kind_,
        "dim": int(x.shape[1]),
        "recall_at_10": recall,
        "p50_ms": p50,
        "p99_ms": p99,
        "build_s": build,
        "index_rss_mb": rss_index,
        "index_disk_mb": disk,
        "baseline_p50_ms": b50,
        "baseline_p99_ms": b99,
        "baseline_recall_at_10": base_hits / (k * max(n_baseline, 1)),
        "queries_recall": n_queries,
        "queries_latency": n_latency,
        "params": index.params,
    }
    log.info("n=%d: %s", n, row)
    return row


def synthetic_records(n: int, config: Config) -> list[Any]:
    """``n`` ShapeRecords of one ball each with realistic feature vectors (ids s0..s{n-1},
    labels c0..c49), for stores whose search cost, not decomposition, is measured."""
    from shapedb.mdbd.decomposition import Decomposition
    from shapedb.store.schema import ShapeRecord

    x = synthetic_vectors(n, config, 7)
    one = Decomposition(
        centers=np.zeros((1, 3)),
        radii=np.ones(1),
        edges=np.zeros((0, 2), np.int32),
        spacing=0.1,
        bounds=np.array([[-1.0, -1, -1], [1, 1, 1]]),
        config=config.mdbd,
        representation="implicit",
    )
    return [
        ShapeRecord(f"s{i}", one, x[i], config, f"h{i}", "implicit", label=f"c{i % 50}")
        for i in range(n)
    ]


def run_store(
    n: int, *, n_latency: int = 300, kernel: KernelConfig | None = None
) -> dict[str, Any]:
    """End-to-end ``query.search.engine.search`` latency on a real store of n synthetic shapes."""
    import query.database as database
    from query.learn.metric import LearnedMetric, block_layout
    from query.search.engine import search
    from query.search.index import open_index

    config = Config(kernel=kernel or KernelConfig())
    with tempfile.TemporaryDirectory() as tmp:
        db = database.connect(Path(tmp) / "store", config=config)
        records = synthetic_records(n, config)
        x = np.stack([r.feature for r in records])
        t0 = time.perf_counter()
        db.commit(records)
        commit = time.perf_counter() - t0
        t0 = time.perf_counter()
        open_index(db)
        build = time.perf_counter() - t0
        rng = np.random.default_rng(0)
        picks = rng.integers(1, n + 1, n_latency).tolist()
        lat, lat_where = [], []
        for sid in picks:
            t0 = time.perf_counter()
            search(db, int(sid), k=10)
            lat.append(time.perf_counter() - t0)
        for sid in picks[:50]:
            t0 = time.perf_counter()
            search(db, int(sid), k=10, where="label = 'c7'")
            lat_where.append(time.perf_counter() - t0)
        # a learned metric (query.learn.metric): the fit on the store's labels, then search
        # under a fixed non-identity weighting (its own index, built at first use)
        t0 = time.perf_counter()
        fitted = db.fit_metric(label="label")
        fit_s = time.perf_counter() - t0
        blocks = block_layout(config)
        metric = LearnedMetric(
            blocks=blocks,
            weights=tuple(1.0 + (i % 3) for i in range(len(blocks))),
            fingerprint=config.fingerprint,
            reg=0.1,
        )
        t0 = time.perf_counter()
        open_index(db, metric=metric)
        metric_build = time.perf_counter() - t0
        lat_metric = []
        for sid in picks:
            t0 = time.perf_counter()
            search(db, int(sid), k=10, metric=metric)
            lat_metric.append(time.perf_counter() - t0)
    p50, p99 = _percentiles(lat)
    w50, w99 = _percentiles(lat_where)
    m50, m99 = _percentiles(lat_metric)
    views = _views_store(n, x, picks, kernel=config.kernel)
    return {
        "n": n,
        "commit_s": commit,
        "index_build_s": build,
        "search_p50_ms": p50,
        "search_p99_ms": p99,
        "filtered_search_p50_ms": w50,
        "filtered_search_p99_ms": w99,
        "metric_fit_s": fit_s,
        "metric_fit_shapes": fitted.n_shapes,
        "metric_index_build_s": metric_build,
        "metric_search_p50_ms": m50,
        "metric_search_p99_ms": m99,
        **views,
    }


def _views_store(
    n: int, x: NDArray[np.float32], picks: list[int], *, kernel: KernelConfig
) -> dict[str, float]:
    """Search latency in a store with sparse views (``view_cells=4``), one in ten shapes sparse.

    Each dense shape's view feature is its feature perturbed; a sparse query searches
    both indexes (own features and views) and merges them, a dense one also reaches
    the sparse shapes through its view (``query.search.engine``).
    """
    import query.database as database
    from query.search.engine import search
    from query.search.index import open_index
    from shapedb.mdbd.decomposition import Decomposition
    from shapedb.store.schema import ShapeRecord

    config = Config(kernel=kernel, cloud=CloudConfig(view_cells=4.0))
    rng = np.random.default_rng(3)
    views = (x * rng.uniform(0.9, 1.1, x.shape)).astype(np.float32)
    sparse = np.arange(n) % 10 == 0
    dec = {
        flag: Decomposition(
            centers=np.zeros((1, 3)),
            radii=np.ones(1),
            edges=np.zeros((0, 2), np.int32),
            spacing=0.1,
            bounds=np.array([[-1.0, -1, -1], [1, 1, 1]]),
            config=config.mdbd,
            representation="pointcloud" if flag else "mesh",
            sampling=0.4 if flag else 0.0,  # 4 cells: a sparse cloud
        )
        for flag in (False, True)
    }
    with tempfile.TemporaryDirectory() as tmp:
        db = database.connect(Path(tmp) / "views", config=config)
        records = [
            ShapeRecord(
                f"s{i}",
                dec[bool(sparse[i])],
                x[i],
                config,
                f"h{i}",
                "mesh",
                view_feature=None if sparse[i] else views[i],
            )  # fmt: skip
            for i in range(n)
        ]
        db.commit(records)
        t0 = time.perf_counter()
        open_index(db)
        open_index(db, view=True)
        build = time.perf_counter() - t0
        ids = np.asarray(picks)
        sparse_ids = db.store.sparse_ids()
        lat: dict[str, list[float]] = {"sparse": [], "dense": []}
        for sid in ids.tolist():
            kind = "sparse" if np.isin(sid, sparse_ids) else "dense"
            t0 = time.perf_counter()
            search(db, int(sid), k=10)
            lat[kind].append(time.perf_counter() - t0)
        extra = db.store.sparse_ids()[:50]  # at least 50 sparse queries
        for sid in extra.tolist():
            t0 = time.perf_counter()
            search(db, int(sid), k=10)
            lat["sparse"].append(time.perf_counter() - t0)
    s50, s99 = _percentiles(lat["sparse"])
    d50, d99 = _percentiles(lat["dense"])
    return {
        "views_index_build_s": build,
        "views_sparse_search_p50_ms": s50,
        "views_sparse_search_p99_ms": s99,
        "views_dense_search_p50_ms": d50,
        "views_dense_search_p99_ms": d99,
    }


def format_table(rows: list[dict[str, Any]], columns: list[tuple[str, str, str]]) -> str:
    """Aligned plain-text table of ``rows`` with (key, header, format) columns."""
    cells = [[h for _, h, _ in columns]] + [
        [f.format(r[key]) for key, _, f in columns] for r in rows
    ]
    widths = [max(len(c[i]) for c in cells) for i in range(len(columns))]
    lines = ["  ".join(c.rjust(wd) for c, wd in zip(row, widths, strict=True)) for row in cells]
    lines.insert(1, "  ".join("-" * wd for wd in widths))
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--store-sizes", type=int, nargs="*", default=[10_000])
    parser.add_argument("--queries", type=int, default=1000, help="queries for recall@10")
    parser.add_argument("--latency-queries", type=int, default=1000)
    parser.add_argument("--baseline-queries", type=int, default=50)
    parser.add_argument(
        "--method",
        choices=("mdbd", "paper"),
        default=KernelConfig().method,
        help="feature vectors: the default descriptor (mdbd) or the paper's Eq. 1 (paper)",
    )
    parser.add_argument("--out", type=Path, default=RESULTS)
    return parser


def _machine(load_start: tuple[float, float, float]) -> dict[str, Any]:
    """CPUs, faiss build and threads, and the load average at the start and now."""
    import faiss

    return {
        "cpus": os.cpu_count(),
        "faiss_threads": faiss.omp_get_max_threads(),
        "python": platform.python_version(),
        "faiss": faiss.__version__,
        "faiss_simd": faiss.get_compile_options(),
        "load_average_start": load_start,
        "load_average_end": os.getloadavg(),
    }


def _print_tables(rows: list[dict[str, Any]], stores: list[dict[str, Any]]) -> None:
    """The index rows against the numpy baseline, then the store rows (plain and with views)."""
    print("Feature index (faiss candidates + exact Eq. 2 re-rank) vs numpy brute force, k=10")
    print(
        format_table(
            rows,
            [
                ("n", "vectors", "{:,}"),
                ("kind", "index", "{}"),
                ("recall_at_10", "recall@10", "{:.4f}"),
                ("p50_ms", "p50 ms", "{:.2f}"),
                ("p99_ms", "p99 ms", "{:.2f}"),
                ("build_s", "build s", "{:.1f}"),
                ("index_rss_mb", "RSS MB", "{:.0f}"),
                ("index_disk_mb", "disk MB", "{:.0f}"),
                ("baseline_p50_ms", "numpy p50 ms", "{:.2f}"),
                ("baseline_p99_ms", "numpy p99 ms", "{:.2f}"),
            ],
        )
    )
    if not stores:
        return
    print("\nEnd-to-end search(db, id, k=10) on a real store")
    print(
        format_table(
            stores,
            [
                ("n", "shapes", "{:,}"),
                ("search_p50_ms", "p50 ms", "{:.2f}"),
                ("search_p99_ms", "p99 ms", "{:.2f}"),
                ("filtered_search_p50_ms", "where p50 ms", "{:.2f}"),
                ("filtered_search_p99_ms", "where p99 ms", "{:.2f}"),
                ("index_build_s", "index build s", "{:.2f}"),
                ("metric_search_p50_ms", "metric p50 ms", "{:.2f}"),
                ("metric_search_p99_ms", "metric p99 ms", "{:.2f}"),
                ("metric_index_build_s", "metric index s", "{:.2f}"),
                ("metric_fit_s", "fit_metric s", "{:.1f}"),
            ],
        )
    )
    print("\nThe same in a store with sparse views (view_cells=4, a tenth of the shapes sparse)")
    print(
        format_table(
            stores,
            [
                ("n", "shapes", "{:,}"),
                ("views_sparse_search_p50_ms", "sparse query p50 ms", "{:.2f}"),
                ("views_sparse_search_p99_ms", "p99 ms", "{:.2f}"),
                ("views_dense_search_p50_ms", "dense query p50 ms", "{:.2f}"),
                ("views_dense_search_p99_ms", "p99 ms", "{:.2f}"),
                ("views_index_build_s", "both indexes s", "{:.2f}"),
            ],
        )
    )


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    kernel = KernelConfig(method=args.method)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    logging.getLogger("faiss.loader").setLevel(logging.WARNING)
    load_start = os.getloadavg()

    started = time.perf_counter()
    rows = [
        run_size(
            n,
            n_queries=args.queries,
            n_latency=args.latency_queries,
            n_baseline=args.baseline_queries,
            config=kernel,
        )
        for n in args.sizes
    ]
    stores = [run_store(n, kernel=kernel) for n in args.store_sizes]
    result = {
        "machine": _machine(load_start),
        "kernel": {
            "method": kernel.method,
            "descriptor": Config(kernel=kernel).descriptor.version,
            "dim": Config(kernel=kernel).dim,
        },
        "index": rows,
        "store_search": stores,
        "total_seconds": time.perf_counter() - started,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))
    _print_tables(rows, stores)
    print(f"\n{result['total_seconds']:.0f} s in all; written to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
