"""Row arrays kept as a list of chunks, saved without rewriting the chunks already on disk.

A part index grows by one chunk of rows per commit (the new shapes' features, contact
edges and faiss codes). :class:`RowChunks` reads its rows across the chunks (a gather
per chunk) and writes itself into a new version directory: a chunk already on disk (a
memory-mapped ``.npy``) is hard-linked there, never rewritten, and only the last chunks
are merged while the earlier is at most twice the later's size (a binary counter: O(log
n) chunks, each row copied O(log n) times over the life of the index). After
:meth:`RowChunks.save` the chunks are the saved files, memory-mapped read only.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["RowChunks", "merge_plan"]


def merge_plan(sizes: list[int]) -> list[list[int]]:
    """Groups of consecutive chunks written as one: the last two merge while the earlier
    is at most twice the later's size."""
    groups: list[list[int]] = []
    rows: list[int] = []
    for i, n in enumerate(sizes):
        groups.append([i])
        rows.append(n)
        while len(rows) >= 2 and rows[-2] <= 2 * rows[-1]:
            groups[-2:] = [groups[-2] + groups[-1]]
            rows[-2:] = [rows[-2] + rows[-1]]
    return groups


class RowChunks:
    """Rows ``(n, *tail)`` of one dtype held as consecutive chunks (arrays or memmaps).

    Parameters
    ----------
    dtype : numpy dtype
        Dtype of every chunk.
    tail : tuple of int
        Shape of one row.
    chunks : list of arrays, optional
        Initial chunks, each ``(r_k, *tail)``.
    """

    def __init__(
        self, dtype: np.dtype | type, tail: tuple[int, ...], chunks: list[NDArray] | None = None
    ) -> None:
        self.dtype = np.dtype(dtype)
        self.tail = tuple(int(t) for t in tail)
        self.chunks: list[NDArray] = []
        self.starts = np.zeros(1, np.int64)
        for c in chunks or []:
            self.append(c)

    def append(self, rows: ArrayLike) -> None:
        """Add one chunk (converted to this dtype; an empty one is skipped)."""
        a = np.asanyarray(rows)
        if a.dtype != self.dtype:
            a = a.astype(self.dtype)
        if a.shape[1:] != self.tail:  # a memmap of the right shape stays one (linkable)
            a = a.reshape((-1, *self.tail))
        if len(a):
            self.chunks.append(a)
            self.starts = np.r_[self.starts, self.starts[-1] + len(a)]

    def __len__(self) -> int:
        return int(self.starts[-1])

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self), *self.tail)

    def take(self, pos: ArrayLike) -> NDArray:
        """Rows at positions ``pos`` (any order, in range), as one in-memory array."""
        p = np.asarray(pos, np.int64).ravel()
        out = np.empty((len(p), *self.tail), self.dtype)
        which = np.searchsorted(self.starts, p, side="right") - 1
        for k in np.unique(which):
            at = which == k
            local = p[at] - self.starts[k]
            if np.all(local[1:] >= local[:-1]):  # sorted: a forward read of the memmap
                out[at] = self.chunks[k][local]
            else:
                o = np.argsort(local, kind="stable")
                sub = np.empty_like(out[at])
                sub[o] = self.chunks[k][local[o]]
                out[at] = sub
        return out

    def __getitem__(self, key: int | slice | ArrayLike) -> NDArray:
        if isinstance(key, (int, np.integer)):
            i = int(key) + (len(self) if int(key) < 0 else 0)
            if not 0 <= i < len(self):
                raise IndexError(f"row {key} of {len(self)}")
            return self.take([i])[0]
        if isinstance(key, slice):
            return self.take(np.arange(*key.indices(len(self))))
        return self.take(key)

    def __array__(self, dtype: np.dtype | None = None, copy: bool | None = None) -> NDArray:
        out = np.concatenate(self.chunks) if self.chunks else np.zeros((0, *self.tail), self.dtype)
        return out if dtype is None else out.astype(dtype)

    def spill(self, directory: Path) -> None:
        """Write the chunks held in memory to new files under ``directory`` and map them
        read only instead (a build then holds one batch of rows in memory)."""
        for k, c in enumerate(self.chunks):
            if not isinstance(c, np.memmap):
                target = directory / f"spill-{uuid.uuid4().hex}.npy"
                np.save(target, c)
                self.chunks[k] = np.load(target, mmap_mode="r")

    def select(self, pos: NDArray[np.int64]) -> RowChunks:
        """A new single-chunk RowChunks of the rows at ``pos`` (compaction)."""
        return RowChunks(self.dtype, self.tail, [self.take(pos)])

    def save(self, directory: Path, prefix: str) -> list[int]:
        """Write ``<prefix>-<k>.npy`` files under ``directory``; returns their row counts.

        Chunks already on disk are hard-linked (copied where links fail); the last ones
        are merged (:func:`merge_plan`).
        """
        plan = merge_plan([len(c) for c in self.chunks])
        for k, group in enumerate(plan):
            _write(directory / f"{prefix}-{k}.npy", [self.chunks[i] for i in group])
        return [int(sum(len(self.chunks[i]) for i in g)) for g in plan]

    @classmethod
    def load(
        cls,
        directory: Path,
        prefix: str,
        sizes: list[int],
        dtype: np.dtype | type,
        tail: tuple[int, ...],
    ) -> RowChunks:
        """The chunks :meth:`save` wrote, memory-mapped read only (ValueError if they
        disagree with ``sizes``, ``dtype`` or ``tail``)."""
        out = cls(dtype, tail)
        for k, n in enumerate(sizes):
            a = np.load(directory / f"{prefix}-{k}.npy", mmap_mode="r")
            if a.shape != (n, *out.tail) or a.dtype != out.dtype:
                raise ValueError(f"{prefix}-{k}.npy holds {a.shape} {a.dtype}")
            out.append(a)
        return out


def _write(target: Path, parts: list[NDArray]) -> None:
    """One chunk file of ``parts``; a single part that is a file on disk is hard-linked."""
    if len(parts) == 1 and isinstance(parts[0], np.memmap) and parts[0].filename:
        try:
            os.link(parts[0].filename, target)
            return
        except OSError:
            pass  # another filesystem, or the file was superseded meanwhile: copy it
    ends = np.cumsum([len(p) for p in parts])
    shape = (int(ends[-1]), *parts[0].shape[1:])
    out = np.lib.format.open_memmap(target, mode="w+", dtype=parts[0].dtype, shape=shape)
    for p, end in zip(parts, ends, strict=True):  # written through the map, chunk by chunk
        out[end - len(p) : end] = p
    out.flush()
    del out
