"""Fine-grained people: subjects that differ like real people, and scans of them.

A *person* is one body plan (pelvis, tapered torso, neck, head, arms with hands, legs
with feet) blended with smooth joints (a polynomial smooth minimum of tapered
capsules). Subjects differ by a few percent, as real people do: an overall height
factor (0.94-1.06), an overall girth factor (0.90-1.10) and a per-segment factor
(0.96-1.04) on every length and radius, so that two subjects' limb lengths and
girths lie about 3-10 % apart. Poses are joint angles in the ranges of a standing
person moving (a registered-scan set: FAUST-like), the same pose index giving the
same angles for every subject.

Meshes: marching cubes on the implicit at :data:`MESH_RESOLUTION` cells, decimated
to about :data:`MESH_VERTICES` vertices (``fast-simplification``), like registered
scans of ~7k vertices. Scans of a mesh (:func:`noisy_cloud`, :func:`partial_cloud`)
start from the paper's cloud, a random 20 % of the vertices.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from shapedb.geometry.implicit import Implicit

__all__ = [
    "MESH_RESOLUTION",
    "MESH_VERTICES",
    "NOISE_SIGMA",
    "person",
    "person_mesh",
    "noisy_cloud",
    "partial_cloud",
]

#: Marching-cubes cells along the longest side before decimation.
MESH_RESOLUTION = 112
#: Vertices of a decimated person mesh (about; registered scans have ~6,900).
MESH_VERTICES = 7000
#: Noise of the noisy clouds, as a fraction of the mesh's bounding-box diagonal.
NOISE_SIGMA = 0.003
#: Blend width of the smooth joints, model units (a person is about 1.75 tall).
BLEND = 0.025

_BASE = {
    # lengths
    "torso": 0.42, "hip": 0.19, "shoulder": 0.36, "neck": 0.09, "upper_arm": 0.29,
    "forearm": 0.26, "hand": 0.09, "thigh": 0.43, "shin": 0.42, "foot": 0.13,
    # radii
    "pelvis_r": 0.105, "waist_r": 0.115, "chest_r": 0.14, "head_r": 0.095,
    "neck_r": 0.048, "arm_r": 0.046, "wrist_r": 0.027, "thigh_r": 0.082,
    "knee_r": 0.052, "ankle_r": 0.034,
}  # fmt: skip

_JOINTS = (
    "l_abduct", "r_abduct", "l_flex", "r_flex", "l_elbow", "r_elbow", "l_hip_abduct",
    "r_hip_abduct", "l_hip_flex", "r_hip_flex", "l_knee", "r_knee", "neck", "bend", "twist",
)  # fmt: skip
_RANGES = {
    "abduct": (0.12, 1.3), "flex": (-0.8, 1.1), "elbow": (0.0, 1.5),
    "hip_abduct": (0.0, 0.35), "hip_flex": (-0.5, 0.8), "knee": (0.0, 1.2),
    "neck": (-0.3, 0.3), "bend": (-0.25, 0.25), "twist": (-0.35, 0.35),
}  # fmt: skip


def proportions(subject: int) -> dict[str, float]:
    """Segment lengths and radii of a subject (model units, about 1.75 tall)."""
    rng = np.random.default_rng([31, subject])
    height, girth = rng.uniform(0.94, 1.06), rng.uniform(0.90, 1.10)
    return {
        k: v * (girth if k.endswith("_r") else height) * rng.uniform(0.96, 1.04)
        for k, v in _BASE.items()
    }


def angles(pose: int) -> dict[str, float]:
    """Joint angles (radians) of a pose; pose 0 is a relaxed A-pose."""
    if pose == 0:
        a = dict.fromkeys(_JOINTS, 0.0)
        a.update(l_abduct=0.3, r_abduct=0.3, l_hip_abduct=0.06, r_hip_abduct=0.06)
        return a
    rng = np.random.default_rng([37, pose])
    out = {}
    for n in _JOINTS:
        lo, hi = _RANGES[n.split("_", 1)[1] if n[:2] in ("l_", "r_") else n]
        out[n] = float(rng.uniform(lo, hi))
    return out


def _rot(axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    return Rotation.from_rotvec(angle * np.asarray(axis, dtype=np.float64)).as_matrix()


def _cone(
    p: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64], ra: float, rb: float
) -> NDArray[np.float64]:
    """Outside-positive distance (approximate) to a capsule tapering from ra at a to rb at b."""
    ab = b - a
    t = np.clip((p - a) @ ab / float(ab @ ab), 0.0, 1.0)
    return np.asarray(
        np.linalg.norm(p - a - t[:, None] * ab, axis=1) - (ra + t * (rb - ra)), dtype=np.float64
    )


def _segments(subject: int, pose: int) -> list[tuple[NDArray[np.float64], ...]]:
    """The body's tapered capsules as (a, b, [ra, rb]) triples of arrays."""
    p, q = proportions(subject), angles(pose)
    up = np.array([0.0, 0.0, 1.0])
    trunk = _rot(np.array([0.0, 0, 1]), q["twist"]) @ _rot(np.array([1.0, 0, 0]), q["bend"])
    top = trunk @ (p["torso"] * up)
    segs: list[tuple[NDArray[np.float64], ...]] = []

    def add(a: NDArray[np.float64], b: NDArray[np.float64], ra: float, rb: float) -> None:
        segs.append((a, b, np.array([ra, rb])))

    add(np.array([-0.5 * p["hip"], 0, 0]), np.array([0.5 * p["hip"], 0, 0]),
        p["pelvis_r"], p["pelvis_r"])  # fmt: skip
    add(np.zeros(3), 0.55 * top, p["waist_r"], p["chest_r"])
    add(0.55 * top, top, p["chest_r"], 0.85 * p["chest_r"])
    neck_dir = trunk @ _rot(np.array([1.0, 0, 0]), q["neck"]) @ up
    neck_top = top + p["neck"] * neck_dir
    add(top, neck_top, p["neck_r"], p["neck_r"])
    head = neck_top + 0.9 * p["head_r"] * neck_dir
    add(head, head + 0.35 * p["head_r"] * neck_dir, p["head_r"], 0.9 * p["head_r"])
    for side, s in (("l", 1.0), ("r", -1.0)):
        shoulder = top + trunk @ np.array([s * 0.5 * p["shoulder"], 0.0, -0.04])
        add(top - 0.03 * up, shoulder, 0.8 * p["chest_r"], p["arm_r"])
        limb = trunk @ _rot(np.array([1.0, 0, 0]), q[f"{side}_flex"])
        limb = limb @ _rot(np.array([0, 1.0, 0]), -s * q[f"{side}_abduct"])
        d1 = limb @ -up
        elbow = shoulder + p["upper_arm"] * d1
        add(shoulder, elbow, p["arm_r"], 0.8 * p["arm_r"])
        d2 = _rot(limb @ np.array([1.0, 0, 0]), q[f"{side}_elbow"]) @ d1
        wrist = elbow + p["forearm"] * d2
        add(elbow, wrist, 0.8 * p["arm_r"], p["wrist_r"])
        add(wrist, wrist + p["hand"] * d2, p["wrist_r"], 0.9 * p["wrist_r"])
        hip = np.array([s * 0.5 * p["hip"], 0.0, 0.0])
        leg = _rot(np.array([1.0, 0, 0]), q[f"{side}_hip_flex"])
        leg = leg @ _rot(np.array([0, 1.0, 0]), -s * q[f"{side}_hip_abduct"])
        d1 = leg @ -up
        knee = hip + p["thigh"] * d1
        add(hip, knee, p["thigh_r"], p["knee_r"])
        d2 = _rot(leg @ np.array([1.0, 0, 0]), -q[f"{side}_knee"]) @ d1
        ankle = knee + p["shin"] * d2
        add(knee, ankle, p["knee_r"], p["ankle_r"])
        fwd = _rot(leg @ np.array([1.0, 0, 0]), -q[f"{side}_knee"]) @ (leg @ np.array([0, 1.0, 0]))
        add(ankle, ankle + p["foot"] * (0.9 * fwd + 0.1 * d2), p["ankle_r"], 0.8 * p["ankle_r"])
    return segs


