"""The one exception hierarchy of shapedb.

Every error raised on purpose by shapedb, ingest or query derives from
:class:`ShapeDBError`, and also from the built-in exception it most resembles, so
``except ValueError`` keeps working for callers that do not know shapedb::

    ShapeDBError
    ├── InvalidShapeError (ValueError)        the geometry itself is unusable
    │   ├── EmptyGeometryError                no vertices / faces / points / voxels
    │   ├── NonFiniteGeometryError            NaN or inf coordinates
    │   └── DegenerateGeometryError           zero volume, too few points, flat
    ├── LoadError (OSError)                   a file could not be read or parsed
    │   └── UnsupportedFormatError            no loader for this file type
    ├── ConfigError (ValueError)              a parameter is out of range or mismatched
    ├── StoreError (OSError)                  the store on disk is missing or damaged
    │   └── StoreLockedError                  another writer holds the store
    ├── NotFoundError (KeyError)              unknown shape id / name / node
    ├── QueryError (ValueError)               a malformed query or SQL statement
    ├── NotFittedError (RuntimeError)         a model used before ``fit``
    └── MissingDependencyError (ImportError)  an optional extra is not installed

Each exception carries the offending input in ``.source`` (a path, shape id or
name) when there is one, and its message names both the input and the reason.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "ShapeDBError",
    "InvalidShapeError",
    "EmptyGeometryError",
    "NonFiniteGeometryError",
    "DegenerateGeometryError",
    "LoadError",
    "UnsupportedFormatError",
    "ConfigError",
    "StoreError",
    "StoreLockedError",
    "NotFoundError",
    "QueryError",
    "NotFittedError",
    "MissingDependencyError",
]


class ShapeDBError(Exception):
    """Root of every error shapedb raises on purpose.

    Parameters
    ----------
    message : str
        What went wrong and why.
    source : Any, optional
        The offending input (a path, a shape id, a name); prefixed to the message.
    """

    def __init__(self, message: str, *, source: Any = None) -> None:
        self.source = source
        self.reason = message
        text = f"{source}: {message}" if source is not None else message
        super().__init__(text)

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0]) if self.args else ""


class InvalidShapeError(ShapeDBError, ValueError):
    """The geometry cannot be decomposed (empty, non-finite, degenerate...)."""


class EmptyGeometryError(InvalidShapeError):
    """The geometry has no vertices, faces, points or occupied voxels."""


class NonFiniteGeometryError(InvalidShapeError):
    """The geometry has NaN or infinite coordinates."""


class DegenerateGeometryError(InvalidShapeError):
    """The geometry encloses no volume (flat, a line, too few points)."""


class LoadError(ShapeDBError, OSError):
    """A file could not be read or parsed."""


class UnsupportedFormatError(LoadError):
    """No loader handles this file type."""


class ConfigError(ShapeDBError, ValueError):
    """A parameter is out of range, or two configurations do not match."""


class StoreError(ShapeDBError, OSError):
    """The store on disk is missing, damaged or of an unknown format version."""


class StoreLockedError(StoreError):
    """Another process holds the store's write lock."""


class NotFoundError(ShapeDBError, KeyError):
    """An unknown shape id, name or node."""


class QueryError(ShapeDBError, ValueError):
    """A malformed query, filter or SQL statement."""


class NotFittedError(ShapeDBError, RuntimeError):
    """An estimator was used before being fitted."""


class MissingDependencyError(ShapeDBError, ImportError):
    """An optional dependency is not installed; the message says what to install."""


def require(module: str, *, extra: str, feature: str) -> Any:
    """Import an optional module or raise :class:`MissingDependencyError`.

    Parameters
    ----------
    module : str
        Module to import, e.g. ``"gmsh"``.
    extra : str
        The pip extra that provides it, e.g. ``"cad"``. When the installed shapedb
        declares no such extra (the module is a core dependency), the message says
        to reinstall shapedb instead.
    feature : str
        What the caller wanted to do, for the message.
    """
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        extras = _declared_extras()
        if extras is not None and extra not in extras:
            raise MissingDependencyError(
                f"{feature} needs '{module}', a dependency of shapedb that is missing or "
                f"broken: reinstall it with  pip install --force-reinstall shapedb  ({exc})"
            ) from exc
        raise MissingDependencyError(
            f"{feature} needs the optional dependency '{module}': "
            f"install it with  pip install 'shapedb[{extra}]'  ({exc})"
        ) from exc


def _declared_extras() -> frozenset[str] | None:
    """The extras the installed shapedb declares; None when it is not installed."""
    from importlib import metadata

    try:
        return frozenset(metadata.metadata("shapedb").get_all("Provides-Extra") or ())
    except metadata.PackageNotFoundError:
        return None
