"""The classifier file: a JSON manifest and named arrays in one ``.npz`` archive.

Every kind of classifier (nearest neighbours, linear, boosting, graph CNN) is
written as plain data: a JSON manifest (format, kind, settings, label names,
configuration fingerprint, selection report) and numpy arrays (training
descriptors, coefficients, network weights). Reading never unpickles code
(``allow_pickle=False``), and needs neither torch nor scikit-learn; a model that
needs them to predict imports them when it is rebuilt.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import LoadError

__all__ = ["FORMAT", "write_model", "read_model", "is_model_file"]

FORMAT = "shapedb.classifier/2"
_MANIFEST = "manifest"


def write_model(
    path: str | os.PathLike[str], manifest: dict[str, Any], arrays: dict[str, NDArray[Any]]
) -> Path:
    """Write a classifier file (the parent folder is created).

    Parameters
    ----------
    path : path
        Written as given (no suffix is added).
    manifest : dict
        JSON-serialisable; ``"format"`` is set to :data:`FORMAT`.
    arrays : dict of str to ndarray
        Numeric or string arrays (no object arrays); names must not be "manifest".

    Returns
    -------
    Path
    """
    if _MANIFEST in arrays:
        raise ValueError(f"array name {_MANIFEST!r} is reserved")
    text = json.dumps({**manifest, "format": FORMAT}, sort_keys=True)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    members: dict[str, Any] = {_MANIFEST: np.array(text), **arrays}
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **members)
    return path


def is_model_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a classifier file of this format (not an older torch file)."""
    try:
        with zipfile.ZipFile(path) as z:
            return f"{_MANIFEST}.npy" in z.namelist()
    except (OSError, zipfile.BadZipFile):
        return False


def read_model(path: str | os.PathLike[str]) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Read a file written by :func:`write_model`.

    Returns
    -------
    manifest : dict
    arrays : dict of str to ndarray

    Raises
    ------
    LoadError
        The file cannot be read or is not a classifier file of this format.
    """
    try:
        with np.load(Path(path), allow_pickle=False) as z:
            if _MANIFEST not in z.files:
                raise LoadError(f"not a shapedb classifier (format {FORMAT})", source=str(path))
            manifest = json.loads(str(z[_MANIFEST]))
            arrays = {k: z[k] for k in z.files if k != _MANIFEST}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise LoadError(f"cannot read a classifier: {exc}", source=str(path)) from exc
    if manifest.get("format") != FORMAT:
        raise LoadError(
            f"not a shapedb classifier (format {manifest.get('format')!r}, expected {FORMAT})",
            source=str(path),
        )
    return manifest, arrays
