"""The measurements of ``python -m bench.scale`` on one store at one size.

Each function takes a connected :class:`query.database.Database` and returns a flat dict
of figures (seconds, milliseconds, bytes); ``bench.scale`` runs them as the store grows
and prints the table. Times are wall-clock medians or percentiles of repeated calls;
memory is the process's resident set (``/proc/self/status``), or a child's.
"""

from __future__ import annotations

import ctypes
import gc
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.compute as pc
import pyarrow.dataset as ds

__all__ = [
    "rss_mb",
    "peak_mb",
    "trim_memory",
    "timed",
    "percentiles",
    "store_figures",
    "commit_figures",
    "table_figures",
    "search_figures",
    "sql_figures",
    "candidate_recall",
    "reference_ranks",
    "part_figures",
    "ingest_figures",
]


def rss_mb(pid: int | str = "self", field: str = "VmRSS") -> float:
    """Resident set (``VmRSS``), its peak (``VmHWM``) or its anonymous part (``RssAnon``:
    not the pages of memory-mapped files, which the system reclaims) of a process, MB."""
    with open(f"/proc/{pid}/status") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")


def peak_mb() -> float:
    """This process's peak resident set so far, MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def trim_memory() -> float:
    """Collect garbage and hand the freed heap back to the system (glibc and Arrow's
    memory pool keep freed blocks for reuse, so a process that released its indexes and
    scanned every ball still holds their pages: 6.6 GB at 10^6 without Arrow's release);
    returns this process's resident set afterwards, MB."""
    import pyarrow as pa

    gc.collect()
    pa.default_memory_pool().release_unused()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: nothing to hand back this way
        pass
    return rss_mb()


def timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    """(seconds, result) of one call."""
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out


def percentiles(seconds: list[float]) -> dict[str, float]:
    """p50 and p99 in milliseconds."""
    a = np.asarray(seconds, np.float64) * 1e3
    return {"p50_ms": float(np.percentile(a, 50)), "p99_ms": float(np.percentile(a, 99))}


def _du(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def store_figures(db: Any) -> dict[str, Any]:
    """Bytes on disk per shape (tables, and the derived folders beside them), open time,
    segment counts, ``shapedb check`` time."""
    import shapedb
    from shapedb.store.integrity import check

    root = Path(db.path)
    n = len(db)
    data = _du(root / "data")
    derived = {p.name: _du(p) for p in root.iterdir() if p.is_dir() and p.name != "data"}
    opens = []
    for _ in range(3):
        t, other = timed(lambda: len(shapedb.connect(root, create=False)))
        opens.append(t)
    t_check, report = timed(lambda: check(root))
    return {
        "shapes": n,
        "table_bytes_per_shape": data / max(n, 1),
        "derived_bytes_per_shape": sum(derived.values()) / max(n, 1),
        "derived_bytes": derived,
        "open_s": float(np.median(opens)),
        "segments": {t: len(db.store.files(t)) for t in ("shapes", "balls", "edges")},
        "check_s": t_check,
        "check_ok": bool(getattr(report, "ok", True)),
    }


def commit_figures(db: Any, records: list[list[Any]]) -> dict[str, Any]:
    """Latency of 1,000-shape commits (the last batches of a store's growth): the whole
    ``db.commit`` (with the derived state already on disk kept up to date) and, within it,
    the store's own commit (Parquet segments and manifest)."""
    store_s: list[float] = []
    commit = db.store.commit

    def timed_store(*args: Any, **kwargs: Any) -> Any:
        t, out = timed(lambda: commit(*args, **kwargs))
        store_s.append(t)
        return out

    whole = []
    db.store.commit = timed_store
    try:
        for batch in records:
            whole.append(timed(lambda b=batch: db.commit(b))[0])
    finally:
        del db.store.commit
    return {"store_commit_s": float(np.median(store_s)), "db_commit_s": float(np.median(whole))}


def search_figures(db: Any, ids: np.ndarray) -> dict[str, Any]:
    """``db.search(id)`` of stored ids, twice over: the first pass opens or builds the
    indexes (its first search) and computes what the stage's side tables do not hold yet
    for these queries' candidates (cold); the second pass is what a store whose tables
    are kept at commit serves (warm): p50 / p99 of each."""
    rss0 = rss_mb()
    t_first, _ = timed(lambda: db.search(int(ids[0])))
    cold = [timed(lambda s=int(sid): db.search(s))[0] for sid in ids[1:]]
    warm, results = [], {}
    for sid in ids[1:]:
        t, hits = timed(lambda s=int(sid): db.search(s))
        warm.append(t)
        results[int(sid)] = [h.id for h in hits]
    return {
        "first_search_s": t_first,
        "cold_p50_ms": percentiles(cold)["p50_ms"],
        **percentiles(warm),
        "rss_growth_mb": rss_mb() - rss0,
        "results": results,
    }


def sql_figures(db: Any, probe: int) -> dict[str, Any]:
    """The four SQL statements through ``db.sql``, with plain DuckDB and a pyarrow scan
    over the same Parquet files as baselines."""
    import duckdb

    files = {t: [str(Path(db.path) / f) for f in db.store.files(t)] for t in ("shapes", "balls")}
    statements = {
        "group_by_label": "select label, count(*) from shapes group by label",
        "balls_aggregate": "select count(*), avg(r), max(r_norm) from balls",
        "shapes_join_balls": (
            "select s.label, avg(b.r) from shapes s join balls b on b.shape_id = s.id"
            " group by s.label"
        ),
        "mdbd_distance_rank": (
            "select id, mdbd_distance(feature, (select feature from shapes where id = "
            f"{int(probe)})) as d from shapes order by d limit 10"
        ),
    }
    out: dict[str, Any] = {}
    db.sql("select 1")  # the first statement of a process starts DuckDB
    for name, statement in statements.items():
        runs = [timed(lambda s=statement: db.sql(s, timeout=None))[0] for _ in range(3)]
        out[f"sql_{name}_s"] = float(np.median(runs))
    con = duckdb.connect()
    plain = {
        "group_by_label": (
            f"select label, count(*) from read_parquet({files['shapes']!r}) group by label"
        ),
        "balls_aggregate": (
            f"select count(*), avg(r), max(r_norm) from read_parquet({files['balls']!r})"
        ),
    }
    for name, statement in plain.items():
        runs = [timed(lambda s=statement: con.sql(s).fetchall())[0] for _ in range(3)]
        out[f"duckdb_{name}_s"] = float(np.median(runs))

    def scan() -> Any:
        t = ds.dataset(files["balls"], format="parquet").to_table(columns=["r", "r_norm"])
        return pc.mean(t.column("r")), pc.max(t.column("r_norm"))

    out["pyarrow_balls_aggregate_s"] = float(np.median([timed(scan)[0] for _ in range(3)]))
    return out


def candidate_recall(db: Any, ids: np.ndarray, k: int = 100) -> dict[str, Any]:
    """Recall@k of the feature index's candidates (what the stage re-ranks) against an
    exact scan of the same vectors (faiss flat L1 over the weighted vectors), and of the
    field vector index's 200 proposals against its exact scan."""
    from query.search.field_fusion import FieldFusion
    from query.search.field_index import field_index
    from query.search.index import FeatureIndex, open_index
    from query.search.rerank_lightfield import stored_arrays

    out: dict[str, Any] = {}
    index = open_index(db)
    out["index"] = index.kind_
    if index.kind_ != "flat":
        live = index.alive_
        exact = FeatureIndex(kind="flat").fit(
            index.ids_[live], index.features_[live], index.weights_
        )
        q = np.asarray(index.features_, np.float64)[index.lookup(ids)]
        got, _ = index.search(q, k)
        want, _ = exact.search(q, k)
        out[f"candidate_recall@{k}"] = _overlap(got, want)
    fusion = FieldFusion.from_config(db.config)
    if fusion.proposes:
        fields = field_index(db)
        vectors = fusion.scaled(stored_arrays(db)("field_vector", np.asarray(ids, np.int64)))
        n = int(fusion.candidates)
        got, _ = fields.search(vectors, n)
        want, _ = fields.search(vectors, n, allowed=fields.ids_[fields.alive_])  # exact scan
        out[f"field_recall@{n}"] = _overlap(got, want)
    return out


def _overlap(got: np.ndarray, want: np.ndarray) -> float:
    hits = [
        len(set(g.tolist()) & set(w[w >= 0].tolist())) / max(int((w >= 0).sum()), 1)
        for g, w in zip(got, want, strict=True)
    ]
    return float(np.mean(hits))


_REFERENCE = """
import json, sys
import shapedb
from query.search import field_index
from query.search.index import build_index
field_index.SCAN_MAX = 1 << 62  # every field proposal by the exact scan
db = shapedb.connect(sys.argv[1], create=False)
build_index(db, kind="flat")
out = {}
for sid in json.loads(sys.argv[2]):
    out[sid] = [h.id for h in db.search(int(sid))]
print(json.dumps(out))
"""


def reference_ranks(db: Any, ids: list[int], timeout: float) -> dict[int, list[int]] | str | None:
    """The exact default ranking of stored ids: in a child process, over a view of the
    same segments (a new folder whose manifest is a copy and whose ``data`` is a link), with
    an exact feature index, exact field vector proposals and side tables computed fresh.
    None when it does not finish within ``timeout`` seconds; the last line of its error
    output (or its exit status) when it fails."""
    import json

    with tempfile.TemporaryDirectory(prefix="scale-ref-") as tmp:
        view = Path(tmp) / "store"
        view.mkdir()
        shutil.copy2(Path(db.path) / "manifest.json", view / "manifest.json")
        os.symlink(Path(db.path) / "data", view / "data")
        try:
            done = subprocess.run(
                [sys.executable, "-c", _REFERENCE, str(view), json.dumps([int(i) for i in ids])],
                capture_output=True, text=True, timeout=timeout, check=True,
            )  # fmt: skip
        except subprocess.TimeoutExpired:
            return None
        except subprocess.CalledProcessError as exc:
            lines = (exc.stderr or "").strip().splitlines()
            return lines[-1] if lines else f"exit status {exc.returncode}"
        got = json.loads(done.stdout.strip().splitlines()[-1])
        return {int(k): v for k, v in got.items()}


def part_figures(db: Any, rng: np.random.Generator, queries: int = 50) -> dict[str, Any]:
    """The part index (built or brought up to date here): build time and memory, p50 / p99
    of a stored part's search and recall@10 (by shape) against the exact scan."""
    from query.parts.store_index import open_parts_index

    gc.collect()
    rss0 = rss_mb()
    t_open, index = timed(lambda: open_parts_index(db))
    rss1 = rss_mb()
    n = len(index.features_)
    picks = rng.choice(n, min(queries, n), replace=False)
    times, recall = [], []
    for p in picks:
        q = np.asarray(index.features_[p], np.float64)
        t, (shapes, _, _) = timed(lambda q=q: index.search(q, 10))
        times.append(t)
        want, _, _ = index.exact_search(q, 10)
        recall.append(len(set(shapes.tolist()) & set(want.tolist())) / max(len(want), 1))
    return {
        "part_vectors": n,
        "part_open_s": t_open,
        "part_rss_mb": rss1 - rss0,
        "part_peak_mb": peak_mb(),
        **{f"part_{k}": v for k, v in percentiles(times).items()},
        "part_recall@10": float(np.mean(recall)),
    }


def ingest_figures(db: Any, model: Path, config: Any) -> dict[str, Any]:
    """Ingest of one real file into the store, against the same file into a new, empty
    store of the same configuration (the baseline, run first so that neither pays this
    process's first imports), in this process."""
    import shapedb

    with tempfile.TemporaryDirectory(prefix="scale-empty-") as tmp:
        empty = shapedb.connect(Path(tmp) / "s", config=config)
        t_empty, _ = timed(lambda: empty.ingest([model], workers=1, progress=False))
    t_full, _ = timed(lambda: db.ingest([model], workers=1, progress=False))
    return {"ingest_one_s": t_full, "ingest_one_empty_s": t_empty}


def table_figures(db: Any) -> dict[str, Any]:
    """The ranking stage's side tables (spreads, shared-neighbour lists): when the store has
    none on disk, built exactly here (``refresh``, the whole store); the seconds it took."""
    from query.search import lightfield_neighbours, lightfield_spread
    from query.search.rerank_lightfield import LightFieldFusion, stored_arrays
    from query.search.versioned import POINTER

    root = Path(db.path)
    if db.config.rerank.scorer != "lightfield":
        return {}
    t = 0.0
    fields = stored_arrays(db)
    if not (root / lightfield_spread.SPREAD_DIR / POINTER).exists():
        t += timed(lambda: lightfield_spread.refresh(db, fields))[0]
    if not (root / lightfield_neighbours.NEIGHBOUR_DIR / POINTER).exists():
        stage = LightFieldFusion(db.config)
        t += timed(lambda: lightfield_neighbours.refresh(db, fields, stage))[0]
    return {"tables_s": t} if t else {}
