"""Verify a store against its manifest (``shapedb check``) and rebuild it (``shapedb repair``).

:func:`check` reads the manifest and verifies every segment it lists: the file exists,
has the size and sha256 recorded at commit time, and its row count agrees. Segments
of stores written before checksums were recorded are read instead, and reported as
"no checksum recorded" (not as damage). It also checks the ids: no id is held by two
rows, and the manifest's ``next_id`` is above every stored id (ids are never reused).

:func:`repair` rebuilds a manifest from the segments that are intact. Segments carry
their ids (``id``, ``shape_id``) and each shape row its configuration, so a store
whose manifest is lost or damaged can be rebuilt from ``data/`` alone. Segments are
taken oldest first (file names start with the commit version), minus those a newer
one says it replaces; every readable row is kept: a row claiming an id an older row
holds gets a new id (a copy of the same record is kept once), each row takes its
balls and edges from its own commit when it can, and shapes whose balls or edges are
lost are dropped and reported. The recovered rows are written as new segments in one
commit, ids continue above every id seen, and every file the old state held is
*moved* to ``lost+found/<time>/`` (never deleted), so nothing is lost by repairing.
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

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
from numpy.typing import NDArray

from shapedb.config.core import Config
from shapedb.errors import StoreError
from shapedb.store.checksums import segment_fault
from shapedb.store.manifest import DATA, MANIFEST, new_manifest, read_manifest
from shapedb.store.schema import TABLES, schema_for
from shapedb.store.transaction import REPLACES, FileLock, Transaction

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
    conflicts : tuple[tuple[str, str], ...]
        ``(what, reason)`` of each way the ids break the rule that an id names one
        shape and is never reused: an id held by more than one row, and a manifest
        ``next_id`` at or below the largest stored id.
    """

    path: str
    checked: int = 0
    damaged: tuple[tuple[str, str], ...] = ()
    unverified: tuple[str, ...] = ()
    unlisted: tuple[str, ...] = ()
    conflicts: tuple[tuple[str, str], ...] = ()

    @property
    def ok(self) -> bool:
        """True when no listed segment is missing or damaged and the ids are consistent."""
        return not self.damaged and not self.conflicts

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary."""
        return {
            "path": self.path,
            "ok": self.ok,
            "checked": self.checked,
            "damaged": [{"file": f, "reason": r} for f, r in self.damaged],
            "unverified": list(self.unverified),
            "unlisted": list(self.unlisted),
            "conflicts": [{"what": w, "reason": r} for w, r in self.conflicts],
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
    reassigned : tuple[tuple[int, int], ...]
        ``(old id, new id)`` of each row that claimed an id an older row holds: both
        rows were kept, the later one under a new id.
    notes : tuple[str, ...]
        What else was fixed without losing a row (ids reassigned, a ``next_id`` that
        would have reused an id, a row count the manifest misrecorded).
    """

    path: str
    changed: bool = False
    manifest: str | None = None
    shapes: int = 0
    recovered: tuple[str, ...] = ()
    lost: tuple[tuple[str, str], ...] = ()
    moved_to: str | None = None
    reassigned: tuple[tuple[int, int], ...] = ()
    notes: tuple[str, ...] = ()

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
            "reassigned": [{"old": a, "new": b} for a, b in self.reassigned],
            "notes": list(self.notes),
        }


# ---------------------------------------------------------------- check
_NAMED = 20
"""Conflicting ids a report names one by one; the rest are counted."""


def _verify(root: Path, seg: dict[str, Any]) -> tuple[str | None, pa.Table | None]:
    """``(None, rows)`` when the segment is intact, else ``(reason, rows or None)``."""
    fault = segment_fault(root, seg)
    if fault is not None:
        return fault, None
    try:
        t = pq.read_table(root / seg["file"], page_checksum_verification=True)
    except Exception as exc:  # any unreadable file
        return f"unreadable ({type(exc).__name__}: {' '.join(str(exc).split())[:120]})", None
    if t.num_rows != int(seg["rows"]):
        return f"damaged: {t.num_rows} rows, the manifest records {seg['rows']}", t
    return None, t


