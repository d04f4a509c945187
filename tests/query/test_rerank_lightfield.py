"""The "lightfield" re-ranking scorer: the study's fusion, stored light fields, search and eval."""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from query_helpers import CONFIG, shape_pairs

from bench.studies.lightfield_balls import fuse
from query.evaluate import evaluate, retrieval_scores
from query.search import rerank
from query.search.index import FeatureIndex
from query.search.rerank_lightfield import COLUMN, LightFieldFusion, stored_arrays
from query.search.stage import scorer_for
from query.search.tuning import PRODUCT
from shapedb.config.core import Config, parse_options
from shapedb.errors import ConfigError
from shapedb.signature.kernel import weights
from shapedb.signature.lightfield import light_field_distance

STAGE = CONFIG.with_options(rerank="lightfield")
#: The stage on the balls' light fields (the fills and the longer packing are theirs).
BALLS = STAGE.with_options(lf_source="balls", lf_resolution=64)


def _study_case(n: int = 40, seed: int = 0) -> tuple[Config, np.ndarray, np.ndarray, np.ndarray]:
    """A v4 store's vectors, light fields and their distances."""
    rng = np.random.default_rng(seed)
    config = Config().with_options(rerank="lightfield")
    x = rng.random((n, config.dim))
    classes = rng.random((4, 3, 10, 46))
    lf = classes[np.arange(n) % 4] + 0.3 * rng.random((n, 3, 10, 46))
    return config, x, lf, light_field_distance(lf)


#: The first light field stage's gate (no pool, no contrast floor, no ratio): its ranks
#: are the study's formula (bench/studies/lightfield_balls.py, without the overlap).
LEGACY = replace(
    PRODUCT, weight=8.0, ceiling=0.09, spread_candidates=100, pool=0, contrast_floor=0.0,
    ramp=0.02, ratio_weight=0.0, field_depth_weight=0.0, field_harmonic_weight=0.0,
    field_candidates=0, shared_neighbours=0,
)  # fmt: skip


def test_with_every_shape_a_candidate_the_legacy_gate_ranks_as_the_study() -> None:
    config, x, lf, dl = _study_case()
    w = weights(config)
    d = np.abs(x[:, None, :] - x[None, :, :]) @ w
    cal = np.log(10.0) / sum(
        b[3] for b in __import__("shapedb.signature.descriptor").signature.descriptor.LAYOUTS[4]
    )
    d4 = d / cal
    # a unit that puts the queries' spreads about the ceiling: some gates open
    near = np.argsort(d4 + np.eye(len(x)) * 1e300, axis=1)[:, :-1]
    ratio = np.median(np.take_along_axis(dl, near, 1), 1) / np.median(
        np.take_along_axis(d4, near, 1), 1
    )
    unit = float(np.median(ratio) / 0.09)
    f = replace(LEGACY, light_field_unit=unit, candidates=len(x))
    study = fuse("adrank", f.weight, d4, dl, unit, f.neighbours, 0.0, f.ceiling, f.ramp)
    index = FeatureIndex(kind="flat").fit(np.arange(len(x)), x.astype(np.float32), w)

    def arrays(name: str, ids: np.ndarray) -> np.ndarray | None:
        return lf[ids] if name == COLUMN else None

    got, _ = rerank.search(
        index, index.features_.astype(np.float64), len(x), config=config,
        query_ids=np.arange(len(x)), arrays=arrays, scorer=LightFieldFusion(config, tuning=f),
    )  # fmt: skip
    want = np.argsort(study, axis=1, kind="stable")
    plain = np.argsort(d, axis=1, kind="stable")
    assert np.array_equal(got, want)
    assert not np.array_equal(want, plain)  # the fusion moved some rankings


def test_without_light_fields_the_stored_order_is_kept_with_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    config, x, _, _ = _study_case(12)
    index = FeatureIndex(kind="flat").fit(np.arange(12), x.astype(np.float32), weights(config))
    q = index.features_.astype(np.float64)
    with caplog.at_level(logging.WARNING, logger="query.search.rerank_lightfield"):
        got, _ = rerank.search(
            index, q, 12, config=config, query_ids=np.arange(12), scorer=LightFieldFusion(config)
        )
    assert np.array_equal(got, index.search(q, 12)[0])
    assert "keeps no light fields" in caplog.text


