"""Generated example solids: jointed figures and machined parts, as implicit CSG.

Everything is deterministic: a figure is fixed by ``(subject, pose)`` and a part by
``(kind, seed)``. Figures mimic an articulated-retrieval benchmark (SHREC'14 style):
each subject has its own limb proportions and can take any pose; the same pose
index gives the same joint angles for every subject. Parts are plates (holes,
slots, bosses, ribs), L-brackets (holes, gusset) and flanges (hub, bore, bolt
circle).

>>> from shapedb import examples
>>> g = examples.figure(subject=1, pose=3)
>>> mesh = examples.to_mesh(g, resolution=96)      # needs scikit-image
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import ConfigError, require
from shapedb.geometry import Geometry, Grid
from shapedb.implicit import Box, Capsule, Cylinder, Implicit, Sphere, Union

if TYPE_CHECKING:
    import trimesh

__all__ = ["figure", "part", "catalogue", "to_mesh", "PART_KINDS"]

logger = logging.getLogger(__name__)

PART_KINDS = ("plate", "bracket", "flange")


def _rot(axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    """Rotation matrix (3, 3) about the unit ``axis`` by ``angle`` radians (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


# -- figures ---------------------------------------------------------------------------
def _proportions(subject: int) -> dict[str, float]:
    """Body proportions of a subject (model units, about 1.8 tall); subject 0 is average."""
    base = {
        "torso": 0.60,
        "torso_r": 0.16,
        "head_r": 0.12,
        "neck": 0.06,
        "shoulder": 0.42,
        "hip": 0.22,
        "upper_arm": 0.30,
        "forearm": 0.28,
        "arm_r": 0.055,
        "thigh": 0.44,
        "shin": 0.42,
        "leg_r": 0.075,
    }
    if subject == 0:
        return base
    rng = np.random.default_rng([7, subject])
    length, girth = rng.uniform(0.8, 1.2), rng.uniform(0.75, 1.3)
    out = {}
    for k, v in base.items():
        f = (
            girth
            if k.endswith("_r")
            else length
            if k in ("upper_arm", "forearm", "thigh", "shin")
            else 1.0
        )
        out[k] = v * f * rng.uniform(0.93, 1.07)
    return out


def _angles(pose: int) -> dict[str, float]:
    """Joint angles (radians) of a pose; pose 0 is a relaxed A-pose, others are random."""
    names = (
        "l_abduct",
        "r_abduct",
        "l_flex",
        "r_flex",
        "l_elbow",
        "r_elbow",
        "l_hip_abduct",
        "r_hip_abduct",
        "l_hip_flex",
        "r_hip_flex",
        "l_knee",
        "r_knee",
        "neck",
    )
    if pose == 0:
        a = dict.fromkeys(names, 0.0)
        a.update(l_abduct=0.35, r_abduct=0.35, l_hip_abduct=0.08, r_hip_abduct=0.08)
        return a
    rng = np.random.default_rng([11, pose])
    lo = {
        "abduct": 0.1,
        "flex": -1.2,
        "elbow": 0.0,
        "hip_abduct": 0.0,
        "hip_flex": -0.9,
        "knee": 0.0,
        "neck": -0.4,
    }
    hi = {
        "abduct": 1.6,
        "flex": 1.2,
        "elbow": 1.8,
        "hip_abduct": 0.5,
        "hip_flex": 0.9,
        "knee": 1.6,
        "neck": 0.4,
    }
    out = {}
    for n in names:
        key = n.split("_", 1)[1] if n[:2] in ("l_", "r_") else n
        out[n] = float(rng.uniform(lo[key], hi[key]))
    return out


def _limb(
    root: NDArray[np.float64],
    side: float,
    abduct: float,
    flex: float,
    bend: float,
    l1: float,
    l2: float,
    radius: float,
    bend_sign: float,
) -> list[Implicit]:
    """Two capsules (upper and lower segment) hanging from ``root``."""
    down = np.array([0.0, 0.0, -1.0])
    R = _rot(np.array([1.0, 0, 0]), flex) @ _rot(np.array([0, 1.0, 0]), -side * abduct)
    d1 = R @ down
    joint = root + l1 * d1
    side_axis = R @ np.array([1.0, 0, 0])
    d2 = _rot(side_axis, bend_sign * bend) @ d1
    return [Capsule(root, joint, radius), Capsule(joint, joint + l2 * d2, 0.9 * radius)]


def figure(subject: int = 0, pose: int = 0) -> Implicit:
    """A jointed human-like figure built from capsules and a sphere.

    Parameters
    ----------
    subject : int >= 0
        Body proportions (limb lengths and girths); 0 is the average subject.
    pose : int >= 0
        Joint angles; 0 is a relaxed A-pose, the same index gives the same angles for
        every subject.

    Returns
    -------
    Implicit
        About 1.8 model units tall, pelvis at the origin, z up.
    """
    if subject < 0 or pose < 0:
        raise ConfigError(f"subject and pose must be >= 0, got subject={subject}, pose={pose}")
    p, a = _proportions(subject), _angles(pose)
    top = np.array([0.0, 0.0, p["torso"]])
    neck_dir = _rot(np.array([1.0, 0, 0]), a["neck"]) @ np.array([0.0, 0, 1])
    parts: list[Implicit] = [
        Capsule([0.0, 0.0, 0.0], top, p["torso_r"]),
        Sphere(top + (p["neck"] + p["head_r"] + 0.5 * p["torso_r"]) * neck_dir, p["head_r"]),
        Capsule(
            top - [0.5 * p["shoulder"], 0, 0.05],
            top + [0.5 * p["shoulder"], 0, -0.05],
            0.8 * p["arm_r"] + 0.02,
        ),
    ]
    for side, s in (("l", 1.0), ("r", -1.0)):
        shoulder = top + [s * 0.5 * p["shoulder"], 0.0, -0.05]
        parts += _limb(
            shoulder,
            s,
            a[f"{side}_abduct"],
            a[f"{side}_flex"],
            a[f"{side}_elbow"],
            p["upper_arm"],
            p["forearm"],
            p["arm_r"],
            bend_sign=1.0,
        )
        hip = np.array([s * 0.5 * p["hip"], 0.0, 0.0])
        parts += _limb(
            hip,
            s,
            a[f"{side}_hip_abduct"],
            a[f"{side}_hip_flex"],
            a[f"{side}_knee"],
            p["thigh"],
            p["shin"],
            p["leg_r"],
            bend_sign=-1.0,
        )
    g = Union(*parts)
    g.name = f"figure-s{subject}-p{pose}"
    return g


# -- machined parts --------------------------------------------------------------------
def _through_holes(
    centres: list[tuple[float, float]], radius: float, z0: float, z1: float
) -> list[Implicit]:
    return [Cylinder([x, y, z0 - 1.0], [x, y, z1 + 1.0], radius) for x, y in centres]


def _plate(rng: np.random.Generator) -> Implicit:
    L, W, T = rng.uniform(2.0, 3.0), rng.uniform(1.0, 1.6), rng.uniform(0.15, 0.3)
    body: Implicit = Box([0, 0, T / 2], [L, W, T])
    adds: list[Implicit] = []
    for _ in range(int(rng.integers(1, 3))):  # bosses on top
        x, y = rng.uniform(-0.3 * L, 0.3 * L), rng.uniform(-0.25 * W, 0.25 * W)
        adds.append(
            Cylinder([x, y, T - 0.01], [x, y, T + rng.uniform(0.15, 0.4)], rng.uniform(0.12, 0.22))
        )
    for k in range(int(rng.integers(0, 3))):  # ribs along x
        y = (k - 0.5) * 0.4 * W
        adds.append(Box([0, y, T + 0.1], [0.8 * L, 0.06, 0.2]))
    body = Union(body, *adds)
    r = rng.uniform(0.06, 0.12)
    corners = [(sx * (L / 2 - 0.2), sy * (W / 2 - 0.2)) for sx in (-1, 1) for sy in (-1, 1)]
    tools = _through_holes(corners[: int(rng.integers(2, 5))], r, 0.0, T)
    if rng.random() < 0.7:  # a through slot: a capsule swept through the plate
        y, half = rng.uniform(-0.2, 0.2) * W, rng.uniform(0.2, 0.4)
        tools.append(
            Union(
                Box([0, y, T / 2], [2 * half, 2 * r, T + 2.0]),
                *_through_holes([(-half, y), (half, y)], r, 0.0, T),
            )
        )
    return body - Union(*tools)


def _bracket(rng: np.random.Generator) -> Implicit:
    L, W, T = rng.uniform(1.2, 2.0), rng.uniform(0.8, 1.4), rng.uniform(0.12, 0.25)
    H = rng.uniform(0.8, 1.5)
    base = Box([L / 2, 0, T / 2], [L, W, T])
    wall = Box([T / 2, 0, H / 2], [T, W, H])
    parts: list[Implicit] = [base, wall]
    if rng.random() < 0.8:  # a triangular gusset: a rotated slab cut to the corner
        g = rng.uniform(0.3, 0.6) * min(L, H)
        slab = Box([0, 0, 0], [2 * g, 0.08, 2 * g]).rotate(_rot(np.array([0, 1.0, 0]), np.pi / 4))
        parts.append(slab.translate([T, 0, T]) & Box([T + g / 2, 0, T + g / 2], [g, 0.08, g]))
    r = rng.uniform(0.05, 0.1)
    holes = _through_holes([(0.65 * L, -W / 4), (0.65 * L, W / 4)], r, 0.0, T)
    rot = _rot(np.array([0, 1.0, 0]), np.pi / 2)  # wall holes along x
    holes += [
        h.rotate(rot, center=[0, 0, 0]).translate([0, 0, 0.65 * H])
        for h in _through_holes([(0.0, -W / 4), (0.0, W / 4)], r, -T, T)
    ]
    return Union(*parts) - Union(*holes)


def _flange(rng: np.random.Generator) -> Implicit:
    R, T = rng.uniform(0.8, 1.2), rng.uniform(0.12, 0.25)
    hub_r, hub_h = rng.uniform(0.3, 0.5) * R, rng.uniform(0.3, 0.7)
    body = Union(
        Cylinder([0, 0, 0], [0, 0, T], R), Cylinder([0, 0, T - 0.01], [0, 0, T + hub_h], hub_r)
    )
    bore = Cylinder([0, 0, -1.0], [0, 0, T + hub_h + 1.0], rng.uniform(0.4, 0.7) * hub_r)
    n = int(rng.integers(3, 9))
    pcd = 0.5 * (hub_r + R)
    phase = rng.uniform(0, 2 * np.pi / n)
    centres = [
        (pcd * np.cos(phase + 2 * np.pi * k / n), pcd * np.sin(phase + 2 * np.pi * k / n))
        for k in range(n)
    ]
    holes = _through_holes(centres, rng.uniform(0.05, 0.35) * (R - hub_r), 0.0, T)
    return body - Union(bore, *holes)


def part(kind: str, seed: int = 0) -> Implicit:
    """A machined part.

    Parameters
    ----------
    kind : {"plate", "bracket", "flange"}
        Class of part.
    seed : int
        Varies dimensions and feature counts deterministically.
    """
    builders = {"plate": _plate, "bracket": _bracket, "flange": _flange}
    if kind not in builders:
        raise ConfigError(f"unknown part kind {kind!r}; choose one of {list(builders)}")
    g = builders[kind](np.random.default_rng([23, PART_KINDS.index(kind), seed]))
    g.name = f"{kind}-{seed}"
    return g


def catalogue() -> list[tuple[str, str, Geometry]]:
    """The default demo set: 20 solids in 5 labelled classes.

    Returns
    -------
    list of (name, label, geometry)
        Figures of two subjects in four poses (labels ``figure-s0``, ``figure-s1``)
        and four each of plates, brackets and flanges (labels = kind).
    """
    out: list[tuple[str, str, Geometry]] = []
    for s in (0, 1):
        out += [(f"figure-s{s}-p{p}", f"figure-s{s}", figure(s, p)) for p in range(4)]
    for kind in PART_KINDS:
        out += [(f"{kind}-{k}", kind, part(kind, k)) for k in range(4)]
    return out


def to_mesh(geometry: Geometry, resolution: int = 128) -> trimesh.Trimesh:
    """Triangle mesh of ``geometry``'s boundary by marching cubes on its grid SDF.

    Parameters
    ----------
    geometry : Geometry
        Any solid.
    resolution : int
        Grid cells along the longest side of the bounding box.

    Returns
    -------
    trimesh.Trimesh
        Watertight where the solid is thicker than a cell; outward normals.
    """
    measure = require("skimage.measure", extra="examples", feature="examples.to_mesh")
    import trimesh

    grid = Grid.fit(geometry.bounds, resolution=resolution, padding=2)
    F = geometry.grid_sdf(grid)
    verts, faces, _, _ = measure.marching_cubes(F, level=0.0, spacing=(grid.spacing,) * 3)
    mesh = trimesh.Trimesh(verts + grid.origin, faces, process=True)
    if mesh.volume < 0:
        mesh.invert()
    return mesh
