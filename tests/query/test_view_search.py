"""One-sided scans found by their silhouette against the stored light fields' views.

The store here keeps no view words, so its scans are ranked by their silhouettes alone;
``test_scan_words.py`` tests the words and their fusion.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import trimesh

from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud

MESHES = {
    "sphere": trimesh.creation.icosphere(subdivisions=3, radius=1.0),
    "box": trimesh.creation.box(extents=(2.4, 1.2, 0.8)),
    "capsule": trimesh.creation.capsule(height=2.4, radius=0.4),
    "cone": trimesh.creation.cone(radius=1.0, height=2.0),
    "torus": trimesh.creation.torus(major_radius=1.0, minor_radius=0.3),
}
#: A camera axis along none of the stored views.
AXIS = np.array([0.62, 0.35, 0.70])


def scan(mesh: trimesh.Trimesh, axis: np.ndarray = AXIS, grid: int = 60) -> np.ndarray:
    """First hits (k, 3) of parallel rays along ``axis``: what an orthographic depth camera
    sees of the mesh."""
    import open3d as o3d

    d = axis / np.linalg.norm(axis)
    u = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(d, u)
    r = float(np.linalg.norm(mesh.vertices, axis=1).max()) * 1.1
    s = np.linspace(-r, r, grid)
    a, b = np.meshgrid(s, s)
    origins = a.reshape(-1, 1) * u + b.reshape(-1, 1) * w - 3 * r * d
    rays = np.hstack([origins, np.broadcast_to(d, origins.shape)]).astype(np.float32)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)),
    )
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    hit = np.isfinite(t)
    return np.asarray(origins[hit] + d * t[hit, None])


def _silhouettes(resolution: int, n_balls: int) -> Any:
    """The default configuration at this size, without view words."""
    from dataclasses import replace

    from shapedb.config import Config, SurfaceWordsConfig

    return replace(
        Config().with_options(resolution=resolution, n_balls=n_balls),
        surface_words=SurfaceWordsConfig(enabled=True, view_words=False),
    )


@pytest.fixture(scope="module")
def db(tmp_path_factory: pytest.TempPathFactory) -> Any:
    import shapedb

    store = shapedb.connect(tmp_path_factory.mktemp("view") / "store", config=_silhouettes(48, 64))
    store.ingest(
        [(n, n, TriangleMesh(m.vertices, m.faces)) for n, m in MESHES.items()],
        workers=1,
        progress=False,
    )
    return store


@pytest.mark.parametrize("name", sorted(MESHES))
def test_a_scan_finds_its_shape_by_the_view_path(db: Any, name: str) -> None:
    hits = db.search(PointCloud(scan(MESHES[name])), k=3)
    # a stored view is framed by its light field's largest reach, the scan by its own:
    # the capsule seen at 45 degrees is as long and thin as the torus edge-on
    assert hits[0].name == name if name != "capsule" else name in {h.name for h in hits}
    assert [h.path for h in hits] == ["view"] * 3
    assert all(0.0 < h.similarity <= 1.0 for h in hits)
    assert [h.distance for h in hits] == sorted(h.distance for h in hits)


def test_the_whole_and_partial_paths_stay_on_request(db: Any) -> None:
    cloud = PointCloud(scan(MESHES["box"]))
    assert {h.path for h in db.search(cloud, k=2, partial=False)} == {"whole"}
    assert {h.path for h in db.search(cloud, k=2, partial=True)} == {"partial"}


def test_a_cloud_all_around_its_surface_takes_the_whole_path(db: Any) -> None:
    points, _ = trimesh.sample.sample_surface(MESHES["box"], 3000, seed=0)
    assert {h.path for h in db.search(PointCloud(np.asarray(points)), k=2)} == {"whole"}


def test_where_restricts_the_view_path(db: Any) -> None:
    hits = db.search(PointCloud(scan(MESHES["torus"])), k=5, where="name <> 'torus'")
    assert "torus" not in {h.name for h in hits} and len(hits) == len(MESHES) - 1
    assert {h.path for h in hits} == {"view"}


def test_a_batch_mixes_the_paths_in_order(db: Any) -> None:
    from query.parts.partial import search_batch

    found = search_batch(db, ["cone", PointCloud(scan(MESHES["cone"]))], k=1)
    assert [(h[0].name, h[0].path) for h in found] == [("cone", "whole"), ("cone", "view")]


def test_a_store_without_light_fields_searches_scans_whole(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    import shapedb

    store = shapedb.connect(
        tmp_path_factory.mktemp("plain") / "store", resolution=32, n_balls=32, rerank="none"
    )
    store.ingest(
        [(n, n, TriangleMesh(MESHES[n].vertices, MESHES[n].faces)) for n in ("box", "sphere")],
        workers=1,
        progress=False,
    )
    hits = store.search(PointCloud(scan(MESHES["box"])), k=2)
    assert {h.path for h in hits} == {"whole"}


def test_the_cli_searches_a_scan_file_by_its_silhouette(
    db: Any, tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    from query.cli import main

    path = tmp_path / "scan.xyz"
    np.savetxt(path, scan(MESHES["cone"]))
    assert main(["search", str(path), "--db", str(db.path), "-k", "2", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["name"] == "cone" and {r["path"] for r in rows} == {"view"}
    assert main(["search", str(path), "--db", str(db.path), "-k", "2", "--whole", "--json"]) == 0
    assert {r["path"] for r in json.loads(capsys.readouterr().out)} == {"whole"}


def test_without_the_array_cache_the_column_is_read(
    db: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    from query.search import view_search

    cloud = PointCloud(scan(MESHES["torus"]))
    cached = db.search(cloud, k=len(MESHES))
    monkeypatch.setattr(view_search, "open_column", lambda db, column: None)
    read = db.search(cloud, k=len(MESHES))
    assert [h.name for h in read] == [h.name for h in cached]
    assert np.allclose([h.distance for h in read], [h.distance for h in cached])


def test_a_deleted_shape_is_not_found(tmp_path_factory: pytest.TempPathFactory) -> None:
    import shapedb

    store = shapedb.connect(tmp_path_factory.mktemp("gone") / "store", config=_silhouettes(32, 32))
    store.ingest(
        [
            (n, n, TriangleMesh(MESHES[n].vertices, MESHES[n].faces))
            for n in ("box", "cone", "torus")
        ],
        workers=1,
        progress=False,
    )
    cloud = PointCloud(scan(MESHES["cone"]))
    assert store.search(cloud, k=1)[0].name == "cone"
    store.delete(["cone"])
    hits = store.search(cloud, k=3)
    assert [h.path for h in hits] == ["view", "view"] and "cone" not in {h.name for h in hits}
    assert store.search(cloud, k=3, where="label = 'nothing'") == []


def test_the_nearest_view_is_the_same_by_faiss_and_by_numpy() -> None:
    from query.search.view_search import nearest_view

    rng = np.random.default_rng(0)
    rows = rng.random((50, 30 * 46), dtype=np.float32)
    q = rng.random((1, 1, 46), dtype=np.float32)
    fast = nearest_view(rows, q, 30, 46)  # faiss over the contiguous views
    plain = nearest_view(np.asfortranarray(rows), q, 30, 46)  # numpy
    exact = np.abs(rows.reshape(50, 30, 46).astype(np.float64) - q).sum(-1).min(-1)
    assert np.allclose(fast, exact, rtol=1e-5) and np.allclose(plain, exact, rtol=1e-5)
    # views holding more than their silhouette part (depth images): numpy over the part
    wide = rng.random((50, 30 * 50), dtype=np.float32)
    part = nearest_view(wide, q, 30, 50)
    assert np.allclose(part, np.abs(wide.reshape(50, 30, 50)[:, :, :46] - q).sum(-1).min(-1))


def test_close_releases_what_the_process_keeps_and_the_store_stays_usable(db: Any) -> None:
    from query.search import array_cache, catalog, field_index, index

    path = str(db.path)
    before = db.search("box", k=3)
    db.search(PointCloud(scan(MESHES["box"])), k=2, where="name <> 'cone'")
    assert any(k[0] == path for k in array_cache._OPEN) and path in catalog._CATALOGS
    db.close()
    assert not any(k[0] == path for k in array_cache._OPEN)
    assert path not in catalog._CATALOGS and path not in index._CACHE
    assert not any(k[0] == path for k in field_index._INDEXES)
    assert [h.name for h in db.search("box", k=3)] == [h.name for h in before]


def test_a_scan_without_a_silhouette_falls_back_to_the_whole_path(
    db: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    from query.search import view_search

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise ValueError("the scan's points project to one spot")

    monkeypatch.setattr(view_search, "scan_view_features", refuse)
    hits = db.search(PointCloud(scan(MESHES["box"])), k=2)
    assert {h.path for h in hits} == {"whole"}


def test_a_with_block_closes_the_store(db: Any) -> None:
    import shapedb
    from query.search import catalog

    with shapedb.connect(db.path, create=False) as again:
        assert again.search("torus", k=1)[0].name == "torus"
        assert str(db.path) in catalog._CATALOGS
    assert str(db.path) not in catalog._CATALOGS
    assert db.search("torus", k=1)[0].name == "torus"  # the store stays usable
