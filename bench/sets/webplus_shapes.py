"""The ``webplus`` set: a held-out web-like set of kinds that ``web`` and ``generic`` lack.

A check for settings tuned on the other sets' validation splits: 39 kinds that no other
generated set has, none of them sharing a builder with ``web`` or ``generic``
(builders in :mod:`bench.sets.webplus_made`, :mod:`bench.sets.webplus_structures` and
:mod:`bench.sets.webplus_natural`), in close families (three seats, three lamps, a rack, a
fence and a gate, four bridges, six towers, three aircraft and two boats) and
category-level natural classes in many poses (four bipeds: dinosaur, kangaroo, ape,
ostrich; three quadrupeds: elephant, rhinoceros, giraffe; spider, insect, snake,
penguin, whale; three plants).

Assembled by :mod:`bench.sets.assembly` as the ``web`` set is, with the same fractions:
every model is a triangle soup of unmerged parts (closed boxes, zero-thickness sheets,
open tubes; parts interpenetrate), :data:`~bench.sets.assembly.FLIPPED` of the parts
have their faces flipped, every model is turned by a random yaw and
:data:`~bench.sets.assembly.TILTED` of them by an arbitrary 3-D rotation, scaled by a
factor in [0.5, 2]; :data:`~bench.sets.assembly.GROUNDED` stand on a ground sheet or
display base and :data:`~bench.sets.assembly.FURNISHED` keep hidden parts inside their
bulkiest part. The seeds are the set's own (``"webplus/<kind>/<seed>"``).

``webplus_mesh(kind, seed)`` is deterministic and cheap (milliseconds);
:func:`webplus_version` is a digest of the generator's code, for cache keys.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from bench.sets import web_furniture, webplus_made, webplus_natural, webplus_structures
from bench.sets.assembly import assemble, code_version
from bench.sets.mesh_parts import F, Part, Rng, V

__all__ = ["KINDS", "FAMILIES", "webplus_mesh", "webplus_version"]

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


def webplus_mesh(kind: str, seed: int) -> tuple[V, F]:
    """Vertices (v, 3) and faces (f, 3) of one model of the ``webplus`` set.

    Assembled by :func:`bench.sets.assembly.assemble` (seed stream
    ``"webplus/<kind>/<seed>"``); the same ``(kind, seed)`` always gives the same arrays
    (for a given :func:`webplus_version`).

    Raises
    ------
    ValueError
        For a kind not in :data:`KINDS`.
    """
    return assemble("webplus", _BUILDERS, kind, seed)


@functools.lru_cache(maxsize=1)
def webplus_version() -> str:
    """sha256 (8 hex) of the generator's code (docstrings and comments excluded)."""
    from bench.sets import webplus_shapes

    return code_version(
        (web_furniture, webplus_made, webplus_structures, webplus_natural, webplus_shapes)
    )
