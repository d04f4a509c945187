"""Read model files of any supported format into a :class:`~shapedb.geometry.base.Geometry`.

The format is decided by the file's content when it announces itself (PLY, OFF,
glTF binary, NPY, NPZ, STEP headers) and by its extension otherwise:

========================  ==================================  ==================
extension                 read as                             with
========================  ==================================  ==================
.obj .off .stl .glb .gltf  TriangleMesh (scenes concatenated)  trimesh
.ply                      TriangleMesh, or PointCloud when    trimesh
                          the file has no faces
.pcd                      PointCloud                          open3d
.xyz .pts                 PointCloud (x y z [nx ny nz] ...)   numpy
.npy                      (n, 3) -> PointCloud,               numpy
                          3-D bool/uint8 -> VoxelGrid
.npz                      VoxelGrid (occupancy, origin,       numpy
                          pitch [, surface]), or points /
                          vertices+faces
.step .stp .iges .igs     B-rep solid, tessellated finely     gmsh (extra "cad")
.brep .brp
========================  ==================================  ==================

Files are checked against themselves before a parser trusts them (OFF and OBJ face
indices, binary STL and NPY sizes, PLY bodies against their headers: :mod:`ingest.ply`),
and the shapes read against absurd coordinates (:mod:`ingest.shapes`). Every failure
raises a :mod:`shapedb.errors` exception whose ``source`` is the path and whose
one-line message says why (empty, truncated, junk, NaN, zero volume, unsupported).
"""

from __future__ import annotations

import io
import logging
import os
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ingest.ply import check_ply
from ingest.shapes import (
    MAX_COORDINATE,
    OUTLIER_RATIO,
    cloud_geometry,
    mesh_geometry,
    voxel_geometry,
)
from shapedb.errors import (
    ConfigError,
    EmptyGeometryError,
    InvalidShapeError,
    LoadError,
    ShapeDBError,
    UnsupportedFormatError,
)
from shapedb.geometry.base import Geometry
from shapedb.store.schema import safe_text

__all__ = [
    "load",
    "detect_format",
    "MESH_FORMATS",
    "CLOUD_FORMATS",
    "VOXEL_FORMATS",
    "CAD_FORMATS",
    "SUPPORTED",
    "MAX_COORDINATE",
    "OUTLIER_RATIO",
]

log = logging.getLogger(__name__)

MESH_FORMATS = {
    ".obj": "obj",
    ".off": "off",
    ".stl": "stl",
    ".glb": "glb",
    ".gltf": "gltf",
    ".ply": "ply",
}
CLOUD_FORMATS = {".pcd": "pcd", ".xyz": "xyz", ".pts": "pts"}
VOXEL_FORMATS = {".npy": "npy", ".npz": "npz"}
CAD_FORMATS = {
    ".step": "step",
    ".stp": "step",
    ".iges": "iges",
    ".igs": "iges",
    ".brep": "brep",
    ".brp": "brep",
}
SUPPORTED = {**MESH_FORMATS, **CLOUD_FORMATS, **VOXEL_FORMATS, **CAD_FORMATS}
"""Extension -> format name of every file type :func:`load` reads."""

_TEXT_FORMATS = {"obj", "off", "xyz", "pts", "gltf", "step", "iges"}
#: Representations a file can be forced into (``load(path, as_=...)``).
AS_OPTIONS = (None, "mesh", "pointcloud", "smooth_voxels")
_AS = AS_OPTIONS


def detect_format(path: str | os.PathLike[str], head: bytes | None = None) -> str:
    """Format name of a file, from its first bytes and then its extension.

    Raises :class:`UnsupportedFormatError` when neither tells.
    """
    p = Path(path)
    if head is None:
        with open(p, "rb") as fh:
            head = fh.read(64)
    sniffed = _sniff(head)
    ext = p.suffix.lower()
    if sniffed is not None:
        return sniffed
    if ext in SUPPORTED:
        return SUPPORTED[ext]
    raise UnsupportedFormatError(
        f"unsupported file type {ext or '(no extension)'!r}; supported: "
        f"{', '.join(sorted(SUPPORTED))}",
        source=str(path),
    )


