"""SQL over a store with DuckDB: ``db.sql("SELECT ...") -> pyarrow.Table``.

Each call opens an in-memory DuckDB connection with

* views ``shapes``, ``balls``, ``edges`` and ``failures`` over exactly the Parquet
  files that the store's manifest lists (``read_parquet([...])``), so a query sees
  one committed version of the store, never a half-written commit;
* SQL macros ``mdbd_distance(a, b)`` (Eq. 2, the weighted L1 distance) and
  ``mdbd_kernel(a, b)`` (Eq. 3, ``exp(-lam * d)``) on feature vectors, with the
  weights ``[la^1..la^nr, lb^1..lb^nr]`` and ``lam`` of the store's KernelConfig
  written in as constants; ``mdbd_weights()`` returns the weight list. Given a learned
  metric (``db.sql(statement, metric=m)``, :mod:`query.learn.metric`), the macros weigh by it,
  as ``db.search(..., metric=m)`` does.

The connection is a sandbox built with DuckDB's own controls, not string matching:
its external access is off except for the store's committed Parquet files
(``allowed_paths`` + ``enable_external_access = false``), extensions cannot be
installed or loaded, and its configuration is locked (``lock_configuration``). A
statement must parse (``duckdb.extract_statements``) as exactly one ``SELECT``; a
``where`` predicate must parse as exactly one expression. COPY, ATTACH, INSTALL /
LOAD, reading any other path and second statements are :class:`QueryError`.

The distance is a SQL macro (``list_zip`` + ``list_transform`` + ``list_sum``) rather
than a Python UDF: it runs inside DuckDB's vectorised, multi-threaded engine, is at
least as fast as a vectorised Arrow UDF (1.2 us a row against 1.4 us, ranking
200 000 rows against one query) and can be pasted into a plain ``duckdb`` session
(docs/sql.md).
"""

from __future__ import annotations

import json
import logging
import os
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from shapedb.errors import QueryError, ShapeDBError, StoreError, require
from shapedb.store.manifest import repair_hint

if TYPE_CHECKING:
    from query.database import Database

__all__ = ["sql", "connect", "script", "allowed_ids", "macros"]

log = logging.getLogger(__name__)

_VIEWS = ("shapes", "balls", "edges", "failures")


def macros(config: Any, metric: Any = None) -> list[str]:
    """The ``CREATE MACRO`` statements of ``mdbd_distance`` and ``mdbd_kernel``.

    Parameters
    ----------
    config : shapedb.config.core.Config
        The store's: its kernel supplies n_r, la, lb and lam, its descriptor the length.
    metric : LearnedMetric, optional
        Multiplies the weights by the metric's (:mod:`query.learn.metric`).

    Returns
    -------
    list of str
        SQL statements, runnable in any DuckDB >= 1.3 session.
    """
    from shapedb.signature.kernel import weights

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


def connect(db: Database, metric: Any = None) -> Any:
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
    from shapedb.store.schema import schema_for

    duckdb = require("duckdb", extra="sql", feature="SQL queries")
    store = db.store
    learned = _metric(db, metric)
    con = duckdb.connect(":memory:")
    for stmt in macros(db.config, learned):
        con.execute(stmt)
    files = _files(store)
    for table, paths in files.items():
        if paths:
            listing = ", ".join(_quote(p) for p in paths)
            view = f"CREATE VIEW {table} AS SELECT * FROM read_parquet([{listing}], union_by_name = true)"
            try:
                con.execute(view)
            except duckdb.Error as exc:  # DuckDB reads the files' schemas here
                con.close()
                raise _error(db, exc, table) from exc
        else:  # no committed file yet: an empty view with the table's schema
            empty = schema_for(table, int(db.config.dim)).empty_table()
            con.register(f"_empty_{table}", empty)
            con.execute(f"CREATE VIEW {table} AS SELECT * FROM _empty_{table}")
    _sandbox(con, [p for paths in files.values() for p in paths])
    return con


def _sandbox(con: Any, paths: list[str]) -> None:
    """Limit a connection to reading ``paths``, then lock its configuration."""
    allowed = "[" + ", ".join(_quote(p) for p in paths) + "]"
    for setting in (
        f"SET allowed_paths = {allowed}",
        "SET allowed_directories = []",
        "SET autoinstall_known_extensions = false",
        "SET autoload_known_extensions = false",
        "SET allow_community_extensions = false",
        "SET enable_external_access = false",
        "SET lock_configuration = true",
    ):
        con.execute(setting)


def _one_select(statement: str, source: str) -> None:
    """QueryError unless ``statement`` parses as exactly one SELECT (DuckDB's parser)."""
    import duckdb

    try:
        parsed = duckdb.extract_statements(statement)
    except duckdb.Error as exc:
        raise QueryError(f"{type(exc).__name__}: {_short(str(exc))}", source=source) from exc
    if len(parsed) != 1:
        raise QueryError(f"exactly one statement is allowed, got {len(parsed)}", source=source)
    kind = parsed[0].type
    if kind != duckdb.StatementType.SELECT:
        raise QueryError(
            f"only read-only SELECT statements are allowed, not {kind.name}", source=source
        )


