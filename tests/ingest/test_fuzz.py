"""Fuzzing of ingest: mutated model files of every format, and hostile file names.

The loader fuzz reads a few hundred seeded mutations (truncation, flipped bytes, huge
counts, NaN text, deleted or repeated lines, junk; :mod:`fuzz_seeds`) of small valid
files of every supported format: each must load as a sane shape or raise a
:class:`~shapedb.errors.ShapeDBError` whose one-line message names the file, within a
time bound, and the valid originals must load.

The ingest fuzz draws mutated files and names with hypothesis: every example must end
as a stored record or as a failure row, never as an exception out of ``ingest``, and
the store must pass ``shapedb check`` afterwards. The default run draws 50 examples on
small generated OBJ / OFF / PLY / STL files; ``-m slow`` draws 1,000 and adds a real
CAPOD model.
"""

from __future__ import annotations

import faulthandler
import os
import signal
import tempfile
import time
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import trimesh
from fuzz_seeds import describe, mutate, seeds
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import query.database as database
from ingest.loaders import CAD_FORMATS, MAX_COORDINATE, load
from shapedb.errors import MissingDependencyError, ShapeDBError
from shapedb.store.integrity import check

#: Mutations drawn per seed file (19 seeds: about 450 cases, ~5 s on this machine).
CASES_PER_SEED = 24
#: Seconds one case may take: the small files load in milliseconds.
CASE_SECONDS = 10


class _Hang(BaseException):
    """Raised in a case that outlives its time bound (a BaseException: load() keeps it)."""


@contextmanager
def _bounded(seconds: float) -> Iterator[None]:
    """Interrupt Python code after ``seconds``; end the process if C code hangs."""

    def alarm(signum: int, frame: object) -> None:
        raise _Hang(f"over {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    faulthandler.dump_traceback_later(3 * seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _sane(g: object) -> str | None:
    """What is wrong with a loaded shape, or None."""
    for attr in ("vertices", "points"):
        a = getattr(g, attr, None)
        if a is not None:
            a = np.asarray(a, dtype=np.float64)
            if not np.all(np.isfinite(a)) or np.abs(a).max() > MAX_COORDINATE:
                return f"{attr} not finite or beyond {MAX_COORDINATE:g}"
    return None


def _case(path: Path) -> str | None:
    """Load one file; what went wrong, or None when it loaded sanely or was refused well."""
    t0 = time.monotonic()
    try:
        with _bounded(CASE_SECONDS):
            g = load(path)
    except _Hang as exc:
        return f"hang: {exc}"
    except ShapeDBError as exc:
        text = str(exc)
        if "\n" in text or path.name not in text:
            return f"message not one line naming the file: {text!r}"
        return None
    except Exception as exc:  # noqa: BLE001 - the very thing this test looks for
        return f"{type(exc).__name__}: {exc}"
    if time.monotonic() - t0 > CASE_SECONDS:
        return "too slow"
    return _sane(g)


def _needs_gmsh(name: str) -> bool:
    return Path(name).suffix in CAD_FORMATS


def test_valid_seed_files_load(tmp_path: Path) -> None:
    for name, data in seeds().items():
        path = tmp_path / name
        path.write_bytes(data)
        if _needs_gmsh(name):  # placeholders: only the refusal without gmsh is checked
            try:
                import gmsh  # noqa: F401
            except ImportError:
                with pytest.raises(MissingDependencyError):
                    load(path)
            continue
        assert _sane(load(path)) is None, name


def test_mutated_files_of_every_format_load_or_raise_shapedb_errors(tmp_path: Path) -> None:
    problems = []
    n = 0
    for name, data in seeds().items():
        for k in range(CASES_PER_SEED):
            seed = zlib.crc32(name.encode()) + k
            how, body = mutate(seed, data)
            if not body:
                continue
            case = tmp_path / f"{seed}-{name}"
            case.write_bytes(body)
            n += 1
            problem = _case(case)
            if problem is not None:
                problems.append(f"{name} seed {seed} ({how}): {problem} {describe(body)}")
            case.unlink()
    assert n >= 250
    assert not problems, "\n".join(problems)


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
    report = db.ingest([os.fsdecode(path)], workers=1, max_bytes=4 << 20, progress=False)
    assert len(report.ingested) + len(report.failed) + len(report.skipped) == 1, report
    assert len(report.outcomes) == 1 and report.ignored == (), report
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