def person(subject: int = 0, pose: int = 0) -> Implicit:
    """A person: tapered capsules joined by a smooth minimum of width :data:`BLEND`.

    Parameters
    ----------
    subject : int >= 0
        Body proportions (:func:`proportions`).
    pose : int >= 0
        Joint angles (:func:`angles`); the same index poses every subject alike.

    Returns
    -------
    Implicit
        About 1.75 model units tall, pelvis at the origin, z up. Its distance is a
        lower bound inside (a smooth union of approximate cone distances), enough for
        meshing.
    """
    if subject < 0 or pose < 0:
        raise ValueError(f"subject and pose must be >= 0, got subject={subject}, pose={pose}")
    segs = _segments(subject, pose)
    k = BLEND

    def sdf(points: NDArray[np.float64]) -> NDArray[np.float64]:
        d = np.full(len(points), np.inf)
        for a, b, r in segs:
            e = _cone(points, a, b, float(r[0]), float(r[1]))
            h = np.clip(k - np.abs(d - e), 0.0, None) / k
            d = np.minimum(d, e) - 0.25 * k * h * h
        return -d

    pts = np.concatenate([np.stack([a, b]) for a, b, _ in segs])
    rmax = max(float(r.max()) for _, _, r in segs)
    bounds = np.stack([pts.min(0) - rmax - k, pts.max(0) + rmax + k])
    return Implicit(sdf, bounds, name=f"person-s{subject}-p{pose}")


