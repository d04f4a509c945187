"""The lightfield stage's pooled gate: stored local spreads, the selection bench's formula."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from bench.studies.gate_checks import ANALYTIC, chain
from bench.support.stores import Store, gate_weights
from bench.support.stores import local_spreads as local_spreads_of
from query.search import rerank
from query.search.field_fusion import FIELD
from query.search.index import FeatureIndex
from query.search.lightfield_spread import (
    FULL_AT_COMMIT,
    SPREAD_DIR,
    calibration,
    commit_distances,
    local_spreads,
    local_statistic,
    pooled,
    store_spreads,
)
from query.search.rerank_lightfield import COLUMN, SPREAD, LightFieldFusion, stored_arrays
from query.search.tuning import PRODUCT, StageTuning
from shapedb.config.core import Config
from shapedb.geometry.implicit import Box, Capsule
from shapedb.signature.kernel import weights
from shapedb.signature.lightfield import light_field_distance


def _case(n: int = 40, seed: int = 1) -> tuple[Config, FeatureIndex, np.ndarray, np.ndarray]:
    """A v4 store of n vectors in 4 classes and their light fields; every shape a candidate."""
    rng = np.random.default_rng(seed)
    config = Config().with_options(rerank="lightfield")
    x = rng.random((n, config.dim))
    classes = rng.random((4, 3, 10, 46))
    lf = classes[np.arange(n) % 4] + 0.3 * rng.random((n, 3, 10, 46))
    index = FeatureIndex(kind="flat").fit(np.arange(n), x.astype(np.float32), weights(config))
    return config, index, lf, light_field_distance(lf)


def _reader(index: FeatureIndex, lf: np.ndarray, config: Config, tuning: StageTuning) -> Any:
    spreads: dict[str, np.ndarray] = {}

    def arrays(name: str, ids: np.ndarray) -> np.ndarray | None:
        if name == COLUMN:
            return lf[ids]
        if name == SPREAD:
            if "s" not in spreads:
                spreads["s"] = local_spreads(index, arrays, config, None, tuning)[1]
            return spreads["s"][ids]
        return None

    return arrays


#: The stage on the light field distance alone, every shape of a 40-shape case a candidate.
PLAIN = replace(PRODUCT, candidates=40, field_depth_weight=0.0, field_harmonic_weight=0.0,
                field_candidates=0, shared_neighbours=0)  # fmt: skip
#: A gate of the spread alone, pooled by the median (the first pooled gate).
SPREAD_GATE = {"ratio_weight": 0.0, "pool_quantile": 0.5}
#: A gate of the ratio (half the local statistic's log), pooled by the lower quartile.
RATIO = {"ratio_weight": 0.5, "ratio_candidates": 12, "spread_candidates": 3,
         "pool_quantile": 0.25}  # fmt: skip


def _with_power(f: StageTuning) -> Any:
    """The bench's gate formula reads the retired overlap's power: 0, off."""
    return SimpleNamespace(**vars(f), power=0.0)


@pytest.mark.parametrize("gate", [SPREAD_GATE, RATIO], ids=["spread", "ratio"])
def test_the_pooled_gate_ranks_as_the_selection_bench(gate: dict[str, Any]) -> None:
    config, index, lf, dl = _case()
    f = replace(PLAIN, **gate)
    x = np.asarray(index.features_, np.float64)
    d = np.abs(x[:, None, :] - x[None, :, :]) @ index.weights_ / calibration(config)
    # a unit and a contrast floor that open some gates and close others
    probe = Store(SimpleNamespace(labels=np.arange(40) % 4, sets=np.zeros(40), d4=d, dl=dl),
                  np.arange(40), candidates=40)  # fmt: skip
    s = local_spreads_of(probe, f.spread_candidates, 1.0, f.ratio_weight, f.ratio_candidates)
    dd = probe.others(probe.D)
    t = np.median(dd[:, : f.neighbours], 1) / dd[:, f.contrast_depth - 1]
    # a unit that puts the ceiling at the median statistic
    unit = (float(np.median(s)) / f.ceiling) ** (1.0 / (1.0 - f.ratio_weight))
    f = replace(f, light_field_unit=unit, contrast_floor=float(np.median(t)) - 0.02)
    want_w = gate_weights(probe, _with_power(f))
    assert 0 < np.count_nonzero(want_w) < 40  # the gate decides
    got, _ = rerank.search(index, x, 40, config=config, query_ids=np.arange(40),
                           arrays=_reader(index, lf, config, f),
                           scorer=LightFieldFusion(config, tuning=f))  # fmt: skip
    assert np.array_equal(got, probe.rankings(want_w))
    assert not np.array_equal(got, probe.order)  # the light field moved some rankings


def test_without_spreads_the_pooled_gate_keeps_the_stored_order() -> None:
    # the gate shuts: the light field moves nothing; the stored distance's own term among
    # the candidates reorders after the nearest, and without it the stored order is kept
    config, index, lf, _ = _case(12)
    x = np.asarray(index.features_, np.float64)

    def fields_only(name: str, ids: np.ndarray) -> np.ndarray | None:
        return lf[ids] if name == COLUMN else None

    stored = index.search(x, 12)[0]
    plain = replace(PRODUCT, descriptor_shared_weight=0.0)
    for tuning in (PRODUCT, plain):
        got, _ = rerank.search(index, x, 12, config=config, query_ids=np.arange(12),
                               arrays=fields_only, scorer=LightFieldFusion(config, tuning=tuning))  # fmt: skip
        assert np.array_equal(got[:, :2], stored[:, :2])
    assert np.array_equal(got, stored)


def _gates(db: Any) -> np.ndarray:
    """g(q) of every stored shape querying the store, from the product's scorer."""
    scorer = LightFieldFusion(db.config)
    ids, x = db.store.features()
    index = __import__("query.search.index").search.index.open_index(db)
    reader = stored_arrays(db)
    out = []
    for sid in ids:
        cand, dist = index.search(index.features_of(int(sid))[None], len(ids))
        c = cand[0]
        fields = reader(COLUMN, np.append(c, sid))
        dl = light_field_distance(fields[-1][None], fields[:-1])[0]
        if scorer.field.active:  # the stage's distance: the field vectors fused in
            fv = reader(FIELD, np.append(c, sid))
            dl = scorer.field.distance(dl, fv[-1], fv[:-1])
        spreads = reader(SPREAD, c)
        d4 = dist[0] / calibration(db.config)
        out.append(scorer.gate(d4, dl, c == sid, spreads))
    return np.asarray(out)


