"""Loaders verify what they read: PLY counts against the data, and sane coordinates."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from ingest_helpers import sphere_points, write_cloud_ply

import shapedb.errors as E
from ingest import load
from ingest.loaders import MAX_COORDINATE


@pytest.fixture(scope="module")
def ascii_ply() -> str:
    return trimesh.creation.box().export(file_type="ply", encoding="ascii").decode()


def _refused(path: Path, error: type[E.ShapeDBError], *words: str) -> str:
    with pytest.raises(error) as info:
        load(path)
    text = str(info.value)
    assert "\n" not in text and text.startswith(str(path)), text
    for w in words:
        assert w in text, (w, text)
    return text


def test_ascii_ply_with_absurd_counts_is_refused(tmp_path: Path, ascii_ply: str) -> None:
    for name, old, new in (
        ("v.ply", "element vertex 8", "element vertex 2000000000"),
        ("f.ply", "element face 12", "element face 4000000000"),
    ):
        path = tmp_path / name
        path.write_text(ascii_ply.replace(old, new))
        _refused(path, E.LoadError, new.split()[-1], "bytes")


def test_truncated_or_padded_ascii_ply_is_refused(tmp_path: Path, ascii_ply: str) -> None:
    lines = ascii_ply.splitlines()
    cases = {
        "cut.ply": (ascii_ply[:-40], "row"),
        "lines.ply": ("\n".join(lines[:-3]) + "\n", "truncated"),
        "vertex.ply": ("\n".join(lines[:12] + lines[13:]) + "\n", "row"),
        "extra.ply": (ascii_ply + "3 0 1 2\n", "after the last row"),
        "word.ply": ("\n".join([*lines[:-1], "3 0 one 2"]) + "\n", "not a number"),
        "index.ply": ("\n".join([*lines[:-1], "3 0 1 99"]) + "\n", "vertices"),
    }
    for name, (text, reason) in cases.items():
        path = tmp_path / name
        path.write_text(text)
        _refused(path, E.LoadError, reason)


def test_bad_ply_headers_are_refused(tmp_path: Path, ascii_ply: str) -> None:
    no_z = tmp_path / "noz.ply"
    no_z.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "end_header\n0 0\n1 0\n0 1\n"
    )
    _refused(no_z, E.LoadError, "x, y and z")
    no_end = tmp_path / "noend.ply"
    no_end.write_text(ascii_ply.replace("end_header", "end_head"))
    _refused(no_end, E.LoadError, "end_header")
    bad_type = tmp_path / "type.ply"
    bad_type.write_text(ascii_ply.replace("property float x", "property quad x"))
    _refused(bad_type, E.LoadError, "header line")


def test_binary_ply_with_absurd_counts_is_refused(tmp_path: Path) -> None:
    data = trimesh.creation.box().export(file_type="ply")
    big = tmp_path / "big.ply"
    big.write_bytes(data.replace(b"element vertex 8", b"element vertex 2000000000"))
    _refused(big, E.LoadError, "2000000000")
    cut = tmp_path / "cut.ply"
    cut.write_bytes(data[:-30])
    _refused(cut, E.LoadError)


def test_valid_ply_files_still_load(tmp_path: Path, ascii_ply: str) -> None:
    path = tmp_path / "ok.ply"
    path.write_text(ascii_ply + "\n\n")  # trailing blank lines are harmless
    assert len(load(path).faces) == 12
    cloud = write_cloud_ply(tmp_path / "cloud.ply", sphere_points(100), sphere_points(100))
    assert load(cloud).representation == "pointcloud"


def test_max_faces_is_checked_from_a_ply_header(tmp_path: Path, ascii_ply: str) -> None:
    path = tmp_path / "ok.ply"
    path.write_text(ascii_ply)
    with pytest.raises(E.LoadError, match="max_faces=4"):
        load(path, max_faces=4)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e13", "-1e30", "1e308"])
def test_non_finite_or_absurd_coordinates_are_refused(tmp_path: Path, value: str) -> None:
    obj = tmp_path / "bad.obj"
    obj.write_text(
        f"v 0 0 0\nv 1 0 0\nv 0 1 0\nv {value} 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
    )
    pts = sphere_points(200).astype(object)
    pts[3, 1] = value
    xyz = tmp_path / "bad.xyz"
    xyz.write_text("\n".join(" ".join(str(v) for v in p) for p in pts) + "\n")
    npy = tmp_path / "bad.npy"
    np.save(npy, pts.astype(np.float64))
    finite = value in ("1e13", "-1e30", "1e308") and float(value) != float("inf")
    for path in (obj, xyz, npy):
        if finite:
            _refused(path, E.InvalidShapeError, f"{MAX_COORDINATE:.0e}")
        else:
            _refused(path, E.NonFiniteGeometryError, "NaN or infinite")


@pytest.mark.parametrize("outlier", [1e308, 1e30, 1e15, 1e6])
def test_xyz_outliers_give_one_clear_error(tmp_path: Path, outlier: float) -> None:
    pts = sphere_points(400)
    for k, rows in enumerate(([5], [5, 9])):
        p = pts.copy()
        p[rows] = outlier
        path = tmp_path / f"out{k}.xyz"
        np.savetxt(path, p, fmt="%.17g")
        text = _refused(path, E.InvalidShapeError)
        assert ("outlier" in text) if outlier < MAX_COORDINATE else ("limit" in text), text
    flat = pts.copy()
    flat[:, 2] = outlier  # every point at an absurd height
    path = tmp_path / "flat.xyz"
    np.savetxt(path, flat, fmt="%.17g")
    if outlier > MAX_COORDINATE:
        _refused(path, E.InvalidShapeError, "limit")


def test_binary_stl_with_huge_count_is_still_refused(tmp_path: Path) -> None:
    data = trimesh.creation.box().export(file_type="stl")
    path = tmp_path / "big.stl"
    path.write_bytes(data[:80] + struct.pack("<I", 2**32 - 1) + data[84:])
    _refused(path, E.LoadError, "truncated")


def test_npy_with_huge_shape_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "huge.npy"
    np.save(path, np.zeros((8, 8, 8), dtype=bool))
    path.write_bytes(path.read_bytes().replace(b"(8, 8, 8)", b"(8, 8, 4000000000)"))
    _refused(path, E.LoadError, "shape")