def person_mesh(subject: int, pose: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices (v, 3) and faces (f, 3) of a person, about :data:`MESH_VERTICES` vertices."""
    import fast_simplification

    from shapedb.examples import to_mesh

    mesh = to_mesh(person(subject, pose), resolution=MESH_RESOLUTION)
    v = np.asarray(mesh.vertices, dtype=np.float32)
    f = np.asarray(mesh.faces, dtype=np.int32)
    if len(v) > MESH_VERTICES:
        v, f = fast_simplification.simplify(v, f, target_count=2 * MESH_VERTICES - 4)
    return np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)


def noisy_cloud(
    points: NDArray[np.float64], vertices: NDArray[np.float64], *, seed: int
) -> NDArray[np.float64]:
    """``points`` (k, 3) with Gaussian noise of :data:`NOISE_SIGMA` x the mesh's diagonal."""
    diag = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
    rng = np.random.default_rng(seed)
    return np.asarray(points + rng.normal(scale=NOISE_SIGMA * diag, size=points.shape))


def partial_cloud(
    points: NDArray[np.float64],
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    seed: int,
    tolerance: float = 1e-3,
) -> NDArray[np.float64]:
    """What one depth camera sees of a cloud: the points of ``points`` not hidden.

    The camera looks horizontally (perpendicular to z) from a seeded direction, as an
    orthographic view: a point is kept when the ray from the camera towards it first
    meets the mesh within ``tolerance`` x the bounding-box diagonal of the point
    (open3d's ray casting). Face orientation is not used, so triangle soups work too.

    Parameters
    ----------
    points : (k, 3) float
        The full cloud (e.g. the paper's 20 % of the vertices), on the mesh.
    vertices, faces : (v, 3) float, (f, 3) int
        The mesh the cloud was taken from.
    seed : int
        Seeds the camera direction.

    Returns
    -------
    (j, 3) float64
        The visible points, j <= k (under half of them for a closed surface); the
        first point alone if none is visible.
    """
    import open3d as o3d

    rng = np.random.default_rng(seed)
    theta = rng.uniform(0, 2 * np.pi)
    view = np.array([np.cos(theta), np.sin(theta), 0.0])  # from the camera into the scene
    v = np.asarray(vertices, dtype=np.float64)
    diag = float(np.linalg.norm(v.max(0) - v.min(0)))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(v.astype(np.float32)),
        o3d.core.Tensor(np.asarray(faces).astype(np.uint32)),
    )
    p = np.asarray(points, dtype=np.float64)
    back = 2.0 * diag  # the camera plane, behind every point
    rays = np.concatenate([p - back * view, np.tile(view, (len(p), 1))], axis=1)
    hit = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))["t_hit"].numpy()
    keep = hit >= back - tolerance * diag
    return p[keep] if keep.any() else p[:1]