def test_bad_stage_numbers_and_light_field_options_name_the_field() -> None:
    for name, value in [("weight", -1.0), ("neighbours", 0), ("ramp", 0.0), ("scale", 0.0),
                        ("light_field_unit", 0.0), ("spread_candidates", 0), ("pool", -1), ("contrast_ramp", 0.0),
                        ("contrast_depth", 1), ("ratio_weight", 1.5), ("ratio_candidates", 0),
                        ("pool_quantile", -0.1), ("weight", float("nan"))]:  # fmt: skip
        with pytest.raises(ConfigError, match=name):
            replace(PRODUCT, **{name: value})
    with pytest.raises(ConfigError, match="n_fields"):
        Config().with_options(lf_n_fields=11)
    typed = parse_options(["rerank=lightfield", "lf_n_fields=10"])
    assert typed == {"rerank": "lightfield", "lf_n_fields": 10}
    assert Config().with_options(**typed).stores_light_fields
    assert Config().stores_light_fields  # the default stage
    assert not Config().with_options(rerank="none").stores_light_fields
    assert Config.from_json(STAGE.to_json()) == STAGE


@pytest.fixture(scope="module")
def lf_db(tmp_path_factory: pytest.TempPathFactory, forget: Callable[[Any], None]) -> Iterator[Any]:
    """Seven analytic shapes ingested by a store with the "lightfield" scorer (K = 6)."""
    import query.database as database

    db = database.connect(tmp_path_factory.mktemp("lf") / "store", config=STAGE)
    shapes = shape_pairs()
    labels = {n: n.split("_")[0] for n in shapes}
    db.ingest([(n, labels[n], g) for n, g in shapes.items()], workers=1)
    yield db
    forget(db)


def test_ingest_stores_the_light_fields_and_a_reopened_store_searches_the_same(
    lf_db: Any,
) -> None:
    import query.database as database

    t = lf_db.store.shapes(["name", COLUMN])
    assert t.num_rows == 7
    assert {len(v) for v in t.column(COLUMN).to_pylist()} == {3 * 10 * 46}
    rec = lf_db.get("ring_a")
    assert rec.light_field is not None and rec.light_field.shape == (3, 10, 46)
    names = ["box_a", "rod_b", "ring_a"]
    before = [[(h.id, h.distance) for h in row] for row in lf_db.search_batch(names, k=7)]
    again = database.connect(lf_db.store.path)
    assert again.config == STAGE
    after = [[(h.id, h.distance) for h in row] for row in again.search_batch(names, k=7)]
    assert after == before
    assert [h.name for h in again.search("box_a", k=2)] == ["box_a", "box_b"]


def test_a_stored_query_and_the_same_shape_from_outside_rank_alike(lf_db: Any) -> None:
    for name, shape in shape_pairs().items():
        inside = [h.id for h in lf_db.search(name, k=7)]
        outside = [h.id for h in lf_db.search(shape, k=7)]
        assert outside == inside, name


def test_hits_are_in_the_stage_s_order_with_the_stored_distance(lf_db: Any) -> None:
    from query.search.index import open_index

    index = open_index(lf_db)
    ids, x = lf_db.store.features()
    stored = dict(zip(*(a[0].tolist() for a in index.search(x[:1].astype(np.float64), 7)),
                      strict=True))  # fmt: skip
    hits = lf_db.search(int(ids[0]), k=7)
    order, _ = rerank.search(index, x[:1].astype(np.float64), 7, config=lf_db.config,
                             query_ids=ids[:1], arrays=stored_arrays(lf_db),
                             scorer=scorer_for(lf_db.config))  # fmt: skip
    assert [h.id for h in hits] == order[0].tolist()
    assert [h.distance for h in hits] == pytest.approx([stored[h.id] for h in hits])
    assert hits[0].id == ids[0] and hits[0].distance == 0.0 and hits[0].similarity == 1.0


