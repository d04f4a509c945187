"""Small generated model files of every format, for the ingest tests."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import trimesh

#: Small settings so that every test shape decomposes in a fraction of a second.
SMALL = {"resolution": 32, "n_balls": 64}


def sphere_points(n: int = 600, radius: float = 1.0, seed: int = 0) -> np.ndarray:
    """Fibonacci points on a sphere: (n, 3); their normals are points / radius."""
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    theta = np.pi * (1 + 5**0.5) * k
    return radius * np.column_stack(
        [np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)]
    )


def write_cloud_ply(path: Path, points: np.ndarray, normals: np.ndarray | None = None) -> Path:
    """An ASCII PLY with vertices only (no faces): a point cloud."""
    props = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals is not None else [])
    data = points if normals is None else np.hstack([points, normals])
    header = ["ply", "format ascii 1.0", f"element vertex {len(points)}"]
    header += [f"property float {p}" for p in props] + ["end_header"]
    lines = [" ".join(f"{v:.6f}" for v in row) for row in data]
    path.write_text("\n".join(header + lines) + "\n")
    return path


def write_pcd(path: Path, points: np.ndarray) -> Path:
    """An ASCII PCD point cloud."""
    n = len(points)
    header = [
        "# .PCD v0.7 - Point Cloud Data file format",
        "VERSION 0.7",
        "FIELDS x y z",
        "SIZE 4 4 4",
        "TYPE F F F",
        "COUNT 1 1 1",
        f"WIDTH {n}",
        "HEIGHT 1",
        "VIEWPOINT 0 0 0 1 0 0 0",
        f"POINTS {n}",
        "DATA ascii",
    ]
    lines = [" ".join(f"{v:.6f}" for v in p) for p in points]
    path.write_text("\n".join(header + lines) + "\n")
    return path


def voxel_ball(n: int = 16) -> np.ndarray:
    """A (n, n, n) bool occupancy grid of a ball."""
    ax = np.arange(n) - (n - 1) / 2
    x, y, z = np.meshgrid(ax, ax, ax, indexing="ij")
    return (x**2 + y**2 + z**2) <= (0.4 * n) ** 2


def make_good(folder: Path) -> dict[str, Path]:
    """One good file of each supported non-CAD format; returns name -> path."""
    folder.mkdir(parents=True, exist_ok=True)
    out: dict[str, Path] = {}
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    out["box.obj"] = folder / "box.obj"
    box.export(out["box.obj"])
    out["ico.off"] = folder / "ico.off"
    trimesh.creation.icosphere(subdivisions=2, radius=1.5).export(out["ico.off"])
    out["cyl.stl"] = folder / "cyl.stl"
    trimesh.creation.cylinder(radius=0.5, height=2.0, sections=24).export(out["cyl.stl"])
    out["capsule.ply"] = folder / "capsule.ply"
    trimesh.creation.capsule(height=2.0, radius=0.5).export(out["capsule.ply"])
    scene = trimesh.Scene(
        [
            trimesh.creation.box(extents=(1, 1, 1)),
            trimesh.creation.box(extents=(1, 1, 1)).apply_translation((2.0, 0, 0)),
        ]
    )
    out["pair.glb"] = folder / "pair.glb"
    scene.export(out["pair.glb"])
    pts = sphere_points(500)
    out["cloud.ply"] = write_cloud_ply(folder / "cloud.ply", pts, pts)
    out["ellipsoid.xyz"] = folder / "ellipsoid.xyz"
    ell = sphere_points(400) * [2.0, 1.0, 1.0]
    normals = ell / np.array([4.0, 1.0, 1.0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.savetxt(out["ellipsoid.xyz"], np.hstack([ell, normals]), fmt="%.6f")
    out["cloud.pcd"] = write_pcd(folder / "cloud.pcd", sphere_points(300, radius=0.7))
    out["ball.npy"] = folder / "ball.npy"
    np.save(out["ball.npy"], voxel_ball(16))
    out["slab.npz"] = folder / "slab.npz"
    occ = np.zeros((12, 12, 12), dtype=np.uint8)
    occ[2:10, 2:10, 4:8] = 1
    np.savez(out["slab.npz"], occupancy=occ, origin=np.array([1.0, 2.0, 3.0]), pitch=0.5)
    return out


def make_bad(folder: Path) -> dict[str, str]:
    """Bad files mixed with two good ones; returns bad name -> expected error class."""
    folder.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box().export(folder / "good_box.obj")
    trimesh.creation.icosphere(subdivisions=1).export(folder / "good_ico.off")
    (folder / "empty.obj").write_bytes(b"")
    stl = trimesh.creation.box().export(file_type="stl")
    (folder / "truncated.stl").write_bytes(stl[: len(stl) // 2])
    ply = trimesh.creation.box().export(file_type="ply")
    (folder / "truncated.ply").write_bytes(ply[: len(ply) - 30])
    rng = np.random.default_rng(7)
    (folder / "junk.obj").write_bytes(rng.bytes(2048))
    (folder / "junk.ply").write_bytes(b"ply\n" + rng.bytes(512))
    (folder / "nan.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
    )
    # every vertex on one line: no surface at all (a flat sheet is a model: shapedb.geometry.sheet)
    (folder / "line.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    (folder / "model.fbx").write_bytes(b"Kaydara FBX Binary  \x00" + rng.bytes(64))
    (folder / "text.obj").write_text("this is not a mesh\njust words\n")
    return {
        "empty.obj": "LoadError",
        "truncated.stl": "LoadError",
        "truncated.ply": "LoadError",
        "junk.obj": "LoadError",
        "junk.ply": "LoadError",
        "nan.obj": "NonFiniteGeometryError",
        "line.obj": "DegenerateGeometryError",
        "model.fbx": "UnsupportedFormatError",
        "text.obj": "EmptyGeometryError",
    }


def write_binary_stl_header(path: Path, n_triangles: int, payload: bytes = b"") -> Path:
    """A binary STL whose header announces ``n_triangles``."""
    path.write_bytes(b"\0" * 80 + struct.pack("<I", n_triangles) + payload)
    return path
