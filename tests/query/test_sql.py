"""db.sql: views over the manifest's files, Eq. 2/3 macros agreeing with search."""

from __future__ import annotations

import numpy as np
import pytest
from query_helpers import CONFIG

from query.search.engine import search
from query.sql import connect, sql
from shapedb.errors import ConfigError, QueryError
from shapedb.signature.kernel import distance, weights


def test_issue_example_agrees_with_search(tmp_db):
    t = sql(
        tmp_db,
        "SELECT s.id, s.name, mdbd_kernel(s.feature, q.feature) AS k "
        "FROM shapes s, shapes q WHERE q.name = 'torus1' ORDER BY k DESC, s.id LIMIT 5",
    )
    hits = search(tmp_db, "torus1", k=5)
    assert t.column("id").to_pylist() == [h.id for h in hits]
    np.testing.assert_allclose(t.column("k").to_numpy(), [h.similarity for h in hits], rtol=1e-12)


def test_distance_macro_matches_eq2(tmp_db):
    t = sql(
        tmp_db,
        "SELECT a.feature AS fa, b.feature AS fb, mdbd_distance(a.feature, b.feature) AS d "
        "FROM shapes a, shapes b",
    )
    fa = np.array(t.column("fa").to_pylist(), np.float64)
    fb = np.array(t.column("fb").to_pylist(), np.float64)
    ref = [distance(x, y, CONFIG.kernel) for x, y in zip(fa, fb, strict=True)]
    np.testing.assert_allclose(t.column("d").to_numpy(), ref, rtol=1e-12, atol=1e-15)
    w = sql(tmp_db, "SELECT mdbd_weights() AS w").column("w")[0].as_py()
    np.testing.assert_allclose(w, weights(CONFIG.kernel))


def test_views_cover_the_store(tmp_db):
    n = len(tmp_db.store)
    assert sql(tmp_db, "SELECT count(*) AS n FROM shapes").column("n")[0].as_py() == n
    balls = sql(tmp_db, "SELECT shape_id, count(*) AS c FROM balls GROUP BY shape_id")
    assert balls.num_rows == n
    per_shape = dict(
        zip(balls.column("shape_id").to_pylist(), balls.column("c").to_pylist(), strict=True)
    )
    stored = tmp_db.store.shapes(["id", "n_balls"]).to_pylist()
    assert all(per_shape[r["id"]] == r["n_balls"] for r in stored)
    edges = sql(tmp_db, "SELECT count(*) AS m FROM edges").column("m")[0].as_py()
    assert edges == len(tmp_db.store.edges())
    assert sql(tmp_db, "SELECT count(*) AS f FROM failures").column("f")[0].as_py() == 0


def test_deleted_shapes_are_gone(tmp_db):
    tmp_db.delete(["box0", "torus2"])
    names = set(sql(tmp_db, "SELECT name FROM shapes").column("name").to_pylist())
    assert not names & {"box0", "torus2"} and len(names) == len(tmp_db.store)
    assert (
        sql(tmp_db, "SELECT count(*) AS n FROM balls WHERE shape_id NOT IN (SELECT id FROM shapes)")
        .column("n")[0]
        .as_py()
        == 0
    )


def test_empty_store(tmp_path):
    import query.database as database

    db = database.connect(tmp_path / "empty", config=CONFIG)
    for table in ("shapes", "balls", "edges", "failures"):
        assert sql(db, f"SELECT * FROM {table}").num_rows == 0
    assert search(db, np.zeros(CONFIG.dim)) == []


def test_errors(tmp_db):
    with pytest.raises(QueryError, match="Parser Error") as info:
        sql(tmp_db, "SELEC name FROM shapes")
    assert "SELEC name FROM shapes" in str(info.value)
    with pytest.raises(QueryError, match="nosuchtable"):
        sql(tmp_db, "SELECT * FROM nosuchtable")
    with pytest.raises(QueryError, match=f"length {CONFIG.dim}"):
        sql(tmp_db, "SELECT mdbd_distance([1.0, 2.0], feature) FROM shapes")
    with pytest.raises(QueryError, match="empty"):
        sql(tmp_db, "   ")


