"""Crash safety: SIGKILL an ingesting process at random moments and at every commit step.

After each kill the store must open, be internally consistent, hold exactly the
shapes of the batches committed before the kill (or all of them), and a re-run
must complete the ingest.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

import query.database as database
from shapedb.config import Config, SurfaceWordsConfig
from shapedb.store.store import MANIFEST, Store

#: Small stores, without view words: these tests do not search scans, and the views would
#: be most of their ingest time (``tests/query/test_scan_words.py`` tests them). The
#: child process below builds the same configuration.
CONFIG = replace(
    Config().with_options(resolution=24, n_balls=32),
    surface_words=SurfaceWordsConfig(enabled=True, view_words=False),
)
N_FILES = 12

SCRIPT = r"""
import os, signal, sys
from dataclasses import replace
from shapedb.config import Config, SurfaceWordsConfig
import pyarrow.parquet as pq
import query.database as database
from shapedb.store.store import Store

db_path, folder, batch, kill_at = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]

# fault injection: SIGKILL ourselves at the n-th call of one step of a commit
if kill_at != "none":
    step, nth = kill_at.split(":")
    calls = {"n": 0}
    def hit():
        calls["n"] += 1
        if calls["n"] == int(nth):
            os.kill(os.getpid(), signal.SIGKILL)
    def wrap(fn, after=False, only=None):
        # only: count only the calls whose destination has this name (the manifest swap;
        # derived files written beside the store, such as thumbnails, do not count)
        def inner(*a, **k):
            counted = only is None or str(a[1]).endswith(only)
            if counted and not after:
                hit()
            out = fn(*a, **k)
            if counted and after:
                hit()
            return out
        return inner
    if step == "write":
        pq.write_table = wrap(pq.write_table)
    elif step == "rename":
        os.rename = wrap(os.rename)
    elif step == "replace":
        os.replace = wrap(os.replace, only="manifest.json")
    elif step == "replaced":
        os.replace = wrap(os.replace, after=True, only="manifest.json")

commit = Store.commit
def logged(self, *a, **k):
    result = commit(self, *a, **k)
    print("COMMIT", result.version, len(self), flush=True)
    return result
Store.commit = logged

if __name__ == "__main__":
    config = replace(
        Config().with_options(resolution=24, n_balls=32),
        surface_words=SurfaceWordsConfig(enabled=True, view_words=False),
    )
    db = database.connect(db_path, config=config)
    print("START", flush=True)
    db.ingest(folder, workers=int(os.environ.get("WORKERS", "1")), batch_size=batch)
    print("DONE", flush=True)