def _analytic(root: Path, **options: Any) -> dict[str, Any]:
    """Two stores: rigid boxes and rods, and one chain in 8 poses (the bench's analytic stores)."""
    import query.database as database

    config = Config().with_options(**ANALYTIC, **options)
    rigid = database.connect(root / "rigid", config=config)
    rigid.ingest([(f"box{k}", Box((0, 0, 0), (2.0 + 0.15 * k, 1.0, 0.6 + 0.05 * k)))
                  for k in range(4)] + [(f"rod{k}", Capsule((0, 0, 0), (3.0 + 0.2 * k, 0, 0), 0.4))
                                        for k in range(4)], workers=1)  # fmt: skip
    jointed = database.connect(root / "chain", config=config)
    poses = [(a, b) for a in (0.0, 0.5, 1.0, 1.5) for b in (-0.8, 0.8)]
    jointed.ingest([(f"pose{k}", chain(a, b)) for k, (a, b) in enumerate(poses)], workers=1)
    return {"rigid": rigid, "chain": jointed}


@pytest.fixture(scope="module")
def stores(tmp_path_factory: pytest.TempPathFactory,
           forget: Callable[[Any], None]) -> Iterator[dict[str, Any]]:  # fmt: skip
    """The analytic stores at the stage's defaults, on the light field distance alone."""
    got = _analytic(tmp_path_factory.mktemp("spread"), fv_enabled=False)
    yield got
    for db in got.values():
        forget(db)


