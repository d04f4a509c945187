"""The default store's behaviour, pinned: a committed small store ranks as it did when built.

``tests/data/pinned`` holds a store of 45 models of every kind the default re-ranking stage
gates on (web-like generic and web models with sheets and open parts, people, jointed
figures, machined parts), built with the default configuration by ``build.py`` there, and
the top-10 ``[id, similarity]`` of every stored shape and of two query files (a mesh of a
person and a point cloud of a chair). Any change to the engine, the store or the query path
that moves one rank or one score fails here; a change meant to move them rebuilds the pin
(``python tests/data/pinned/build.py``) and says why in its commit.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import shapedb

PINNED = Path(__file__).resolve().parent / "data" / "pinned"
RANKS = json.loads((PINNED / "ranks.json").read_text())


@pytest.fixture(scope="module")
def pinned_db(tmp_path_factory: pytest.TempPathFactory) -> shapedb.Database:
    copy = tmp_path_factory.mktemp("pinned") / "store"
    shutil.copytree(PINNED / "store", copy)
    return shapedb.connect(copy, create=False)


def _query(key: str) -> int | Path:
    return PINNED / "queries" / key[len("file:") :] if key.startswith("file:") else int(key)


@pytest.mark.parametrize("key", sorted(RANKS))
def test_search_ranks_are_pinned(pinned_db: shapedb.Database, key: str) -> None:
    hits = pinned_db.search(_query(key), k=len(RANKS[key]))
    assert [h.id for h in hits] == [int(i) for i, _ in RANKS[key]]
    np.testing.assert_allclose([h.similarity for h in hits], [s for _, s in RANKS[key]], rtol=1e-9)


def test_reingest_gives_the_stored_records(tmp_path: Path, pinned_db: shapedb.Database) -> None:
    """The engine still turns the same files into the same records (features, balls, light
    fields, field vectors, surface words)."""
    files = ["generic_sink_0.ply", "generic_wheel_1.ply", "web_church_2.ply"]
    names = [f.removesuffix(".ply") for f in files]
    db = shapedb.connect(tmp_path / "fresh")
    db.ingest([PINNED / "models" / n for n in files])
    columns = "name, feature, light_field, field_vector, surface_words, n_balls"
    fresh = db.sql(f"SELECT {columns} FROM shapes ORDER BY name").to_pylist()
    listed = ", ".join(f"'{n}'" for n in names)
    stored = pinned_db.sql(
        f"SELECT {columns} FROM shapes WHERE name IN ({listed}) ORDER BY name"
    ).to_pylist()
    assert [r["name"] for r in fresh] == [r["name"] for r in stored]
    for a, b in zip(fresh, stored, strict=True):
        assert a["n_balls"] == b["n_balls"]
        for column in ("feature", "light_field", "field_vector"):
            np.testing.assert_allclose(a[column], b[column], rtol=1e-9, atol=1e-12)
        # a feature on the edge of two words may fall either side on another machine's
        # floating point: a share of 1 / 2,000 of the histogram moves
        np.testing.assert_allclose(a["surface_words"], b["surface_words"], rtol=0, atol=1e-3)
