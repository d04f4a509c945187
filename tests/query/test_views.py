"""Stores with sparse views (CloudConfig.view_cells): ingest, search routing, evaluate.

Expected results are computed here from the stored features with the rule of
``query.search.engine``: two exact shapes, and two sparse clouds, compare their own features;
a pair of a sparse cloud and a dense shape is as far apart as the nearest of own-own,
the cloud's own feature against the dense shape's view, and the cloud's
reconstruction (:mod:`shapedb.mdbd.reconstruct`, stored as its view) against the dense
shape's own feature.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

import shapedb
from query.evaluate import retrieval_scores
from shapedb.config.core import Config
from shapedb.errors import ConfigError
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud
from shapedb.geometry.view import view_geometry
from shapedb.mdbd.decomposition import decompose
from shapedb.mdbd.reconstruct import reconstructed
from shapedb.signature.kernel import features

CONFIG = Config().with_options(resolution=40, n_balls=96, view_cells=4.0)


def _meshes() -> dict[str, tuple[str, TriangleMesh]]:
    c = trimesh.creation
    shapes = {
        "box-a": ("box", c.box(extents=(2.0, 1.0, 1.0))),
        "box-b": ("box", c.box(extents=(3.0, 1.0, 1.2))),
        "capsule-a": ("capsule", c.capsule(height=2.0, radius=0.4, count=[24, 24])),
        "capsule-b": ("capsule", c.capsule(height=3.0, radius=0.45, count=[24, 24])),
        "disc-a": ("disc", c.cylinder(radius=1.0, height=0.3, sections=48)),
        "disc-b": ("disc", c.cylinder(radius=1.2, height=0.4, sections=48)),
    }
    return {n: (lab, TriangleMesh.from_trimesh(m, name=n)) for n, (lab, m) in shapes.items()}


def _cloud(mesh: TriangleMesh, name: str, n: int = 600) -> PointCloud:
    return PointCloud(mesh.sample_surface(n, seed=7), name=name)


@pytest.fixture(scope="module")
def view_db(
    tmp_path_factory: pytest.TempPathFactory, forget: Callable[[Any], None]
) -> Iterator[Any]:
    """Six meshes and one sparse cloud (of capsule-b), ingested with views."""
    meshes = _meshes()
    names = [*meshes, "cloud-capsule-b"]
    geoms = [g for _, g in meshes.values()] + [_cloud(meshes["capsule-b"][1], "c")]
    labels = {n: lab for n, (lab, _) in meshes.items()} | {"cloud-capsule-b": "capsule"}
    db = shapedb.connect(Path(tmp_path_factory.mktemp("views")) / "store", config=CONFIG)
    report = db.ingest(geoms, names=names, labels=labels, workers=1)
    assert len(report.failed) == 0, report.failed
    yield db
    forget(db)


def _table(db: Any) -> dict[str, Any]:
    t = db.shapes(["id", "name", "feature", "view_feature", "timings"]).to_pylist()
    return {r["name"]: r for r in t}


def _own_and_view(db: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    ids, own = db.store.features()
    _, view = db.store.features(view=True)
    sparse = np.isin(ids, db.store.sparse_ids())
    return ids, own.astype(np.float64), view.astype(np.float64), sparse


def test_meshes_get_a_view_and_clouds_a_reconstruction(view_db: Any) -> None:
    rows = _table(view_db)
    for name, row in rows.items():
        assert row["view_feature"] is not None, name
        assert dict(row["timings"])["view"] > 0
        assert not np.allclose(row["view_feature"], row["feature"])  # a real other packing
    cloud = _cloud(_meshes()["capsule-b"][1], "c")
    dec = decompose(cloud, config=CONFIG.mdbd)
    recon = reconstructed(cloud, dec, CONFIG.mdbd)
    assert recon is not None
    np.testing.assert_allclose(
        rows["cloud-capsule-b"]["view_feature"], features(recon, CONFIG.kernel), rtol=1e-5
    )
    ids = view_db.store.sparse_ids()
    assert [view_db.get(int(i)).name for i in ids] == ["cloud-capsule-b"]
    record = view_db.get("box-a")
    assert record.view_feature is not None and record.view_feature.shape == record.feature.shape


def test_features_view_falls_back_to_own_feature(view_db: Any) -> None:
    ids, own, view, sparse = _own_and_view(view_db)
    rows = _table(view_db)
    for i, sid in enumerate(ids):
        row = rows[view_db.get(int(sid)).name]
        want = row["feature"] if row["view_feature"] is None else row["view_feature"]
        np.testing.assert_array_equal(view[i], np.asarray(want, np.float32))
    assert sparse.sum() == 1


def test_sparse_query_takes_the_nearest_of_its_comparisons(view_db: Any) -> None:
    mesh = _meshes()["disc-a"][1]
    query = _cloud(mesh, "q", n=500)
    dec = decompose(query, config=CONFIG.mdbd)
    f = features(dec, CONFIG.kernel)
    r = features(reconstructed(query, dec, CONFIG.mdbd), CONFIG.kernel)
    ids, own, view, sparse = _own_and_view(view_db)
    own_own = np.abs(own - f).sum(axis=1)
    by_view = np.abs(view - f).sum(axis=1)
    by_recon = np.abs(own - r).sum(axis=1)
    want = np.where(sparse, own_own, np.minimum(own_own, np.minimum(by_view, by_recon)))
    # the rule matters here: each comparison is the nearest for some shape
    assert (want < own_own).any() and (want < by_view).any() and (want < by_recon).any()
    hits = view_db.search(query, k=len(ids))
    got = {h.id: h.distance for h in hits}
    assert set(got) == set(ids.tolist())
    for sid, d in zip(ids, want, strict=True):
        assert got[int(sid)] == pytest.approx(d, rel=1e-5, abs=1e-6)
    # disc-a and disc-b are near twins (the descriptor is nearly scale-free): which one comes
    # first moves with trimesh and open3d releases; a disc comes first
    assert hits[0].label == "disc"


def test_dense_query_reaches_sparse_records_through_feature_or_view(view_db: Any) -> None:
    mesh = _meshes()["capsule-b"][1]
    dec = decompose(mesh, config=CONFIG.mdbd)
    f = features(dec, CONFIG.kernel)
    v = features(
        decompose(view_geometry(mesh, dec.spacing, 4.0), config=CONFIG.mdbd), CONFIG.kernel
    )
    ids, own, view, sparse = _own_and_view(view_db)
    want = np.abs(own - f).sum(1)
    near = np.minimum(np.abs(own - v).sum(1), np.abs(view - f).sum(1))
    want = np.where(sparse, np.minimum(want, near), want)
    hits = view_db.search(mesh, k=len(ids))
    assert [h.id for h in hits] == ids[np.lexsort((ids, want))].tolist()
    for h in hits:
        assert h.distance == pytest.approx(want[ids == h.id][0], rel=1e-5, abs=1e-6)
    assert hits[0].name == "capsule-b" and hits[0].distance == pytest.approx(0.0, abs=1e-6)
    # the same mesh's stored record, and a where predicate restricting the results
    stored = view_db.search("capsule-b", k=3, where="label = 'capsule'")
    assert [h.name for h in stored][0] == "capsule-b"
    assert {h.name for h in stored} == {"capsule-a", "capsule-b", "cloud-capsule-b"}


def test_stored_cloud_query_is_symmetric_with_its_mesh(view_db: Any) -> None:
    from_cloud = {h.name: h.distance for h in view_db.search("cloud-capsule-b", k=7)}
    from_mesh = {h.name: h.distance for h in view_db.search("capsule-b", k=7)}
    assert from_cloud["capsule-b"] == pytest.approx(from_mesh["cloud-capsule-b"], rel=1e-6)
    assert from_cloud["cloud-capsule-b"] == 0.0


def test_evaluate_follows_the_view_rule(view_db: Any) -> None:
    ids, own, view, sparse = _own_and_view(view_db)
    d_own = np.abs(own[:, None] - own[None]).sum(-1)
    a = np.abs(own[:, None] - view[None]).sum(-1)  # own_i against view_j
    one = sparse[:, None] != sparse[None, :]
    d = np.where(one, np.minimum(d_own, np.minimum(a, a.T)), d_own)
    labels = np.asarray([view_db.get(int(i)).label for i in ids])
    want = retrieval_scores(-d, labels)
    got = view_db.evaluate()
    assert got.nn == pytest.approx(want.nn)
    assert got.first_tier == pytest.approx(want.first_tier)
    assert got.dcg == pytest.approx(want.dcg)


def test_a_learned_metric_weighs_views_too(view_db: Any) -> None:
    from query.learn.metric import LearnedMetric, block_layout

    blocks = block_layout(CONFIG)
    metric = LearnedMetric(
        blocks=blocks,
        weights=tuple(float(i + 1) for i in range(len(blocks))),
        fingerprint=view_db.config.fingerprint,
        reg=0.1,
    )
    w = metric.dim_weights()
    ids, own, view, sparse = _own_and_view(view_db)
    cloud = int(ids[sparse][0])
    hits = view_db.search(cloud, k=len(ids), metric=metric)  # a sparse query
    q, r = own[ids == cloud][0], view[ids == cloud][0]
    near = np.minimum(np.abs(view - q) @ w, np.abs(own - r) @ w)
    want = np.abs(own - q) @ w
    want = np.where(sparse, want, np.minimum(want, near))
    for h in hits:
        assert h.distance == pytest.approx(want[ids == h.id][0], rel=1e-5, abs=1e-6)
    d_own = np.abs(own[:, None] - own[None]) @ w
    a = np.abs(own[:, None] - view[None]) @ w
    one = sparse[:, None] != sparse[None, :]
    d = np.where(one, np.minimum(d_own, np.minimum(a, a.T)), d_own)
    labels = np.asarray([view_db.get(int(i)).label for i in ids])
    assert view_db.evaluate(metric=metric).nn == pytest.approx(retrieval_scores(-d, labels).nn)
    fitted = view_db.fit_metric(folds=2)  # the dense shapes' views are extra queries
    assert fitted.n_shapes == len(ids) and fitted.n_extra == int((~sparse).sum())
    assert fitted.fingerprint == view_db.config.fingerprint


def test_store_without_views_keeps_meshes_to_one_feature(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    """Without views a mesh has one feature; a sparse cloud still has its reconstruction."""
    cfg = Config().with_options(resolution=32, n_balls=48)
    db = shapedb.connect(tmp_path / "plain", config=cfg)
    mesh = _meshes()["box-a"][1]
    db.ingest([mesh, _cloud(mesh, "c")], names=["box", "cloud"], workers=1)
    try:
        assert db.get("box").view_feature is None
        assert db.get("cloud").view_feature is not None
        ids, own = db.store.features()
        _, view = db.store.features(view=True)
        is_box = ids == db.get("box").id
        np.testing.assert_array_equal(own[is_box], view[is_box])
        query = _cloud(mesh, "q")
        hits = db.search(query, k=2)
        dec = decompose(query, config=cfg.mdbd)
        f = features(dec, cfg.kernel)
        r = features(reconstructed(query, dec, cfg.mdbd), cfg.kernel)
        want = np.abs(own - f).sum(1)  # the cloud: own features; the box: also by r
        want = np.where(is_box, np.minimum(want, np.abs(own - r).sum(1)), want)
        assert {h.id: round(h.distance, 4) for h in hits} == {
            int(i): round(float(w), 4) for i, w in zip(ids, want, strict=True)
        }
    finally:
        forget(db)


def _forget_checksums(root: Path) -> None:
    import json

    manifest = json.loads((root / "manifest.json").read_text())
    for segments in manifest["tables"].values():
        for seg in segments:
            seg.pop("bytes", None)
            seg.pop("sha256", None)
    (root / "manifest.json").write_text(json.dumps(manifest))


def test_rows_written_before_the_view_column_read_as_null(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    """A store whose first Parquet file predates ``view_feature`` (the column is absent)."""
    import pyarrow.parquet as pq

    cfg = Config().with_options(resolution=32, n_balls=48, view_cells=4.0)
    db = shapedb.connect(tmp_path / "old", config=cfg)
    meshes = _meshes()
    try:
        db.ingest([meshes["box-a"][1]], names=["old"], workers=1)
        (old_file,) = db.store.files("shapes")
        table = pq.read_table(old_file)
        pq.write_table(table.drop_columns(["view_feature"]), old_file)
        _forget_checksums(db.store.path)  # as a store written before they were recorded
        db.ingest([meshes["disc-a"][1]], names=["new"], workers=1)
        assert db.get("old").view_feature is None
        assert db.get("new").view_feature is not None
        ids, own = db.store.features()
        _, view = db.store.features(view=True)
        np.testing.assert_array_equal(view[0], own[0])  # no view: its own feature
        assert not np.array_equal(view[1], own[1])
        counts = db.sql("SELECT count(*) AS n, count(view_feature) AS v FROM shapes").to_pylist()
        assert counts == [{"n": 2, "v": 1}]
        assert {h.name for h in db.search(_cloud(meshes["disc-a"][1], "q"), k=2)} == {"old", "new"}
    finally:
        forget(db)


def test_a_shape_whose_view_fails_is_stored_without_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forget: Callable[[Any], None]
) -> None:
    import shapedb.geometry.view as view_module
    from shapedb.errors import DegenerateGeometryError

    def broken(*args: Any, **kwargs: Any) -> None:
        raise DegenerateGeometryError("all points lie on a plane or a line", source="view")

    monkeypatch.setattr(view_module, "view_geometry", broken)
    cfg = Config().with_options(resolution=32, n_balls=48, view_cells=4.0)
    db = shapedb.connect(tmp_path / "broken", config=cfg)
    try:
        report = db.ingest([_meshes()["box-a"][1]], names=["box"], workers=1)
        assert len(report.ingested) == 1 and not report.failed
        assert db.get("box").view_feature is None
    finally:
        forget(db)


def test_implicit_and_voxel_shapes_get_views_too(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    from shapedb.geometry.implicit import Capsule
    from shapedb.geometry.voxels import VoxelGrid

    cfg = Config().with_options(resolution=32, n_balls=48, view_cells=4.0)
    db = shapedb.connect(tmp_path / "implicit", config=cfg)
    capsule = Capsule([0, 0, 0], [2, 0, 0], 0.5)
    occupancy = np.zeros((12, 12, 12), bool)
    occupancy[2:10, 3:9, 4:8] = True
    try:
        report = db.ingest(
            [capsule, VoxelGrid(occupancy, pitch=0.1)], names=["capsule", "block"], workers=1
        )
        assert len(report.ingested) == 2, report.failed
        for name in ("capsule", "block"):
            record = db.get(name)
            assert record.view_feature is not None, name
            assert not np.allclose(record.view_feature, record.feature)
    finally:
        forget(db)


def test_merged_lists_keep_each_shape_once_at_its_smallest_distance() -> None:
    from query.search.engine import _nearest

    ids, dist = _nearest(
        [
            (np.array([[4, 2, -1]]), np.array([[0.5, 1.0, np.inf]])),
            (np.array([[2, 7, 4]]), np.array([[0.25, 0.5, 0.75]])),
            (np.array([[9, -1, -1]]), np.array([[0.1, np.inf, np.inf]])),
        ],
        3,
    )
    assert ids.tolist() == [9, 2, 4]  # 2 at its smaller distance; 4 before 7 (tie: by id)
    assert dist.tolist() == [0.1, 0.25, 0.5]
    ids, dist = _nearest([(np.array([[-1, -1]]), np.full((1, 2), np.inf)),
                          (np.array([[3, -1]]), np.array([[1.0, np.inf]]))], 2)  # fmt: skip
    assert ids.tolist() == [3, -1] and dist[1] == np.inf


def test_a_cloud_decomposes_alike_however_it_was_handled(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    """Hashing, ingesting and reconstructing a cloud leave no state that changes its packing."""
    cfg = Config().with_options(resolution=32, n_balls=48)
    mesh = _meshes()["box-a"][1]
    fresh = features(decompose(_cloud(mesh, "fresh"), config=cfg.mdbd), cfg.kernel)
    cloud = _cloud(mesh, "c")
    db = shapedb.connect(tmp_path / "plain", config=cfg)
    try:
        db.ingest([cloud], names=["cloud"], workers=1)
        np.testing.assert_allclose(db.get("cloud").feature, fresh, rtol=1e-6, atol=1e-7)
        first = db.search(cloud, k=1)[0]
        again = db.search(cloud, k=1)[0]
        assert first.name == again.name == "cloud"
        assert first.distance == again.distance == pytest.approx(0.0, abs=1e-5)
    finally:
        forget(db)


def test_asking_for_a_clouds_normals_first_changes_nothing() -> None:
    cfg = Config().with_options(resolution=32, n_balls=48)
    mesh = _meshes()["box-a"][1]
    fresh = features(decompose(_cloud(mesh, "fresh"), config=cfg.mdbd), cfg.kernel)
    asked = _cloud(mesh, "asked")
    assert asked.normals.shape == asked.points.shape  # estimated in the model's frame
    again = features(decompose(asked, config=cfg.mdbd), cfg.kernel)
    np.testing.assert_allclose(again, fresh, rtol=1e-9, atol=1e-12)  # rounding only


def test_a_failed_reconstruction_leaves_the_cloud_with_one_feature(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forget: Callable[[Any], None]
) -> None:
    import shapedb.mdbd.reconstruct as rec

    def boom(cloud: Any, **_: Any) -> None:
        raise RuntimeError("solver failed")

    monkeypatch.setattr(rec, "reconstruct", boom)
    cfg = Config().with_options(resolution=32, n_balls=48)
    db = shapedb.connect(tmp_path / "plain", config=cfg)
    try:
        report = db.ingest([_cloud(_meshes()["box-a"][1], "c")], names=["cloud"], workers=1)
        assert len(report.failed) == 0
        assert db.get("cloud").view_feature is None
        assert db.search("cloud", k=1)[0].name == "cloud"
    finally:
        forget(db)


def test_reconstructions_can_be_turned_off_and_old_stores_read_without(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    cfg = Config().with_options(resolution=32, n_balls=48, reconstruct=False)
    db = shapedb.connect(tmp_path / "plain", config=cfg)
    mesh = _meshes()["box-a"][1]
    try:
        db.ingest([mesh, _cloud(mesh, "c")], names=["box", "cloud"], workers=1)
        assert db.get("cloud").view_feature is None
        ids, own = db.store.features()
        query = _cloud(mesh, "q")
        f = features(decompose(query, config=cfg.mdbd), cfg.kernel)
        got = {h.id: h.distance for h in db.search(query, k=2)}
        for sid, d in zip(ids, np.abs(own - f).sum(1), strict=True):  # own features only
            assert got[int(sid)] == pytest.approx(d, rel=1e-5, abs=1e-6)
    finally:
        forget(db)
    stored = Config().to_dict()
    del stored["cloud"]["reconstruct"]  # a store written before reconstructions
    assert Config.from_dict(stored).cloud.reconstruct is False
    assert Config().cloud.reconstruct is True


def test_the_stores_poisson_depth_reaches_ingest_and_search(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forget: Callable[[Any], None]
) -> None:
    import shapedb.mdbd.reconstruct as rec

    depths: list[int] = []
    solve = rec.reconstruct

    def spy(cloud: Any, *, depth: int = rec.DEPTH) -> Any:
        depths.append(depth)
        return solve(cloud, depth=depth)

    monkeypatch.setattr(rec, "reconstruct", spy)
    cfg = Config().with_options(resolution=32, n_balls=48, reconstruct_depth=6)
    db = shapedb.connect(tmp_path / "depth", config=cfg)
    mesh = _meshes()["box-a"][1]
    try:
        db.ingest([mesh, _cloud(mesh, "c")], names=["box", "cloud"], workers=1)
        db.search(_cloud(mesh, "q"), k=1)
    finally:
        forget(db)
    assert depths == [6, 6]  # the stored cloud, then the query
    stored = Config().to_dict()
    del stored["cloud"]["reconstruct_depth"]  # written before the depth was stored
    assert Config.from_dict(stored).cloud.reconstruct_depth == 8
    with pytest.raises(ConfigError, match="reconstruct_depth"):
        Config().with_options(reconstruct_depth=20)


def test_a_store_of_meshes_never_builds_a_second_index(
    tmp_path: Path, forget: Callable[[Any], None]
) -> None:
    cfg = Config().with_options(resolution=32, n_balls=48)
    db = shapedb.connect(tmp_path / "meshes", config=cfg)
    meshes = _meshes()
    try:
        db.ingest([meshes["box-a"][1], meshes["disc-a"][1]], names=["box", "disc"], workers=1)
        assert [h.name for h in db.search("box", k=2)][0] == "box"
        db.search(meshes["disc-a"][1], k=2)
        assert not (db.store.path / "index_view").exists()
    finally:
        forget(db)


@pytest.mark.parametrize("query", ["cloud-capsule-b", "capsule-b", "disc-a"])
def test_filtered_and_scanned_searches_agree(
    view_db: Any, query: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    import query.search.engine as engine

    n = len(view_db.store.features()[0])
    scanned = [(h.id, h.distance) for h in view_db.search(query, k=n)]
    monkeypatch.setattr(engine, "_SCAN_IDS", 0)  # every restriction by filtering
    filtered = [(h.id, h.distance) for h in view_db.search(query, k=n)]
    assert filtered == scanned
    few = [(h.id, h.distance) for h in view_db.search(query, k=2)]
    assert few == scanned[:2]