def _sniff(head: bytes) -> str | None:
    if head.startswith(b"ply"):
        return "ply"
    if head.startswith(b"glTF"):
        return "glb"
    if head.startswith(b"\x93NUMPY"):
        return "npy"
    if head.startswith(b"ISO-10303-21"):
        return "step"
    if head[:4] in (b"OFF\n", b"OFF\r", b"OFF ", b"COFF", b"NOFF"):
        return "off"
    if head.startswith(b"# .PCD") or head.startswith(b"VERSION"):
        return "pcd"
    return None


def load(
    path: str | os.PathLike[str],
    *,
    as_: str | None = None,
    max_bytes: int | None = None,
    max_faces: int | None = None,
) -> Geometry:
    """Read a model file into a Geometry.

    Parameters
    ----------
    path : str or Path
        The file.
    as_ : {None, "mesh", "pointcloud", "smooth_voxels"}
        Force the representation: ``"pointcloud"`` takes a mesh file's vertices as a
        point cloud (the paper's Table 3 setting); ``"mesh"`` refuses point clouds;
        ``"smooth_voxels"`` reads an occupancy grid with ``surface="smooth"`` (its
        marching-cubes boundary, for grids that sample a smooth solid; see
        :mod:`shapedb.geometry.voxels`) and refuses other files.
    max_bytes : int, optional
        Refuse files larger than this (checked before reading).
    max_faces : int, optional
        Refuse meshes with more faces (checked from the header of OFF and binary STL
        files before reading them, after reading otherwise).

    Returns
    -------
    Geometry
        A TriangleMesh, PointCloud, VoxelGrid, or a tessellated CAD solid.

    Raises
    ------
    LoadError
        Missing, empty, truncated or unparsable file; an OFF or PLY whose header
        counts disagree with its body; faces naming vertices the file does not have;
        a file above ``max_bytes`` or ``max_faces``.
    UnsupportedFormatError
        No loader for this file type.
    InvalidShapeError
        The content is no usable solid (no faces, NaN coordinates, coordinates beyond
        :data:`MAX_COORDINATE`, cloud outliers, zero volume...).
    MissingDependencyError
        A CAD file without the ``cad`` extra (gmsh) installed.
    """
    if as_ not in _AS:
        raise ConfigError(f"as_={as_!r} is invalid: must be one of {list(_AS)}")
    p = Path(path)
    src = str(p)
    if not p.exists():
        raise LoadError("no such file", source=src)
    if not p.is_file():
        raise LoadError("not a regular file", source=src)
    size = p.stat().st_size
    if size == 0:
        raise LoadError("file is empty (0 bytes)", source=src)
    if max_bytes is not None and size > max_bytes:
        raise LoadError(f"file has {size} bytes, above the cap max_bytes={max_bytes}", source=src)
    with open(p, "rb") as fh:
        head = fh.read(4096)
    fmt = detect_format(p, head)
    if fmt in _TEXT_FORMATS and b"\x00" in head:
        raise LoadError(f"binary junk in what should be a text {fmt.upper()} file", source=src)
    try:
        return _convert(_read(p, fmt, head, size, max_faces), as_, src)
    except ShapeDBError as exc:
        if exc.source is None:  # name the file
            raise type(exc)(exc.reason, source=src) from exc
        raise
    except (MemoryError, KeyboardInterrupt):
        raise
    except Exception as exc:
        raise LoadError(
            f"cannot parse as {fmt.upper()}: {type(exc).__name__}: {exc}", source=src
        ) from exc


def _read(p: Path, fmt: str, head: bytes, size: int, max_faces: int | None) -> Geometry:
    """Check what can be checked before parsing, parse, then check the result."""
    header = None
    if fmt in ("obj", "off"):
        _check_faces(p, fmt, max_faces)
    elif fmt == "ply":
        header = check_ply(p, size, max_faces)
    geometry = _LOADERS[fmt](p, head, size)
    if header is not None:
        got = len(getattr(geometry, "vertices", getattr(geometry, "points", ())))
        if got != header.count("vertex"):
            raise LoadError(
                f"the PLY header announces {header.count('vertex')} vertices, the parser read {got}"
            )
    _check_cap(geometry, max_faces)
    return geometry


