"""The bench scripts' decomposition cache: what its key holds and what loading rebuilds."""

from __future__ import annotations

import os
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

import bench.common as common
from bench.sets.datasets import Model
from shapedb.config.core import MDBDConfig
from shapedb.mdbd.graph import contact_edges

CONFIG = MDBDConfig(resolution=24, n_balls=48, contact_tol_cells=0.5)


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(common, "CACHE_DIR", tmp_path / "cache")
    return tmp_path / "cache"


@pytest.fixture
def model(tmp_path: Path) -> Model:
    path = tmp_path / "capsule.obj"
    trimesh.creation.capsule(height=2.0, radius=0.6).export(path)
    return Model(name="capsule", label="capsule", source=str(path))


def test_contact_tolerance_is_not_part_of_the_key(model: Model, cache: Path) -> None:
    wider = replace(CONFIG, contact_tol_cells=1.5)
    assert common.cache_path(model, "mesh", CONFIG) == common.cache_path(model, "mesh", wider)
    assert common.cache_path(model, "mesh", CONFIG) != common.cache_path(
        model, "mesh", replace(CONFIG, n_balls=32)
    )


def test_loading_rebuilds_the_contacts_at_the_requested_tolerance(
    model: Model, cache: Path
) -> None:
    (narrow,) = common.decompose_all([model], "mesh", CONFIG, workers=1, progress=None)
    assert narrow is not None
    assert len(list((cache / "dec").glob("*.npz"))) == 1
    (wide,) = common.decompose_all(
        [model], "mesh", replace(CONFIG, contact_tol_cells=2.0), workers=1, progress=None
    )
    assert wide is not None
    assert len(list((cache / "dec").glob("*.npz"))) == 1  # nothing decomposed again
    np.testing.assert_array_equal(wide.radii, narrow.radii)
    for balls, tol in ((narrow, 0.5), (wide, 2.0)):
        want = contact_edges(balls.centers, balls.radii, tol * balls.spacing)
        np.testing.assert_array_equal(balls.edges, want)
    assert len(wide.edges) > len(narrow.edges)  # 2 cells join balls 0.5 cells do not


def test_source_key_follows_the_content_not_the_modification_time(
    model: Model, tmp_path: Path
) -> None:
    key = common._source_key(model)
    os.utime(model.source, (1_000_000, 1_000_000))
    assert common._source_key(model) == key  # data copied afresh keeps its cache
    copy = tmp_path / "elsewhere.obj"
    shutil.copy(model.source, copy)
    assert common._source_key(replace_source(model, copy)).split(":")[1:] == key.split(":")[1:]
    data = bytearray(copy.read_bytes())
    data[data.index(b"v ") + 2] ^= 0x01  # one vertex coordinate's digit or sign: same size
    copy.write_bytes(bytes(data))
    os.utime(copy, (1_000_000, 1_000_000))
    assert common._source_key(replace_source(model, copy)).split(":")[1:] != key.split(":")[1:]


def replace_source(model: Model, path: Path) -> Model:
    return Model(name=model.name, label=model.label, source=str(path))


def test_engine_digest_ignores_docstrings_and_comments() -> None:
    a = 'def f(x):\n    """Doc."""\n    return x + 1\n'
    b = 'def f(x):\n    """Other words."""\n    # a comment\n    return x + 1  # why\n'
    c = 'def f(x):\n    """Doc."""\n    return x + 2\n'
    assert common._code_only(a) == common._code_only(b)
    assert common._code_only(a) != common._code_only(c)


def test_view_variant_is_the_library_view_of_the_cached_mesh(model: Model, cache: Path) -> None:
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.geometry.view import view_geometry

    (mesh,) = common.decompose_all([model], "mesh", CONFIG, workers=1, progress=None)
    assert mesh is not None
    got = common.variant_geometry(model, "view_4", CONFIG)
    assert isinstance(got, PointCloud)
    v, f = common.mesh_arrays(model)
    want = view_geometry(TriangleMesh(v, f), mesh.spacing, 4.0)
    assert want is not None
    np.testing.assert_array_equal(got.points, want.points)
    # views depend on shapedb/geometry/view.py and the point-cloud code; meshes on neither
    assert common.engine_version("view_4") != common.engine_version("mesh")
    assert common.cache_path(model, "view_4", CONFIG) != common.cache_path(model, "view_5", CONFIG)


def test_turned_clouds_are_the_frame_cloud_turned_about_each_axis(model: Model) -> None:
    from scipy.spatial.transform import Rotation

    turned = [common.variant_geometry(model, f"pointcloud_turn_{k}", CONFIG) for k in range(3)]
    angle = np.deg2rad(common.CLOUD_TURN_DEGREES)
    for a in range(3):
        for b in range(a + 1, 3):
            # the same cloud, turned about axis a and about axis b: one rotation apart
            want = Rotation.from_rotvec(angle * np.eye(3)[b]) * Rotation.from_rotvec(
                -angle * np.eye(3)[a]
            )
            got, _ = Rotation.align_vectors(turned[b].points, turned[a].points)
            assert (got * want.inv()).magnitude() < 1e-9
    # a turn is about the frame's centroid, whatever the model's own placement
    np.testing.assert_allclose(turned[0].points.mean(axis=0), 0.0, atol=1e-9)


