"""Cached decompositions of the bench's sets, read without decomposing anything.

:func:`load` gives a split's models and their balls from ``SHAPEDB_BENCH_CACHE`` (today's
engine, else the older engines of :data:`ENGINE_COMMITS`); models not cached are left out
and counted. Used by the benches that re-rank or fuse stored balls. :data:`SETS` are the
sets they iterate by default; :data:`HELD_OUT` (``webplus``, a test split only) is read
on request, to check settings chosen on the others; :data:`EXTRA` (``enclosures``) are
sets with both splits read on request only, until their caches are filled.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from bench.common import cache_path, load_balls
from bench.sets.datasets import Dataset, capod, enclosures, generic, parts, people, web, webplus
from bench.sets.datasets import articulated as figures
from shapedb.config.core import MDBDConfig

__all__ = ["ENGINE_COMMITS", "SETS", "HELD_OUT", "EXTRA", "CHOICES", "load", "model_key"]

#: Older engines whose cached decompositions are read where today's key has none
#: (b95b2be: test splits, differs only in how flat quads are thickened; f031e22: the
#: people set, before the sheet rule, which leaves closed solids unchanged; 2ba8d98:
#: before the packing could continue past its balls (``tail_balls``), which leaves
#: the balls of ``tail_balls=0`` unchanged; 7ad60e6: before ``decompose`` could keep
#: the field's inside (``keep_inside``), which leaves the balls bit-identical; c106441:
#: before the greedy loop moved from ``mdbd.py`` to ``packing.py``, the same code).
ENGINE_COMMITS = ("c106441", "7ad60e6", "2ba8d98", "b95b2be", "f031e22")
SETS = ("web", "generic", "capod", "figures", "parts", "people")
#: Held-out sets (test split only), never in a default run: nothing is tuned on them.
HELD_OUT = ("webplus",)
#: Sets with validation and test splits that a run reads only when it names them.
EXTRA = ("enclosures",)
#: Every set :func:`load` reads.
CHOICES = SETS + HELD_OUT + EXTRA


def load(name: str, split: str, variants: Sequence[str] = ("mesh",)) -> tuple[Dataset, list[Any]]:
    """The split's models decomposed (cached) in every variant, and their balls.

    Returns the models and, per model, its Balls (one variant) or a tuple of Balls.
    """
    ds = {"web": web, "generic": generic, "capod": capod, "figures": figures, "parts": parts,
          "people": people, "webplus": webplus, "enclosures": enclosures}[name]().split(split)  # fmt: skip
    cfg = MDBDConfig()
    keep, balls = [], []
    for i, m in enumerate(ds.models):
        found = []
        for variant in variants:
            paths = [cache_path(m, variant, cfg)]
            paths += [cache_path(m, variant, cfg, engine_commit=c) for c in ENGINE_COMMITS]
            found.append(next((p for p in paths if p.exists()), None))
        if all(p is not None for p in found):
            keep.append(i)
            got = [load_balls(p, cfg.contact_tol_cells) for p in found if p is not None]
            balls.append(got[0] if len(got) == 1 else tuple(got))
    if len(keep) < len(ds):
        print(f"  {name}: {len(ds) - len(keep)} of {len(ds)} models not cached, left out")
    return Dataset(ds.name, tuple(ds.models[i] for i in keep)), balls


def model_key(model: Any) -> str:
    """A key of what a model's cached decomposition, field and light fields depend on: its
    name, source and today's decomposition cache key (model, MDBD configuration, engine
    code), for caches of values derived from them (distance matrices, field vectors)."""
    return f"{model.name}{model.source}|{cache_path(model, 'mesh', MDBDConfig()).stem}"
