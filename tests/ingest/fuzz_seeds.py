"""Small valid files of every supported format, and seeded ways to damage them.

Used by the loader fuzz test (``test_fuzz.py``): each mutation is one a disk, a
transfer or a careless edit produces: truncation, flipped bytes, a huge count, a
number turned into NaN / inf / 1e308 text, deleted or repeated lines, inserted junk.
"""

from __future__ import annotations

import io
import json
import random
import re
import struct
from collections.abc import Callable

import numpy as np
import trimesh
from ingest_helpers import sphere_points, voxel_ball


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def _npz(**arrays: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    return buf.getvalue()


def _text_cloud(pts: np.ndarray, count: bool = False) -> bytes:
    lines = [f"{len(pts)}"] if count else []
    lines += [" ".join(f"{v:.5f}" for v in p) for p in pts]
    return ("\n".join(lines) + "\n").encode()


def _pcd(pts: np.ndarray) -> bytes:
    head = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n"
        f"SIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {len(pts)}\nHEIGHT 1\n"
        f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(pts)}\nDATA ascii\n"
    )
    return (head + "\n".join(" ".join(f"{v:.5f}" for v in p) for p in pts) + "\n").encode()


def _gltf(mesh: trimesh.Trimesh) -> bytes:
    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(mesh), embed_buffers=True)
    return bytes(files["model.gltf"])


def _step() -> bytes:
    return (
        b"ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('x'),'2;1');\nENDSEC;\nDATA;\n"
        b"#1=CARTESIAN_POINT('',(0.,0.,0.));\n#2=DIRECTION('',(0.,0.,1.));\nENDSEC;\n"
        b"END-ISO-10303-21;\n"
    )


def seeds() -> dict[str, bytes]:
    """File name -> bytes of a small valid file, one or more per supported format."""
    box = trimesh.creation.box(extents=(1.0, 0.7, 0.5))
    ico = trimesh.creation.icosphere(subdivisions=1)
    pts = sphere_points(60)
    return {
        "box.obj": box.export(file_type="obj").encode(),
        "ico.off": ico.export(file_type="off").encode(),
        "box.stl": box.export(file_type="stl"),
        "ascii.stl": box.export(file_type="stl_ascii").encode(),
        "ico.ply": ico.export(file_type="ply"),
        "ascii.ply": box.export(file_type="ply", encoding="ascii"),
        "cloud.ply": trimesh.PointCloud(pts).export(file_type="ply", encoding="ascii"),
        "box.glb": box.export(file_type="glb"),
        "box.gltf": _gltf(box),
        "cloud.xyz": _text_cloud(np.hstack([pts, pts])),
        "cloud.pts": _text_cloud(pts, count=True),
        "cloud.pcd": _pcd(pts),
        "cloud.npy": _npy(pts),
        "ball.npy": _npy(voxel_ball(8)),
        "slab.npz": _npz(occupancy=voxel_ball(8), origin=np.zeros(3), pitch=np.array(0.5)),
        "mesh.npz": _npz(vertices=np.asarray(box.vertices), faces=np.asarray(box.faces)),
        "part.step": _step(),
        "part.iges": b"                                                                        S      1\n",
        "part.brep": b"DBRep_DrawableShape\n\nCASCADE Topology V1, (c) Matra-Datavision\n",
    }


# ---------------------------------------------------------------- mutations
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
_HUGE = (b"2000000000", b"4000000000", b"99999999999999999999", b"-1", b"1e9")
_BAD_NUMBERS = (b"nan", b"inf", b"-inf", b"1e308", b"-1e30", b"NaN", b"1e999")


def truncate(rng: random.Random, b: bytes) -> bytes:
    return b[: rng.randrange(len(b))]


def flip(rng: random.Random, b: bytes) -> bytes:
    out = bytearray(b)
    for _ in range(rng.randint(1, 8)):
        out[rng.randrange(len(out))] = rng.randrange(256)
    return bytes(out)


def _replace_number(rng: random.Random, b: bytes, new: bytes, head: int | None) -> bytes:
    found = list(_NUMBER.finditer(b[:head] if head else b))
    if not found:
        return flip(rng, b)
    m = rng.choice(found)
    return b[: m.start()] + new + b[m.end() :]


def huge_count(rng: random.Random, b: bytes) -> bytes:
    if b[:5].lower() != b"solid" and len(b) >= 84 and b[80:84] == struct.pack("<I", 12):
        return b[:80] + struct.pack("<I", rng.choice([2**31, 2**32 - 1, 13])) + b[84:]
    head = b.find(b"end_header")  # PLY: a count of the header
    return _replace_number(rng, b, rng.choice(_HUGE), head if head > 0 else 400)


def nan_text(rng: random.Random, b: bytes) -> bytes:
    return _replace_number(rng, b, rng.choice(_BAD_NUMBERS), None)


def _lines(b: bytes) -> list[bytes]:
    return b.splitlines(keepends=True) or [b]


def delete_lines(rng: random.Random, b: bytes) -> bytes:
    lines = _lines(b)
    k = rng.randrange(len(lines))
    del lines[k : k + rng.randint(1, 3)]
    return b"".join(lines)


def repeat_line(rng: random.Random, b: bytes) -> bytes:
    lines = _lines(b)
    k = rng.randrange(len(lines))
    lines.insert(k, lines[k])
    return b"".join(lines)


def junk(rng: random.Random, b: bytes) -> bytes:
    k = rng.randrange(len(b) + 1)
    return b[:k] + rng.randbytes(rng.randint(1, 32)) + b[k:]


MUTATIONS: tuple[Callable[[random.Random, bytes], bytes], ...] = (
    truncate, flip, huge_count, nan_text, delete_lines, repeat_line, junk,
)  # fmt: skip


def mutate(seed: int, data: bytes) -> tuple[str, bytes]:
    """One or two mutations of ``data``, drawn from ``seed``: (their names, the bytes)."""
    rng = random.Random(seed)
    names = []
    for _ in range(rng.choice((1, 1, 2))):
        op = rng.choice(MUTATIONS)
        data = op(rng, data) if data else data
        names.append(op.__name__)
    return "+".join(names), data


def describe(data: bytes) -> str:
    """A short printable view of a case's first bytes, for failure messages."""
    return json.dumps(data[:120].decode("latin-1"))