def _id_conflicts(
    manifest: dict[str, Any], held: list[tuple[str, NDArray[np.int64]]]
) -> list[tuple[str, str]]:
    """Ids held by more than one row, and a ``next_id`` that would reuse one."""
    out: list[tuple[str, str]] = []
    if not held:
        return out
    every = np.concatenate([ids for _, ids in held])
    values, counts = np.unique(every, return_counts=True)
    twice = values[counts > 1]
    for sid in twice[:_NAMED].tolist():
        files = [f for f, ids in held for _ in range(int((ids == sid).sum()))]
        out.append((f"id {sid}", f"held by {len(files)} rows ({', '.join(files)})"))
    if len(twice) > _NAMED:
        out.append((f"{len(twice) - _NAMED} more ids", "each held by more than one row"))
    top = int(every.max()) if len(every) else 0
    if int(manifest["next_id"]) <= top:
        out.append(
            (
                "manifest.json",
                f"next_id {manifest['next_id']} is at or below the largest id {top}: "
                "a new shape would reuse an id",
            )
        )
    return out


def check(path: str | os.PathLike[str]) -> CheckReport:
    """Verify every segment the manifest lists, and the ids they hold.

    Parameters
    ----------
    path : str or Path
        The store directory.

    Returns
    -------
    CheckReport
        ``report.ok`` is False when a listed segment is missing or damaged, or when
        an id is held twice or the manifest's ``next_id`` would reuse one.

    Raises
    ------
    StoreError
        The manifest itself is missing or damaged (the message says how to repair).
    """
    root = Path(path).absolute()
    manifest = read_manifest(root)
    damaged, unverified, checked = [], [], 0
    held: list[tuple[str, NDArray[np.int64]]] = []
    for table in TABLES:
        for seg in manifest["tables"][table]:
            reason, t = _verify(root, seg)
            if reason is not None:
                damaged.append((seg["file"], reason))
            elif "sha256" in seg:
                checked += 1
            else:
                unverified.append(seg["file"])
            if table == "shapes" and t is not None:
                held.append((seg["file"], t.column("id").to_numpy().astype(np.int64)))
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
        conflicts=tuple(_id_conflicts(manifest, held)),
    )


# ---------------------------------------------------------------- repair
def _candidates(root: Path, manifest: dict[str, Any] | None) -> dict[str, list[dict[str, Any]]]:
    """Segments to recover from, oldest first (file names start with the commit version):
    the manifest's, or every file in data/; each file once."""
    if manifest is not None:
        out = {}
        for t in TABLES:
            entries = {s["file"]: s for s in manifest["tables"][t]}
            out[t] = [entries[f] for f in sorted(entries)]
        return out
    out = {}
    for t in TABLES:
        folder = root / DATA / t
        files = sorted(folder.glob("*.parquet")) if folder.is_dir() else []
        out[t] = [{"file": f"{DATA}/{t}/{f.name}"} for f in files]
    return out


def _readable(
    root: Path, segments: list[dict[str, Any]], lost: list[tuple[str, str]], notes: list[str]
) -> list[tuple[str, pa.Table]]:
    """The rows of each segment whose bytes are intact; a misrecorded row count is noted."""
    out = []
    for seg in segments:
        fault = segment_fault(root, seg) if "sha256" in seg else None
        if fault is None:
            try:
                t = pq.read_table(root / seg["file"], page_checksum_verification=True)
            except FileNotFoundError:
                fault = "missing"
            except Exception as exc:  # any unreadable file
                fault = f"unreadable ({type(exc).__name__})"
        if fault is not None:
            lost.append((seg["file"], fault))
            continue
        if "rows" in seg and t.num_rows != int(seg["rows"]):
            notes.append(
                f"{seg['file']}: the manifest recorded {seg['rows']} rows, the file holds "
                f"{t.num_rows} intact ones: they were kept"
            )
        out.append((seg["file"], t))
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


def _same_config(
    shapes: list[tuple[str, pa.Table]], config: Config, lost: list[tuple[str, str]]
) -> list[tuple[str, pa.Table]]:
    """Each segment's rows built with ``config`` (others are left out and reported)."""
    fingerprint = config.to_json()
    out = []
    for name, t in shapes:
        if "config" in t.schema.names:
            same = pc.equal(t.column("config"), fingerprint)
            if not pc.all(same).as_py():
                lost.append((name, "rows built with another configuration were left out"))
                t = t.filter(same)
        out.append((name, t))
    return out