def test_connection_for_duckdb_users(tmp_db):
    con = connect(tmp_db)
    try:
        rows = con.sql(
            "SELECT label, count(*) AS n FROM shapes GROUP BY label ORDER BY label"
        ).fetchall()
    finally:
        con.close()
    assert rows == [("box", 4), ("capsule", 4), ("cylinder", 3), ("torus", 3)]


def test_script_sets_up_a_plain_duckdb_session(tmp_db):
    import duckdb

    from query.sql import script

    con = duckdb.connect()
    try:
        con.execute(script(tmp_db))
        got = con.sql(
            "SELECT s.id, mdbd_kernel(s.feature, q.feature) AS k FROM shapes s, shapes q "
            "WHERE q.name = 'box2' ORDER BY k DESC, s.id LIMIT 3"
        ).fetchall()
    finally:
        con.close()
    hits = search(tmp_db, "box2", k=3)
    assert [r[0] for r in got] == [h.id for h in hits]
    np.testing.assert_allclose([r[1] for r in got], [h.similarity for h in hits], rtol=1e-12)


def test_macros_weigh_by_a_learned_metric(tmp_db, tmp_path):
    import duckdb

    from query.learn.metric import LearnedMetric, block_layout
    from query.sql import script

    blocks = block_layout(tmp_db.config)
    metric = LearnedMetric(
        blocks=blocks,
        weights=tuple(float(i % 3 + 1) for i in range(len(blocks))),
        fingerprint=tmp_db.config.fingerprint,
        reg=0.1,
    )
    query = (
        "SELECT s.id, mdbd_kernel(s.feature, q.feature) AS k FROM shapes s, shapes q "
        "WHERE q.name = 'torus1' ORDER BY k DESC, s.id LIMIT 5"
    )
    hits = search(tmp_db, "torus1", k=5, metric=metric)
    for how in (metric, metric.save(tmp_path / "m.json")):  # the object, or its file
        t = sql(tmp_db, query, metric=how)
        assert t.column("id").to_pylist() == [h.id for h in hits]
        np.testing.assert_allclose(
            t.column("k").to_numpy(), [h.similarity for h in hits], rtol=1e-6
        )
    w = sql(tmp_db, "SELECT mdbd_weights() AS w", metric=metric).column("w")[0].as_py()
    np.testing.assert_allclose(w, weights(CONFIG.kernel) * metric.dim_weights())
    con = duckdb.connect()
    try:
        con.execute(script(tmp_db, metric))
        assert [r[0] for r in con.sql(query).fetchall()] == [h.id for h in hits]
    finally:
        con.close()
    other = LearnedMetric(blocks=blocks, weights=metric.weights, fingerprint="x", reg=0.1)
    with pytest.raises(ConfigError, match="another configuration"):
        sql(tmp_db, "SELECT 1", metric=other)


# ---------------------------------------------------------------- the sandbox
def _files_on_disk(db):
    return sorted((p, p.stat().st_mtime_ns) for p in db.store.path.rglob("*") if p.is_file())


@pytest.mark.parametrize(
    "statement",
    [
        "COPY (SELECT 'x') TO '{root}/manifest.json' (FORMAT csv)",
        "COPY (SELECT * FROM shapes LIMIT 0) TO '{segment}' (FORMAT parquet)",
        "SELECT * FROM read_csv('/etc/passwd')",
        "SELECT * FROM read_text('{root}/manifest.json')",
        "SELECT * FROM read_parquet('{root}/../outside.parquet')",
        "ATTACH '{root}/x.duckdb' AS x",
        "INSTALL httpfs",
        "LOAD httpfs",
        "SET enable_external_access = true",
        "CREATE TABLE t AS SELECT 1",
        "SELECT 1; COPY (SELECT 42) TO '{root}/y.csv'",
    ],
)
def test_sql_never_leaves_the_store(tmp_db, statement):
    before = _files_on_disk(tmp_db)
    segment = tmp_db.store.files("shapes")[0]
    with pytest.raises(QueryError):
        sql(tmp_db, statement.format(root=tmp_db.store.path, segment=segment))
    assert _files_on_disk(tmp_db) == before
    assert sql(tmp_db, "SELECT count(*) AS n FROM shapes").column("n")[0].as_py() == len(
        tmp_db.store
    )


