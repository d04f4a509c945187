"""The outcome of every input of an ingest, from which its report is built.

Each input given to an ingest ends in exactly one outcome: ``stored`` (with its id),
``unchanged`` (its content is already stored), ``failed`` (with the reason) or, for
what walking a folder leaves out, ``ignored`` (with why). :class:`Ledger` records
them as they happen, in any order, and refuses a second outcome for one input.
"""

from __future__ import annotations

from shapedb.results import IngestReport
from shapedb.store.schema import safe_text

__all__ = ["Ledger"]


class Ledger:
    """Outcomes of one ingest's inputs, keyed by their index in the input list."""

    def __init__(self) -> None:
        self._rows: dict[int, tuple[str, str, str]] = {}
        self._ids: dict[int, int] = {}
        self._ignored: list[tuple[str, str]] = []

    def _set(self, index: int, source: str, outcome: str, detail: str) -> None:
        assert index not in self._rows, f"input {index} ({source}) has two outcomes"
        self._rows[index] = (safe_text(source), outcome, safe_text(detail))

    def stored(self, index: int, source: str, shape_id: int) -> None:
        """Input ``index`` was stored as shape ``shape_id``."""
        self._set(index, source, "stored", str(shape_id))
        self._ids[index] = shape_id

    def unchanged(self, index: int, source: str, why: str) -> None:
        """Input ``index`` has content already stored."""
        self._set(index, source, "unchanged", why)

    def failed(self, index: int, source: str, reason: str) -> None:
        """Input ``index`` could not be ingested."""
        self._set(index, source, "failed", reason)

    def ignore(self, path: str, why: str) -> None:
        """``path``, found by walking a folder, is not an input."""
        self._ignored.append((safe_text(path), safe_text(why)))

    def __len__(self) -> int:
        return len(self._rows)

    def report(
        self, seconds: float, notes: list[tuple[str, str]], labels_matched: int | None
    ) -> IngestReport:
        """The report of the inputs recorded so far (in input order), and these extras."""
        rows = [self._rows[k] for k in sorted(self._rows)]
        return IngestReport(
            ingested=tuple(self._ids[k] for k in sorted(self._ids)),
            skipped=tuple(s for s, o, _ in rows if o == "unchanged"),
            failed=tuple((s, d) for s, o, d in rows if o == "failed"),
            seconds=seconds,
            notes=tuple(notes),
            ignored=tuple(self._ignored),
            outcomes=tuple(rows) + tuple((p, "ignored", w) for p, w in self._ignored),
            labels_matched=labels_matched,
        )
