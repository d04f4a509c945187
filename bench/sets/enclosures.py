"""The ``enclosures`` set: thin-walled, enclosing man-made kinds, built as web and CAD models are.

Twelve kinds (builders in :mod:`bench.sets.enclosure_shapes`): house, rail car, desk,
bookcase, sink, housing, wheel, dish, book, bracket, tent and boat, in close pairs
(:data:`FAMILIES`). Within a kind, proportions vary by up to about 40 %, part counts
(windows, drawers, shelves, spokes, holes) and optional parts vary, and styles differ
(round or square basins, ridge, dome or bell tents, L, U, Z or hat brackets, sheets or
thin boards).

The models are what web and CAD exporters write, not clean solids: walls are single
zero-thickness sheets with doors, windows and vents as gaps, boxes are open, parts
interpenetrate and are not merged. Every model's winding is the builder's own and
inconsistent: a model has :data:`FLIPPED` of its parts turned inside out or, for
:data:`FACE_FLIPS` of the models, :data:`FLIPPED` of its faces one by one;
:data:`DUPLICATED` of the models repeat some faces (a coplanar copy, on its own
vertices, wound either way) and :data:`STRAYS` carry vertices no face uses. Every model
is turned by a random yaw about its up axis; :data:`Y_UP` of them have the builder's
up axis along +y instead of +z. Sizes are in the builder's units (a house in metres, a
bracket a few centimetres) times a factor in :data:`SCALE` (log-uniform); models stand
where the builder put them (on z = 0 before the turn), not centred.

``enclosure_mesh(kind, seed)`` is deterministic and cheap (milliseconds);
:func:`enclosure_version` is a digest of the generator's code, for cache keys.
"""

from __future__ import annotations

import functools
import zlib

import numpy as np

from bench.sets import enclosure_shapes
from bench.sets.assembly import code_version
from bench.sets.enclosure_shapes import BUILDERS, join
from bench.sets.mesh_parts import F, V, rotation

__all__ = [
    "KINDS", "FAMILIES", "FLIPPED", "FACE_FLIPS", "DUPLICATED", "STRAYS", "Y_UP", "SCALE",
    "enclosure_mesh", "enclosure_version",
]  # fmt: skip

#: The kinds, in a fixed order.
KINDS: tuple[str, ...] = tuple(BUILDERS)

#: Pairs of close kinds (each kind is in exactly one).
FAMILIES: dict[str, tuple[str, ...]] = {
    "pierced shell": ("house", "rail_car"),
    "boards": ("desk", "bookcase"),
    "open box": ("sink", "housing"),
    "round": ("wheel", "dish"),
    "bent sheet": ("book", "bracket"),
    "single-sided shell": ("tent", "boat"),
}

#: Fraction of the parts (or, in a face-flipping model, of the faces) turned inside out.
FLIPPED = 0.3
#: Fraction of the models whose faces are flipped one by one rather than by part.
FACE_FLIPS = 0.5
#: Fraction of the models that repeat some of their faces (coplanar copies).
DUPLICATED = 0.25
#: Fraction of the models carrying vertices that no face uses.
STRAYS = 0.25
#: Fraction of the models built with +y up (the rest +z).
Y_UP = 0.5
#: Range of the random scale factor (log-uniform: a factor 10 end to end).
SCALE = (0.3, 3.0)


def enclosure_mesh(kind: str, seed: int) -> tuple[V, F]:
    """Vertices (v, 3) and faces (f, 3) of one model of the ``enclosures`` set.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
        Model number; the same ``(kind, seed)`` always gives the same arrays (for a
        given :func:`enclosure_version`), from the seed stream ``"enclosures/<kind>/<seed>"``.

    Returns
    -------
    vertices : (v, 3) float64
        Positions in the builder's units times a random scale; some may be unreferenced.
    faces : (f, 3) int64
        Triangles of unmerged parts, inconsistently wound, some repeated.

    Raises
    ------
    ValueError
        For a kind not in :data:`KINDS`.
    """
    if kind not in BUILDERS:
        raise ValueError(f"unknown enclosures kind {kind!r}: choose from {KINDS}")
    rng = np.random.default_rng(zlib.crc32(f"enclosures/{kind}/{seed}".encode()))
    parts = BUILDERS[kind](rng)
    by_face = rng.random() < FACE_FLIPS
    if not by_face:
        parts = [(v, f[:, ::-1] if rng.random() < FLIPPED else f) for v, f in parts]
    v, f = join(parts)
    if by_face:
        flip = rng.random(len(f)) < FLIPPED
        f[flip] = f[flip][:, ::-1]
    if rng.random() < DUPLICATED:
        copied = f[rng.random(len(f)) < rng.uniform(0.02, 0.2)]
        if rng.random() < 0.5:
            copied = copied[:, ::-1]
        f = np.vstack([f, len(v) + np.arange(copied.size).reshape(-1, 3)])
        v = np.vstack([v, v[copied.ravel()]])
    if rng.random() < STRAYS:
        lo, hi = v.min(axis=0), v.max(axis=0)
        v = np.vstack([v, rng.uniform(lo, hi, (int(rng.integers(1, 30)), 3))])
    turn = rotation(2, rng.uniform(0, 2 * np.pi))
    if rng.random() < Y_UP:
        turn = rotation(0, -np.pi / 2) @ turn  # z up becomes y up
    scale = float(np.exp(rng.uniform(*np.log(SCALE))))
    return scale * (v @ turn.T), f


@functools.lru_cache(maxsize=1)
def enclosure_version() -> str:
    """sha256 (8 hex) of the generator's code (docstrings and comments excluded)."""
    from bench.sets import enclosures, web_furniture, web_structures, webplus_made

    return code_version((web_furniture, web_structures, webplus_made, enclosure_shapes, enclosures))