def _assign_ids(
    tables: list[tuple[str, pa.Table]], floor: int, notes: list[str]
) -> tuple[pa.Table | None, list[tuple[int, int, str]]]:
    """Give every readable shape row an id of its own, oldest segment first.

    The first row to claim an id keeps it. A copy of a row already kept (same content
    hash and creation time: one record in two files) is dropped. Any other row that
    claims a taken id gets the next free one, from ``floor`` up, and is noted.

    Returns
    -------
    shapes : pa.Table or None
        The rows kept, with their ids.
    origins : list of (old id, new id, file)
        One per kept row.
    """
    claims: dict[int, list[tuple[Any, Any]]] = {}
    parts, origins = [], []
    next_free = floor
    for name, t in tables:
        keep, ids = [], []
        for sid, digest, made, label in zip(
            *(t.column(c).to_pylist() for c in ("id", "content_hash", "created_at", "name")),
            strict=True,
        ):
            held = claims.setdefault(int(sid), [])
            keep.append((digest, made) not in held)
            if not keep[-1]:
                continue
            new = int(sid) if not held else next_free
            if held:
                next_free += 1
                notes.append(
                    f"shape {label!r} in {name} claimed id {sid}, which an older row holds: "
                    f"both were kept, it is now id {new}"
                )
            held.append((digest, made))
            ids.append(new)
            origins.append((int(sid), new, name))
        t = t.filter(pa.array(keep, pa.bool_()))
        column = t.schema.get_field_index("id")
        parts.append(t.set_column(column, t.schema.field(column), pa.array(ids, pa.int64())))
    shapes = pa.concat_tables(parts, promote_options="permissive") if parts else None
    return shapes, origins


def _commit(file: str) -> str:
    """The commit version a segment's file name starts with."""
    return Path(file).name.split("-", 1)[0]


