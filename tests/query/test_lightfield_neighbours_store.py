"""The shared-neighbour term in a store of analytic shapes: search, eval, the table on disk.

Seven shapes (two boxes, two rods, two rings, a ball; ids 1-7 in that order) in a store
whose stage has K = 5, K2 = 2 and an open gate (g = 1), the term at k = 2 and the
product's beta 0.8. Its lists ``N_2`` (each shape's two nearest by the stage distance
among its own candidates) are

    box_a {box_b, rod_b}   box_b {box_a, rod_b}   rod_a {rod_b, box_b}   rod_b {rod_a, box_b}
    ring_a {ring_b, box_b}   ring_b {ring_a, box_b}   ball {box_a, box_b}

so for the query box_a ({box_a, box_b, rod_b}) ``S`` is 2/3 for rod_a (it shares box_b and
rod_b) and 1/3 for ring_b (box_b only): the term promotes rod_a above ring_b.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG, SMALL_STAGE, shape_pairs

import query.search.lightfield_neighbours as neighbours
from query.evaluate import evaluate, retrieval_scores
from query.search import rerank
from query.search.field_fusion import FIELD
from query.search.index import open_index
from query.search.lightfield_neighbours import (
    NEIGHBOUR_DIR,
    NEIGHBOURS,
    nearest_others,
    neighbour_table,
    shared_scores,
    store_neighbours,
)
from query.search.rerank import stage_batch
from query.search.rerank_lightfield import COLUMN, LightFieldFusion, stored_arrays
from query.search.tuning import PRODUCT, StageTuning, tuned
from shapedb.geometry.implicit import Box

STAGE = CONFIG.with_options(rerank="lightfield", fv_enabled=True)
#: K 5 and K2 2, the gate open, the term at k 2, beta 0.8 (``ON``) and off (``OFF``).
ON = replace(PRODUCT, **SMALL_STAGE, pool=0)
OFF = replace(ON, shared_neighbours=0)


@pytest.fixture(autouse=True)
def _stage() -> Iterator[None]:
    """Every search and commit of these tests runs the stage at :data:`ON`."""
    with tuned(ON):
        yield


LISTS = {
    "box_a": ["box_b", "rod_b"], "box_b": ["box_a", "rod_b"], "rod_a": ["rod_b", "box_b"],
    "rod_b": ["rod_a", "box_b"], "ring_a": ["ring_b", "box_b"], "ring_b": ["ring_a", "box_b"],
    "ball": ["box_a", "box_b"],
}  # fmt: skip


def _connect(root: Path, tuning: StageTuning = ON) -> Any:
    import query.database as database

    db = database.connect(root, config=STAGE)
    with tuned(tuning):
        db.ingest([(n, n.split("_")[0], g) for n, g in shape_pairs().items()], workers=1)
    return db


@pytest.fixture(scope="module")
def dbs(tmp_path_factory: pytest.TempPathFactory,
        forget: Callable[[Any], None]) -> Iterator[dict[str, Any]]:  # fmt: skip
    """The store with the term (``"on"``) and the same store without it (``"off"``)."""
    root = tmp_path_factory.mktemp("snn")
    got = {"on": _connect(root / "on"), "off": _connect(root / "off", OFF)}
    yield got
    for db in got.values():
        forget(db)


def _names(db: Any) -> dict[int, str]:
    t = db.store.shapes(["id", "name"])
    return dict(zip(t.column("id").to_pylist(), t.column("name").to_pylist(), strict=True))


def _orders(db: Any, tuning: StageTuning = ON) -> dict[str, list[str]]:
    with tuned(tuning):
        return {n: [h.name for h in db.search(n, k=7)] for n in shape_pairs()}


def test_the_lists_and_the_order_with_the_term_on_and_off(dbs: dict[str, Any]) -> None:
    db = dbs["on"]
    names = _names(db)
    lists = store_neighbours(db, stored_arrays(db), LightFieldFusion(db.config, tuning=ON))
    assert {names[i]: [names[int(j)] for j in v] for i, v in lists.items()} == LISTS
    on, off = _orders(db), _orders(dbs["off"], OFF)
    assert off["box_a"] == ["box_a", "box_b", "rod_b", "ring_b", "rod_a", "ring_a", "ball"]
    assert on["box_a"] == ["box_a", "box_b", "rod_b", "rod_a", "ring_b", "ring_a", "ball"]
    assert off["box_b"] == ["box_b", "box_a", "rod_b", "ring_b", "rod_a", "ring_a", "ball"]
    assert on["box_b"] == ["box_b", "box_a", "rod_b", "rod_a", "ring_b", "ring_a", "ball"]
    for name in shape_pairs():  # the first result never changes
        assert on[name][:2] == off[name][:2] and sorted(on[name]) == sorted(off[name]), name
        if name not in ("box_a", "box_b"):
            assert on[name] == off[name], name


def test_evaluation_ranks_as_search_does(dbs: dict[str, Any]) -> None:
    db = dbs["on"]
    ids, _ = db.store.features()
    labels = db.store.shapes(["label"]).column("label").to_pylist()
    ranks = np.empty((len(ids), len(ids)))
    for row, found in enumerate(db.search_batch([int(i) for i in ids], k=len(ids))):
        ranks[row, np.searchsorted(ids, [h.id for h in found])] = np.arange(len(ids))
    want = retrieval_scores(ranks, labels, ids=ids, distance=True).to_dict()
    got = evaluate(db).to_dict()
    for key in ("nn", "first_tier", "dcg"):
        assert got[key] == pytest.approx(want[key], abs=1e-12)


def test_an_outside_copy_differs_from_the_stored_id_by_the_reciprocal_term_only(
    dbs: dict[str, Any],
) -> None:
    db = dbs["on"]
    shapes = shape_pairs()
    scorer = LightFieldFusion(db.config, tuning=ON)
    reader = stored_arrays(db)
    index = open_index(db)
    ids, _ = db.store.features()
    x = np.asarray(index.features_, np.float64)[index.lookup(ids)]
    cand, dist = index.search(x, 5)
    own_arrays = {COLUMN: reader(COLUMN, ids), FIELD: reader(FIELD, ids)}
    shared = {}
    for tag, qids, given in (("stored", ids, None), ("outside", np.full(len(ids), -1), own_arrays)):
        batch = stage_batch(index, x, cand, dist, config=db.config, scorer=scorer,
                            query_ids=qids, arrays=reader, query_arrays=given)  # fmt: skip
        for row, cols, dl, own in scorer.stage_rows(batch):
            c = batch.ids[row, cols]
            lists = reader(NEIGHBOURS, c).astype(np.int64)
            mine = nearest_others(dl, own, c, 2)
            shared[tag, row] = (c, shared_scores(mine, int(qids[row]), c, lists, 2), lists)
    for row, q in enumerate(ids):
        c, stored, lists = shared["stored", row]
        c2, outside, _ = shared["outside", row]
        assert np.array_equal(c, c2)
        reciprocal = np.array([q == x or q in lists[j] for j, x in enumerate(c)], float)
        assert np.array_equal((stored - outside) * 3, reciprocal), int(q)
    for name, shape in shapes.items():  # here the reciprocal term moves no result
        assert [h.name for h in db.search(shape, k=7)] == [h.name for h in db.search(name, k=7)]


def test_a_closed_gate_leaves_the_term_out_and_reads_no_lists(dbs: dict[str, Any]) -> None:
    db = dbs["on"]
    # the light field's gates shut (the contrast floor), the words off (their own gate is
    # the pose gate alone: test_word_fusion)
    shut = LightFieldFusion(db.config, tuning=replace(ON, contrast_floor=1.0, word_weight=0.0))
    reader = stored_arrays(db)
    asked: list[str] = []

    def spy(name: str, ids: np.ndarray) -> np.ndarray | None:
        asked.append(name)
        return reader(name, ids)

    index = open_index(db)
    ids, _ = db.store.features()
    x = np.asarray(index.features_, np.float64)[index.lookup(ids)]
    got, _ = rerank.search(index, x, 7, config=db.config, query_ids=ids, arrays=spy,
                           scorer=shut)  # fmt: skip
    assert np.array_equal(got, index.search(x, 7)[0])  # the stored distance's order
    assert NEIGHBOURS not in asked and COLUMN in asked


def test_the_table_is_kept_per_version_and_read_back_by_a_new_connection(
    tmp_path: Path, forget: Callable[[Any], None], monkeypatch: pytest.MonkeyPatch
) -> None:
    import query.database as database

    db = _connect(tmp_path / "s")
    root = Path(db.store.path) / NEIGHBOUR_DIR
    assert (root / "current.json").exists()  # written at commit, the one place that writes
    before = _orders(db)
    first = store_neighbours(db, stored_arrays(db), LightFieldFusion(db.config, tuning=ON))
    meta = json.loads((root / "current.json").read_text())
    assert meta["version"] == db.store.version and meta["shared_neighbours"] == 2
    ids, lists = (
        np.load(root / meta["dir"] / "ids.npy"),
        np.load(root / meta["dir"] / "neighbours.npy"),
    )
    assert {int(i): v.tolist() for i, v in zip(ids, lists, strict=True)} == {
        i: v.tolist() for i, v in first.items()
    }
    # a new connection in a fresh cache reads the table back: nothing is computed
    forget(db)
    neighbours._CACHE.clear()

    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("the lists were computed again")

    monkeypatch.setattr(neighbours, "stage_lists", refuse)
    again = database.connect(tmp_path / "s")
    assert _orders(again) == before
    table = neighbour_table(again, stored_arrays(again), LightFieldFusion(again.config, tuning=ON))
    assert table.complete and table.version == meta["version"]
    monkeypatch.undo()
    # a commit is a new version: a small store's lists are recomputed at commit
    again.ingest([("box_c", "box", Box((0, 0, 0), (2.2, 1.0, 0.95)))], workers=1)
    meta2 = json.loads((root / "current.json").read_text())
    assert meta2["version"] == again.store.version > meta["version"]
    box_c = again.store.resolve("box_c")
    lists2 = neighbour_table(
        again, stored_arrays(again), LightFieldFusion(again.config, tuning=ON)
    ).values
    assert len(lists2) == 8 and any(box_c in v for v in lists2.values())
    # a deletion: the deleted shape is in no list and in no result
    box_b = again.store.resolve("box_b")
    again.delete(["box_b"])
    lists3 = neighbour_table(again, stored_arrays(again), LightFieldFusion(again.config, tuning=ON))
    assert lists3.complete and lists3.version == again.store.version
    assert all(box_b not in v for v in lists3.values.values())
    for name in [*shape_pairs(), "box_c"]:
        if name != "box_b":
            hits = again.search(name, k=8)
            assert len(hits) == 7 and "box_b" not in [h.name for h in hits]
    forget(again)


def test_a_where_filter_is_honoured(dbs: dict[str, Any]) -> None:
    db = dbs["on"]
    for name in shape_pairs():
        hits = db.search(name, k=7, where="label <> 'rod'")
        assert [h.label for h in hits].count("rod") == 0 and len(hits) == 5, name
    hits = db.search("box_a", k=7, where="label IN ('box', 'ring')")
    assert [h.name for h in hits][:2] == ["box_a", "box_b"] and len(hits) == 4


def test_the_table_s_key_holds_k_and_the_stage_not_beta(dbs: dict[str, Any]) -> None:
    db = dbs["on"]
    lists = store_neighbours(db, stored_arrays(db), LightFieldFusion(db.config, tuning=ON))
    for options, same in (({"shared_weight": 3.0}, True), ({"shared_neighbours": 3}, False),
                          ({"field_candidates": 1}, False), ({"candidates": 4}, False)):  # fmt: skip
        stage = LightFieldFusion(db.config, tuning=replace(ON, **options))
        table = neighbour_table(db, stored_arrays(db), stage)
        assert table.complete == same, options
        got = table.get(np.array(sorted(lists)))
        assert got.shape == (7, stage.tuning.shared_neighbours)
        if same:
            assert got.tolist() == [lists[i].tolist() for i in sorted(lists)]
    assert neighbour_table(db, stored_arrays(db), LightFieldFusion(db.config, tuning=ON)).get(
        np.array(sorted(lists))
    ).tolist() == [lists[i].tolist() for i in sorted(lists)]
