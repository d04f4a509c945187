"""SQL over a store with DuckDB: ``db.sql("SELECT ...") -> pyarrow.Table``.

Each call opens an in-memory DuckDB connection with

* views ``shapes``, ``balls``, ``edges`` and ``failures`` over exactly the Parquet
  files that the store's manifest lists (``read_parquet([...])``), so a query sees
  one committed version of the store, never a half-written commit;
* SQL macros ``mdbd_distance(a, b)`` (Eq. 2, the weighted L1 distance) and
  ``mdbd_kernel(a, b)`` (Eq. 3, ``exp(-lam * d)``) on feature vectors, with the
  weights ``[la^1..la^nr, lb^1..lb^nr]`` and ``lam`` of the store's KernelConfig
  written in as constants; ``mdbd_weights()`` returns the weight list. Given a learned
  metric (``db.sql(statement, metric=m)``, :mod:`query.metric`), the macros weigh by it,
  as ``db.search(..., metric=m)`` does.

The distance is a SQL macro (``list_zip`` + ``list_transform`` + ``list_sum``) rather
than a Python UDF: it runs inside DuckDB's vectorised, multi-threaded engine, is at
least as fast as a vectorised Arrow UDF (1.2 us a row against 1.4 us, ranking
200 000 rows against one query) and can be pasted into a plain ``duckdb`` session
(docs/sql.md).
"""

from __future__ import annotations

import logging
import os
from typing import Any

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from shapedb.errors import QueryError, StoreError, require

__all__ = ["sql", "connect", "script", "allowed_ids", "macros"]

log = logging.getLogger(__name__)

_VIEWS = ("shapes", "balls", "edges", "failures")


def macros(config: Any, metric: Any = None) -> list[str]:
    """The ``CREATE MACRO`` statements of ``mdbd_distance`` and ``mdbd_kernel``.

    Parameters
    ----------
    config : shapedb.config.Config
        The store's: its kernel supplies n_r, la, lb and lam, its descriptor the length.
    metric : LearnedMetric, optional
        Multiplies the weights by the metric's (:mod:`query.metric`).

    Returns
    -------
    list of str
        SQL statements, runnable in any DuckDB >= 1.3 session.
    """
    from shapedb.kernel import weights

    w = np.asarray(weights(config), dtype=np.float64)
    if metric is not None:
        if metric.dim != len(w):
            raise QueryError(
                f"the metric weighs {metric.dim}-long vectors, the store's are {len(w)}",
                source="metric",
            )
        w = w * metric.dim_weights()
    d = len(w)
    wl = "[" + ", ".join(repr(float(x)) for x in w) + "]::DOUBLE[]"
    lam = repr(float(config.kernel.lam))
    return [
        f"CREATE OR REPLACE MACRO mdbd_weights() AS {wl}",
        "CREATE OR REPLACE MACRO mdbd_distance(a, b) AS ("
        " CASE WHEN a IS NULL OR b IS NULL THEN NULL"
        f" WHEN len(a::DOUBLE[]) <> {d} OR len(b::DOUBLE[]) <> {d}"
        f" THEN error('mdbd_distance: feature vectors must have length {d}')"
        " ELSE list_sum(list_transform("
        f"list_zip(a::DOUBLE[], b::DOUBLE[], {wl}),"
        " lambda x: abs(x[1] - x[2]) * x[3])) END)",
        f"CREATE OR REPLACE MACRO mdbd_kernel(a, b) AS exp(-{lam} * mdbd_distance(a, b))",
    ]


def _files(store: Any) -> dict[str, list[str]]:
    """Committed files of every table, all from one manifest version."""
    for _ in range(5):
        version = store.version
        files = {t: list(store.files(t)) for t in _VIEWS}
        if store.version == version:
            return files
    raise StoreError("the store kept changing while its files were listed", source=str(store.path))