def test_an_older_engines_key_reads_its_code_at_that_commit(model: Model) -> None:
    import subprocess

    root = Path(common.__file__).resolve().parents[1]
    clean = subprocess.run(
        ["git", "diff", "--quiet", "HEAD", "--", "shapedb"], cwd=root, check=False
    ).returncode
    if clean != 0:
        pytest.skip("the engine has uncommitted changes: HEAD is not the working tree")
    assert common.engine_version("mesh", commit="HEAD") == common.engine_version("mesh")
    assert common.cache_path(model, "mesh", CONFIG, engine_commit="HEAD") == common.cache_path(
        model, "mesh", CONFIG
    )
    # a commit before shapedb/geometry/sheet.py existed: another engine, and no sheet_cells in the key
    before = common.cache_path(model, "mesh", CONFIG, engine_commit="f031e22")
    assert before != common.cache_path(model, "mesh", CONFIG)


def test_sphere_variant_is_the_paper_cloud_with_the_sphere_distance(model: Model) -> None:
    plain = common.variant_geometry(model, "pointcloud", CONFIG)
    fitted = common.variant_geometry(model, "pointcloud_sphere", CONFIG)
    np.testing.assert_array_equal(fitted.points, plain.points)
    assert (plain.distance, fitted.distance) == ("splat", "sphere")
    assert common.cache_path(model, "pointcloud_sphere", CONFIG) != common.cache_path(
        model, "pointcloud", CONFIG
    )


def test_mesh_keys_leave_the_point_cloud_distance_out(monkeypatch: pytest.MonkeyPatch) -> None:
    """Editing shapedb/geometry/surface_fit.py (or pointcloud.py) changes cloud keys, not mesh keys."""
    real = common._module_code.__wrapped__

    def edited(path: str, size: int, mtime_ns: int) -> str:
        code = real(path, size, mtime_ns)
        return code + "EDITED" if path.endswith("surface_fit.py") else code

    before = (common.engine_version("mesh"), common.engine_version("pointcloud"))
    monkeypatch.setattr(common, "_module_code", edited)
    after = (common.engine_version("mesh"), common.engine_version("pointcloud"))
    assert after[0] == before[0]
    assert after[1] != before[1]


def test_derived_caches_are_keyed_by_the_engine(
    model: Model, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Distance matrices and field vectors derived from a decomposition are re-computed when
    the engine changes (bench.support.cached.model_key holds the decomposition's cache key)."""
    from bench.support.cached import model_key

    before = model_key(model)
    assert before.startswith("capsule" + model.source)
    real = common.engine_version
    monkeypatch.setattr(common, "engine_version", lambda *a, **k: "another" + real(*a, **k))
    assert model_key(model) != before


def test_a_commit_before_the_sheet_rule_keys_without_it(model: Model) -> None:
    # 32bb41a had no MDBDConfig.sheet_rule: its key is that of the config without the field
    if common._source_at("32bb41a", "config") is None:
        pytest.skip("the history before the sheet rule is not in this clone")
    import hashlib
    import json
    from dataclasses import asdict

    params = asdict(CONFIG)
    del params["contact_tol_cells"], params["sheet_rule"]
    version = common.engine_version("mesh", commit="32bb41a")
    text = json.dumps([common._source_key(model), "mesh", params, version], sort_keys=True)
    expected = common.CACHE_DIR / "dec" / f"{hashlib.sha256(text.encode()).hexdigest()[:20]}.npz"
    assert common.cache_path(model, "mesh", CONFIG, engine_commit="32bb41a") == expected


def test_scan_variants_are_the_quality_bench_queries(model: Model, cache: Path) -> None:
    """bench.representations' one-sided and cropped kinds decompose the very queries
    ``bench.quality --queries one-sided cropped`` searches with, and their cache keys
    change with bench.sets.scans."""
    from bench.support.scan_queries import query_geometry

    scan = common.variant_geometry(model, "pointcloud_scan", CONFIG)
    np.testing.assert_array_equal(scan.points, query_geometry(model, "one-sided").points)
    half = common.variant_geometry(model, "mesh_cropped", CONFIG)
    want = query_geometry(model, "cropped")
    np.testing.assert_array_equal(half.vertices, want.vertices)
    np.testing.assert_array_equal(half.faces, want.faces)
    assert common.recon_variant("pointcloud_scan", 8) == "pointcloud_scan_recon"
    assert common.recon_variant("pointcloud_scan", 8) in common.VARIANTS
    key = common.cache_path(model, "pointcloud_scan", CONFIG)
    common._scans_version.cache_clear()
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(common, "_scans_version", lambda: "changed!")
            assert common.cache_path(model, "pointcloud_scan", CONFIG) != key
            assert common.cache_path(model, "mesh", CONFIG) == common.cache_path(
                model, "mesh", CONFIG
            )
    finally:
        common._scans_version.cache_clear()
