"""Loaders: every format, content detection, forced representation, every failure."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from ingest_helpers import write_binary_stl_header

import shapedb.errors as E
from ingest import load
from ingest.labels import LabelTable, folder_label, read_labels
from ingest.loaders import detect_format

EXPECTED = {
    "box.obj": ("mesh", [[-0.5, -1, -1.5], [0.5, 1, 1.5]]),
    "ico.off": ("mesh", [[-1.5] * 3, [1.5] * 3]),
    "cyl.stl": ("mesh", [[-0.5, -0.5, -1], [0.5, 0.5, 1]]),
    "capsule.ply": ("mesh", [[-0.5, -0.5, -1.5], [0.5, 0.5, 1.5]]),
    "pair.glb": ("mesh", [[-0.5, -0.5, -0.5], [2.5, 0.5, 0.5]]),
    "cloud.ply": ("pointcloud", [[-1] * 3, [1] * 3]),
    "ellipsoid.xyz": ("pointcloud", [[-2, -1, -1], [2, 1, 1]]),
    "cloud.pcd": ("pointcloud", [[-0.7] * 3, [0.7] * 3]),
    "ball.npy": ("voxels", None),
    "slab.npz": ("voxels", None),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_each_format_loads(good_files: dict[str, Path], name: str) -> None:
    representation, bounds = EXPECTED[name]
    g = load(good_files[name])
    assert g.representation == representation
    if bounds is not None:
        np.testing.assert_allclose(g.bounds, bounds, atol=0.02)
    assert np.all(np.isfinite(g.signed_distance(np.zeros((1, 3)))))


def test_scene_meshes_are_concatenated(good_files: dict[str, Path]) -> None:
    g = load(good_files["pair.glb"])
    assert len(g.faces) == 24 and len(g.vertices) == 16


def test_ply_detection_mesh_vs_cloud(good_files: dict[str, Path]) -> None:
    assert load(good_files["capsule.ply"]).representation == "mesh"
    assert load(good_files["cloud.ply"]).representation == "pointcloud"


def test_forced_pointcloud_takes_mesh_vertices(good_files: dict[str, Path]) -> None:
    mesh = load(good_files["ico.off"])
    cloud = load(good_files["ico.off"], as_="pointcloud")
    assert cloud.representation == "pointcloud"
    np.testing.assert_allclose(np.asarray(cloud.points), np.unique(mesh.vertices, axis=0))
    with pytest.raises(E.InvalidShapeError, match="cloud.ply"):
        load(good_files["cloud.ply"], as_="mesh")
    with pytest.raises(E.ConfigError):
        load(good_files["ico.off"], as_="banana")


def test_forced_smooth_voxels(good_files: dict[str, Path]) -> None:
    cubes = load(good_files["slab.npz"])
    smooth = load(good_files["slab.npz"], as_="smooth_voxels")
    assert smooth.representation == "voxels" and smooth.surface == "smooth"  # type: ignore[attr-defined]
    np.testing.assert_array_equal(smooth.occupancy, cubes.occupancy)  # type: ignore[attr-defined]
    with pytest.raises(E.InvalidShapeError, match="ico.off"):
        load(good_files["ico.off"], as_="smooth_voxels")


def test_voxel_npz_keeps_origin_and_pitch(good_files: dict[str, Path]) -> None:
    g = load(good_files["slab.npz"])
    b = np.asarray(g.bounds)
    assert b[0, 0] >= 1.0 - 0.5 and b[1, 0] <= 1.0 + 12 * 0.5
    assert b[1, 2] - b[0, 2] == pytest.approx(4 * 0.5, abs=0.5)
    assert g.surface == "cubes"  # type: ignore[attr-defined]


def test_voxel_npz_surface(tmp_path: Path) -> None:
    occ = np.zeros((8, 8, 8), dtype=bool)
    occ[2:6, 2:6, 2:6] = True
    np.savez(tmp_path / "v.npz", occupancy=occ, surface="smooth")
    g = load(tmp_path / "v.npz")
    assert g.surface == "smooth"  # type: ignore[attr-defined]
    assert g.signed_distance([[3.5, 3.5, 3.5]])[0] == pytest.approx(2.0)
    np.savez(tmp_path / "bad.npz", occupancy=occ, surface="blobby")
    with pytest.raises(E.ShapeDBError, match="surface"):
        load(tmp_path / "bad.npz")


def test_content_wins_over_extension(tmp_path: Path, good_files: dict[str, Path]) -> None:
    odd = tmp_path / "capsule.dat"
    odd.write_bytes(good_files["capsule.ply"].read_bytes())
    assert detect_format(odd) == "ply"
    assert load(odd).representation == "mesh"


@pytest.mark.parametrize(
    "name",
    [
        "empty.obj",
        "truncated.stl",
        "truncated.ply",
        "junk.obj",
        "junk.ply",
        "nan.obj",
        "line.obj",
        "model.fbx",
        "text.obj",
    ],
)
def test_bad_files_raise_clear_errors(bad_dir: tuple[Path, dict[str, str]], name: str) -> None:
    folder, expected = bad_dir
    with pytest.raises(E.ShapeDBError) as info:
        load(folder / name)
    err = info.value
    assert type(err).__name__ == expected[name] or expected[name] in [
        c.__name__ for c in type(err).__mro__
    ]
    assert str(folder / name) in str(err)  # names the file
    assert err.reason  # and says why


def test_bad_reasons_are_specific(bad_dir: tuple[Path, dict[str, str]]) -> None:
    folder, _ = bad_dir
    reasons = {}
    for name in ("empty.obj", "truncated.stl", "junk.obj", "nan.obj", "line.obj", "model.fbx"):
        with pytest.raises(E.ShapeDBError) as info:
            load(folder / name)
        reasons[name] = info.value.reason.lower()
    assert "empty" in reasons["empty.obj"]
    assert "truncated" in reasons["truncated.stl"]
    assert "junk" in reasons["junk.obj"]
    assert "nan" in reasons["nan.obj"]
    assert "a point or a line" in reasons["line.obj"]
    assert "unsupported" in reasons["model.fbx"]


def test_missing_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(E.LoadError, match="no such file"):
        load(tmp_path / "nope.obj")
    with pytest.raises(E.LoadError, match="not a regular file"):
        load(tmp_path)


def test_stl_header_checks(tmp_path: Path) -> None:
    with pytest.raises(E.LoadError, match="truncated"):
        load(write_binary_stl_header(tmp_path / "a.stl", 10))
    with pytest.raises(E.EmptyGeometryError):
        load(write_binary_stl_header(tmp_path / "b.stl", 0))


def test_npy_arrays(tmp_path: Path) -> None:
    np.save(tmp_path / "bad.npy", np.zeros((4, 5)))
    with pytest.raises(E.LoadError, match="neither"):
        load(tmp_path / "bad.npy")
    pts = np.random.default_rng(0).normal(size=(200, 3))
    np.save(tmp_path / "pts.npy", pts)
    assert load(tmp_path / "pts.npy").representation == "pointcloud"
    (tmp_path / "trunc.npy").write_bytes((tmp_path / "pts.npy").read_bytes()[:300])
    with pytest.raises(E.LoadError):
        load(tmp_path / "trunc.npy")
    pts[3, 1] = np.nan
    np.save(tmp_path / "nan.npy", pts)
    with pytest.raises(E.NonFiniteGeometryError, match="nan.npy"):
        load(tmp_path / "nan.npy")


def test_text_cloud_errors(tmp_path: Path) -> None:
    (tmp_path / "a.xyz").write_text("1 2 3\n4 5\n")
    with pytest.raises(E.LoadError, match="columns"):
        load(tmp_path / "a.xyz")
    (tmp_path / "b.xyz").write_text("1 2 3\nfoo bar baz\n")
    with pytest.raises(E.LoadError, match="line 2"):
        load(tmp_path / "b.xyz")
    (tmp_path / "c.pts").write_text("# nothing\n")
    with pytest.raises(E.EmptyGeometryError):
        load(tmp_path / "c.pts")


def test_cad_without_gmsh_asks_for_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "part.step"
    path.write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nEND-ISO-10303-21;\n")
    monkeypatch.setitem(sys.modules, "gmsh", None)
    with pytest.raises(E.MissingDependencyError, match=r"shapedb\[cad\]"):
        load(path)


def test_step_file_is_tessellated(tmp_path: Path) -> None:
    gmsh = pytest.importorskip("gmsh")
    from ingest.cad import _quiet_stdout

    path = tmp_path / "part.step"
    with _quiet_stdout():
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.model.add("part")
            box = gmsh.model.occ.addBox(0, 0, 0, 2, 1, 1)
            hole = gmsh.model.occ.addCylinder(1, 0.5, -1, 0, 0, 3, 0.25)
            gmsh.model.occ.cut([(3, box)], [(3, hole)])
            gmsh.model.occ.synchronize()
            gmsh.write(str(path))
        finally:
            gmsh.finalize()
    g = load(path)
    assert g.representation == "brep"
    np.testing.assert_allclose(g.bounds, [[0, 0, 0], [2, 1, 1]], atol=1e-6)
    sd = g.signed_distance(np.array([[0.3, 0.5, 0.5], [1.0, 0.5, 0.5], [3.0, 0.5, 0.5]]))
    assert sd[0] > 0 and sd[1] < 0 and sd[2] < 0  # inside, in the hole, outside
    junk = tmp_path / "junk.step"
    junk.write_text("ISO-10303-21;\nthis is not step\n")
    with pytest.raises(E.ShapeDBError, match="junk.step"):
        load(junk)


# ---------------------------------------------------------------- labels
def test_labels_csv_with_metadata(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    csv = tmp_path / "labels.csv"
    csv.write_text("path,label,author,year\nsub/a.obj,chair,alice,2020\n/abs/b.ply,table,,\n")
    table = read_labels(csv)
    a = table.lookup(tmp_path / "sub" / "a.obj")
    assert a is not None and a.label == "chair"
    assert dict(a.metadata) == {"author": "alice", "year": "2020"}
    b = table.lookup("/abs/b.ply")
    assert b is not None and b.label == "table" and dict(b.metadata) == {}
    # a CSV written for another root still matches by path suffix
    assert table.lookup("/elsewhere/sub/a.obj").label == "chair"  # type: ignore[union-attr]
    assert table.lookup(tmp_path / "c.obj") is None


def test_labels_csv_errors(tmp_path: Path) -> None:
    csv = tmp_path / "labels.csv"
    csv.write_text("file,label\na.obj,x\n")
    with pytest.raises(E.LoadError, match="'path' column"):
        read_labels(csv)
    with pytest.raises(E.LoadError, match="cannot read"):
        read_labels(tmp_path / "missing.csv")


def test_folder_label_and_mapping(tmp_path: Path) -> None:
    assert folder_label(tmp_path / "chairs" / "c1.obj") == "chairs"
    table = LabelTable.from_mapping({str(tmp_path / "x.obj"): "x"})
    assert table.lookup(tmp_path / "x.obj").label == "x"  # type: ignore[union-attr]
