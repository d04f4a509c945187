"""CAD B-rep solids (STEP, IGES, BREP) through the optional ``cad`` extra (gmsh).

The solid is read with gmsh's OpenCASCADE kernel and its boundary tessellated
finely (element size a fraction of the bounding-box diagonal, refined with the
curvature), then handled as a :class:`TessellatedSolid`, a triangle mesh that
remembers it came from a B-rep (``representation == "brep"``).
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from shapedb.errors import EmptyGeometryError, LoadError, require
from shapedb.geometry.mesh import TriangleMesh

__all__ = ["load_cad", "TessellatedSolid"]

_GMSH_LOCK = threading.Lock()  # gmsh keeps global state: one model at a time per process

#: Element size as a fraction of the bounding-box diagonal.
DEFAULT_SIZE_FRACTION = 0.01


class TessellatedSolid(TriangleMesh):
    """A triangle mesh obtained by tessellating a CAD B-rep solid finely."""

    representation = "brep"


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence OpenCASCADE, which writes to the C-level stdout directly."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # pragma: no cover - captured stdout
        yield
        return
    sys.stdout.flush()
    saved = os.dup(fd)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)


def load_cad(
    path: str | os.PathLike[str], *, size_fraction: float = DEFAULT_SIZE_FRACTION
) -> TessellatedSolid:
    """Read a STEP / IGES / BREP file and tessellate its boundary.

    Parameters
    ----------
    path : str or Path
        The CAD file.
    size_fraction : float
        Largest triangle edge, as a fraction of the bounding-box diagonal.

    Raises
    ------
    MissingDependencyError
        gmsh is not installed (``pip install 'shapedb[cad]'``).
    LoadError
        The file cannot be read, or holds no surface.
    """
    gmsh = require("gmsh", extra="cad", feature="reading CAD files (STEP, IGES, BREP)")
    src = str(Path(path))
    with _GMSH_LOCK, _quiet_stdout():
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setNumber("General.Verbosity", 0)
            gmsh.model.add("shapedb")
            try:
                gmsh.model.occ.importShapes(src)
                gmsh.model.occ.synchronize()
            except Exception as exc:
                raise LoadError(f"cannot read the CAD file: {exc}", source=src) from exc
            if not gmsh.model.getEntities(2):
                raise EmptyGeometryError("the CAD file holds no surface or solid", source=src)
            lo = np.array(gmsh.model.getBoundingBox(-1, -1)[:3])
            hi = np.array(gmsh.model.getBoundingBox(-1, -1)[3:])
            diag = float(np.linalg.norm(hi - lo))
            gmsh.option.setNumber("Mesh.MeshSizeMax", max(diag * size_fraction, 1e-12))
            gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 24)
            gmsh.option.setNumber("Mesh.Algorithm", 6)
            try:
                gmsh.model.mesh.generate(2)
            except Exception as exc:
                raise LoadError(f"cannot tessellate the CAD solid: {exc}", source=src) from exc
            tags, coords, _ = gmsh.model.mesh.getNodes()
            types, _, nodes = gmsh.model.mesh.getElements(2)
        finally:
            gmsh.finalize()
    faces = [
        np.asarray(n, dtype=np.int64).reshape(-1, 3)
        for t, n in zip(types, nodes, strict=True)
        if t == 2
    ]
    if not faces or not len(tags):
        raise EmptyGeometryError("tessellation produced no triangles", source=src)
    index = np.zeros(int(np.max(tags)) + 1, dtype=np.int64)
    index[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    vertices = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    return TessellatedSolid(vertices, index[np.concatenate(faces)], name=src)
