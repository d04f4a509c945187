"""Verify a store against its manifest (``shapedb check``) and rebuild it (``shapedb repair``).

:func:`check` reads the manifest and verifies every segment it lists: the file exists,
has the size and sha256 recorded at commit time, and its row count agrees. Segments
of stores written before checksums were recorded are read instead, and reported as
"no checksum recorded" (not as damage).

:func:`repair` rebuilds a manifest from the segments that are intact. Segments carry
their ids (``id``, ``shape_id``) and each shape row its configuration, so a store
whose manifest is lost or damaged can be rebuilt from ``data/`` alone: newest segments
first (file names start with the commit version), each shape id taken once, balls and
edges kept for the recovered shapes only, shapes whose balls or edges are lost
dropped and reported. The recovered rows are written as new segments in one commit,
and every file the old state held is *moved* to ``lost+found/<time>/`` (never
deleted), so nothing is lost by repairing.
"""

from __future__ import annotations

import collections
import json
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from shapedb.config.core import Config
from shapedb.errors import StoreError
from shapedb.store.manifest import DATA, new_manifest, read_manifest
from shapedb.store.schema import TABLES, schema_for
from shapedb.store.transaction import REPLACES, FileLock, Transaction, file_digest

__all__ = ["check", "repair", "CheckReport", "RepairReport", "LOST_AND_FOUND"]

log = logging.getLogger(__name__)

LOST_AND_FOUND = "lost+found"
_LOCK = ".lock"


@dataclass(frozen=True)
class CheckReport:
    """What :func:`check` found.

    Attributes
    ----------
    path : str
        The store.
    checked : int
        Segments verified against a recorded checksum.
    damaged : tuple[tuple[str, str], ...]
        ``(file, reason)`` of each listed segment that is missing or damaged.
    unverified : tuple[str, ...]
        Listed segments with no checksum recorded (written by an older shapedb);
        they were read in full instead.
    unlisted : tuple[str, ...]
        Files under ``data/`` that the manifest neither lists nor retires (leftovers;
        not damage).
    """

    path: str
    checked: int = 0
    damaged: tuple[tuple[str, str], ...] = ()
    unverified: tuple[str, ...] = ()
    unlisted: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """True when no listed segment is missing or damaged."""
        return not self.damaged

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary."""
        return {
            "path": self.path,
            "ok": self.ok,
            "checked": self.checked,
            "damaged": [{"file": f, "reason": r} for f, r in self.damaged],
            "unverified": list(self.unverified),
            "unlisted": list(self.unlisted),
        }


@dataclass(frozen=True)
class RepairReport:
    """What :func:`repair` did.

    Attributes
    ----------
    path : str
        The store.
    changed : bool
        False when the store was intact and nothing was written.
    manifest : str or None
        What was wrong with the manifest (None when it was valid); the manifest is
        rebuilt, no data is lost by this alone.
    shapes : int
        Shapes in the repaired store.
    recovered : tuple[str, ...]
        Segments whose rows were recovered.
    lost : tuple[tuple[str, str], ...]
        ``(file or shape, reason)`` of what could not be recovered.
    moved_to : str or None
        Folder the previous files were moved to (``lost+found/<time>``).
    """

    path: str
    changed: bool = False
    manifest: str | None = None
    shapes: int = 0
    recovered: tuple[str, ...] = ()
    lost: tuple[tuple[str, str], ...] = ()
    moved_to: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary."""
        return {
            "path": self.path,
            "changed": self.changed,
            "manifest": self.manifest,
            "shapes": self.shapes,
            "recovered": list(self.recovered),
            "lost": [{"what": w, "reason": r} for w, r in self.lost],
            "moved_to": self.moved_to,
        }


# ---------------------------------------------------------------- check
def _verify(root: Path, seg: dict[str, Any]) -> str | None:
    """None when the segment is intact, else the reason."""
    path = root / seg["file"]
    if not path.is_file():
        return "missing"
    if "sha256" in seg:
        size, digest = file_digest(path)
        if size != int(seg.get("bytes", size)):
            return f"damaged: {size} bytes, the manifest records {seg['bytes']}"
        if digest != seg["sha256"]:
            return "damaged: checksum differs from the one recorded at commit"
    try:
        t = pq.read_table(path, page_checksum_verification=True)
    except Exception as exc:  # any unreadable file
        return f"unreadable ({type(exc).__name__}: {' '.join(str(exc).split())[:120]})"
    if t.num_rows != int(seg["rows"]):
        return f"damaged: {t.num_rows} rows, the manifest records {seg['rows']}"
    return None