# ---------------------------------------------------------------- text mesh checks
def _check_cap(geometry: Geometry, max_faces: int | None) -> None:
    faces = getattr(geometry, "faces", None)
    if max_faces is not None and faces is not None and len(faces) > max_faces:
        raise LoadError(f"mesh has {len(faces)} faces, above the cap max_faces={max_faces}")


def _check_faces(p: Path, fmt: str, max_faces: int | None) -> None:
    """OBJ / OFF: every face names existing vertices, and an OFF body matches its header.

    Trimesh would otherwise drop such faces, or read a file cut short as a point
    cloud of its vertices, without a word.
    """
    with open(p, "rb") as fh:
        if fmt == "off":
            _check_off(fh, max_faces)
        else:
            _check_obj(fh, max_faces)


def _data_lines(fh: Any) -> Iterator[tuple[int, list[bytes]]]:
    for k, line in enumerate(fh, 1):
        tokens = line.split(b"#", 1)[0].split()
        if tokens:
            yield k, tokens


def _check_off(fh: Any, max_faces: int | None) -> None:
    lines = _data_lines(fh)
    k, tokens = next(lines, (0, []))
    if not tokens or not tokens[0].endswith(b"OFF"):
        raise LoadError("no OFF header")
    counts = tokens[1:] or next(lines, (0, []))[1]
    try:
        nv, nf = int(counts[0]), int(counts[1])
    except (IndexError, ValueError):
        raise LoadError("the OFF header has no vertex and face counts") from None
    if nv < 0 or nf < 0:
        raise LoadError(f"the OFF header announces {nv} vertices and {nf} faces")
    if max_faces is not None and nf > max_faces:
        raise LoadError(f"the OFF header announces {nf} faces, above the cap max_faces={max_faces}")
    seen_v = seen_f = 0
    for k, tokens in lines:
        if seen_v < nv:
            if len(tokens) < 3:
                raise LoadError(f"line {k}: a vertex needs 3 coordinates, got {len(tokens)}")
            seen_v += 1
            continue
        if seen_f >= nf:
            break
        try:
            n = int(tokens[0])
            idx = [int(t) for t in tokens[1 : n + 1]]
        except ValueError:
            raise LoadError(f"line {k}: a face must be integers") from None
        if len(idx) != n or any(i < 0 or i >= nv for i in idx):
            raise LoadError(
                f"line {k}: face names vertices {idx[:6]} but the file has {nv} vertices (0-based)"
            )
        seen_f += 1
    if seen_v < nv or seen_f < nf:
        raise LoadError(
            f"truncated: the header announces {nv} vertices and {nf} faces, "
            f"the file has {seen_v} and {seen_f}"
        )


def _check_obj(fh: Any, max_faces: int | None) -> None:
    nv = nf = 0
    top, top_line = 0, 0  # largest positive vertex index, and where
    for k, tokens in _data_lines(fh):
        if tokens[0] == b"v":
            nv += 1
        elif tokens[0] == b"f":
            nf += 1
            if max_faces is not None and nf > max_faces:
                raise LoadError(f"more than max_faces={max_faces} faces")
            for t in tokens[1:]:
                try:
                    i = int(t.split(b"/", 1)[0])
                except ValueError:
                    raise LoadError(f"line {k}: face index {t[:20]!r} is not an integer") from None
                if i == 0 or -i > nv:  # 0 is no index; negative ones count back from here
                    raise LoadError(f"line {k}: face names vertex {i}, which does not exist")
                if i > top:
                    top, top_line = i, k
    if top > nv:
        raise LoadError(f"line {top_line}: face names vertex {top} but the file has {nv} vertices")


def _convert(geometry: Geometry, as_: str | None, src: str) -> Geometry:
    if as_ is None or geometry.representation == as_:
        return geometry
    if as_ == "smooth_voxels" and geometry.representation == "voxels":
        g: Any = geometry
        return voxel_geometry(g.occupancy, g.origin, g.pitch, src, surface="smooth")
    if as_ == "pointcloud" and geometry.representation in ("mesh", "brep"):
        return cloud_geometry(np.asarray(geometry.vertices), None, src)  # type: ignore[attr-defined]
    raise InvalidShapeError(f"cannot read a {geometry.representation} file as a {as_}", source=src)


