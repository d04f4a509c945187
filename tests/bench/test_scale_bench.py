"""bench.scale's logic on a small store: synthetic records are real-shaped, the growth
reaches each size through db.commit, and every figure of the table is measured."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import shapedb
from bench import scale
from bench.support.scale_vectors import compressed_figures, make_vectors
from bench.support.synthetic_records import MAX_DROPPED, RecordMaker

PINNED = Path(__file__).resolve().parents[1] / "data" / "pinned" / "store"


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list]:
    """The pinned store's real records (a copy: the bench only reads it)."""
    root = tmp_path_factory.mktemp("seed") / "store"
    shutil.copytree(PINNED, root)
    return root, scale.seed_records(root)


def test_synthetic_records_are_real_shaped_and_reproducible(seeds) -> None:
    _, records = seeds
    maker = RecordMaker(records, seed=3)
    by_name = {r.name: r for r in records}
    for i in range(20):
        r = maker.make(i)
        seed = by_name[r.name.split("-", 2)[2]]
        d, s = r.decomposition, seed.decomposition
        assert s.n_balls * (1 - MAX_DROPPED) - 1 <= d.n_balls <= s.n_balls
        assert np.all(np.diff(d.radii) <= 0) and np.all(d.radii > 0)
        e = np.asarray(d.edges)
        assert len(e) <= len(s.edges) and np.all(e[:, 0] < e[:, 1]) and e.max() < d.n_balls
        assert r.feature.shape == seed.feature.shape and np.all(np.isfinite(r.feature))
        assert r.light_field.shape == seed.light_field.shape
        assert r.field_vector.shape == seed.field_vector.shape
        assert r.label == seed.label and r.id is None
        again = maker.make(i)
        np.testing.assert_array_equal(again.decomposition.centers, d.centers)
        np.testing.assert_array_equal(again.light_field, r.light_field)
    assert len({maker.make(i).content_hash for i in range(20)}) == 20


def test_the_bench_grows_one_store_and_measures_every_figure(seeds, tmp_path, capsys) -> None:
    seed_root, _ = seeds
    out = tmp_path / "scale.json"
    argv = ["--sizes", "120", "240", "--dir", str(tmp_path / "grown"), "--seed-store",
            str(seed_root), "--queries", "4", "--reference-queries", "3", "--part-max", "120",
            "--tables-max", "120", "--vectors", "3000", "--keep", "--out",
            str(out)]  # fmt: skip
    assert scale.main(argv) == 0
    saved = json.loads(out.read_text())
    rows = saved["sizes"]
    assert [r["shapes"] for r in rows] == [120, 240]
    assert saved["vectors"]["vectors"] == 3000 and saved["vectors"]["compressed_p50_ms"] > 0
    first, second = rows
    assert first["tables_s"] > 0 and "tables_s" not in second  # built once, dropped past 120
    assert first["recall@10"] == 1.0  # a flat index and exact tables: the exact ranking
    assert "part_recall@10" in first and "part_recall@10" not in second
    for row in rows:
        assert row["table_bytes_per_shape"] > 1000 and row["check_ok"]
        assert row["db_commit_s"] >= row["store_commit_s"] > 0
        assert row["p50_ms"] > 0 and row["serve_p50_ms"] > 0
        assert row["serve_peak_mb"] >= row["serve_anon_mb"] > 0
        assert row["bench_rss_at_serve_mb"] > 0  # what the bench held beside the server
        assert row["sql_balls_aggregate_s"] > 0 and row["duckdb_balls_aggregate_s"] > 0
        assert row["ingest_one_s"] > 0 and row["ingest_one_empty_s"] > 0
    db = shapedb.connect(tmp_path / "grown", create=False)
    assert len(db) == 241  # grown to 240, then the second probe file
    printed = capsys.readouterr().out
    assert "serve p50 / p99 ms" in printed and "compressed_recall@10" in printed


def test_compressed_vectors_find_the_exact_ten_after_the_re_rank(tmp_path) -> None:
    """Clustered vectors (mixtures of 40 points) through IVF-PQ proposals and an exact L1
    re-rank: the re-rank of many proposals recovers the exact ten, of few does not."""
    rng = np.random.default_rng(0)
    source = rng.random((40, 24)).astype(np.float32)
    made = make_vectors(source, 5, np.random.default_rng(1))
    assert made.shape == (5, 24) and made.dtype == np.float32
    got = compressed_figures(source, 4000, tmp_path, lists=16, m=8,
                             settings=((1, 10), (16, 400)), queries=20)  # fmt: skip
    narrow, wide = got["settings"]
    assert wide["recall@10"] >= 0.95 and narrow["recall@10"] < wide["recall@10"]
    assert got["compressed_recall@10"] == wide["recall@10"]  # the first to reach 0.95
    assert got["index"].startswith("IVF16,PQ8 nprobe 16")
    assert got["index_bytes"] < got["vector_file_bytes"]


@pytest.mark.parametrize("vectors", ["-5", "10"])
def test_too_few_compressed_vectors_is_refused_before_anything_runs(vectors, capsys) -> None:
    with pytest.raises(SystemExit):
        scale.main(["--sizes", "10", "--vectors", vectors])
    assert "--vectors" in capsys.readouterr().err


def test_a_failed_reference_says_why(tmp_path) -> None:
    """The exact reference runs in a child process; when it fails (at 10^6 it once ran
    out of memory) the bench keeps the reason instead of stopping."""
    from types import SimpleNamespace

    from bench.support.scale_measures import reference_ranks

    root = tmp_path / "broken"
    (root / "data").mkdir(parents=True)
    (root / "manifest.json").write_text("{not json")
    why = reference_ranks(SimpleNamespace(path=str(root)), [1, 2], timeout=300)
    assert isinstance(why, str) and "manifest" in why.lower()
