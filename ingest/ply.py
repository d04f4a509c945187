"""Check a PLY file against its own header before a parser trusts it.

A PLY header announces its elements (``element vertex 8``) and their properties;
trimesh reads that many rows without checking that the file holds them, so a
truncated file or a corrupt count becomes a smaller or garbled mesh without a word.
:func:`check_ply` refuses such files with a :class:`~shapedb.errors.LoadError`
naming the reason:

* the header itself: the ``ply`` magic, a known format, integer counts, known
  property types, a vertex element with ``x``, ``y`` and ``z``, an ``end_header``;
* the size: the announced rows need at least so many bytes (checked before reading,
  so ``element vertex 2000000000`` costs nothing);
* ASCII bodies, row by row: each row has the values its properties call for, every
  value is a number, faces name existing vertices, and no row is missing or extra.

Binary bodies are checked for size here and by trimesh's own length check, and the
loader compares the vertices it got with the header's count (:func:`vertex_count`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import IO

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import LoadError

__all__ = ["PlyElement", "PlyHeader", "read_header", "check_ply"]

#: Bytes the header may take before ``end_header``; real headers take a few hundred.
MAX_HEADER_BYTES = 1 << 16

_SIZES = {
    "char": 1, "uchar": 1, "int8": 1, "uint8": 1,
    "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
    "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
    "double": 8, "float64": 8,
}  # fmt: skip
_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")
_FACE_LISTS = ("vertex_indices", "vertex_index")


@dataclass(frozen=True)
class PlyElement:
    """One ``element`` of a PLY header.

    ``properties`` holds ``(name, is_list)`` pairs; ``min_bytes`` is the least a row
    can take in the file's format (an empty list still stores its count).
    """

    name: str
    count: int
    properties: tuple[tuple[str, bool], ...]
    min_bytes: int


@dataclass(frozen=True)
class PlyHeader:
    """A parsed PLY header: format, elements in file order, and where the body starts."""

    format: str
    elements: tuple[PlyElement, ...]
    body_offset: int

    def count(self, name: str) -> int:
        """Rows announced for element ``name`` (0 when the file has no such element)."""
        return sum(e.count for e in self.elements if e.name == name)


def read_header(fh: IO[bytes]) -> PlyHeader:
    """Parse the header of the PLY file open at its start.

    Raises
    ------
    LoadError
        No ``ply`` magic, no ``end_header`` within :data:`MAX_HEADER_BYTES`, an
        unknown format or property type, a count that is not a non-negative integer,
        or no vertex element with x, y and z.
    """
    raw = fh.read(MAX_HEADER_BYTES)
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        where = "no 'ply' magic" if not raw.startswith(b"ply") else "no end_header"
        raise LoadError(f"not a valid PLY header: {where} in its first {len(raw)} bytes")
    eol = raw.find(b"\n", end)
    body_offset = len(raw) if eol < 0 else eol + 1
    try:
        lines = raw[:end].decode("ascii").splitlines()[1:]
    except UnicodeDecodeError:
        raise LoadError("the PLY header is not ASCII text") from None
    fmt, elements = _parse_lines(lines)
    vertex = next((e for e in elements if e.name == "vertex"), None)
    names = {n for n, _ in vertex.properties} if vertex is not None else set()
    if not {"x", "y", "z"} <= names:
        raise LoadError(
            f"the PLY has no vertex element with x, y and z properties (it has {sorted(names)})"
        )
    return PlyHeader(fmt, tuple(elements), body_offset)


def _parse_lines(lines: list[str]) -> tuple[str, list[PlyElement]]:
    fmt = ""
    elements: list[PlyElement] = []
    current: tuple[str, int, list[tuple[str, bool]], int] | None = None
    for k, line in enumerate(lines, 2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2 and words[1] in _FORMATS:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            if current is not None:
                elements.append(_element(*current))
            current = (words[1], int(words[2]), [], 0)
        elif words[0] == "property" and current is not None and _known_property(words):
            name, count, props, size = current
            is_list = words[1] == "list"
            props.append((words[-1], is_list))
            step = 2 if fmt == "ascii" else _SIZES[words[2] if is_list else words[1]]
            current = (name, count, props, size + step)
        else:
            raise LoadError(f"PLY header line {k} is not valid: {line[:60]!r}")
    if current is not None:
        elements.append(_element(*current))
    if not fmt:
        raise LoadError("the PLY header has no valid 'format' line")
    return fmt, elements


def _known_property(words: list[str]) -> bool:
    if len(words) == 3:
        return words[1] in _SIZES
    return len(words) == 5 and words[1] == "list" and words[2] in _SIZES and words[3] in _SIZES


def _element(name: str, count: int, props: list[tuple[str, bool]], size: int) -> PlyElement:
    return PlyElement(name, count, tuple(props), size)


def check_ply(path: str | os.PathLike[str], size: int, max_faces: int | None = None) -> PlyHeader:
    """Refuse a PLY file whose body cannot hold, or does not hold, what its header says.

    Parameters
    ----------
    path : str or Path
        The file.
    size : int
        Its size in bytes.
    max_faces : int, optional
        Refuse a header announcing more faces.

    Returns
    -------
    PlyHeader

    Raises
    ------
    LoadError
        A bad header; more faces than ``max_faces``; counts that need more bytes than
        the file has; an ASCII row with the wrong number of values, a value that is
        not a number, a face naming a vertex the file does not have, a missing row
        or data after the last announced row.
    """
    with open(path, "rb") as fh:
        header = read_header(fh)
        n_faces = header.count("face")
        if max_faces is not None and n_faces > max_faces:
            raise LoadError(
                f"the PLY header announces {n_faces} faces, above the cap max_faces={max_faces}"
            )
        body = size - header.body_offset
        need = sum(e.count * e.min_bytes for e in header.elements)
        if need > body:
            counts = ", ".join(f"{e.count} {e.name}" for e in header.elements)
            raise LoadError(
                f"truncated or corrupt counts: the header announces {counts} rows, which "
                f"need at least {need} bytes; the file has {body} after its header"
            )
        if header.format == "ascii":
            fh.seek(header.body_offset)
            _check_ascii_body(fh, header)
    return header


def _check_ascii_body(fh: IO[bytes], header: PlyHeader) -> None:
    first = header.body_offset  # line numbers: count the header's lines
    fh.seek(0)
    first_line = fh.read(first).count(b"\n") + 1
    lines = fh.read().split(b"\n")
    n_vertices = header.count("vertex")
    at = 0
    for element in header.elements:
        rows = [line.split() for line in lines[at : at + element.count]]
        if len(rows) < element.count:
            raise LoadError(
                f"truncated: the header announces {element.count} {element.name} rows, "
                f"the file ends after {len(rows)}"
            )
        if not _rows_look_right(rows, element, n_vertices):  # say which row, and why
            for r, tokens in enumerate(rows):
                _check_row(first_line + at + r, tokens, element, n_vertices)
        at += element.count
    for r, line in enumerate(lines[at:]):
        if line.strip():
            raise LoadError(f"line {first_line + at + r}: data after the last row announced")


def _rows_look_right(rows: list[list[bytes]], element: PlyElement, n_vertices: int) -> bool:
    """Vectorised check of the common elements: numbers only, or one list of indices.

    False when a row is wrong, or when the element has another layout (the caller
    then checks row by row, which also says which row is wrong).
    """
    props = element.properties
    if not rows:
        return True
    if all(not is_list for _, is_list in props):
        if any(len(t) != len(props) for t in rows):
            return False
        return _numbers([x for t in rows for x in t]) is not None
    if len(props) != 1:
        return False
    lengths = np.fromiter((len(t) for t in rows), dtype=np.int64, count=len(rows))
    values = _numbers([x for t in rows for x in t])
    if values is None or not np.all(lengths > 0):
        return False
    starts = np.concatenate(([0], np.cumsum(lengths)[:-1]))
    counts = values[starts]
    if not np.array_equal(counts, lengths - 1):
        return False
    items = np.delete(values, starts)
    if props[0][0] in _FACE_LISTS:
        return bool(np.all((items >= 0) & (items < n_vertices) & (items == np.round(items))))
    return True


def _numbers(tokens: list[bytes]) -> NDArray[np.float64] | None:
    """The tokens as floats, or None when one is not a number."""
    try:
        return np.array(tokens, dtype=np.bytes_).astype(np.float64)
    except ValueError:
        return None


def _check_row(k: int, tokens: list[bytes], element: PlyElement, n_vertices: int) -> None:
    at = 0
    try:
        for name, is_list in element.properties:
            if not is_list:
                float(tokens[at])
                at += 1
                continue
            n = int(tokens[at])
            floats = [float(t) for t in tokens[at + 1 : at + 1 + n]]
            if n < 0 or len(floats) != n:
                raise IndexError
            if name in _FACE_LISTS and not all(v.is_integer() for v in floats):
                raise ValueError
            values = [int(v) for v in floats]
            if name in _FACE_LISTS and any(v < 0 or v >= n_vertices for v in values):
                raise LoadError(
                    f"line {k}: face names vertices {values[:6]} but the file has "
                    f"{n_vertices} vertices (0-based)"
                )
            at += 1 + n
    except IndexError:
        raise LoadError(
            f"line {k}: a {element.name} row has too few values: {b' '.join(tokens)[:60]!r}"
        ) from None
    except (ValueError, OverflowError):
        raise LoadError(
            f"line {k}: a {element.name} row holds a value that is not a number "
            f"(or an index that is not an integer): "
            f"{b' '.join(tokens)[:60]!r}"
        ) from None
    if at != len(tokens):
        raise LoadError(
            f"line {k}: a {element.name} row has {len(tokens)} values, its properties take {at}"
        )