def _attach(
    tables: list[tuple[str, pa.Table]], origins: list[tuple[int, int, str]]
) -> tuple[pa.Table | None, list[str]]:
    """The balls (or edges) of each kept shape row, each from one segment, under its new id.

    A row takes them from a segment of its own commit when one holds its id, else from
    the newest segment holding its id that no other row claiming that id has taken.

    Returns
    -------
    rows : pa.Table or None
    used : list of str
        The segments rows were taken from.
    """
    holders: dict[int, list[int]] = {}
    for k, (_, t) in enumerate(tables):
        for sid in pc.unique(t.column("shape_id")).to_pylist():
            holders.setdefault(int(sid), []).append(k)
    taken: dict[int, set[int]] = collections.defaultdict(set)
    picks: dict[int, dict[int, int]] = collections.defaultdict(dict)
    placed: set[int] = set()
    for own_commit_only in (True, False):
        for old, new, origin in origins:
            free = [k for k in holders.get(old, []) if k not in taken[old]]
            if own_commit_only:
                free = [k for k in free if _commit(tables[k][0]) == _commit(origin)]
            if free and new not in placed:
                taken[old].add(free[-1])  # holders are oldest first
                picks[free[-1]][old] = new
                placed.add(new)
    parts = []
    for k, mapping in sorted(picks.items()):
        t = tables[k][1]
        old_ids = pa.array(list(mapping), pa.int64())
        t = t.filter(pc.is_in(t.column("shape_id"), old_ids))
        moved = pc.take(
            pa.array(list(mapping.values()), pa.int64()), pc.index_in(t.column("shape_id"), old_ids)
        )
        column = t.schema.get_field_index("shape_id")
        parts.append(t.set_column(column, t.schema.field(column), moved))
    rows = pa.concat_tables(parts, promote_options="permissive") if parts else None
    return rows, [tables[k][0] for k in sorted(picks)]


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
        The folder holds no store (neither ``manifest.json`` nor ``data/``; it is left
        untouched, no lock file is created), nothing to rebuild from (no readable
        shapes segment), or another writer holds the store.
    """
    root = Path(path).absolute()
    if not root.is_dir():
        raise StoreError("no such folder", source=str(root))
    if not (root / MANIFEST).exists() and not (root / DATA).is_dir():
        raise StoreError(
            "no shapedb store here (neither manifest.json nor data/): nothing to repair",
            source=str(root),
        )
    lock = FileLock(root / _LOCK)
    fresh = not lock.path.exists()
    lock.acquire(0.0, source=str(root))
    try:
        return _repair(root)
    except StoreError:
        if fresh and not (root / MANIFEST).exists():
            lock.path.unlink(missing_ok=True)  # refused: leave the folder as it was
        raise
    finally:
        lock.release()


def _repair(root: Path) -> RepairReport:
    lost: list[tuple[str, str]] = []
    notes: list[str] = []
    problem = None
    try:
        manifest: dict[str, Any] | None = read_manifest(root)
    except StoreError as exc:
        manifest = None
        problem = exc.reason.split(";")[0]
    if manifest is not None and check(root).ok:
        n = sum(int(s["rows"]) for s in manifest["tables"]["shapes"])
        return RepairReport(path=str(root), changed=False, shapes=n)
    found = {
        t: _readable(root, segs, lost, notes) for t, segs in _candidates(root, manifest).items()
    }
    # ids of replaced (deleted) rows count too: they are never given out again
    top = max([0, *(int(pc.max(t.column("id")).as_py()) for _, t in found["shapes"] if t.num_rows)])
    replaced = {f for tables in found.values() for _, t in tables for f in _replaces(t)}
    found = {t: [(n, x) for n, x in tables if n not in replaced] for t, tables in found.items()}
    config = _choose_config(manifest, found["shapes"])
    floor = max(int(manifest["next_id"]) if manifest is not None else 1, top + 1)
    if manifest is not None and int(manifest["next_id"]) <= top:
        notes.append(f"next_id {manifest['next_id']} was at or below the largest id {top}")
    shapes, origins = _assign_ids(_same_config(found["shapes"], config, lost), floor, notes)
    balls, used_b = _attach(found["balls"], origins)
    edges, used_e = _attach(found["edges"], origins)
    shapes = _drop_incomplete(shapes, balls, edges, lost)
    ids = set() if shapes is None else {int(i) for i in shapes.column("id").to_pylist()}
    keep = pa.array(sorted(ids), pa.int64())
    tables = {
        "shapes": shapes,
        "balls": None if balls is None else balls.filter(pc.is_in(balls.column("shape_id"), keep)),
        "edges": None if edges is None else edges.filter(pc.is_in(edges.column("shape_id"), keep)),
        "failures": found["failures"][-1][1] if found["failures"] else None,
    }
    base = dict(manifest) if manifest is not None else new_manifest(config)
    next_id = max([floor, *(i + 1 for i in ids)])
    moved = _rebuild(root, base, tables, config.dim, next_id)
    log.info("repaired store %s: %d shapes, %d lost", root, len(ids), len(lost))
    reassigned = tuple((old, new) for old, new, _ in origins if old != new and new in ids)
    return RepairReport(
        path=str(root),
        changed=True,
        manifest=problem,
        shapes=len(ids),
        recovered=tuple(sorted({f for _, _, f in origins} | set(used_b) | set(used_e))),
        lost=tuple(lost),
        moved_to=moved,
        reassigned=reassigned,
        notes=tuple(notes),
    )


def _rebuild(
    root: Path, base: dict[str, Any], tables: dict[str, pa.Table | None], dim: int, next_id: int
) -> str | None:
    """Commit ``tables`` as the whole store; move every earlier file aside; returns where."""
    base = dict(base, tables={t: [] for t in TABLES}, retired=[])
    for t in TABLES:  # a store whose data/ was lost gets its folders back
        (root / DATA / t).mkdir(parents=True, exist_ok=True)
    old = {p for p in (root / DATA).rglob("*") if p.is_file()}
    txn = Transaction(root, base)
    columns: dict[str, str | None] = {
        "shapes": "id",
        "balls": "shape_id",
        "edges": "shape_id",
        "failures": None,
    }
    for table, col in columns.items():
        rows = tables[table]
        if rows is not None and rows.num_rows:
            txn.tables[table].append(txn.stage(table, _conform(rows, table, dim), col))
    txn.publish(next_id=next_id)
    return _move_aside(root, old)


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
