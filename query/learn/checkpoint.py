"""The selection checkpoint: validation folds already scored, so a second run continues.

A small JSON file next to the classifier file (``<out>.selection.json``) holds,
per candidate, the (correct, total, seconds) of every validation fold it finished,
under a key: a hash of the store (path, version,
configuration fingerprint), the label and every setting of the selection. A run
with another key ignores the file and starts afresh (then overwrites it).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from pathlib import Path
from typing import Any

__all__ = ["Checkpoint", "checkpoint_path", "FoldScore"]

log = logging.getLogger(__name__)

FORMAT = "shapedb.selection-checkpoint/1"
FoldScore = tuple[int, int, float]
"""(correct, total, seconds) of one validation fold."""


def checkpoint_path(out: str | os.PathLike[str]) -> Path:
    """Where the checkpoint of a classifier written to ``out`` lives."""
    return Path(f"{os.fspath(out)}.selection.json")


class Checkpoint:
    """Finished validation folds of the candidates, read from and written to ``path``.

    Parameters
    ----------
    path : path or None
        The JSON file; None keeps the checkpoint in memory only.
    key : dict
        JSON-ready settings the scores depend on (store version, label, folds, ...);
        a file written under another key is ignored.
    """

    def __init__(self, path: str | os.PathLike[str] | None, key: dict[str, Any]) -> None:
        self.path = None if path is None else Path(path)
        text = json.dumps(key, sort_keys=True, default=str)
        self.key = hashlib.sha256(text.encode()).hexdigest()[:16]
        self.settings = json.loads(text)
        self.folds: dict[str, list[FoldScore]] = {}
        self._read()

    def _read(self) -> None:
        if self.path is None or not self.path.is_file():
            return
        try:
            data = json.loads(self.path.read_text())
        except (OSError, ValueError) as exc:
            log.warning("ignoring the unreadable selection checkpoint %s: %s", self.path, exc)
            return
        if data.get("format") != FORMAT or data.get("key") != self.key:
            log.info("the selection checkpoint %s is of other settings: starting afresh", self.path)
            return
        for name, entry in dict(data.get("candidates", {})).items():
            self.folds[name] = [(int(c), int(t), float(s)) for c, t, s in entry.get("folds", [])]
        if self.folds:
            log.info("continuing from %s: %s", self.path, ", ".join(sorted(self.folds)))

    def done(self, name: str) -> list[FoldScore]:
        """The folds of ``name`` finished so far (in fold order)."""
        return list(self.folds.get(name, []))

    def add_fold(self, name: str, score: FoldScore) -> None:
        """Record the next finished fold of ``name`` and write the file."""
        self.folds.setdefault(name, []).append(score)
        self._write()

    def _write(self) -> None:
        if self.path is None:
            return
        data = {
            "format": FORMAT,
            "key": self.key,
            "settings": self.settings,
            "candidates": {n: {"folds": f} for n, f in sorted(self.folds.items())},
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(self.path.name + ".tmp")
        tmp.write_text(json.dumps(data, indent=1))
        os.replace(tmp, self.path)
