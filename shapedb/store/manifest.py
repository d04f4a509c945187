"""The store's manifest: creating it, reading it, and refusing one that is damaged.

The manifest (``DIR/manifest.json``, see ``docs/store.md``) is the only source of
truth of a store. It is never inferred from what is on disk: a folder whose manifest
is missing, unreadable or incomplete is reported as such (:class:`StoreError` naming
what is wrong and how to recover, ``shapedb repair --db DIR``), and nothing in it is
touched until it is repaired.
"""

from __future__ import annotations

import json
import time
import uuid
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq

from shapedb.config.core import Config
from shapedb.errors import StoreError
from shapedb.store.schema import SCHEMA_VERSION, TABLES

__all__ = [
    "FORMAT_VERSION",
    "MANIFEST",
    "DATA",
    "new_manifest",
    "read_manifest",
    "validate_manifest",
    "repair_hint",
    "require_empty",
    "check_sizes",
    "unreadable",
]

FORMAT_VERSION = 1
"""Version of the directory layout and manifest format."""

MANIFEST = "manifest.json"
DATA = "data"

_REQUIRED: dict[str, type | tuple[type, ...]] = {
    "format": str,
    "format_version": int,
    "version": int,
    "next_id": int,
    "config": dict,
    "dim": int,
    "tables": dict,
}


def repair_hint(root: Path) -> str:
    """The recovery advice appended to every damaged-store message."""
    return f"`shapedb check --db {root}` lists the damage; `shapedb repair --db {root}` rebuilds the manifest from the intact segments"


def new_manifest(config: Config) -> dict[str, Any]:
    """The manifest of an empty store built with ``config`` (version 0, a fresh store id)."""
    now = time.time()
    return {
        "format": "shapedb-store",
        "format_version": FORMAT_VERSION,
        "schema_version": SCHEMA_VERSION,
        "store_id": uuid.uuid4().hex,
        "version": 0,
        "next_id": 1,
        "created_at": now,
        "updated_at": now,
        "config": config.to_dict(),
        "config_fingerprint": config.fingerprint,
        "dim": config.dim,
        "tables": {t: [] for t in TABLES},
        "retired": [],
    }


def read_manifest(root: Path) -> dict[str, Any]:
    """Read and validate ``root/manifest.json``.

    Raises
    ------
    StoreError
        No manifest (the message says whether the folder holds data, and how to
        recover), unreadable, not JSON, not a shapedb manifest, an unsupported format
        version, or a key missing or of the wrong type.
    """
    path = root / MANIFEST
    try:
        text = path.read_text()
    except FileNotFoundError:
        if (root / DATA).is_dir():
            raise StoreError(
                "manifest.json is missing but the folder holds data/: the store's "
                f"manifest was lost; nothing was changed; {repair_hint(root)}",
                source=str(root),
            ) from None
        raise StoreError(
            "no shapedb store here (manifest.json missing)", source=str(root)
        ) from None
    except OSError as exc:
        raise StoreError(f"cannot read manifest.json: {exc}", source=str(root)) from exc
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise StoreError(
            f"manifest.json is not valid JSON ({exc}); {repair_hint(root)}", source=str(root)
        ) from exc
    validate_manifest(data, root)
    return data  # type: ignore[no-any-return]


def validate_manifest(data: Any, root: Path) -> None:
    """Check the keys, types and segment entries of a parsed manifest.

    Raises
    ------
    StoreError
        The first problem found, with :func:`repair_hint`.
    """
    if not isinstance(data, dict) or data.get("format") != "shapedb-store":
        raise StoreError("manifest.json is not a shapedb manifest", source=str(root))
    if data.get("format_version") != FORMAT_VERSION:
        raise StoreError(
            f"store format version {data.get('format_version')} is not supported "
            f"(this shapedb reads version {FORMAT_VERSION})",
            source=str(root),
        )

    def bad(what: str) -> StoreError:
        return StoreError(
            f"manifest.json is damaged: {what}; {repair_hint(root)}", source=str(root)
        )

    for key, kind in _REQUIRED.items():
        if key not in data:
            raise bad(f"key {key!r} is missing")
        if not isinstance(data[key], kind) or isinstance(data[key], bool):
            raise bad(f"key {key!r} is a {type(data[key]).__name__}")
    try:
        Config.from_dict(data["config"])
    except Exception as exc:  # any malformed configuration
        raise bad(f"its configuration cannot be read ({exc})") from exc
    for table in TABLES:
        segments = data["tables"].get(table)
        if not isinstance(segments, list):
            raise bad(f"table {table!r} is missing")
        for seg in segments:
            if (
                not isinstance(seg, dict)
                or not isinstance(seg.get("file"), str)
                or not seg["file"].startswith(f"{DATA}/{table}/")
                or ".." in seg["file"]
                or not isinstance(seg.get("rows"), int)
            ):
                raise bad(f"a segment entry of {table!r} is malformed ({seg!r:.80})")
    retired = data.get("retired", [])
    if not isinstance(retired, list) or not all(
        isinstance(r, dict) and isinstance(r.get("file"), str) and "since" in r for r in retired
    ):
        raise bad("key 'retired' is malformed")


def require_empty(root: Path, *, ignore: tuple[str, ...] = ()) -> None:
    """Refuse to create a store anywhere but in a missing or empty folder.

    Raises
    ------
    StoreError
        A store is already there, the folder holds ``data/`` but no valid manifest
        (with :func:`repair_hint`), or it holds anything else (names in ``ignore``
        apart).
    """
    if not root.is_dir():
        return
    if (root / MANIFEST).exists():
        raise StoreError("a store already exists here", source=str(root))
    entries = sorted(p.name for p in root.iterdir() if p.name not in ignore)
    if DATA in entries or (
        DATA in ignore and (root / DATA).is_dir() and any((root / DATA).rglob("*.parquet"))
    ):
        read_manifest(root)  # raises: data/ without a manifest names the way to repair
    if entries:
        raise StoreError(
            f"the folder is not empty ({', '.join(entries[:3])}{', ...' if len(entries) > 3 else ''}) "
            "and holds no shapedb store: create a store in a new or empty folder",
            source=str(root),
        )


def check_sizes(root: Path, segments: list[dict[str, Any]], *, missing: bool = False) -> None:
    """StoreError naming the first segment whose size differs from the manifest's record.

    A missing file raises FileNotFoundError (a writer may have just retired it), or a
    StoreError when ``missing`` (the manifest was re-read and still lists it).
    """
    for seg in segments:
        path = root / seg["file"]
        try:
            size = path.stat().st_size
        except FileNotFoundError:
            if missing:
                raise StoreError(
                    f"segment {seg['file']} is missing; {repair_hint(root)}", source=str(root)
                ) from None
            raise
        if "bytes" in seg and size != int(seg["bytes"]):
            raise StoreError(
                f"segment {seg['file']} is damaged: {size} bytes, the manifest records "
                f"{seg['bytes']}; {repair_hint(root)}",
                source=str(root),
            )


def unreadable(root: Path, segments: list[dict[str, Any]], exc: BaseException) -> StoreError:
    """A StoreError naming the segment that cannot be read (the first, when none alone fails)."""
    culprit = segments[0]["file"] if segments else "?"
    for seg in segments:
        try:
            pq.read_table(root / seg["file"], page_checksum_verification=True)
        except Exception:  # any unreadable file
            culprit = seg["file"]
            break
    reason = " ".join(str(exc).split())[:160]
    return StoreError(
        f"segment {culprit} cannot be read ({type(exc).__name__}: {reason}); {repair_hint(root)}",
        source=str(root),
    )