# ---------------------------------------------------------------- trimesh formats
def _load_trimesh(p: Path, head: bytes, size: int) -> Geometry:
    import trimesh

    fmt = detect_format(p, head)
    src = str(p)
    if fmt == "stl":
        _check_stl(head, size, src)
    if safe_text(src) == src:
        scene = trimesh.load_scene(src, file_type=fmt, process=False)
    else:  # trimesh cannot take a file name that is not UTF-8: hand it the bytes
        scene = trimesh.load_scene(io.BytesIO(p.read_bytes()), file_type=fmt, process=False)
    parts = scene.dump()
    meshes = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    clouds = [g for g in parts if isinstance(g, trimesh.PointCloud)]
    if meshes:
        verts, faces, offset = [], [], 0
        for m in meshes:
            verts.append(np.asarray(m.vertices, dtype=np.float64))
            faces.append(np.asarray(m.faces, dtype=np.int64) + offset)
            offset += len(m.vertices)
        return mesh_geometry(np.concatenate(verts), np.concatenate(faces), src)
    bare = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.vertices)]
    if clouds or (fmt == "ply" and bare):
        pts = np.concatenate([np.asarray(g.vertices) for g in clouds + bare])
        normals = _ply_normals(clouds[0]) if len(clouds) == 1 and not bare else None
        return cloud_geometry(pts, normals, src)
    raise EmptyGeometryError(
        f"no vertices or faces found: the file is empty, junk, or not a valid {fmt.upper()}",
        source=src,
    )


def _ply_normals(cloud: Any) -> NDArray[np.float64] | None:
    """Per-vertex normals (nx, ny, nz) of a PLY point cloud, when the file has them."""
    raw = cloud.metadata.get("_ply_raw", {}).get("vertex", {}).get("data")
    if raw is None:
        return None
    names = list(raw.keys()) if isinstance(raw, dict) else list(raw.dtype.names or ())
    if not all(n in names for n in ("nx", "ny", "nz")):
        return None
    n = np.column_stack([np.asarray(raw[k], dtype=np.float64) for k in ("nx", "ny", "nz")])
    return n if np.all(np.isfinite(n)) and np.any(n) else None


def _check_stl(head: bytes, size: int, src: str) -> None:
    """Binary STL: the header announces the triangle count, so the size is known."""
    if head[:5].lower() == b"solid" and b"facet" in head[:4096].lower():
        return  # ASCII STL
    if size < 84:
        raise LoadError(
            f"truncated: a binary STL needs at least 84 bytes, file has {size}", source=src
        )
    (n,) = struct.unpack("<I", head[80:84])
    expected = 84 + 50 * n
    if size < expected:
        raise LoadError(
            f"truncated: header announces {n} triangles ({expected} bytes), file has {size}",
            source=src,
        )
    if n == 0:
        raise EmptyGeometryError("STL header announces 0 triangles", source=src)


# ---------------------------------------------------------------- point clouds
def _load_pcd(p: Path, head: bytes, size: int) -> Geometry:
    import open3d as o3d

    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        pcd = o3d.io.read_point_cloud(str(p), format="pcd")  # type: ignore[arg-type]
    pts = np.asarray(pcd.points)
    if len(pts) == 0:
        raise LoadError("no points read: the PCD file is empty, truncated or junk", source=str(p))
    normals = np.asarray(pcd.normals) if pcd.has_normals() else None
    return cloud_geometry(pts, normals, str(p))


def _load_text_cloud(p: Path, head: bytes, size: int) -> Geometry:
    src = str(p)
    rows: list[list[float]] = []
    with open(p, encoding="utf-8", errors="strict") as fh:
        for k, line in enumerate(fh):
            text = line.split("#", 1)[0].replace(",", " ").split()
            if not text:
                continue
            if k == 0 and len(text) == 1:  # PTS: a point count first
                continue
            try:
                rows.append([float(x) for x in text])
            except ValueError:
                raise LoadError(
                    f"line {k + 1} is not a list of numbers: {line[:60]!r}", source=src
                ) from None
    if not rows:
        raise EmptyGeometryError("no points in the file", source=src)
    widths = {len(r) for r in rows}
    if len(widths) != 1 or min(widths) < 3:
        raise LoadError(
            f"rows have {sorted(widths)} columns; expected the same number, >= 3 "
            "(x y z [nx ny nz ...]); the file may be truncated",
            source=src,
        )
    a = np.asarray(rows, dtype=np.float64)
    pts, normals = a[:, :3], None
    if a.shape[1] >= 6:
        n = a[:, 3:6]
        unit = np.all(np.abs(n) <= 1.5) and np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-2)
        if unit:
            normals = n
    return cloud_geometry(pts, normals, src)