def test_one_select_is_allowed_even_with_a_trailing_semicolon(tmp_db):
    assert sql(tmp_db, "SELECT 42 AS x;").column("x").to_pylist() == [42]
    assert sql(tmp_db, "WITH a AS (SELECT 1 AS v) SELECT v FROM a").num_rows == 1


@pytest.mark.parametrize(
    "where",
    [
        "true); COPY (SELECT 42) TO 'y.csv'; SELECT id FROM shapes WHERE (true",
        "true) UNION SELECT 424242 --",
        "true) LIMIT 1 --",
        "true) ORDER BY id; SELECT (1",
    ],
)
def test_where_is_one_expression(tmp_db, tmp_path, monkeypatch, where):
    from query.sql import allowed_ids

    monkeypatch.chdir(tmp_path)
    with pytest.raises(QueryError):
        allowed_ids(tmp_db, where)
    assert not (tmp_path / "y.csv").exists()
    ids = allowed_ids(tmp_db, "label = 'box' OR n_balls > 0 AND (id IN (SELECT id FROM shapes))")
    assert len(ids) == len(tmp_db.store)


def test_damaged_segment_is_a_store_error_naming_it(tmp_db):
    from pathlib import Path

    from shapedb.errors import StoreError

    seg = Path(tmp_db.store.files("shapes")[0])
    seg.write_bytes(seg.read_bytes()[:200])
    with pytest.raises(StoreError, match=f"segment data/shapes/{seg.name}"):
        sql(tmp_db, "SELECT count(*) FROM shapes")


# ---------------------------------------------------------------- every byte served is verified
def _silently_wrong(seg, query):
    """Flip one byte of the ``x`` column of a balls segment such that a plain DuckDB
    session returns a wrong sum instead of an error; returns (original bytes, wrong rows)."""
    import duckdb
    import pyarrow.parquet as pq

    original = seg.read_bytes()
    good = duckdb.sql(query.format(seg=seg)).fetchall()
    chunk = pq.ParquetFile(seg).metadata.row_group(0).column(2)
    start = chunk.dictionary_page_offset or chunk.data_page_offset
    for offset in range(start + chunk.total_compressed_size - 1, start, -1):
        data = bytearray(original)
        data[offset] ^= 0x10
        seg.write_bytes(bytes(data))
        try:
            got = duckdb.sql(query.format(seg=seg)).fetchall()
        except duckdb.Error:
            continue
        if got != good:
            return original, got
    raise AssertionError("no silent flip found")


def test_flipped_bytes_in_a_balls_segment_are_a_store_error(tmp_db):
    from pathlib import Path

    from shapedb.errors import StoreError

    statement = "select shape_id, sum(x) from balls group by 1 order by 1"
    before = sql(tmp_db, statement)
    seg = Path(tmp_db.store.files("balls")[0])
    original, wrong = _silently_wrong(
        seg, "select shape_id, sum(x) from read_parquet('{seg}') group by 1 order by 1"
    )
    assert wrong != before.to_pylist()  # plain DuckDB serves wrong numbers without a word
    for _ in range(2):  # the verdict is not cached across a change of the file
        with pytest.raises(StoreError, match=f"segment data/balls/{seg.name} is damaged") as info:
            sql(tmp_db, statement)
        assert "\n" not in str(info.value) and "checksum" in str(info.value)
    seg.write_bytes(original)
    assert sql(tmp_db, statement).equals(before)


