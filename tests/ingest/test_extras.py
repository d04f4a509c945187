"""Optional dependencies of ingest: a clear error naming the extra when one is missing."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import query.database as database
from shapedb.errors import MissingDependencyError


def test_scheduler_without_dask_names_the_extra(
    tmp_db: database.Database,
    good_files,  # type: ignore[no-untyped-def]
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # "import distributed" fails
    with pytest.raises(MissingDependencyError, match=r"pip install 'shapedb\[distributed\]'"):
        tmp_db.ingest([good_files["box.obj"]], scheduler="tcp://127.0.0.1:1")
    assert tmp_db.store.version == 0


def test_the_extra_is_declared() -> None:
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())["project"]
    assert any(
        d.startswith("dask[distributed]") for d in project["optional-dependencies"]["distributed"]
    )
    assert not any(d.startswith("dask") for d in project["dependencies"])