def check(path: str | os.PathLike[str]) -> CheckReport:
    """Verify every segment the manifest lists.

    Parameters
    ----------
    path : str or Path
        The store directory.

    Returns
    -------
    CheckReport
        ``report.ok`` is False when a listed segment is missing or damaged.

    Raises
    ------
    StoreError
        The manifest itself is missing or damaged (the message says how to repair).
    """
    root = Path(path).absolute()
    manifest = read_manifest(root)
    damaged, unverified, checked = [], [], 0
    for table in TABLES:
        for seg in manifest["tables"][table]:
            reason = _verify(root, seg)
            if reason is not None:
                damaged.append((seg["file"], reason))
            elif "sha256" in seg:
                checked += 1
            else:
                unverified.append(seg["file"])
    known = {s["file"] for t in TABLES for s in manifest["tables"][t]}
    known |= {r["file"] for r in manifest.get("retired", [])}
    unlisted = sorted(
        f"{DATA}/{t}/{f.name}"
        for t in TABLES
        if (root / DATA / t).is_dir()
        for f in (root / DATA / t).iterdir()
        if f"{DATA}/{t}/{f.name}" not in known
    )
    return CheckReport(
        path=str(root),
        checked=checked,
        damaged=tuple(damaged),
        unverified=tuple(unverified),
        unlisted=tuple(unlisted),
    )


# ---------------------------------------------------------------- repair
def _candidates(root: Path, manifest: dict[str, Any] | None) -> dict[str, list[dict[str, Any]]]:
    """Segments to recover from, newest first: the manifest's, or every file in data/."""
    if manifest is not None:
        return {
            t: sorted(manifest["tables"][t], key=lambda s: s["file"], reverse=True) for t in TABLES
        }
    out: dict[str, list[dict[str, Any]]] = {}
    for t in TABLES:
        folder = root / DATA / t
        files = sorted(folder.glob("*.parquet"), reverse=True) if folder.is_dir() else []
        out[t] = [{"file": f"{DATA}/{t}/{f.name}"} for f in files]
    return out


def _readable(
    root: Path, segments: list[dict[str, Any]], lost: list[tuple[str, str]]
) -> list[tuple[str, pa.Table]]:
    out = []
    for seg in segments:
        if "rows" in seg:
            reason = _verify(root, seg)
            if reason is not None:
                lost.append((seg["file"], reason))
                continue
        try:
            out.append(
                (seg["file"], pq.read_table(root / seg["file"], page_checksum_verification=True))
            )
        except Exception as exc:  # any unreadable file
            lost.append((seg["file"], f"unreadable ({type(exc).__name__})"))
    return out


def _replaces(t: pa.Table) -> list[str]:
    """Segments a segment's metadata says it supersedes (a deletion's or compaction's)."""
    raw = (t.schema.metadata or {}).get(REPLACES)
    try:
        return [str(f) for f in json.loads(raw)] if raw else []
    except ValueError:
        return []


def _choose_config(manifest: dict[str, Any] | None, shapes: list[tuple[str, pa.Table]]) -> Config:
    if manifest is not None:
        return Config.from_dict(manifest["config"])
    counts: collections.Counter[str] = collections.Counter()
    for _, t in shapes:
        if "config" in t.schema.names:
            counts.update(t.column("config").to_pylist())
    if not counts:
        raise StoreError(
            "no readable shapes segment holds a configuration: nothing to rebuild a manifest from",
            source="repair",
        )
    return Config.from_json(counts.most_common(1)[0][0])


def _first_per_id(
    tables: list[tuple[str, pa.Table]], column: str, keep: set[int] | None
) -> tuple[pa.Table | None, list[str]]:
    """Rows of each id from the newest segment holding it (and only ids in ``keep``)."""
    seen: set[int] = set()
    parts, used = [], []
    for name, t in tables:
        ids = t.column(column).to_numpy()
        fresh = {int(i) for i in ids} - seen
        if keep is not None:
            fresh &= keep
        if not fresh:
            continue
        t = t.filter(pc.is_in(t.column(column), pa.array(sorted(fresh), pa.int64())))
        parts.append(t)
        used.append(name)
        seen |= fresh
    return (pa.concat_tables(parts, promote_options="permissive") if parts else None), used


def repair(path: str | os.PathLike[str]) -> RepairReport:
    """Rebuild the store's manifest from its intact segments (under the write lock).

    Parameters
    ----------
    path : str or Path
        The store directory.

    Returns
    -------
    RepairReport
        What was recovered and what was not. An intact store is left unchanged.

    Raises
    ------
    StoreError
        Nothing to rebuild from (no readable shapes segment), or another writer holds
        the store.
    """
    root = Path(path).absolute()
    lock = FileLock(root / _LOCK)
    if not root.is_dir():
        raise StoreError("no such folder", source=str(root))
    lock.acquire(0.0, source=str(root))
    try:
        return _repair(root)
    finally:
        lock.release()


