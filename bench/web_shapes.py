"""The ``web`` set: close families of kinds, built and oriented the way web models are.

A harder sibling of :mod:`bench.generic_shapes`: 45 kinds in close families (seven
seats, five tables, three storage pieces, bed and stairs, two lamps, three vessels,
five buildings, four road and rail vehicles, four aircraft, three boats, two
quadrupeds, bird, fish, person, head, tree; builders in :mod:`bench.web_furniture`,
:mod:`bench.web_structures`, :mod:`bench.web_organic`). Within a kind, proportions
vary by up to about 40 %, part counts and optional parts vary, and styles differ
(box or sheet boards, box, round or splayed legs).

As on the web, every model is a triangle soup of unmerged parts (closed boxes,
zero-thickness sheets, open tubes; parts interpenetrate), 30 % of the parts have their
faces flipped, and the orientation is not canonical: every model is turned by a
random angle about its up axis, and :data:`TILTED` of them are turned arbitrarily in
3-D. Sizes are random too (a factor in [0.5, 2]), and :data:`GROUNDED` of the models
stand on a ground sheet or a display base, as some web models do; :data:`FURNISHED`
of them keep hidden parts inside their bulkiest part (interiors no view shows).

``web_mesh(kind, seed)`` is deterministic and cheap (milliseconds).
:func:`web_version` is a digest of the generator's code, for cache keys.
"""

from __future__ import annotations

import functools
import zlib
from collections.abc import Callable

import numpy as np

from bench import web_furniture, web_organic, web_structures
from bench.mesh_parts import F, Part, Rng, V

__all__ = [
    "KINDS",
    "FAMILIES",
    "TILTED",
    "FLIPPED",
    "GROUNDED",
    "FURNISHED",
    "web_mesh",
    "web_version",
]

_BUILDERS: dict[str, Callable[[Rng], list[Part]]] = {
    **web_furniture.BUILDERS,
    **web_structures.BUILDERS,
    **web_organic.BUILDERS,
}
#: The kinds, in a fixed order.
KINDS: tuple[str, ...] = tuple(_BUILDERS)

#: Families of close kinds (each kind is in exactly one).
FAMILIES: dict[str, tuple[str, ...]] = {
    "seat": ("dining_chair", "armchair", "office_chair", "stool", "bar_stool", "bench", "sofa"),
    "table": ("table", "round_table", "coffee_table", "desk", "school_desk"),
    "storage": ("bookshelf", "cabinet", "wardrobe"),
    "room": ("bed", "staircase"),
    "lamp": ("floor_lamp", "desk_lamp"),
    "vessel": ("bottle", "vase", "mug"),
    "building": ("house", "two_story_home", "skyscraper", "church", "tower"),
    "vehicle": ("car", "truck", "bus", "train_car"),
    "aircraft": ("airplane", "biplane", "helicopter", "glider"),
    "boat": ("ship", "sailboat", "submarine"),
    "creature": ("dog", "horse", "bird", "fish", "human", "head", "tree"),
}

#: Fraction of the models turned by an arbitrary 3-D rotation (the rest only about z).
TILTED = 0.2
#: Fraction of the parts whose faces are flipped.
FLIPPED = 0.3
#: Fraction of the models that stand on a ground sheet or a display base.
GROUNDED = 0.15
#: Fraction of the models with hidden parts inside their bulkiest part (interiors).
FURNISHED = 0.4


def _random_rotation(rng: Rng) -> np.ndarray:
    """A uniformly random (3, 3) rotation."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _ground(rng: Rng, v: V) -> Part:
    """A ground sheet, or a display base (a flat box), under the points ``v`` (k, 3)."""
    from bench.mesh_parts import box, hquad

    lo, hi = v.min(axis=0), v.max(axis=0)
    c, size = 0.5 * (lo + hi), hi - lo
    grow = rng.uniform(1.1, 2.5)
    if rng.random() < 0.5:
        return hquad((c[0], c[1], lo[2]), grow * size[0], grow * size[1])
    t = 0.05 * float(size.max())
    return box((c[0], c[1], lo[2] - t / 2), (grow * size[0], grow * size[1], t))


def _interior(rng: Rng, parts: list[Part]) -> list[Part]:
    """1-5 boxes and floor sheets hidden inside the part of largest bounding box.

    They stay within 0.55 of its half-extents about its centre, so inside a box or an
    ellipsoid they are out of sight from every side (web models keep interiors, engines,
    inner walls and floors that no view shows).
    """
    from bench.mesh_parts import box, hquad

    ext = [np.ptp(v, axis=0) for v, _ in parts]
    volume = [float(np.prod(e)) for e in ext]
    k = int(np.argmax(volume))
    if not volume[k] > 0:  # only sheets: nothing is hidden inside a sheet
        return []
    v = parts[k][0]
    c, half = 0.5 * (v.min(axis=0) + v.max(axis=0)), 0.55 * 0.5 * ext[k]
    out: list[Part] = []
    for _ in range(int(rng.integers(1, 6))):
        size = half * rng.uniform(0.2, 1.0, 3)
        at = c + (half - size) * rng.uniform(-1, 1, 3)
        if rng.random() < 0.5:
            out.append(box(at, 2 * size))
        else:
            out.append(hquad((at[0], at[1], at[2]), 2 * size[0], 2 * size[1]))
    return out


def web_mesh(kind: str, seed: int) -> tuple[V, F]:
    """Vertices (v, 3) and faces (f, 3) of one model of the ``web`` set.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
        Model number; the same ``(kind, seed)`` always gives the same arrays (for a
        given :func:`web_version`).

    Returns
    -------
    vertices : (v, 3) float64
        Positions, centred near the origin, in arbitrary units.
    faces : (f, 3) int64
        Triangles of unmerged parts; orientation inconsistent.

    Raises
    ------
    ValueError
        For an unknown kind.
    """
    if kind not in _BUILDERS:
        raise ValueError(f"unknown web kind {kind!r}: choose from {KINDS}")
    rng = np.random.default_rng(zlib.crc32(f"web/{kind}/{seed}".encode()))
    parts = _BUILDERS[kind](rng)
    if rng.random() < FURNISHED:
        parts += _interior(rng, parts)
    if rng.random() < GROUNDED:
        parts.append(_ground(rng, np.concatenate([v for v, _ in parts])))
    vs, fs, at = [], [], 0
    for v, f in parts:
        f = np.asarray(f, dtype=np.int64)
        if rng.random() < FLIPPED:
            f = f[:, ::-1]
        vs.append(np.asarray(v, dtype=np.float64))
        fs.append(f + at)
        at += len(v)
    v = np.concatenate(vs)
    v = v - 0.5 * (v.min(axis=0) + v.max(axis=0))
    a = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    if rng.random() < TILTED:
        rot = _random_rotation(rng)
    scale = float(np.exp(rng.uniform(np.log(0.5), np.log(2.0))))
    return scale * (v @ rot.T), np.concatenate(fs)


@functools.lru_cache(maxsize=1)
def web_version() -> str:
    """sha256 (8 hex) of the generator's code (docstrings and comments excluded)."""
    import ast
    import hashlib
    import inspect

    from bench import mesh_parts, web_shapes

    digest = hashlib.sha256()
    for module in (mesh_parts, web_furniture, web_structures, web_organic, web_shapes):
        tree = ast.parse(inspect.getsource(module))
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                    and isinstance(getattr(body[0], "value", None), ast.Constant)):  # fmt: skip
                body[0] = ast.Pass()
        digest.update(ast.dump(tree).encode())
    return digest.hexdigest()[:8]
