"""Fixtures for the ingest tests: small generated model files of every format."""

from __future__ import annotations

from pathlib import Path

import pytest
from ingest_helpers import SMALL, make_bad, make_good

import query.database as database


@pytest.fixture(scope="session")
def good_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("good")
    make_good(folder)
    return folder


@pytest.fixture(scope="session")
def good_files(good_dir: Path) -> dict[str, Path]:
    return {p.name: p for p in sorted(good_dir.iterdir())}


@pytest.fixture()
def bad_dir(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    folder = tmp_path / "bad"
    return folder, make_bad(folder)


@pytest.fixture()
def tmp_db(tmp_path: Path) -> database.Database:
    """A fresh small-config database in a temporary folder."""
    return database.connect(tmp_path / "db", **SMALL)


@pytest.fixture()
def tmp_store(tmp_db: database.Database):  # type: ignore[no-untyped-def]
    """The store of :func:`tmp_db`."""
    return tmp_db.store
