"""The ``webplus`` set: a held-out web-like set of kinds that ``web`` and ``generic`` lack.

A check for settings tuned on the other sets' validation splits: 39 kinds that no other
generated set has, none of them sharing a builder with ``web`` or ``generic``
(builders in :mod:`bench.webplus_made`, :mod:`bench.webplus_structures` and
:mod:`bench.webplus_natural`), in close families (three seats, three lamps, a rack, a
fence and a gate, four bridges, six towers, three aircraft and two boats) and
category-level natural classes in many poses (four bipeds: dinosaur, kangaroo, ape,
ostrich; three quadrupeds: elephant, rhinoceros, giraffe; spider, insect, snake,
penguin, whale; three plants).

Built and oriented as :mod:`bench.web_shapes` builds the ``web`` set, with the same
fractions: every model is a triangle soup of unmerged parts (closed boxes,
zero-thickness sheets, open tubes; parts interpenetrate), :data:`FLIPPED` of the parts
have their faces flipped, every model is turned by a random yaw and :data:`TILTED` of
them by an arbitrary 3-D rotation, scaled by a factor in [0.5, 2]; :data:`GROUNDED`
stand on a ground sheet or display base and :data:`FURNISHED` keep hidden parts inside
their bulkiest part. The seeds are the set's own (``"webplus/<kind>/<seed>"``).

``webplus_mesh(kind, seed)`` is deterministic and cheap (milliseconds);
:func:`webplus_version` is a digest of the generator's code, for cache keys.
"""

from __future__ import annotations

import functools
import zlib
from collections.abc import Callable

import numpy as np

from bench import webplus_made, webplus_natural, webplus_structures
from bench.mesh_parts import F, Part, Rng, V, box, hquad

__all__ = [
    "KINDS",
    "FAMILIES",
    "TILTED",
    "FLIPPED",
    "GROUNDED",
    "FURNISHED",
    "webplus_mesh",
    "webplus_version",
]

_BUILDERS: dict[str, Callable[[Rng], list[Part]]] = {
    **webplus_made.BUILDERS,
    **webplus_structures.BUILDERS,
    **webplus_natural.BUILDERS,
}
#: The kinds, in a fixed order.
KINDS: tuple[str, ...] = tuple(_BUILDERS)

#: Families of close kinds (each kind is in exactly one).
FAMILIES: dict[str, tuple[str, ...]] = {
    "seat": ("rocking_chair", "folding_chair", "lounge_chair"),
    "lamp": ("chandelier", "pendant_lamp", "street_lamp"),
    "rack": ("shoe_rack", "fence", "gate"),
    "bridge": ("arch_bridge", "suspension_bridge", "truss_bridge", "beam_bridge"),
    "tower": ("lighthouse", "water_tower", "silo", "pylon", "radio_mast", "wind_turbine"),
    "craft": ("fighter_jet", "airship", "quadcopter", "rowboat", "catamaran"),
    "biped": ("dinosaur", "kangaroo", "ape", "ostrich"),
    "quadruped": ("elephant", "rhinoceros", "giraffe"),
    "small": ("spider", "insect", "snake"),
    "swimmer": ("penguin", "whale"),
    "plant": ("palm_tree", "cactus", "potted_plant"),
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
    lo, hi = v.min(axis=0), v.max(axis=0)
    c, size = 0.5 * (lo + hi), hi - lo
    grow = rng.uniform(1.1, 2.5)
    if rng.random() < 0.5:
        return hquad((c[0], c[1], lo[2]), grow * size[0], grow * size[1])
    t = 0.05 * float(size.max())
    return box((c[0], c[1], lo[2] - t / 2), (grow * size[0], grow * size[1], t))


def _interior(rng: Rng, parts: list[Part]) -> list[Part]:
    """1-5 boxes and floor sheets inside the part of largest bounding box (hidden interiors)."""
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


def webplus_mesh(kind: str, seed: int) -> tuple[V, F]:
    """Vertices (v, 3) and faces (f, 3) of one model of the ``webplus`` set.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
        Model number; the same ``(kind, seed)`` always gives the same arrays (for a
        given :func:`webplus_version`).

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
        raise ValueError(f"unknown webplus kind {kind!r}: choose from {KINDS}")
    rng = np.random.default_rng(zlib.crc32(f"webplus/{kind}/{seed}".encode()))
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
def webplus_version() -> str:
    """sha256 (8 hex) of the generator's code (docstrings and comments excluded)."""
    import ast
    import hashlib
    import inspect

    from bench import mesh_parts, web_furniture, webplus_shapes

    digest = hashlib.sha256()
    modules = (mesh_parts, web_furniture, webplus_made, webplus_structures, webplus_natural,
               webplus_shapes)  # fmt: skip
    for module in modules:
        tree = ast.parse(inspect.getsource(module))
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                    and isinstance(getattr(body[0], "value", None), ast.Constant)):  # fmt: skip
                body[0] = ast.Pass()
        digest.update(ast.dump(tree).encode())
    return digest.hexdigest()[:8]