def _quote(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def connect(db: Any, metric: Any = None) -> Any:
    """A new in-memory DuckDB connection with the store's views and macros.

    Parameters
    ----------
    db : shapedb.Database
    metric : LearnedMetric or path, optional
        Weigh the macros by a learned metric (checked against the store's config).

    Returns
    -------
    duckdb.DuckDBPyConnection
    """
    from shapedb.schema import schema_for

    duckdb = require("duckdb", extra="sql", feature="SQL queries")
    store = db.store
    learned = _metric(db, metric)
    con = duckdb.connect(":memory:")
    for stmt in macros(db.config, learned):
        con.execute(stmt)
    for table, paths in _files(store).items():
        if paths:
            listing = ", ".join(_quote(p) for p in paths)
            con.execute(
                f"CREATE VIEW {table} AS SELECT * FROM read_parquet([{listing}], union_by_name = true)"
            )
        else:  # no committed file yet: an empty view with the table's schema
            empty = schema_for(table, int(db.config.dim)).empty_table()
            con.register(f"_empty_{table}", empty)
            con.execute(f"CREATE VIEW {table} AS SELECT * FROM _empty_{table}")
    return con


def _metric(db: Any, metric: Any) -> Any:
    from query.metric import as_metric

    learned = as_metric(metric)
    if learned is not None:
        learned.check(db.config)
    return learned


def script(db: Any, metric: Any = None) -> str:
    """SQL that sets up a plain ``duckdb`` session like :func:`connect` does.

    The views name the files of the store's current version explicitly (absolute
    paths), so the script is a snapshot: regenerate it after the store changes.

    Parameters
    ----------
    db : shapedb.Database
    metric : LearnedMetric or path, optional
        Weigh the macros by a learned metric.

    Returns
    -------
    str
        ``CREATE MACRO`` and ``CREATE VIEW`` statements, one per line.
    """
    lines = [stmt + ";" for stmt in macros(db.config, _metric(db, metric))]
    for table, paths in _files(db.store).items():
        if paths:
            listing = ", ".join(_quote(p) for p in paths)
            lines.append(
                f"CREATE OR REPLACE VIEW {table} AS SELECT * FROM read_parquet([{listing}], union_by_name = true);"
            )
    return "\n".join(lines) + "\n"


def sql(db: Any, statement: str, *, metric: Any = None) -> pa.Table:
    """Run one SQL statement over the store and return its result.

    Parameters
    ----------
    db : shapedb.Database
    statement : str
        Any DuckDB SQL; the views and macros of :func:`connect` are available.
    metric : LearnedMetric or path, optional
        Weigh ``mdbd_distance`` / ``mdbd_kernel`` by a learned metric.

    Returns
    -------
    pyarrow.Table
        The result (an empty table for statements that return nothing).

    Raises
    ------
    QueryError
        The statement is malformed or fails; the message is DuckDB's.
    """
    import duckdb

    if not isinstance(statement, str) or not statement.strip():
        raise QueryError("empty SQL statement", source=repr(statement))
    con = connect(db, metric)
    try:
        rel = con.sql(statement)
        return pa.table({}) if rel is None else rel.to_arrow_table()
    except duckdb.Error as exc:
        raise QueryError(f"{type(exc).__name__}: {exc}", source=_short(statement)) from exc
    finally:
        con.close()


def _short(statement: str, limit: int = 200) -> str:
    s = " ".join(statement.split())
    return s if len(s) <= limit else s[: limit - 3] + "..."


_CONNECTIONS: dict[str, tuple[int, Any]] = {}


def allowed_ids(db: Any, where: str) -> NDArray[np.int64]:
    """Ids of the shapes satisfying an SQL predicate over ``shapes``.

    Parameters
    ----------
    db : shapedb.Database
    where : str
        A boolean SQL expression over the ``shapes`` columns, e.g.
        ``"label = 'Chair' AND representation = 'mesh'"``.

    Returns
    -------
    (m,) int64
        Ascending ids.

    Raises
    ------
    QueryError
        The predicate is malformed; the message names it.
    """
    import duckdb

    if not isinstance(where, str) or not where.strip():
        raise QueryError("empty filter predicate", source=repr(where))
    key = os.fspath(db.store.path)
    version = db.store.version
    cached = _CONNECTIONS.get(key)
    if cached is None or cached[0] != version:
        if cached is not None:
            cached[1].close()
        _CONNECTIONS[key] = (version, connect(db))
    cur = _CONNECTIONS[key][1].cursor()
    try:
        table = cur.sql(f"SELECT id FROM shapes WHERE ({where}) ORDER BY id").to_arrow_table()
    except duckdb.Error as exc:
        raise QueryError(f"malformed filter predicate: {exc}", source=f"where={where!r}") from exc
    finally:
        cur.close()
    return table.column("id").to_numpy().astype(np.int64)