def test_a_damaged_shapes_segment_stops_a_where_filter(tmp_db):
    from pathlib import Path

    from query.sql import allowed_ids
    from shapedb.errors import StoreError

    assert len(allowed_ids(tmp_db, "n_balls > 0")) == len(tmp_db.store)  # connection cached
    seg = Path(tmp_db.store.files("shapes")[0])
    data = bytearray(seg.read_bytes())
    data[len(data) // 2] ^= 0x01
    seg.write_bytes(bytes(data))
    with pytest.raises(StoreError, match=f"segment data/shapes/{seg.name}"):
        allowed_ids(tmp_db, "n_balls > 0")


# ---------------------------------------------------------------- limits
def test_a_statement_stops_at_its_time_limit(tmp_db):
    import time

    start = time.monotonic()
    with pytest.raises(QueryError, match=r"time limit of 1 s \(raise it with timeout=\)") as info:
        tmp_db.sql("SELECT count(*) FROM range(1000000000000)", timeout=1)
    assert time.monotonic() - start < 10 and "\n" not in str(info.value)


_PEAK = """
import resource, sys
import query.database as database
from shapedb.errors import QueryError
db = database.connect(sys.argv[1], create=False)
try:
    db.sql("SELECT list(range) FROM range(1000000000000)")
except QueryError as exc:
    print(str(exc))
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def test_a_statement_stops_at_its_memory_limit(tmp_db):
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    run = subprocess.run(
        [sys.executable, "-c", _PEAK, str(tmp_db.store.path)],
        capture_output=True,
        text=True,
        cwd=root,
        env={**os.environ, "PYTHONPATH": str(root)},
        timeout=120,
    )
    # the last line is the peak; anything a library printed before it is left aside
    *printed, peak_kib = run.stdout.strip().splitlines() or [""]
    shown = f"stdout {run.stdout!r}, stderr {run.stderr[-2000:]!r}"
    messages = [m for m in printed if "memory limit of 1 GiB (raise it with memory_limit=)" in m]
    assert len(messages) == 1, shown
    assert peak_kib.isdigit() and int(peak_kib) < 2 << 20, shown  # the process stays under 2 GiB
    with pytest.raises(QueryError, match="result is larger than the memory limit of 16 MiB"):
        sql(tmp_db, "SELECT range FROM range(10000000)", memory_limit=16 << 20)
    assert sql(tmp_db, "SELECT count(*) AS n FROM range(10000000)", memory_limit=16 << 20)[
        "n"
    ].to_pylist() == [10000000]


@pytest.mark.parametrize("limits", [{"timeout": 0}, {"timeout": -1.0}, {"memory_limit": 0}])
def test_limits_are_checked(tmp_db, limits):
    with pytest.raises(QueryError, match="must be a positive"):
        sql(tmp_db, "SELECT 1", **limits)


def test_duckdbs_temp_folder_is_not_readable(tmp_db, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / ".tmp").mkdir()
    (tmp_path / ".tmp" / "secret.csv").write_text("a,b\n1,2\n")
    with pytest.raises(QueryError, match="Permission"):
        sql(tmp_db, f"SELECT * FROM read_csv('{tmp_path}/.tmp/secret.csv')")
    with pytest.raises(QueryError, match="Permission"):
        sql(tmp_db, "SELECT * FROM read_csv('.tmp/secret.csv')")


def test_a_caller_can_interrupt_a_running_statement(tmp_db):
    import threading
    import time

    from query.sql import InterruptHandle

    handle = InterruptHandle()
    errors: list[Exception] = []

    def run() -> None:
        try:
            tmp_db.sql("SELECT count(*) FROM range(1000000000000)", timeout=None, interrupt=handle)
        except QueryError as exc:
            errors.append(exc)

    worker = threading.Thread(target=run)
    start = time.monotonic()
    worker.start()
    time.sleep(0.5)
    handle.interrupt()
    worker.join(30)
    assert not worker.is_alive() and time.monotonic() - start < 10
    assert len(errors) == 1 and "interrupted by the caller" in str(errors[0])
    with pytest.raises(QueryError, match="interrupted by the caller"):  # before it starts
        sql(tmp_db, "SELECT 1", interrupt=handle)
    assert sql(tmp_db, "SELECT 1 AS x", interrupt=InterruptHandle())["x"].to_pylist() == [1]
