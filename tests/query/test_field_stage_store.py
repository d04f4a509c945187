"""The field vectors in the light field stage of a store: search, eval, outside queries, spreads."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from query_helpers import CONFIG, shape_pairs

from query.evaluate import evaluate, retrieval_scores
from query.search.field_fusion import FIELD, FieldFusion, query_field_vectors
from query.search.field_index import field_index
from query.search.lightfield_spread import SPREAD_DIR, spread_table, store_spreads
from query.search.rerank_lightfield import stored_arrays
from query.search.tuning import PRODUCT, tuned
from shapedb.mdbd.decomposition import decompose

#: The stage with field vectors: K = 3 of version 4 and K2 = 2 by the field vectors, the
#: gate open (g = 1) so that the fused distance always counts (the research's weights 0.5
#: and 0.5 at its scales 20.67, 6.045, 2.168).
FIELD_STAGE = CONFIG.with_options(rerank="lightfield", fv_enabled=True)
TUNING = replace(
    PRODUCT, candidates=3, field_depth_weight=0.5 * 20.67 / 6.045,
    field_harmonic_weight=0.5 * 20.67 / 2.168, scale=2.0 * 20.67,
    field_candidates=2, ceiling=0.0, contrast_floor=0.0, pool=0,
)  # fmt: skip


@pytest.fixture(autouse=True)
def _stage() -> Iterator[None]:
    """Every search and commit of these tests runs the stage at :data:`TUNING`."""
    with tuned(TUNING):
        yield


@pytest.fixture(scope="module")
def fv_db(tmp_path_factory: pytest.TempPathFactory, forget: Callable[[Any], None]) -> Iterator[Any]:
    """Seven analytic shapes in a store whose stage reads field vectors."""
    import query.database as database

    db = database.connect(tmp_path_factory.mktemp("fv") / "store", config=FIELD_STAGE)
    shapes = shape_pairs()
    with tuned(TUNING):
        db.ingest([(n, n.split("_")[0], g) for n, g in shapes.items()], workers=1)
    yield db
    forget(db)


def test_the_store_keeps_field_vectors_and_the_stage_reads_them(fv_db: Any) -> None:
    assert fv_db.config.stores_field_vectors
    fusion = FieldFusion.from_config(fv_db.config, TUNING)
    assert fusion.active and fusion.proposes
    ids, _ = fv_db.store.features()
    got = stored_arrays(fv_db)(FIELD, ids)
    assert got is not None and got.shape[0] == 7 and np.all(np.isfinite(got))
    assert len(field_index(fv_db)) == 7


def test_evaluation_ranks_as_search_does(fv_db: Any) -> None:
    ids, _ = fv_db.store.features()
    labels = fv_db.store.shapes(["label"]).column("label").to_pylist()
    hits = fv_db.search_batch([int(i) for i in ids], k=len(ids))
    ranks = np.empty((len(ids), len(ids)))
    for row, found in enumerate(hits):
        assert len(found) == len(ids)
        ranks[row, np.searchsorted(ids, [h.id for h in found])] = np.arange(len(ids))
    want = retrieval_scores(ranks, labels, ids=ids, distance=True).to_dict()
    got = evaluate(fv_db).to_dict()
    for key in ("nn", "first_tier", "dcg"):
        assert got[key] == pytest.approx(want[key], abs=1e-12)


def test_an_outside_query_uses_its_own_field_vector(fv_db: Any) -> None:
    config = fv_db.config
    shapes = shape_pairs()
    d = decompose(shapes["rod_b"], config=config.mdbd, keep_inside=True)
    own = query_field_vectors(config, [d, None])
    sid = fv_db.store.resolve("rod_b")
    stored = stored_arrays(fv_db)(FIELD, np.array([sid]))
    assert np.all(np.isnan(own[1]))
    np.testing.assert_allclose(own[0], stored[0], rtol=1e-6, atol=1e-7)
    for name, shape in shapes.items():
        inside = [h.id for h in fv_db.search(name, k=7)]
        outside = [h.id for h in fv_db.search(shape, k=7)]
        assert outside == inside, name


def test_a_file_query_computes_its_field_vector(
    fv_db: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import trimesh

    import query.search.field_fusion as field_fusion

    seen: list[np.ndarray] = []

    def spy(config: Any, decompositions: Any) -> np.ndarray:
        out = query_field_vectors(config, decompositions)
        seen.append(out)
        return out

    monkeypatch.setattr(field_fusion, "query_field_vectors", spy)
    path = tmp_path / "box.obj"
    trimesh.creation.box(extents=(2.0, 1.0, 1.0)).export(path)
    hits = fv_db.search(str(path), k=3)
    assert hits[0].name == "box_a"
    assert len(seen) == 1 and np.all(np.isfinite(seen[0]))
    fv_db.search("box_a", k=3)  # a stored query: its vector is read by id
    assert np.all(np.isnan(seen[1]))


def test_a_where_filter_and_a_deletion_keep_the_union_within_the_store(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    import query.database as database

    db = database.connect(tmp_path / "s", config=FIELD_STAGE)
    db.ingest([(n, n.split("_")[0], g) for n, g in shape_pairs().items()], workers=1)
    hits = db.search("box_a", k=7, where="label <> 'ring'")
    assert {h.label for h in hits} == {"box", "rod", "ball"} and len(hits) == 5
    db.delete(["box_b"])
    hits = db.search("box_a", k=7)
    assert "box_b" not in [h.name for h in hits] and len(hits) == 6
    assert len({h.id for h in hits}) == 6
    forget(db)


def test_the_spread_table_is_recomputed_when_the_fusion_changes(fv_db: Any) -> None:
    first = store_spreads(fv_db, stored_arrays(fv_db), TUNING)
    table = spread_table(fv_db, stored_arrays(fv_db), TUNING)
    assert table.meta["field_fusion"] == FieldFusion.from_config(fv_db.config, TUNING).key()
    assert not (Path(fv_db.store.path) / SPREAD_DIR).exists()  # pool 0: nothing to keep
    other = replace(TUNING, field_depth_weight=4.0, field_harmonic_weight=0.0)
    table = spread_table(fv_db, stored_arrays(fv_db), other)
    assert not table.complete  # the table in memory is another fusion's
    again = dict(zip(sorted(first), table.get(np.array(sorted(first))), strict=True))
    assert again != first
    assert spread_table(fv_db, stored_arrays(fv_db), TUNING).get(
        np.array(sorted(first))
    ).tolist() == [first[i] for i in sorted(first)]