def _repair(root: Path) -> RepairReport:
    lost: list[tuple[str, str]] = []
    problem = None
    try:
        manifest: dict[str, Any] | None = read_manifest(root)
    except StoreError as exc:
        manifest = None
        problem = exc.reason.split(";")[0]
    if manifest is not None and check(root).ok:
        n = sum(int(s["rows"]) for s in manifest["tables"]["shapes"])
        return RepairReport(path=str(root), changed=False, shapes=n)
    found = {t: _readable(root, segs, lost) for t, segs in _candidates(root, manifest).items()}
    replaced = {f for tables in found.values() for _, t in tables for f in _replaces(t)}
    found = {t: [(n, x) for n, x in tables if n not in replaced] for t, tables in found.items()}
    config = _choose_config(manifest, found["shapes"])
    dim = config.dim
    fingerprint = config.to_json()
    shapes_in = []
    for name, t in found["shapes"]:
        if "config" in t.schema.names:
            same = pc.equal(t.column("config"), fingerprint)
            if not pc.all(same).as_py():
                lost.append((name, "rows built with another configuration were left out"))
                t = t.filter(same)
        shapes_in.append((name, t))
    shapes, used = _first_per_id(shapes_in, "id", None)
    ids = set() if shapes is None else {int(i) for i in shapes.column("id").to_pylist()}
    balls, used_b = _first_per_id(found["balls"], "shape_id", ids)
    edges, used_e = _first_per_id(found["edges"], "shape_id", ids)
    shapes = _drop_incomplete(shapes, balls, edges, lost)
    ids = set() if shapes is None else {int(i) for i in shapes.column("id").to_pylist()}
    balls, _ = _first_per_id(found["balls"], "shape_id", ids)
    edges, _ = _first_per_id(found["edges"], "shape_id", ids)
    failures = found["failures"][0][1] if found["failures"] else None

    base = dict(manifest) if manifest is not None else new_manifest(config)
    base["tables"] = {t: [] for t in TABLES}
    base["retired"] = []
    txn = Transaction(root, base)
    for table, t, col in (
        ("shapes", shapes, "id"),
        ("balls", balls, "shape_id"),
        ("edges", edges, "shape_id"),
        ("failures", failures, None),
    ):
        if t is not None and t.num_rows:
            txn.tables[table].append(txn.stage(table, _conform(t, table, dim), col))
    old = {p for p in (root / DATA).rglob("*") if p.is_file()} if (root / DATA).is_dir() else set()
    next_id = max([int(base.get("next_id", 1)), *(i + 1 for i in ids)])
    txn.publish(next_id=next_id)
    moved = _move_aside(root, old)
    log.info("repaired store %s: %d shapes, %d lost", root, len(ids), len(lost))
    return RepairReport(
        path=str(root),
        changed=True,
        manifest=problem,
        shapes=len(ids),
        recovered=tuple(sorted(set(used) | set(used_b) | set(used_e))),
        lost=tuple(lost),
        moved_to=moved,
    )


def _conform(t: pa.Table, table: str, dim: int) -> pa.Table:
    """The rows in the table's current schema (columns added since are null)."""
    schema = schema_for(table, dim)
    cols = [
        t.column(f.name).cast(f.type) if f.name in t.schema.names else pa.nulls(t.num_rows, f.type)
        for f in schema
    ]
    return pa.Table.from_arrays(cols, schema=schema)


def _drop_incomplete(
    shapes: pa.Table | None,
    balls: pa.Table | None,
    edges: pa.Table | None,
    lost: list[tuple[str, str]],
) -> pa.Table | None:
    """Shapes whose balls or edges were not all recovered are left out (and reported)."""
    if shapes is None:
        return None

    def counts(t: pa.Table | None) -> dict[int, int]:
        if t is None:
            return {}
        c = collections.Counter(t.column("shape_id").to_pylist())
        return {int(k): int(v) for k, v in c.items()}

    nb, ne = counts(balls), counts(edges)
    keep = []
    for row in shapes.select(["id", "name", "n_balls", "n_edges"]).to_pylist():
        sid = int(row["id"])
        if nb.get(sid, 0) != int(row["n_balls"]) or ne.get(sid, 0) != int(row["n_edges"]):
            lost.append((f"shape {sid} ({row['name']})", "its balls or edges were not recovered"))
        else:
            keep.append(sid)
    return shapes.filter(pc.is_in(shapes.column("id"), pa.array(keep, pa.int64())))


def _move_aside(root: Path, files: set[Path]) -> str | None:
    """Move the previous files into ``lost+found/<time>/`` (keeping their paths)."""
    if not files:
        return None
    dest = root / LOST_AND_FOUND / time.strftime("%Y%m%dT%H%M%S")
    for f in sorted(files):
        target = dest / f.relative_to(root)
        target.parent.mkdir(parents=True, exist_ok=True)
        os.rename(f, target)
    (dest / "README.txt").write_text(
        "Files of the store before `shapedb repair` rebuilt it; the repaired store does not "
        "use them. Safe to delete once you are satisfied with the repair.\n"
    )
    (dest / "report.json").write_text(json.dumps({"moved": len(files)}))
    return str(dest)
