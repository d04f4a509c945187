"""Property-based fuzzing of ingest: mutated model files and hostile file names.

Every example must end as a stored record or as a failure row, never as an exception
out of ``ingest``, and the store must pass ``shapedb check`` afterwards. The default
run draws 50 examples on small generated OBJ / OFF / PLY / STL files; ``-m slow`` draws
1,000 and adds a real CAPOD model.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import query.database as database
from shapedb.store.integrity import check

OPTIONS = {"resolution": 24, "n_balls": 32}
CAPOD = Path("/work/shared/data/capod/class1/m6.obj")


def _seeds(real: bool) -> list[tuple[str, bytes]]:
    box = trimesh.creation.box(extents=(1.0, 0.7, 0.5))
    ico = trimesh.creation.icosphere(subdivisions=1)
    seeds = [
        ("obj", box.export(file_type="obj").encode()),
        ("off", ico.export(file_type="off").encode()),
        ("ply", ico.export(file_type="ply")),
        ("ply", box.export(file_type="ply", encoding="ascii")),
        ("stl", box.export(file_type="stl")),
        ("stl", box.export(file_type="stl_ascii").encode()),
    ]
    if real and CAPOD.is_file():
        seeds.append(("obj", CAPOD.read_bytes()))
    return seeds


def _mutate(data: bytes, ops: list[tuple[int, int, int, bytes]]) -> bytes:
    """Apply (kind, position, length, bytes) edits: flip, cut, insert, duplicate, truncate."""
    b = bytearray(data)
    for kind, pos, length, junk in ops:
        if not b:
            break
        p = pos % len(b)
        if kind == 0:  # overwrite
            b[p : p + len(junk)] = junk
        elif kind == 1:  # delete a slice
            del b[p : p + length]
        elif kind == 2:  # insert junk
            b[p:p] = junk
        elif kind == 3:  # duplicate a slice
            b[p:p] = b[p : p + length]
        else:  # truncate
            del b[p:]
    return bytes(b)


_OPS = st.lists(
    st.tuples(
        st.integers(0, 4),
        st.integers(0, 1 << 20),
        st.integers(1, 400),
        st.binary(min_size=1, max_size=24),
    ),
    min_size=0,
    max_size=4,
)
_NAME = st.one_of(
    st.text(min_size=1, max_size=40).map(lambda s: os.fsencode(s) if "\0" not in s else b"x"),
    st.binary(min_size=1, max_size=60),
).map(lambda b: b.replace(b"/", b"_").replace(b"\0", b"_")[:200] or b"x")


def _fuzz(
    db: database.Database, folder: Path, seeds: list[tuple[str, bytes]], data: st.DataObject
) -> None:
    ext, seed = data.draw(st.sampled_from(seeds), label="seed")
    body = _mutate(seed, data.draw(_OPS, label="ops"))
    name = data.draw(_NAME, label="name")
    if name in (b".", b".."):
        name = b"dot"
    keep_ext = data.draw(st.sampled_from([True, True, True, True, False]), label="extension")
    fname = name + (b"." + ext.encode() if keep_ext else b"")
    case = Path(tempfile.mkdtemp(dir=folder))
    path = os.path.join(os.fsencode(case), fname)
    with open(path, "wb") as fh:
        fh.write(body)
    report = db.ingest([os.fsdecode(path)], workers=1, max_bytes=4 << 20)
    assert len(report.ingested) + len(report.failed) + len(report.skipped) == 1, report
    assert all(isinstance(e, str) and e.encode("utf-8") for _, e in report.failed)


@pytest.fixture(scope="module")
def fuzz_db(tmp_path_factory: pytest.TempPathFactory) -> tuple[database.Database, Path]:
    root = tmp_path_factory.mktemp("fuzz")
    (root / "inputs").mkdir()
    db = database.connect(root / "db", **OPTIONS)
    # one good file first: the libraries ingest loads change the recursion limit once,
    # which hypothesis would otherwise report as a change made by the test
    warm = root / "warm.obj"
    warm.write_bytes(_seeds(real=False)[0][1])
    assert len(db.ingest([warm], workers=1).ingested) == 1
    return db, root / "inputs"


@settings(
    max_examples=50,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_mutated_files_end_as_records_or_failure_rows(fuzz_db, data) -> None:
    db, folder = fuzz_db
    _fuzz(db, folder, _seeds(real=False), data)


def test_store_checks_clean_after_fuzzing(fuzz_db) -> None:
    db, _ = fuzz_db
    report = check(db.store.path)
    assert report.ok, report.damaged
    # the mutations are neither all harmless nor all fatal: both outcomes occur
    assert len(db.store) > 1 and len(db.store.failures()) > 0


@pytest.mark.slow
@settings(
    max_examples=1000,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_mutated_files_end_as_records_or_failure_rows_long(fuzz_db, data) -> None:
    db, folder = fuzz_db
    _fuzz(db, folder, _seeds(real=True), data)
    assert check(db.store.path).ok