def test_evaluation_ranks_as_search_does(lf_db: Any) -> None:
    ids, _ = lf_db.store.features()
    labels = lf_db.store.shapes(["label"]).column("label").to_pylist()
    hits = lf_db.search_batch([int(i) for i in ids], k=len(ids))
    ranks = np.empty((len(ids), len(ids)))
    for row, found in enumerate(hits):
        ranks[row, np.searchsorted(ids, [h.id for h in found])] = np.arange(len(ids))
    want = retrieval_scores(ranks, labels, ids=ids, distance=True).to_dict()
    got = evaluate(lf_db).to_dict()
    for key in ("nn", "first_tier", "dcg"):
        assert got[key] == pytest.approx(want[key], abs=1e-12)


def test_a_store_written_before_the_column_searches_in_the_stored_order(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, forget: Callable[[Any], None]
) -> None:
    import query.database as database

    db = database.connect(tmp_path / "old", config=STAGE)
    db.ingest([(n, g) for n, g in list(shape_pairs().items())[:4]], workers=1)
    forget(db)
    for seg in (tmp_path / "old").rglob("*.parquet"):
        if "shapes" in str(seg):
            pq.write_table(pq.read_table(seg).drop_columns([COLUMN]), seg)
    manifest = json.loads((tmp_path / "old" / "manifest.json").read_text())
    for segments in manifest["tables"].values():
        for seg in segments:
            seg.pop("bytes", None)
            seg.pop("sha256", None)
    (tmp_path / "old" / "manifest.json").write_text(json.dumps(manifest))
    old = database.connect(tmp_path / "old")
    assert old.get("box_a").light_field is None
    with caplog.at_level(logging.WARNING, logger="query.search.rerank_lightfield"):
        hits = old.search("box_a", k=4)
    assert "keeps no light fields" in caplog.text
    plain = old.config.with_options(rerank="none")
    index = __import__("query.search.index").search.index.open_index(old)
    want, _ = index.search(index.features_of(hits[0].id)[None], 4)
    assert [h.id for h in hits] == want[0].tolist() and plain.rerank.scorer == "none"
    forget(old)


def test_the_store_s_stage_is_the_light_field_stage() -> None:
    assert isinstance(scorer_for(STAGE), LightFieldFusion)


