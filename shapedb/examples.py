"""Generated example solids: jointed figures and machined parts, as implicit CSG.

Everything is deterministic: a figure is fixed by ``(subject, pose)`` and a part by
``(kind, seed)``. Figures mimic an articulated-retrieval benchmark (SHREC'14 style):
each subject has its own limb proportions and can take any pose; the same pose
index gives the same joint angles for every subject. Parts come in the twelve
families of :data:`PART_KINDS` (plates, brackets, flanges, shafts, pipe tees,
I-beams, gear discs, hex nuts, hinges, ribbed plates, boss plates, handles; built in
:mod:`shapedb._parts`), each with seeded proportions and feature counts.

>>> from shapedb import examples
>>> g = examples.figure(subject=1, pose=3)
>>> mesh = examples.to_mesh(g, resolution=96)      # needs scikit-image
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from shapedb._parts import BUILDERS
from shapedb._parts import rotation as _rotation
from shapedb.errors import ConfigError, require
from shapedb.geometry.base import Geometry, Grid
from shapedb.geometry.implicit import Capsule, Implicit, Sphere, Union

if TYPE_CHECKING:
    import trimesh

__all__ = ["figure", "part", "catalogue", "to_mesh", "PART_KINDS"]

logger = logging.getLogger(__name__)

#: Every machined-part kind :func:`part` builds; new kinds are appended so that the
#: seeds (and shapes) of the earlier kinds stay the same.
PART_KINDS: tuple[str, ...] = tuple(BUILDERS)
#: The kinds in :func:`catalogue` (the demo set keeps its 20 solids in 5 classes).
_CATALOGUE_KINDS = ("plate", "bracket", "flange")


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
    R = _rotation(np.array([1.0, 0, 0]), flex) @ _rotation(np.array([0, 1.0, 0]), -side * abduct)
    d1 = R @ down
    joint = root + l1 * d1
    side_axis = R @ np.array([1.0, 0, 0])
    d2 = _rotation(side_axis, bend_sign * bend) @ d1
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
    neck_dir = _rotation(np.array([1.0, 0, 0]), a["neck"]) @ np.array([0.0, 0, 1])
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
def part(kind: str, seed: int = 0) -> Implicit:
    """A machined part.

    Parameters
    ----------
    kind : str
        Class of part, one of :data:`PART_KINDS`: ``plate`` (holes, slot, bosses,
        ribs), ``bracket`` (L-bracket with gusset), ``flange`` (hub, bore, bolt
        circle), ``shaft`` (stepped, keyway), ``pipe_tee`` (hollow tee),
        ``i_beam`` (segment, web holes), ``gear_disc`` (teeth, bore, keyway),
        ``hex_nut`` (hex prism, bore), ``hinge`` (two leaves on a knuckle),
        ``rib_plate`` (parallel ribs), ``boss_plate`` (drilled bosses) and
        ``handle`` (U of capsules on feet).
    seed : int
        Varies dimensions and feature counts deterministically.

    Raises
    ------
    ConfigError
        (a ``ValueError``) for an unknown ``kind``; the message lists the valid ones.
    """
    if kind not in BUILDERS:
        raise ConfigError(f"unknown part kind {kind!r}; choose one of {list(PART_KINDS)}")
    g = BUILDERS[kind](np.random.default_rng([23, PART_KINDS.index(kind), seed]))
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
    for kind in _CATALOGUE_KINDS:
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
