"""The class labels of a store's shapes, read for evaluation and metric fitting."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import QueryError

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["stored_labels"]


def stored_labels(db: StoreHandle, label: str) -> tuple[NDArray[np.int64], NDArray[Any]]:
    """Ids and labels of every stored shape.

    Parameters
    ----------
    db : shapedb.Database
    label : str
        A column of ``shapes`` (e.g. ``"label"``) or a metadata key.

    Returns
    -------
    ids : (n,) int64
        Shape ids, in the store's order.
    labels : (n,) object
        Each shape's label as a string, None where it has none.

    Raises
    ------
    QueryError
        ``label`` is neither a column nor a metadata key of any shape.
    """
    try:
        t = db.store.shapes(["id", label])
        values = t.column(label).to_pylist()
    except QueryError:  # not a column: a metadata key
        t = db.store.shapes(["id", "metadata"])
        meta = [dict(m) if m is not None else {} for m in t.column("metadata").to_pylist()]
        if not any(label in m for m in meta):
            raise QueryError(
                "neither a column of shapes nor a metadata key of any shape",
                source=f"label={label!r}",
            ) from None
        values = [m.get(label) for m in meta]
    labels = np.asarray([None if v is None else str(v) for v in values], dtype=object)
    return t.column("id").to_numpy(), labels
