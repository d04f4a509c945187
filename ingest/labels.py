"""Labels and metadata for ingested files: from a CSV, or from folder names.

A labels CSV has a header with a ``path`` column, usually a ``label`` column, and
any other columns, which are kept as string metadata::

    path,label,author
    chairs/c1.obj,chair,alice
    /abs/path/t7.ply,table,bob

Relative paths are relative to the CSV's folder. A file is matched by its absolute
path, or failing that by the longest CSV path that is a suffix of it (so a CSV
written for ``capod/`` still matches when the folder is given another way).
"""

from __future__ import annotations

import csv
import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from shapedb.errors import ConfigError, LoadError

log = logging.getLogger(__name__)

__all__ = ["LabelEntry", "LabelTable", "read_labels", "folder_label", "summarise_matches"]


@dataclass(frozen=True)
class LabelEntry:
    """Label and extra metadata of one file."""

    label: str | None
    metadata: Mapping[str, str] = field(default_factory=dict)


class LabelTable:
    """Lookup of :class:`LabelEntry` by file path.

    Parameters
    ----------
    entries : mapping of path -> LabelEntry
        Absolute paths, or paths relative to ``root``.
    root : str or Path, optional
        Folder that relative paths are relative to (the CSV's folder).
    source : str, optional
        Where the table came from (the CSV's path), for messages.
    """

    def __init__(
        self,
        entries: Mapping[str, LabelEntry] | Mapping[str | os.PathLike[str], LabelEntry],
        *,
        root: str | os.PathLike[str] | None = None,
        source: str | None = None,
    ) -> None:
        base = Path(root or ".").absolute()
        self.source = source
        self._entries: dict[str, LabelEntry] = {str(k): v for k, v in entries.items()}
        self._exact: dict[str, str] = {}
        self._suffix: dict[tuple[str, ...], str] = {}
        for key in self._entries:
            p = Path(key)
            full = p if p.is_absolute() else base / p
            self._exact[os.path.normpath(full)] = key
            parts = tuple(x for x in Path(os.path.normpath(key)).parts if x not in ("/", "."))
            self._suffix[parts] = key

    def __len__(self) -> int:
        return len(self._exact)

    def keys(self) -> list[str]:
        """The paths the table lists, as written (in the CSV's order)."""
        return list(self._entries)

    def match(self, path: str | os.PathLike[str]) -> str | None:
        """The table's key for ``path`` (as written in the CSV), or None when it has none."""
        full = os.path.normpath(Path(path).absolute())
        if full in self._exact:
            return self._exact[full]
        parts = Path(full).parts
        for k in range(max(len(parts) - 1, 1), 0, -1):
            hit = self._suffix.get(parts[-k:])
            if hit is not None:
                return hit
        return None

    def lookup(self, path: str | os.PathLike[str]) -> LabelEntry | None:
        """The entry of ``path``, or None when the table does not list it."""
        key = self.match(path)
        return None if key is None else self._entries[key]

    @classmethod
    def from_mapping(cls, labels: Mapping[str, str]) -> LabelTable:
        """A table from ``{path: label}``."""
        return cls({k: LabelEntry(v) for k, v in labels.items()})


def read_labels(path: str | os.PathLike[str]) -> LabelTable:
    """Read a labels CSV (``path,label,...``; extra columns become metadata).

    Raises
    ------
    LoadError
        The file is missing, has no ``path`` column, or a row has no path.
    """
    src = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.DictReader(fh)
            header = [h.strip() for h in (reader.fieldnames or [])]
            lower = {h.lower(): h for h in header}
            if "path" not in lower:
                raise LoadError(f"labels CSV needs a 'path' column; header is {header}", source=src)
            pcol, lcol = lower["path"], lower.get("label")
            entries: dict[str, LabelEntry] = {}
            for k, raw in enumerate(reader, start=2):
                row = {
                    (a or "").strip(): (b or "").strip()
                    for a, b in raw.items()
                    if a is not None and not isinstance(b, list)
                }
                if not row.get(pcol):
                    raise LoadError(f"row {k} has no path", source=src)
                meta = {a: b for a, b in row.items() if a not in (pcol, lcol) and b != ""}
                entries[row[pcol]] = LabelEntry(row.get(lcol) or None if lcol else None, meta)
    except OSError as exc:
        if isinstance(exc, LoadError):
            raise
        raise LoadError(f"cannot read labels CSV: {exc.strerror or exc}", source=src) from exc
    except (csv.Error, UnicodeDecodeError) as exc:
        raise LoadError(f"malformed labels CSV: {exc}", source=src) from exc
    return LabelTable(entries, root=Path(path).absolute().parent, source=src)


def folder_label(path: str | os.PathLike[str]) -> str | None:
    """The label a file gets from its folder: the name of its parent directory."""
    parent = Path(path).absolute().parent.name
    return parent or None


def summarise_matches(
    table: LabelTable, looked_up: int, matched: set[str], unlabelled: list[str]
) -> int:
    """Check how a label table matched the inputs; return how many inputs it labelled.

    Logs the count; when some inputs matched, warns naming the table's paths that
    matched no input, and the inputs the table does not list.

    Raises
    ------
    ConfigError
        The table matched none of the ``looked_up`` (> 0) inputs.
    """
    where = f"labels {table.source}" if table.source else "labels"
    n = looked_up - len(unlabelled)
    if looked_up and not n:
        keys = table.keys()
        raise ConfigError(
            f"the {where} match none of the {looked_up} inputs (e.g. {keys[0]!r} vs "
            f"{unlabelled[0]!r}); CSV paths are relative to the CSV's folder",
            source=table.source,
        )
    log.info("%s: %d of %d inputs labelled", where, n, looked_up)
    unused = [k for k in table.keys() if k not in matched]
    if n and unused:
        log.warning("%s: %d path(s) matched no input: %s", where, len(unused), _some(unused))
    if n and unlabelled:
        log.warning("%s: %d input(s) are not listed: %s", where, len(unlabelled), _some(unlabelled))
    return n


def _some(names: list[str], k: int = 5) -> str:
    shown = ", ".join(repr(x) for x in names[:k])
    return shown + (f" and {len(names) - k} more" if len(names) > k else "")