def _metric(db: Database, metric: Any) -> Any:
    from query.learn.metric import as_metric

    learned = as_metric(metric)
    if learned is not None:
        learned.check(db.config)
    return learned


def script(db: Database, metric: Any = None) -> str:
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


def sql(db: Database, statement: str, *, metric: Any = None) -> pa.Table:
    """Run one SQL statement over the store and return its result.

    Parameters
    ----------
    db : shapedb.Database
    statement : str
        One DuckDB ``SELECT`` statement; the views and macros of :func:`connect` are
        available, no other file is.
    metric : LearnedMetric or path, optional
        Weigh ``mdbd_distance`` / ``mdbd_kernel`` by a learned metric.

    Returns
    -------
    pyarrow.Table
        The result (an empty table for statements that return nothing).

    Raises
    ------
    QueryError
        The statement is malformed, is not exactly one SELECT, reaches outside the
        store (COPY, ATTACH, INSTALL/LOAD, other files) or fails; the message is DuckDB's.
    StoreError
        One of the store's own files cannot be read (damaged); the message names it.
    """
    import duckdb

    if not isinstance(statement, str) or not statement.strip():
        raise QueryError("empty SQL statement", source=repr(statement))
    _one_select(statement, _short(statement))
    con = connect(db, metric)
    try:
        rel = con.sql(statement)
        return pa.table({}) if rel is None else rel.to_arrow_table()
    except duckdb.Error as exc:
        raise _error(db, exc, _short(statement)) from exc
    finally:
        con.close()


def _error(db: Database, exc: Exception, source: str) -> ShapeDBError:
    """QueryError, or StoreError when DuckDB could not read one of the store's own files."""
    import duckdb

    text = " ".join(str(exc).split())
    if not isinstance(exc, duckdb.PermissionException):
        for path in (p for paths in _files(db.store).values() for p in paths):
            if path in text:
                rel = os.path.relpath(path, db.store.path)
                return StoreError(
                    f"segment {rel} cannot be read ({type(exc).__name__}: {_short(text, 160)}); "
                    f"{repair_hint(db.store.path)}",
                    source=str(db.store.path),
                )
    return QueryError(f"{type(exc).__name__}: {_short(text, 300)}", source=source)


def _short(statement: str, limit: int = 200) -> str:
    s = " ".join(statement.split())
    return s if len(s) <= limit else s[: limit - 3] + "..."


_CONNECTIONS: dict[str, tuple[int, Any]] = {}


def allowed_ids(db: Database, where: str) -> NDArray[np.int64]:
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
        The predicate is malformed or is more than one expression; the message names it.
    """
    import duckdb

    if not isinstance(where, str) or not where.strip():
        raise QueryError("empty filter predicate", source=repr(where))
    statement = f"SELECT id FROM shapes WHERE ({where}) ORDER BY id"
    _one_expression(statement, where)
    key = os.fspath(db.store.path)
    version = db.store.version
    cached = _CONNECTIONS.get(key)
    if cached is None or cached[0] != version:
        if cached is not None:
            cached[1].close()
        _CONNECTIONS[key] = (version, connect(db))
    cur = _CONNECTIONS[key][1].cursor()
    try:
        table = cur.sql(statement).to_arrow_table()
    except duckdb.Error as exc:
        err = _error(db, exc, f"where={where!r}")
        if isinstance(err, StoreError):
            raise err from exc
        raise QueryError(
            f"malformed filter predicate: {_short(str(exc), 300)}", source=f"where={where!r}"
        ) from exc
    finally:
        cur.close()
    return table.column("id").to_numpy().astype(np.int64)


_TEMPLATE = "SELECT id FROM shapes WHERE (TRUE) ORDER BY id"


def _one_expression(statement: str, where: str) -> None:
    """QueryError unless ``statement`` is :data:`_TEMPLATE` with only its WHERE expression changed.

    Both are parsed by DuckDB (``json_serialize_sql``) and compared with the WHERE
    clause and the source positions left out, so a predicate that closes the
    parenthesis and adds a statement, a UNION, a LIMIT or a comment is refused.
    """
    import duckdb

    source = f"where={where!r}"
    _one_select(statement, source)
    con = duckdb.connect(":memory:")
    try:
        got, want = (
            json.loads(con.execute("SELECT json_serialize_sql(?)", [s]).fetchone()[0])  # type: ignore[index]
            for s in (statement, _TEMPLATE)
        )
    finally:
        con.close()
    if got.get("error"):
        raise QueryError(f"malformed filter predicate: {got.get('error_message')}", source=source)
    if _skeleton(got) != _skeleton(want):
        raise QueryError(
            "the filter must be one boolean expression over the shapes columns", source=source
        )


def _skeleton(tree: Any) -> Any:
    """A parsed statement without its WHERE clause and source positions."""
    if isinstance(tree, dict):
        return {
            k: _skeleton(v)
            for k, v in tree.items()
            if k not in ("where_clause", "query_location", "query_location_length")
        }
    if isinstance(tree, list):
        return [_skeleton(v) for v in tree]
    return tree
