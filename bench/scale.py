"""A store at 10^4, 10^5 and 10^6 shapes: storage, commits, search, SQL, parts and ingest.

``python -m bench.scale --sizes 10000 100000 1000000`` grows ONE store through the
product's write path (``Database.commit`` of 10,000-shape batches) and measures it at
each size. The records are made from the real records of a seed store (by default the
CAPOD models of ``../shared/data/capod``, ingested once into ``--seed-store``) by
perturbing centres, radii and ball counts and mixing descriptors, light fields and field
vectors within a class (:mod:`bench.support.synthetic_records` says exactly how), so
every record has real-shaped balls, edges and vectors.

At each size (:mod:`bench.support.scale_measures`):

* **store**: table bytes per shape and those of the derived folders (indexes, tables),
  open time, segments, ``shapedb check``; latency of a 1,000-shape commit, the store's
  own and the whole ``db.commit``;
* **search**: ``db.search(id)``: the first search of a process (indexes loaded or built)
  and p50 / p99 of the next; the same over HTTP in ``shapedb serve`` (a child process),
  with its peak resident set; recall@100 of the feature index's candidates against an
  exact scan; recall@10 of the whole default path against the exact default ranking
  (exact indexes, side tables computed fresh: a child process, ``--reference-queries``
  queries, skipped past ``--reference-max`` shapes);
* **SQL**: group by label, an aggregate over every ball, a join of shapes and balls and
  an ``mdbd_distance`` ranking of every shape, through ``db.sql``; plain DuckDB and a
  pyarrow scan over the same Parquet files as baselines;
* **parts**: the part index (``shapedb match``) up to ``--part-max`` shapes: build,
  memory, p50 / p99, recall@10 against its exact scan;
* **ingest**: one real file into the grown store against the same into an empty store;
* **compressed vectors** (``--vectors``, after the sizes): the descriptor index alone at
  10^7 vectors made from the grown store's, compressed (:mod:`bench.support.scale_vectors`).

Writes ``bench/results/scale.json`` after every phase (a long run keeps what it measured)
and prints the table after every size. The store lives in ``--dir``, which is kept (a
store already there is grown further), or in a temporary folder removed at the end unless
``--keep``. Check the free disk first: about 26 KB a shape for the tables, more for the
indexes beside them.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json
from bench.support import scale_measures as m
from bench.support.synthetic_records import RecordMaker
from query.parts.index import PARTS_DIR
from query.search.lightfield_neighbours import NEIGHBOUR_DIR
from query.search.lightfield_spread import SPREAD_DIR

log = logging.getLogger("bench.scale")

RESULTS = Path(__file__).parent / "results" / "scale.json"
CAPOD = Path(__file__).resolve().parents[2] / "shared" / "data" / "capod"
#: Shapes per commit while the store grows.
GROW_BATCH = 10_000
#: 1,000-shape commits timed at the end of each growth.
TIMED_COMMITS = 3
#: Fewest vectors of the compressed index (its product quantiser trains 256 centroids).
MIN_VECTORS = 1000
#: Seconds one search over HTTP may take (a cold one at 10^6 took over 120 s on 2 busy cores).
COLD_TIMEOUT = 1800.0


def seed_records(seed_store: Path) -> list[Any]:
    """The records of the seed store, ingesting CAPOD into it first when it is missing."""
    import shapedb

    if not (seed_store / "manifest.json").exists():
        if not CAPOD.is_dir():
            raise SystemExit(f"no seed store at {seed_store} and no CAPOD models at {CAPOD}")
        log.info("ingesting the CAPOD models into %s (once)", seed_store)
        db = shapedb.connect(seed_store)
        db.ingest([CAPOD], labels=CAPOD / "labels.csv", progress=False)
    db = shapedb.connect(seed_store, create=False)
    return [db.store.get(int(i)) for i in db.store.ids()]


def probe_model(folder: Path, seeds: list[Any], n: int) -> Path:
    """A real model file not in the store: a seed's source (or, when none is on this
    machine, a built-in example shape), scaled by a size-dependent factor so its content
    (and hash) is new."""
    import trimesh

    from shapedb.examples import catalogue, to_mesh

    source = next((Path(s.source) for s in seeds if s.source and Path(s.source).is_file()), None)
    if source is not None:
        mesh = trimesh.load(source, force="mesh")
    else:
        mesh = to_mesh(catalogue()[0][2], resolution=48)
    mesh.apply_scale(1.0 + 1e-3 * (1 + np.log10(max(n, 1))))
    out = folder / f"probe-{n}.obj"
    mesh.export(out)
    return out


def grow(db: Any, maker: RecordMaker, target: int, made: int) -> tuple[int, float, dict[str, Any]]:
    """Commit synthetic records until the store holds ``target``: batches of
    :data:`GROW_BATCH`, the last :data:`TIMED_COMMITS` of 1,000 shapes timed. Returns the
    records made so far, the seconds and the commit figures (empty when the store
    already held ``target``)."""
    t = time.perf_counter()
    timed_from = target - TIMED_COMMITS * 1000
    while len(db) < min(timed_from, target):
        count = min(GROW_BATCH, timed_from - len(db))
        db.commit(maker.batch(made, count))
        made += count
        log.info("%d shapes (%.0f s)", len(db), time.perf_counter() - t)
    batches = []
    while len(db) + 1000 * len(batches) < target:
        count = min(1000, target - len(db) - 1000 * len(batches))
        batches.append(maker.batch(made, count))
        made += count
    figures = m.commit_figures(db, batches) if batches else {}
    return made, time.perf_counter() - t, figures


def serve_figures(root: Path, ids: np.ndarray) -> dict[str, Any]:
    """``GET /api/search?id=`` in ``shapedb serve``, one request at a time: two passes over
    the ids as :func:`bench.support.scale_measures.search_figures` (cold, warm), the
    server's peak resident set and, at the end, its anonymous part (what it holds itself,
    without the pages of the memory-mapped rows it read)."""
    import http.client

    from bench.serve import Server, get_timed

    server = Server(root)
    try:
        # a cold search of a large store computes side tables for minutes on loaded cores
        conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=COLD_TIMEOUT)

        own: list[float] = []  # the server's own milliseconds (its Server-Timing header)

        def one(sid: int) -> float:
            t, (status, _, ms) = m.timed(lambda: get_timed(conn, f"/api/search?id={sid}&k=10"))
            if status != 200:
                raise RuntimeError(f"search of {sid} answered {status}")
            own.append(ms / 1e3)
            return t

        first = one(int(ids[0]))
        cold = [one(int(s)) for s in ids[1:]]
        own.clear()
        warm = [one(int(s)) for s in ids[1:]]
        return {
            "serve_first_s": first,
            "serve_cold_p50_ms": m.percentiles(cold)["p50_ms"],
            **{f"serve_{k}": v for k, v in m.percentiles(warm).items()},
            "serve_own_p50_ms": m.percentiles(own)["p50_ms"],
            "serve_peak_mb": m.rss_mb(server.proc.pid, "VmHWM"),
            "serve_anon_mb": m.rss_mb(server.proc.pid, "RssAnon"),
        }
    finally:
        server.stop()


def vector_figures(db: Any, n: int, folder: Path) -> dict[str, Any]:
    """The compressed descriptor index of ``n`` vectors made from the store's weighted
    descriptors (:func:`bench.support.scale_vectors.compressed_figures`); its float32
    vectors are written to a temporary file in ``folder`` and removed after."""
    from bench.support.scale_vectors import compressed_figures
    from query.search.index import open_index

    index = open_index(db)
    live = np.flatnonzero(index.alive_)
    take = np.sort(np.random.default_rng(1).choice(live, min(len(live), 1_000_000), replace=False))
    source = np.asarray(index.features_[take], np.float32) * np.asarray(index.weights_, np.float32)
    free = shutil.disk_usage(folder).free
    if free < 1.2 * n * source.shape[1] * 4:
        raise SystemExit(f"{folder}: {free / 1e9:.1f} GB free, {n:,} vectors need "
                         f"{n * source.shape[1] * 4 / 1e9:.1f} GB")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="scale-vectors-", dir=folder) as tmp:
        return compressed_figures(source, n, Path(tmp))


def drop_derived(db: Any, names: tuple[str, ...], why: str) -> None:
    """Remove derived folders of the benchmark's own store (the stage's side tables, the
    part index), so growing past ``--tables-max`` or ``--part-max`` does not keep them up
    to date for every new shape (tens of milliseconds a shape each)."""
    for name in names:
        if (Path(db.path) / name).is_dir():
            log.info("growing past %s: %s of %s dropped", why, name, db.path)
            shutil.rmtree(Path(db.path) / name)


def measure(db: Any, args: argparse.Namespace, seeds: list[Any], rng: np.random.Generator,
            out: dict[str, Any], save: Callable[[], None]) -> None:  # fmt: skip
    """Every figure at the store's current size, into ``out``; ``save()`` after each phase
    (the cheap ones first: a run stopped during a long index build keeps them)."""
    n = len(db)
    ids = db.store.ids()
    out["shapes"] = n
    out.update(m.store_figures(db))
    out.update(m.sql_figures(db, int(ids[0])))
    save()
    if n <= args.tables_max:
        out.update(m.table_figures(db))
    # serve first, with this process's indexes released: the growth's commits kept the
    # feature index and array copies here (10.7 GB at 10^6), and with them held the
    # server's memory-mapped rows left the page cache (warm p50 1.75 s against 24 ms)
    db.close()
    out["bench_rss_at_serve_mb"] = m.trim_memory()
    out.update(serve_figures(Path(db.path), rng.choice(ids, args.queries + 1, replace=False)))
    save()
    sample = rng.choice(ids, args.queries + 1, replace=False)
    searched = m.search_figures(db, sample)
    results = searched.pop("results")
    out.update(searched)
    save()
    out.update(m.candidate_recall(db, sample[:50]))
    if n <= args.reference_max:
        wanted = [int(i) for i in list(results)[: args.reference_queries]]
        # the reference's exact indexes need the memory this process's searches hold
        # (17 GB at 10^6 with them: the child ran out)
        db.close()
        m.trim_memory()
        ref = m.reference_ranks(db, wanted, timeout=args.reference_timeout)
        if isinstance(ref, str):
            out["recall@10_failed"] = ref
            log.warning("the exact reference failed: %s", ref)
        elif ref is not None:
            got = [len(set(results[i]) & set(ref[i])) / 10 for i in wanted]
            out["recall@10"] = float(np.mean(got))
    save()
    if n <= args.part_max:
        out.update(m.part_figures(db, rng))
        save()
    with tempfile.TemporaryDirectory(prefix="scale-model-") as tmp:
        out.update(m.ingest_figures(db, probe_model(Path(tmp), seeds, n), db.config))
    after = m.store_figures(db)  # with the indexes the searches built
    out["derived_bytes_per_shape"] = after["derived_bytes_per_shape"]
    out["derived_bytes"] = after["derived_bytes"]
    save()


_COLUMNS = [
    ("shapes", "shapes", "{:,}"),
    ("KB/shape tables", "table_bytes_per_shape", "{:.1f}", 1e-3),
    ("KB/shape derived", "derived_bytes_per_shape", "{:.1f}", 1e-3),
    ("open s", "open_s", "{:.2f}"),
    ("check s", "check_s", "{:.1f}"),
    ("commit 1k s (store / db)", ("store_commit_s", "db_commit_s"), "{:.2f} / {:.2f}"),
    ("side tables s", "tables_s", "{:.0f}"),
    ("first search s", "first_search_s", "{:.1f}"),
    ("search cold p50 ms", "cold_p50_ms", "{:.0f}"),
    ("search p50 / p99 ms", ("p50_ms", "p99_ms"), "{:.1f} / {:.1f}"),
    ("serve cold p50 ms", "serve_cold_p50_ms", "{:.0f}"),
    ("serve p50 / p99 ms", ("serve_p50_ms", "serve_p99_ms"), "{:.1f} / {:.1f}"),
    ("serve's own p50 ms", "serve_own_p50_ms", "{:.1f}"),
    ("serve peak MB (own at the end)", ("serve_peak_mb", "serve_anon_mb"), "{:,.0f} ({:,.0f})"),
    ("bench's own MB beside serve", "bench_rss_at_serve_mb", "{:,.0f}"),
    ("cand. recall@100", "candidate_recall@100", "{:.3f}"),
    ("field recall@200", "field_recall@200", "{:.3f}"),
    ("recall@10", "recall@10", "{:.3f}"),
    ("SQL label s (duckdb)", ("sql_group_by_label_s", "duckdb_group_by_label_s"),
     "{:.2f} ({:.2f})"),
    ("SQL balls s (duckdb / pyarrow)",
     ("sql_balls_aggregate_s", "duckdb_balls_aggregate_s", "pyarrow_balls_aggregate_s"),
     "{:.1f} ({:.1f} / {:.1f})"),
    ("SQL join s", "sql_shapes_join_balls_s", "{:.1f}"),
    ("SQL mdbd rank s", "sql_mdbd_distance_rank_s", "{:.1f}"),
    ("parts p50 / p99 ms", ("part_p50_ms", "part_p99_ms"), "{:.1f} / {:.1f}"),
    ("parts recall@10", "part_recall@10", "{:.3f}"),
    ("parts MB", "part_rss_mb", "{:,.0f}"),
    ("ingest 1 file s (empty store)", ("ingest_one_s", "ingest_one_empty_s"),
     "{:.1f} ({:.1f})"),
]  # fmt: skip


def _cell(row: dict[str, Any], key: Any, fmt: str, scale: float = 1.0) -> str:
    keys = key if isinstance(key, tuple) else (key,)
    if any(k not in row for k in keys):
        return "-"
    return fmt.format(*(row[k] * scale if scale != 1.0 else row[k] for k in keys))


def report(rows: list[dict[str, Any]]) -> str:
    """The table: one column per size, one row per figure."""
    header = ["figure"] + [f"{r['shapes']:,}" for r in rows]
    lines = []
    for title, key, fmt, *scale in _COLUMNS[1:]:
        lines.append([title] + [_cell(r, key, fmt, *scale) for r in rows])
    return format_table("bench.scale", header, lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    p.add_argument("--dir", type=Path, help="the grown store's folder (default: a temp folder)")
    p.add_argument(
        "--seed-store", type=Path, default=Path(tempfile.gettempdir()) / "shapedb-scale-seed"
    )
    p.add_argument("--queries", type=int, default=50, help="searches timed at each size")
    p.add_argument("--reference-queries", type=int, default=10)
    p.add_argument("--reference-max", type=int, default=1_000_000)
    p.add_argument("--reference-timeout", type=float, default=3600.0)
    p.add_argument(
        "--part-max", type=int, default=10_000, help="build the part index up to this size"
    )
    p.add_argument(
        "--tables-max",
        type=int,
        default=10_000,
        help="build the ranking stage's side tables up to this size",
    )
    p.add_argument(
        "--grow-only", action="store_true", help="grow the store; measure only its last commits"
    )
    p.add_argument(
        "--keep",
        action="store_true",
        help="keep the grown temporary store (a --dir is always kept; a store there grows)",
    )
    p.add_argument(
        "--vectors",
        type=int,
        default=10_000_000,
        help="vectors of the compressed descriptor index measured last (0: skip)",
    )
    p.add_argument("--out", type=Path, default=RESULTS)
    args = p.parse_args(argv)
    if args.vectors and args.vectors < MIN_VECTORS:
        p.error(f"--vectors {args.vectors}: 0 (skip) or at least {MIN_VECTORS:,}")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    import shapedb

    seeds = seed_records(args.seed_store)
    root = args.dir or Path(tempfile.mkdtemp(prefix="shapedb-scale-")) / "store"
    resumed = (root / "manifest.json").exists()
    db = shapedb.connect(root, config=None if resumed else seeds[0].config)
    made = int(db.store.ids().max()) + 1 if len(db) else 0
    maker, rng = RecordMaker(seeds), np.random.default_rng(0)
    rows: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    try:
        for size in sorted(args.sizes):
            if size > args.tables_max:
                drop_derived(db, (SPREAD_DIR, NEIGHBOUR_DIR), "--tables-max")
            if size > args.part_max:
                drop_derived(db, (PARTS_DIR,), "--part-max")
            made, grow_s, commits = grow(db, maker, size, made)
            row: dict[str, Any] = {"shapes": len(db), **commits, "grow_s": grow_s}
            rows.append(row)

            def save(row: dict[str, Any] = row) -> None:
                row["elapsed_s"] = time.perf_counter() - t0
                write_json(args.out, {"seeds": len(seeds), "sizes": rows, "load": os.getloadavg()})

            if args.grow_only:  # the growth's timed commits only
                save()
                continue
            measure(db, args, seeds, rng, row, save)
            print(report(rows), flush=True)
        if args.vectors:
            vectors = vector_figures(db, args.vectors, root.parent)
            write_json(args.out, {"seeds": len(seeds), "sizes": rows, "vectors": vectors,
                                  "load": os.getloadavg()})  # fmt: skip
            print(format_table("bench.scale: compressed descriptor index", ["figure", "value"],
                               [[k, str(v)] for k, v in vectors.items() if k != "settings"]),
                  format_table("its settings", ["nprobe", "re-ranked", "p50 ms", "p99 ms",
                                                "recall@10"],
                               [[r["nprobe"], r["rerank"], r["p50_ms"], r["p99_ms"],
                                 r["recall@10"]] for r in vectors["settings"]]),
                  sep="\n", flush=True)  # fmt: skip
    finally:
        if args.dir is None and not args.keep:  # a --dir given is the user's: kept
            shutil.rmtree(root.parent, ignore_errors=True)
    print(json.dumps({"elapsed_s": time.perf_counter() - t0}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
