"""The Database facade: connect, config checks, info, delete, extension lookup."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from test_store import CONFIG, make_record  # noqa: I001 - sibling test module

import query.database as database
from shapedb.config.core import Config
from shapedb.errors import ConfigError, NotFoundError, StoreError
from shapedb.store.schema import Failure
from shapedb.store.store import CommitResult


@pytest.fixture()
def tmp_db(tmp_path: Path) -> database.Database:
    return database.connect(tmp_path / "db", config=CONFIG)


def test_connect_creates_then_opens(tmp_path: Path) -> None:
    db = database.connect(tmp_path / "db", resolution=48, n_r=8)
    assert db.config == Config().with_options(resolution=48, n_r=8)
    assert db.store.dim == db.config.dim and len(db) == 0
    paper = database.connect(tmp_path / "paper", n_r=8, method="paper")
    assert paper.store.dim == 16
    again = database.connect(tmp_path / "db")  # no options: the stored config
    assert again.config == db.config
    same = database.connect(tmp_path / "db", resolution=48, n_r=8)
    assert same.config == db.config


def test_connect_refuses_other_config_and_missing_store(tmp_path: Path) -> None:
    database.connect(tmp_path / "db", resolution=48)
    with pytest.raises(ConfigError, match="resolution: store 48, requested 64"):
        database.connect(tmp_path / "db", resolution=64)
    with pytest.raises(StoreError, match="no shapedb store"):
        database.connect(tmp_path / "missing", create=False)
    assert not (tmp_path / "missing").exists()
    with pytest.raises(ConfigError, match="unknown"):
        database.connect(tmp_path / "x", colour="red")


def test_info_shapes_get_and_contains(tmp_db: database.Database) -> None:
    tmp_db.commit(
        [
            make_record("a", label="chair"),
            make_record("b", label="chair"),
            make_record("c", label=None),
        ],
        failures=[Failure("/x/bad.obj", "LoadError", "junk")],
    )
    info = tmp_db.info()
    assert set(info) == {"shapes", "labels", "failures", "config"}
    assert info["shapes"] == 3 and info["labels"] == {"chair": 2}
    assert info["failures"] == [{"path": "/x/bad.obj", "error": "LoadError: junk"}]
    assert info["config"] == CONFIG.to_dict()
    assert tmp_db.shapes(["name"]).column("name").to_pylist() == ["a", "b", "c"]
    assert tmp_db.get("b").id == 2
    assert "a" in tmp_db and 3 in tmp_db and "zz" not in tmp_db and 9 not in tmp_db


def test_delete_by_id_and_name(tmp_db: database.Database) -> None:
    tmp_db.commit([make_record("a"), make_record("b"), make_record("c")])
    assert tmp_db.delete(["a", 3]) == 2
    assert tmp_db.delete("2") == 1  # digits: an id when no shape has that name
    assert len(tmp_db) == 0
    with pytest.raises(NotFoundError, match="a"):
        tmp_db.delete("a")


def test_every_commit_that_changes_shapes_updates_the_derived_state(
    tmp_db: database.Database, monkeypatch: pytest.MonkeyPatch
) -> None:
    from query.search import index

    calls: list[CommitResult] = []
    monkeypatch.setattr(index, "on_commit", lambda db, result: calls.append(result))
    tmp_db.commit([make_record("a")])
    tmp_db.delete("a")
    tmp_db.commit(failures=[Failure("x", "LoadError", "junk")])  # no shape changed
    assert [(c.added, c.deleted) for c in calls] == [((1,), ()), ((), (1,))]


def test_a_failing_index_update_does_not_undo_the_commit(
    tmp_db: database.Database, monkeypatch: pytest.MonkeyPatch
) -> None:
    from query.search import index

    def boom(db: Any, result: Any) -> None:
        raise RuntimeError("index broke")

    monkeypatch.setattr(index, "on_commit", boom)
    tmp_db.commit([make_record("a")])
    assert len(tmp_db) == 1


def test_the_core_loads_no_downstream_package() -> None:
    """The store, the engine and ``import shapedb`` load nothing of ``ingest`` or ``query``;
    only the facade (``shapedb.connect``, a lazy re-export) does."""
    import subprocess
    import sys

    code = (
        "import sys, shapedb, shapedb.store, shapedb.mdbd, shapedb.signature, shapedb.geometry;"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('ingest', 'query')];"
        "print(bad); sys.exit(1 if bad else 0)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
