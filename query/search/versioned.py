"""Atomic, versioned directories for derived state kept beside a store (indexes).

Layout under ``root``: one sub-directory per saved version, written completely under
a temporary name and renamed into place, and a pointer file ``current.json`` (the
metadata, with ``dir`` naming the live sub-directory) swapped with :func:`os.replace`.
Readers follow the pointer, so they never see a half-written version; superseded
versions and temporary directories of dead writers are removed after the swap.
"""

from __future__ import annotations

import json
import os
import shutil
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

POINTER = "current.json"
_STALE_SECONDS = 3600


def save_version(
    root: str | os.PathLike[str],
    write: Callable[[Path], None],
    meta: dict[str, Any],
    *,
    version: int | None,
) -> Path:
    """Write a new version with ``write(directory)`` and point ``current.json`` at it.

    Parameters
    ----------
    root : path
        The versioned directory (created if missing).
    write : callable
        Fills the fresh sub-directory it is given.
    meta : dict
        JSON-serialisable metadata stored in the pointer; ``dir`` is added.
    version : int or None
        Store version the content reflects (part of the sub-directory's name).

    Returns
    -------
    Path
        The live sub-directory.
    """
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    name = f"v{version if version is not None else 'x'}-{uuid.uuid4().hex[:12]}"
    tmp = root / f".tmp-{name}"
    tmp.mkdir()
    write(tmp)
    os.replace(tmp, root / name)
    ptmp = root / f".{POINTER}.{uuid.uuid4().hex[:8]}"
    ptmp.write_text(json.dumps({**meta, "dir": name}, indent=1))
    os.replace(ptmp, root / POINTER)
    for old in root.iterdir():  # superseded versions, and temp dirs of dead writers
        try:
            age = time.time() - old.stat().st_mtime
        except FileNotFoundError:  # another process renamed or removed it meanwhile
            continue
        stale = old.name.startswith(".tmp-") and age > _STALE_SECONDS
        if old.is_dir() and old.name != name and (old.name.startswith("v") or stale):
            shutil.rmtree(old, ignore_errors=True)
    return root / name


def current(root: str | os.PathLike[str]) -> tuple[dict[str, Any], Path]:
    """The metadata of the live version and its sub-directory (OSError/ValueError if bad)."""
    root = Path(root)
    meta = json.loads((root / POINTER).read_text())
    return meta, root / meta["dir"]
