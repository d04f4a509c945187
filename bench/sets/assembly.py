"""How the web-like sets (``web``, ``webplus``) turn a kind's parts into one model.

Both sets build a kind's parts with their own builders, then assemble them the way
web models are: optional hidden interiors inside the bulkiest part (:data:`FURNISHED`),
an optional ground sheet or display base (:data:`GROUNDED`), every part a separate
triangle soup with :data:`FLIPPED` of them turned inside out, the whole model centred,
turned by a random yaw (:data:`TILTED` of them by an arbitrary 3-D rotation) and scaled
by a factor in [0.5, 2]. :func:`assemble` does this from a seeded generator, so the
same set, kind and seed always give the same arrays; :func:`code_version` digests the
generators' code for cache keys.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Mapping, Sequence
from types import ModuleType

import numpy as np

from bench.sets.mesh_parts import F, Part, Rng, V, box, hquad

__all__ = ["TILTED", "FLIPPED", "GROUNDED", "FURNISHED", "assemble", "code_version"]

#: Fraction of the models turned by an arbitrary 3-D rotation (the rest only about z).
TILTED = 0.2
#: Fraction of the parts whose faces are flipped.
FLIPPED = 0.3
#: Fraction of the models that stand on a ground sheet or a display base.
GROUNDED = 0.15
#: Fraction of the models with hidden parts inside their bulkiest part (interiors).
FURNISHED = 0.4


def random_rotation(rng: Rng) -> np.ndarray:
    """A uniformly random (3, 3) rotation."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def ground(rng: Rng, v: V) -> Part:
    """A ground sheet, or a display base (a flat box), under the points ``v`` (k, 3)."""
    lo, hi = v.min(axis=0), v.max(axis=0)
    c, size = 0.5 * (lo + hi), hi - lo
    grow = rng.uniform(1.1, 2.5)
    if rng.random() < 0.5:
        return hquad((c[0], c[1], lo[2]), grow * size[0], grow * size[1])
    t = 0.05 * float(size.max())
    return box((c[0], c[1], lo[2] - t / 2), (grow * size[0], grow * size[1], t))


def interior(rng: Rng, parts: list[Part]) -> list[Part]:
    """1-5 boxes and floor sheets hidden inside the part of largest bounding box.

    They stay within 0.55 of its half-extents about its centre, so inside a box or an
    ellipsoid they are out of sight from every side (web models keep interiors, engines,
    inner walls and floors that no view shows).
    """
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


def assemble(
    set_name: str, builders: Mapping[str, Callable[[Rng], list[Part]]], kind: str, seed: int
) -> tuple[V, F]:
    """Vertices (v, 3) and faces (f, 3) of one model of a web-like set.

    Parameters
    ----------
    set_name : str
        The set (``"web"``, ``"webplus"``): the seed stream is ``"<set_name>/<kind>/<seed>"``.
    builders : mapping of str to callable
        The set's kinds and their part builders (a seeded generator in, parts out).
    kind : str
        One of ``builders``.
    seed : int
        Model number; the same ``(set_name, kind, seed)`` always gives the same arrays.

    Returns
    -------
    vertices : (v, 3) float64
        Positions, centred near the origin, in arbitrary units.
    faces : (f, 3) int64
        Triangles of unmerged parts; orientation inconsistent.

    Raises
    ------
    ValueError
        For a kind not in ``builders``.
    """
    if kind not in builders:
        raise ValueError(f"unknown {set_name} kind {kind!r}: choose from {tuple(builders)}")
    rng = np.random.default_rng(zlib.crc32(f"{set_name}/{kind}/{seed}".encode()))
    parts = builders[kind](rng)
    if rng.random() < FURNISHED:
        parts += interior(rng, parts)
    if rng.random() < GROUNDED:
        parts.append(ground(rng, np.concatenate([v for v, _ in parts])))
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
        rot = random_rotation(rng)
    scale = float(np.exp(rng.uniform(np.log(0.5), np.log(2.0))))
    return scale * (v @ rot.T), np.concatenate(fs)


def code_version(modules: Sequence[ModuleType]) -> str:
    """sha256 (8 hex) of the modules' code (docstrings and comments excluded)."""
    import ast
    import hashlib
    import inspect

    from bench.sets import assembly, mesh_parts

    digest = hashlib.sha256()
    for module in (mesh_parts, assembly, *modules):
        tree = ast.parse(inspect.getsource(module))
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                    and isinstance(getattr(body[0], "value", None), ast.Constant)):  # fmt: skip
                body[0] = ast.Pass()
        digest.update(ast.dump(tree).encode())
    return digest.hexdigest()[:8]