def test_rigid_shapes_turn_the_light_field_on_and_a_chain_in_poses_turns_it_off(
    stores: dict[str, Any],
) -> None:
    rigid, chain = _gates(stores["rigid"]), _gates(stores["chain"])
    assert np.count_nonzero(rigid) >= 6, rigid
    assert np.count_nonzero(chain) == 0, chain


def test_on_the_fused_distance_the_product_stage_keeps_the_chain_shut(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    # the product's fusion (chosen on validation): the stored spreads, the gate and the
    # ranks read the fused distance
    got = _analytic(tmp_path, fv_enabled=True)
    assert LightFieldFusion(got["chain"].config).field.active
    rigid, chain = _gates(got["rigid"]), _gates(got["chain"])
    assert np.count_nonzero(rigid) >= 6, rigid
    assert np.count_nonzero(chain) == 0, chain
    for db in got.values():
        forget(db)


def test_the_spreads_are_kept_with_the_store_at_its_version(stores: dict[str, Any]) -> None:
    db = stores["rigid"]
    first = store_spreads(db, stored_arrays(db))
    assert len(first) == 8 and all(np.isfinite(v) for v in first.values())
    root = Path(db.store.path) / SPREAD_DIR
    meta = json.loads((root / "current.json").read_text())
    assert meta["version"] == db.store.version
    assert meta["spread_candidates"] == PRODUCT.spread_candidates
    ids, spreads = (
        np.load(root / meta["dir"] / "ids.npy"),
        np.load(root / meta["dir"] / "spreads.npy"),
    )
    assert dict(zip(ids.tolist(), spreads.tolist(), strict=True)) == first


def test_the_local_statistic_of_a_hand_made_neighbourhood() -> None:
    d = np.array([1.0, 2.0, 3.0, 4.0, 5.0])  # calibrated stored distances, list order
    dl = np.array([6.0, 2.0, 9.0, 1.0, 4.0])  # the light field's nearest are the 4th, 2nd
    f = replace(PRODUCT, spread_candidates=2, scale=2.0, ratio_weight=0.0)
    assert local_statistic(d, dl, f) == (4.0 / 2.0) / 1.5  # median l / scale / median d
    f = replace(f, ratio_weight=1.0, ratio_candidates=5)
    assert local_statistic(d, dl, f) == 4.0 / 1.5  # median of 6, 2 over median of 1, 2
    f = replace(f, ratio_candidates=3)  # among the first 3: 2 and 6
    assert local_statistic(d, dl, f) == 1.0
    f = replace(f, ratio_weight=0.5, ratio_candidates=5)
    assert np.isclose(local_statistic(d, dl, f), np.sqrt((2.0 / 1.5) * (4.0 / 1.5)))
    assert np.isnan(local_statistic(d[:0], dl[:0], f))
    values = np.array([[4.0, 1.0, np.nan, 3.0, 2.0]])
    assert pooled(values, 0.5).tolist() == [2.5]
    assert pooled(values, 0.25).tolist() == [1.75]


@pytest.mark.parametrize("gate", [SPREAD_GATE, RATIO], ids=["spread", "ratio"])
def test_spreads_asked_for_a_few_shapes_equal_the_whole_store_s(gate: dict[str, Any]) -> None:
    config, index, lf, _ = _case()
    f = replace(PLAIN, **gate)
    _, whole = local_spreads(index, _reader(index, lf, config, f), config, None, f)
    few = np.array([31, 3, 17, 99])  # 99 is not stored: left out
    got_ids, got = local_spreads(index, _reader(index, lf, config, f), config, few, f)
    assert got_ids.tolist() == [3, 17, 31]
    assert np.array_equal(got, whole[[3, 17, 31]])


def test_a_search_computes_only_the_spreads_it_pools(
    stores: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    import query.search.lightfield_spread as spread_module

    db = stores["rigid"]
    whole = store_spreads(db, stored_arrays(db))
    asked: list[int] = []
    real = spread_module.local_spreads

    def counting(
        index: Any, fields: Any, config: Config, ids: Any = None, tuning: Any = PRODUCT
    ) -> Any:
        asked.append(-1 if ids is None else len(ids))
        return real(index, fields, config, ids, tuning)

    monkeypatch.setattr(spread_module, "local_spreads", counting)
    spread_module._CACHE.clear()
    table = spread_module.SpreadTable(db, stored_arrays(db))
    assert table.complete and asked == []  # read back from the store, nothing computed
    root = Path(db.store.path) / SPREAD_DIR
    (root / "current.json").unlink()  # as if never written: computed on demand
    table = spread_module.SpreadTable(db, stored_arrays(db))
    got = table.get(np.array([2, 5]))
    assert asked == [2] and not table.complete
    assert got.tolist() == [whole[2], whole[5]]
    table.get(np.array([5]))
    assert asked == [2]  # known: not computed again
    table.get(None)
    assert table.complete and not (root / "current.json").exists()  # a search never writes


def test_a_commit_recomputes_the_statistics_within_a_budget_of_light_field_distances() -> None:
    ratio, spread = PRODUCT, replace(PRODUCT, ratio_weight=0.0, spread_candidates=5)
    assert commit_distances(2000, spread) == FULL_AT_COMMIT  # the spread gate's 2,000 shapes
    assert commit_distances(100, ratio) == 100 * max(ratio.ratio_candidates, 3)
    assert commit_distances(101, ratio) > FULL_AT_COMMIT >= commit_distances(100, ratio)


def _chain_cloud(angle: float, bend: float, n: int = 800) -> Any:
    """Samples of a chain's surface (trimesh spheres and capsules, as ``chain`` builds it)."""
    import trimesh

    from shapedb.geometry.pointcloud import PointCloud

    pts = [np.zeros(3)]
    heading = 0.0
    for turn in (0.0, angle, bend):
        heading += turn
        pts.append(pts[-1] + 1.6 * np.array([np.cos(heading), np.sin(heading), 0.0]))
    parts = [trimesh.creation.icosphere(radius=0.45).apply_translation(p) for p in pts]
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        rod = trimesh.creation.cylinder(radius=0.25, segment=np.stack([a, b]))
        parts.append(rod)
    mesh = trimesh.util.concatenate(parts)
    return PointCloud(np.asarray(trimesh.sample.sample_surface(mesh, n, seed=3)[0]))


def test_a_cloud_of_a_jointed_subject_keeps_its_own_row(stores: dict[str, Any]) -> None:
    # its proxy's own search shuts the gate (silhouettes do not tell poses apart): the
    # cloud ranks as without the proxy; among rigid shapes a cloud ranks as its proxy
    import trimesh

    from query.search.tuning import PRODUCT, tuned
    from shapedb.geometry.pointcloud import PointCloud

    chain_db, rigid_db = stores["chain"], stores["rigid"]
    cloud = _chain_cloud(0.5, 0.8)
    hits = [h.name for h in chain_db.search(cloud, k=len(chain_db))]
    with tuned(replace(PRODUCT, proxy=False)):
        own = [h.name for h in chain_db.search(cloud, k=len(chain_db))]
    assert hits == own
    box = trimesh.creation.box(extents=(2.3, 1.0, 0.7))
    cloud = PointCloud(np.asarray(trimesh.sample.sample_surface(box, 800, seed=3)[0]))
    found = rigid_db.search(cloud, k=len(rigid_db))
    assert [h.id for h in found] == [h.id for h in rigid_db.search(found[0].id, k=len(rigid_db))]