"""


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("crash-models")
    for k in range(N_FILES):
        box = trimesh.creation.box(extents=(1.0, 1.0 + 0.1 * k, 1.5))
        box.export(folder / f"m{k:02d}.obj")
    return folder


def _run(
    tmp_path: Path,
    db: Path,
    folder: Path,
    *,
    batch: int,
    kill_at: str = "none",
    kill_after: tuple[int, float] | None = None,
    workers: int = 1,
) -> tuple[str, int, list[float]]:
    """Run the ingest script; returns its stdout, exit code and the arrival time of each line.

    ``kill_after=(k, delay)`` SIGKILLs the process group ``delay`` seconds after the
    k-th COMMIT line (k = 0: after START), so the kill lands inside the ingest however
    fast or slow this machine is today.
    """
    script = tmp_path / "ingest_script.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "WORKERS": str(workers)}
    proc = subprocess.Popen(
        [sys.executable, str(script), str(db), str(folder), str(batch), kill_at],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    lines: list[str] = []
    times: list[float] = []
    try:
        assert proc.stdout is not None
        commits = 0
        for line in proc.stdout:
            lines.append(line)
            times.append(time.monotonic())
            commits += line.startswith("COMMIT")
            if kill_after is not None and line.startswith(("START", "COMMIT")):
                if commits == kill_after[0]:
                    time.sleep(kill_after[1])
                    os.killpg(proc.pid, signal.SIGKILL)
                    break
        proc.wait(timeout=300)
        # worker processes and the fork server must go away with their parent
        deadline = time.monotonic() + 20
        while _group_alive(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        stragglers = _group_alive(proc.pid)
        rest, _ = proc.communicate(timeout=30) if not stragglers else ("", None)
        lines.append(rest)
    finally:
        if proc.poll() is None or _group_alive(proc.pid):  # only on a hung child
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert not stragglers, "processes of the killed ingest outlived it"
    return "".join(lines), proc.returncode, times


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _committed(out: str) -> int:
    """Shapes in the store after the last commit the child reported."""
    counts = [int(line.split()[2]) for line in out.splitlines() if line.startswith("COMMIT")]
    return counts[-1] if counts else 0


def check_consistent(path: Path) -> Store:
    """The store opens and every table agrees with every other."""
    store = Store.open(path)
    for table in ("shapes", "balls", "edges", "failures"):
        for f in store.files(table):
            assert Path(f).is_file(), f
    shapes = store.shapes(["id", "name", "content_hash", "n_balls", "n_edges"])
    ids = shapes.column("id").to_numpy()
    assert len(np.unique(ids)) == len(ids)
    assert len(set(shapes.column("content_hash").to_pylist())) == len(ids)
    for table, column in (("balls", "n_balls"), ("edges", "n_edges")):
        t = store.balls() if table == "balls" else store.edges()
        sid, counts = np.unique(t.column("shape_id").to_numpy(), return_counts=True)
        got = dict(zip(sid.tolist(), counts.tolist(), strict=True))
        want = {
            i: n for i, n in zip(ids.tolist(), shapes.column(column).to_pylist(), strict=True) if n
        }
        assert got == want, table
    return store


def _names(store: Store) -> list[str]:
    return sorted(store.shapes(["name"]).column("name").to_pylist())


def _complete(path: Path, folder: Path, already: int) -> None:
    """A re-run adds exactly the missing shapes and leaves no leftovers."""
    db = database.connect(path, config=CONFIG)
    report = db.ingest(folder, workers=1)
    assert len(report.skipped) == already
    assert len(report.ingested) == N_FILES - already and report.failed == ()
    store = check_consistent(path)
    assert _names(store) == [f"m{k:02d}" for k in range(N_FILES)]
    assert not any((path / "staging").iterdir())
    import json

    manifest = json.loads((path / MANIFEST).read_text())
    listed = {s["file"] for t in manifest["tables"].values() for s in t}
    listed |= {r["file"] for r in manifest["retired"]}
    on_disk = {str(p.relative_to(path)) for p in (path / "data").rglob("*.parquet")}
    assert on_disk <= listed  # no orphans


def test_sigkill_at_random_moments(tmp_path: Path, models: Path) -> None:
    rng = random.Random(1234)
    batch = 2
    n_batches = N_FILES // batch
    # a whole run first, to learn how long one batch takes here
    out, code, times = _run(tmp_path, tmp_path / "full", models, batch=batch)
    assert code == 0 and "DONE" in out, out
    assert len(check_consistent(tmp_path / "full")) == N_FILES
    per_batch = (times[-1] - times[0]) / n_batches  # START .. DONE
    outcomes = []
    for trial in range(5):
        path = tmp_path / f"db{trial}"
        database.connect(path, config=CONFIG)  # the store exists before the child starts
        # after a random number of commits, at a random moment of the next batch
        kill_after = (rng.randrange(n_batches - 1), rng.uniform(0.05, 0.95) * per_batch)
        out, code, _ = _run(tmp_path, path, models, batch=batch, kill_after=kill_after)
        store = check_consistent(path)
        n = len(store)
        reported = _committed(out)
        # exactly the batches committed before the kill; the kill may fall between
        # the manifest swap and the child's report of it: then one batch more
        assert n in (reported, min(reported + batch, N_FILES)), (n, reported, out)
        assert n % batch == 0 or n == N_FILES
        # ingest is in input order with one worker: the stored shapes are a prefix
        failures = store.failures().to_pylist()
        assert _names(store) == [f"m{k:02d}" for k in range(n)], (failures, out)
        outcomes.append((code, n))
        _complete(path, models, n)
    assert any(code == -signal.SIGKILL for code, _ in outcomes), outcomes


@pytest.mark.parametrize(
    ("kill_at", "expect"),
    [
        ("write:5", "before"),  # writing the second batch's segments to staging
        ("rename:5", "before"),  # second batch half renamed into data/
        ("replace:2", "before"),  # just before the second manifest swap
        ("replaced:2", "after"),  # just after it, before the directory fsync
    ],
)
def test_sigkill_at_each_commit_step(
    tmp_path: Path, models: Path, kill_at: str, expect: str
) -> None:
    path = tmp_path / "db"
    database.connect(path, config=CONFIG)
    batch = 3
    out, code, _ = _run(tmp_path, path, models, batch=batch, kill_at=kill_at)
    assert code == -signal.SIGKILL, out
    store = check_consistent(path)
    # the first batch is committed; the second is entirely absent or entirely present
    assert len(store) == (batch if expect == "before" else 2 * batch)
    _complete(path, models, len(store))


def test_sigkill_with_worker_processes(tmp_path: Path, models: Path) -> None:
    path = tmp_path / "db"
    database.connect(path, config=CONFIG)
    out, code, _ = _run(tmp_path, path, models, batch=2, kill_at="replace:3", workers=2)
    assert code == -signal.SIGKILL, out
    store = check_consistent(path)
    assert len(store) == 4
    _complete(path, models, 4)