# ---------------------------------------------------------------- numpy
def _check_npy(fh: Any, size: int, what: str) -> None:
    """Refuse an NPY stream whose header announces more data than its ``size`` bytes hold."""
    try:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
    except ValueError as exc:
        raise LoadError(f"{what} has no valid NPY header: {exc}") from None
    need = int(np.prod(shape, dtype=object)) * dtype.itemsize
    if need > size:
        raise LoadError(
            f"truncated or corrupt shape: {what} announces an array of shape {shape} "
            f"({need} bytes) in {size} bytes"
        )


def _load_npy(p: Path, head: bytes, size: int) -> Geometry:
    src = str(p)
    with open(p, "rb") as fh:
        _check_npy(fh, size, "the file")
    try:
        a = np.load(p, allow_pickle=False)
    except ValueError as exc:
        raise LoadError(
            f"not a readable NPY array (truncated or pickled?): {exc}", source=src
        ) from exc
    return _from_array(a, src)


def _from_array(a: NDArray[Any], src: str) -> Geometry:
    if a.ndim == 3 and (a.dtype == np.bool_ or np.issubdtype(a.dtype, np.integer)):
        return voxel_geometry(a.astype(bool), np.zeros(3), 1.0, src)
    if a.ndim == 2 and a.shape[1] in (3, 6) and np.issubdtype(a.dtype, np.number):
        normals = a[:, 3:6] if a.shape[1] == 6 else None
        return cloud_geometry(a[:, :3], normals, src)
    raise LoadError(
        f"array of shape {a.shape} and dtype {a.dtype} is neither an (n, 3) point array "
        "nor a 3-D bool/uint8 occupancy grid",
        source=src,
    )


def _load_npz(p: Path, head: bytes, size: int) -> Geometry:
    src = str(p)
    try:
        _check_npz(p)
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (ValueError, OSError, EOFError) as exc:
        raise LoadError(
            f"not a readable NPZ archive (truncated or junk?): {exc}", source=src
        ) from exc
    except Exception as exc:  # zipfile.BadZipFile and friends
        raise LoadError(f"not a readable NPZ archive: {exc}", source=src) from exc
    if "occupancy" in data:
        return voxel_geometry(
            data["occupancy"].astype(bool),
            data.get("origin", np.zeros(3)),
            float(np.asarray(data.get("pitch", 1.0))),
            src,
            str(np.asarray(data.get("surface", "cubes"))),
        )
    if "vertices" in data and "faces" in data:
        return mesh_geometry(data["vertices"], data["faces"], src)
    if "points" in data:
        return cloud_geometry(data["points"], data.get("normals"), src)
    if len(data) == 1:
        return _from_array(next(iter(data.values())), src)
    raise LoadError(
        f"NPZ has keys {sorted(data)}; expected 'occupancy' [+ 'origin', 'pitch', 'surface'], "
        "'points' [+ 'normals'] or 'vertices' + 'faces'",
        source=src,
    )


def _check_npz(p: Path) -> None:
    """Refuse an NPZ archive holding an array whose header announces more than it holds."""
    import zipfile

    with zipfile.ZipFile(p) as z:
        for info in z.infolist():
            if info.filename.endswith(".npy"):
                with z.open(info) as fh:
                    _check_npy(fh, info.file_size, f"its array {info.filename!r}")


def _load_cad(p: Path, head: bytes, size: int) -> Geometry:
    from ingest.cad import load_cad

    return load_cad(p)


_LOADERS = {
    "obj": _load_trimesh,
    "off": _load_trimesh,
    "stl": _load_trimesh,
    "glb": _load_trimesh,
    "gltf": _load_trimesh,
    "ply": _load_trimesh,
    "pcd": _load_pcd,
    "xyz": _load_text_cloud,
    "pts": _load_text_cloud,
    "npy": _load_npy,
    "npz": _load_npz,
    "step": _load_cad,
    "iges": _load_cad,
    "brep": _load_cad,
}