def test_a_store_with_filled_silhouettes_fills_its_records_and_its_queries(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    import query.database as database
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.lightfield import record_light_field

    balls = BALLS.with_options(lf_n_balls=0)  # the decomposition's balls
    filled = replace(balls, light_field=replace(balls.light_field, edges=True))  # a study's fill
    db = database.connect(tmp_path / "store", config=filled)
    shapes = {n: g for n, g in shape_pairs().items() if n in ("box_a", "rod_a", "ring_a")}
    db.ingest([(n, n.split("_")[0], g) for n, g in shapes.items()], workers=1)
    again = database.connect(tmp_path / "store")
    assert again.config.light_field.edges is True
    ring = decompose(shapes["ring_a"], config=filled.mdbd)
    assert len(ring.edges) > 0
    want = record_light_field(ring.centers, ring.radii, filled.light_field, edges=ring.edges)
    plain = record_light_field(ring.centers, ring.radii, replace(filled.light_field, edges=False))
    got = again.get("ring_a").light_field
    assert got is not None and np.array_equal(got, want) and not np.array_equal(got, plain)
    for name, shape in shapes.items():  # a query from outside is filled the same way
        assert [h.id for h in again.search(shape, k=3)] == [h.id for h in again.search(name, k=3)]
    forget(db)
    forget(again)


def test_a_store_with_a_longer_packing_renders_records_and_queries_from_it(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    import query.database as database
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.lightfield import decomposition_light_field, record_light_field

    longer = BALLS.with_options(lf_n_balls=STAGE.mdbd.n_balls + 200)
    db = database.connect(tmp_path / "store", config=longer)
    shapes = {n: g for n, g in shape_pairs().items() if n in ("box_a", "box_b", "rod_a", "ring_a")}
    db.ingest([(n, n.split("_")[0], g) for n, g in shapes.items()], workers=1)
    again = database.connect(tmp_path / "store")
    assert again.config.light_field.n_balls == longer.light_field.n_balls
    box = decompose(shapes["box_a"], config=longer.mdbd, tail_balls=200)
    today = decompose(shapes["box_a"], config=longer.mdbd)
    assert len(box.tail_radii) > 0
    rec = again.get("box_a")
    assert np.array_equal(rec.decomposition.radii, today.radii)  # the record's balls: today's
    got = rec.light_field
    want = decomposition_light_field(box, longer.light_field)
    assert got is not None and np.array_equal(got, want)
    assert not np.array_equal(
        got, record_light_field(today.centers, today.radii, longer.light_field)
    )
    for name, shape in shapes.items():  # a query from outside gets the same tail
        assert [h.id for h in again.search(shape, k=3)] == [h.id for h in again.search(name, k=3)]
    forget(db)
    forget(again)


def test_a_decomposition_query_without_the_store_s_tail_is_warned_about(
    tmp_path: Path, forget: Callable[[Any], None], caplog: pytest.LogCaptureFixture
) -> None:
    import query.database as database
    from shapedb.mdbd.decomposition import decompose

    db = database.connect(tmp_path / "store", config=BALLS)
    shapes = {n: g for n, g in shape_pairs().items() if n in ("box_a", "rod_a", "ring_a")}
    db.ingest([(n, n.split("_")[0], g) for n, g in shapes.items()], workers=1)
    cfg = db.config
    assert cfg.light_field_tail > 0
    shape = shapes["box_a"]
    with caplog.at_level(logging.WARNING, logger="query.search.engine"):
        db.search(decompose(shape, config=cfg.mdbd, tail_balls=cfg.light_field_tail), k=2)
    assert "tail" not in caplog.text
    with caplog.at_level(logging.WARNING, logger="query.search.engine"):
        db.search(decompose(shape, config=cfg.mdbd), k=2)
    assert "no tail balls" in caplog.text
    forget(db)


def test_a_store_of_the_field_s_light_fields_renders_records_and_queries_from_the_inside(
    tmp_path: Path, forget: Callable[[Any], None], caplog: pytest.LogCaptureFixture
) -> None:
    import query.database as database
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.lightfield import inside_light_field

    field = STAGE.with_options(lf_source="field")
    db = database.connect(tmp_path / "store", config=field)
    shapes = {n: g for n, g in shape_pairs().items() if n in ("box_a", "box_b", "rod_a", "ring_a")}
    db.ingest([(n, n.split("_")[0], g) for n, g in shapes.items()], workers=1)
    again = database.connect(tmp_path / "store")
    assert again.config.light_field.source == "field" and again.config.light_field_tail == 0
    box = decompose(shapes["box_a"], config=field.mdbd, keep_inside=True)
    rec = again.get("box_a")
    assert rec.decomposition.inside is None  # never stored
    assert np.array_equal(rec.decomposition.radii, box.radii)
    assert box.inside is not None
    got = rec.light_field
    assert got is not None and np.array_equal(
        got, inside_light_field(box.inside, field.light_field)
    )
    for name, shape in shapes.items():  # a query from outside sees its inside too
        assert [h.id for h in again.search(shape, k=3)] == [h.id for h in again.search(name, k=3)]
    assert [h.name for h in again.search(box, k=2)][0] == "box_a"
    # a record (no inside: never stored) queries with the light fields it carries
    assert [h.id for h in again.search(rec, k=3)] == [h.id for h in again.search("box_a", k=3)]
    plain = database.connect(tmp_path / "plain", config=field.with_options(rerank="none"))
    plain.ingest([(n, n.split("_")[0], g) for n, g in shapes.items()], workers=1)
    with caplog.at_level(logging.WARNING, logger="query.search.engine"):  # no inside: stored order
        hits = again.search(decompose(shapes["box_a"], config=field.mdbd), k=3)
    assert "no inside" in caplog.text
    assert [h.name for h in hits] == [h.name for h in plain.search(shapes["box_a"], k=3)]
    forget(plain)
    forget(db)
    forget(again)
