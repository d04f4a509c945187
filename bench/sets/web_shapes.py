"""The ``web`` set: close families of kinds, built and oriented the way web models are.

A harder sibling of :mod:`bench.sets.generic_shapes`: 45 kinds in close families (seven
seats, five tables, three storage pieces, bed and stairs, two lamps, three vessels,
five buildings, four road and rail vehicles, four aircraft, three boats, two
quadrupeds, bird, fish, person, head, tree; builders in :mod:`bench.sets.web_furniture`,
:mod:`bench.sets.web_structures`, :mod:`bench.sets.web_organic`). Within a kind, proportions
vary by up to about 40 %, part counts and optional parts vary, and styles differ
(box or sheet boards, box, round or splayed legs).

As on the web, every model is a triangle soup of unmerged parts (closed boxes,
zero-thickness sheets, open tubes; parts interpenetrate), 30 % of the parts have their
faces flipped, and the orientation is not canonical: every model is turned by a random
angle about its up axis, and :data:`~bench.sets.assembly.TILTED` of them are turned
arbitrarily in 3-D. Sizes are random too (a factor in [0.5, 2]), and
:data:`~bench.sets.assembly.GROUNDED` of the models stand on a ground sheet or a display
base, as some web models do; :data:`~bench.sets.assembly.FURNISHED` of them keep hidden
parts inside their bulkiest part (interiors no view shows).

``web_mesh(kind, seed)`` is deterministic and cheap (milliseconds).
:func:`web_version` is a digest of the generator's code, for cache keys.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from bench.sets import web_furniture, web_organic, web_structures
from bench.sets.assembly import assemble, code_version
from bench.sets.mesh_parts import F, Part, Rng, V

__all__ = ["KINDS", "FAMILIES", "web_mesh", "web_version"]

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


def web_mesh(kind: str, seed: int) -> tuple[V, F]:
    """Vertices (v, 3) and faces (f, 3) of one model of the ``web`` set.

    Assembled by :func:`bench.sets.assembly.assemble` (seed stream
    ``"web/<kind>/<seed>"``); the same ``(kind, seed)`` always gives the same arrays
    (for a given :func:`web_version`).

    Raises
    ------
    ValueError
        For a kind not in :data:`KINDS`.
    """
    return assemble("web", _BUILDERS, kind, seed)


@functools.lru_cache(maxsize=1)
def web_version() -> str:
    """sha256 (8 hex) of the generator's code (docstrings and comments excluded)."""
    from bench.sets import web_shapes

    return code_version((web_furniture, web_structures, web_organic, web_shapes))
