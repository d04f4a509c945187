"""Fixtures of the query tests: a small real store built from example shapes."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from query_helpers import CONFIG, _shapes, make_record, solids, synthetic_features  # noqa: F401

from shapedb.store.schema import ShapeRecord


@pytest.fixture(scope="session")
def example_records() -> list[ShapeRecord]:
    """14 decomposed implicit shapes in 4 classes (resolution 32, 64 balls)."""
    return [make_record(name, label, g) for name, label, g in _shapes()]


@pytest.fixture(scope="session")
def solids_db(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """A store of the six :func:`query_helpers.solids` (resolution 32, 32 balls), read only."""
    import shapedb

    store = shapedb.connect(tmp_path_factory.mktemp("solids") / "store", resolution=32, n_balls=32)
    store.ingest([(n, n, g) for n, g in solids().items()], workers=1, progress=False)
    return store


@pytest.fixture()
def tmp_db(tmp_path: Path, example_records: list[ShapeRecord]) -> Iterator[Any]:
    """A real Database holding the example records."""
    import query.database as database

    db = database.connect(tmp_path / "store", config=CONFIG)
    db.commit(example_records)
    yield db
    _forget(db)


def _forget(db: Any) -> None:
    db.close()


@pytest.fixture(scope="session")
def forget() -> Callable[[Any], None]:
    """Drop the process's caches of a store (index, catalog, SQL connection), as a new process would."""
    return _forget


@pytest.fixture()
def tmp_store(tmp_db: Any) -> Any:
    """The Store of :func:`tmp_db` (14 example shapes)."""
    return tmp_db.store
