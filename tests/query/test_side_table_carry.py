"""The stage's side tables (spreads, shared-neighbour lists) carried from version to version.

Seven analytic shapes (ids 1-7) ingested with both tables on; each test works on a copy.
With the tables' limit for computing them whole set to 0 (a large store), a commit computes
only its new shapes' values and carries the others'.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG, SMALL_STAGE

import query.search.lightfield_neighbours as neighbours
import query.search.lightfield_spread as spreads
from query.search.index import open_index
from query.search.rerank_lightfield import LightFieldFusion, stored_arrays
from query.search.shape_table import fingerprints
from query.search.tuning import PRODUCT, StageTuning, tuned
from shapedb.geometry.implicit import Box, Capsule, Cylinder, Sphere, Torus

STAGE = CONFIG.with_options(rerank="lightfield", fv_enabled=True)
#: The small stores' stage with the spreads pooled over 3 candidates.
ON = replace(PRODUCT, **SMALL_STAGE, pool=3)
TABLES = {"spreads": spreads.SPREAD_DIR, "lists": neighbours.NEIGHBOUR_DIR}


@pytest.fixture(autouse=True)
def _stage() -> Iterator[None]:
    with tuned(ON):
        yield


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory, forget: Callable[[Any], None]) -> Path:
    """The ingested store (both tables written at the ingest's end)."""
    import query.database as database

    root = tmp_path_factory.mktemp("carry") / "s"
    db = database.connect(root, config=STAGE)
    shapes = {
        "box_a": Box((0, 0, 0), (2.0, 1.0, 1.0)), "box_b": Box((0, 0, 0), (2.4, 1.0, 0.9)),
        "rod_a": Capsule((0, 0, 0), (3.0, 0, 0), 0.4),
        "rod_b": Cylinder((0, 0, 0), (3.2, 0, 0), 0.45),
        "ring_a": Torus((0, 0, 0), 1.0, 0.3), "ring_b": Torus((0, 0, 0), 1.1, 0.35),
        "ball": Sphere((0, 0, 0), 1.0),
    }  # fmt: skip
    with tuned(ON):
        db.ingest([(n, n.split("_")[0], g) for n, g in shapes.items()], workers=1)
    forget(db)
    return root


@pytest.fixture()
def db(built: Path, tmp_path: Path, forget: Callable[[Any], None]) -> Iterator[Any]:
    """A fresh connection to a copy of the store, the process's table caches emptied."""
    import query.database as database

    shutil.copytree(built, tmp_path / "s")
    spreads._CACHE.clear()
    neighbours._CACHE.clear()
    got = database.connect(tmp_path / "s")
    yield got
    forget(got)


def _tables(db: Any, tuning: StageTuning = ON) -> dict[str, Any]:
    fields = stored_arrays(db)
    return {
        "spreads": spreads.spread_table(db, fields, tuning),
        "lists": neighbours.neighbour_table(db, fields, LightFieldFusion(db.config, tuning=tuning)),
    }


def _values(db: Any) -> dict[str, dict[int, Any]]:
    out = {}
    for name, table in _tables(db).items():
        table.known(None)
        out[name] = {i: np.asarray(v).tolist() for i, v in table.values.items()}
    return out


def _stored(db: Any, name: str) -> tuple[dict[str, Any], dict[int, Any], dict[int, int]]:
    """(pointer, values by id, version computed at by id) of a table on disk."""
    root = Path(db.store.path) / TABLES[name]
    meta = json.loads((root / "current.json").read_text())
    sub = root / meta["dir"]
    ids = np.load(sub / "ids.npy").tolist()
    file = spreads.SpreadTable.file if name == "spreads" else neighbours.NeighbourTable.file
    values = [np.asarray(v).tolist() for v in np.load(sub / file)]
    at = np.load(sub / "at.npy").tolist()
    return meta, dict(zip(ids, values, strict=True)), dict(zip(ids, at, strict=True))


@pytest.fixture()
def asked(monkeypatch: pytest.MonkeyPatch) -> dict[str, list[Any]]:
    """The ids each table computes (None: every shape), and the limit for computing a
    table whole set to 0 (as in a large store)."""
    got: dict[str, list[Any]] = {"spreads": [], "lists": []}
    real_spreads, real_lists = spreads.local_spreads, neighbours.stage_lists

    def spread_ids(
        index: Any, fields: Any, config: Any, ids: Any = None, tuning: Any = PRODUCT
    ) -> Any:
        got["spreads"].append(None if ids is None else sorted(np.asarray(ids).tolist()))
        return real_spreads(index, fields, config, ids, tuning)

    def list_ids(index: Any, fields: Any, config: Any, scorer: Any, ids: Any = None) -> Any:
        got["lists"].append(None if ids is None else sorted(np.asarray(ids).tolist()))
        return real_lists(index, fields, config, scorer, ids)

    monkeypatch.setattr(spreads, "local_spreads", spread_ids)
    monkeypatch.setattr(neighbours, "stage_lists", list_ids)
    monkeypatch.setattr(spreads, "FULL_AT_COMMIT", 0)
    monkeypatch.setattr(neighbours, "FULL_AT_COMMIT", 0)
    return got


def _copy(db: Any, name: str, new: str, id: int | None = None) -> Any:
    return replace(db.store.get(name), id=id, name=new)


def test_a_commit_carries_the_old_values_and_computes_the_new_shapes(
    db: Any, asked: dict[str, list[Any]]
) -> None:
    before, v0 = _values(db), db.store.version
    for name in TABLES:
        meta, _, at = _stored(db, name)
        assert meta["exact"] and meta["carried"] == 0 and set(at.values()) == {v0}
    ball = db.store.resolve("ball")
    _, added = db.commit([_copy(db, "box_a", "box_c"), _copy(db, "ring_a", "ring_c")])
    new = sorted(int(r.id) for r in added)
    db.delete(["ball"])
    v = db.store.version
    assert asked == {"spreads": [new], "lists": [new]}  # the new shapes only, once
    for name in TABLES:
        meta, values, at = _stored(db, name)
        assert meta["version"] == v and not meta["exact"]
        assert meta["carried"] == 6 + 2 and meta["oldest"] == v0  # box_c, ring_c: at v - 1
        assert sorted(values) == sorted({*before[name], *new} - {ball})
        assert all(values[i] == before[name][i] for i in before[name] if i != ball)
        assert {at[i] for i in new} == {v - 1} and {at[i] for i in before[name] if i != ball} == {
            v0
        }
        assert all(np.all(np.isfinite(values[i])) for i in new)
        root = Path(db.store.path) / TABLES[name]
        prints = np.load(root / meta["dir"] / "prints.npy")
        assert prints.tolist() == fingerprints(open_index(db), np.array(sorted(values))).tolist()
    # what a search reads: the table of the new version, complete, nothing computed
    assert all(t.complete and not t.exact for t in _tables(db).values())
    assert asked == {"spreads": [new], "lists": [new]}
    assert [h.name for h in db.search("box_c", k=2)] in (["box_c", "box_a"], ["box_a", "box_c"])


def test_a_fresh_process_reads_the_carried_table(
    db: Any, asked: dict[str, list[Any]], forget: Callable[[Any], None]
) -> None:
    import query.database as database

    db.commit([_copy(db, "rod_a", "rod_c")])
    want = {name: _stored(db, name)[1] for name in TABLES}
    forget(db)
    spreads._CACHE.clear()
    neighbours._CACHE.clear()
    asked["spreads"].clear()
    asked["lists"].clear()
    again = database.connect(db.store.path)
    tables = _tables(again)
    for name, table in tables.items():
        assert table.complete and table.version == again.store.version and not table.exact
        assert {i: np.asarray(v).tolist() for i, v in table.values.items()} == want[name]
    again.search("rod_c", k=3)
    assert asked == {"spreads": [], "lists": []}
    forget(again)


def test_an_id_re_added_with_another_vector_is_recomputed(
    db: Any, asked: dict[str, list[Any]]
) -> None:
    box_a = db.store.resolve("box_a")
    db.commit([_copy(db, "ring_a", "box_a", id=box_a)], delete=[box_a])
    assert asked == {"spreads": [[box_a]], "lists": [[box_a]]}
    for name in TABLES:
        assert _stored(db, name)[2][box_a] == db.store.version


def test_refresh_recomputes_exactly_what_a_fresh_table_computes(
    db: Any, asked: dict[str, list[Any]]
) -> None:
    db.commit([_copy(db, "box_b", "box_c"), _copy(db, "rod_b", "rod_c")])
    fields, stage = stored_arrays(db), LightFieldFusion(db.config, tuning=ON)
    index = open_index(db)
    fresh = {
        "spreads": dict(zip(*spreads.local_spreads(index, fields, db.config, None, ON), strict=True)),
        "lists": dict(zip(*neighbours.stage_lists(index, fields, db.config, stage, None), strict=True)),
    }  # fmt: skip
    spreads.refresh(db, fields, ON)
    neighbours.refresh(db, fields, stage)
    for name in TABLES:
        meta, values, at = _stored(db, name)
        assert meta["exact"] and meta["carried"] == 0 and set(at.values()) == {db.store.version}
        assert values == {int(i): np.asarray(v).tolist() for i, v in fresh[name].items()}
    assert _values(db) == _stored_values(db)


def _stored_values(db: Any) -> dict[str, dict[int, Any]]:
    return {name: _stored(db, name)[1] for name in TABLES}


def test_other_parameters_discard_the_stored_values(db: Any, asked: dict[str, list[Any]]) -> None:
    other = replace(ON, spread_candidates=2, shared_neighbours=3)
    with tuned(other):
        db.commit([_copy(db, "box_a", "box_c")])
    assert asked == {"spreads": [None], "lists": [None]}  # every shape, none carried
    for name, key, value in (
        ("spreads", "spread_candidates", 2),
        ("lists", "shared_neighbours", 3),
    ):
        meta, values, _ = _stored(db, name)
        assert meta[key] == value and meta["exact"] and len(values) == 8
    assert all(not t.complete for t in _tables(db).values())  # the stage's own numbers


def test_a_store_that_cannot_be_written_keeps_the_carried_table_in_memory(
    db: Any, asked: dict[str, list[Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    import query.search.shape_table as shape_table

    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise PermissionError(13, "Permission denied")

    v0 = db.store.version
    monkeypatch.setattr(shape_table, "save_version", refuse)
    _, added = db.commit([_copy(db, "rod_b", "rod_c")])
    assert asked == {"spreads": [[added[0].id]], "lists": [[added[0].id]]}
    for name, table in _tables(db).items():
        assert table.complete and len(table.values) == 8 and not table.exact
        assert _stored(db, name)[0]["version"] == v0  # the disk holds the old table
    db.search("rod_c", k=3)
    assert len(asked["spreads"]) == len(asked["lists"]) == 1  # nothing computed again


def test_a_commit_to_a_store_without_tables_opens_no_index(
    db: Any, tmp_path: Path, asked: dict[str, list[Any]]
) -> None:
    """Above the size a table is created at, a commit of a store that never wrote one
    computes nothing and builds no index (it did: the hook counted shapes by the index)."""
    import shapedb
    from query.search.index import INDEX_DIR

    other = shapedb.connect(tmp_path / "plain", config=db.config)
    other.commit([_copy(db, "box_a", "box_x"), _copy(db, "ring_a", "ring_x")])
    assert not (other.path / INDEX_DIR).exists()
    assert asked == {"spreads": [], "lists": []}
    assert not any((other.path / d).exists() for d in TABLES.values())
