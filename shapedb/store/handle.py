"""What the query stages need of a database: :class:`StoreHandle`.

The stages under the facade (search, part search, learning, evaluation, SQL, pictures) take
the database as their first argument but read only its store and configuration, and load
files; typing them by this protocol rather than by ``query.database.Database`` keeps the
facade on the top floor, above everything it calls.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from shapedb.config.core import Config
    from shapedb.geometry.base import Geometry
    from shapedb.store.schema import ShapeRecord
    from shapedb.store.store import Store

__all__ = ["StoreHandle"]


class StoreHandle(Protocol):
    """A database as the query stages read it (``query.database.Database`` is one)."""

    @property
    def store(self) -> Store:
        """The store on disk."""
        ...

    @property
    def config(self) -> Config:
        """The configuration of every record."""
        ...

    @property
    def path(self) -> Path:
        """The store directory."""
        ...

    def get(self, id_or_name: int | str) -> ShapeRecord:
        """One stored shape, with its decomposition."""
        ...

    def load(self, path: str | os.PathLike[str], *, as_: str | None = None) -> Geometry:
        """A model file read into a geometry."""
        ...
