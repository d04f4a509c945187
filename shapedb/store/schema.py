"""The versioned Arrow schemas of a shapedb store, and its record types.

A store holds four tables, each a set of Parquet files (see ``docs/store.md``):

``shapes``
    one row per shape: identity, provenance, configuration and the Eq. 1 feature.
``balls``
    one row per ball of every decomposition (centre, radius, radius / largest radius).
``edges``
    one row per contact-graph edge (i < j).
``failures``
    one row per input that could not be ingested, with the reason.

:class:`ShapeRecord` and :class:`Failure` are the in-memory rows; the functions
``*_table`` turn lists of them into Arrow tables with exactly these schemas, and
:func:`record_from_rows` rebuilds a record (with its :class:`Decomposition`) from them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from shapedb.config.core import Config
from shapedb.mdbd.decomposition import Decomposition

__all__ = [
    "SCHEMA_VERSION",
    "TABLES",
    "ShapeRecord",
    "Failure",
    "shapes_schema",
    "BALLS_SCHEMA",
    "EDGES_SCHEMA",
    "FAILURES_SCHEMA",
    "schema_for",
    "shapes_table",
    "balls_table",
    "edges_table",
    "failures_table",
    "record_from_rows",
    "safe_text",
]

SCHEMA_VERSION = 1
"""Bumped whenever a column is added, removed or changes type."""

TABLES = ("shapes", "balls", "edges", "failures")

_TS = pa.timestamp("us", tz="UTC")


def shapes_schema(dim: int) -> pa.Schema:
    """Schema of the ``shapes`` table for features of length ``dim`` (``Config.dim``).

    Parameters
    ----------
    dim : int
        Length of the Eq. 1 feature vector.
    """
    fields = [
        pa.field("id", pa.int64(), nullable=False),
        pa.field("name", pa.string(), nullable=False),
        pa.field("label", pa.string()),
        pa.field("metadata", pa.map_(pa.string(), pa.string())),
        pa.field("representation", pa.string(), nullable=False),
        pa.field("source", pa.string()),
        pa.field("content_hash", pa.string(), nullable=False),
        pa.field("config", pa.string(), nullable=False),
        pa.field("config_fingerprint", pa.string(), nullable=False),
        pa.field("n_balls", pa.int32(), nullable=False),
        pa.field("n_edges", pa.int32(), nullable=False),
        pa.field("spacing", pa.float64(), nullable=False),
        pa.field("bounds", pa.list_(pa.float64(), 6), nullable=False),
        # (4, 4) grid frame -> model, row-major; null in rows written before it existed
        pa.field("frame", pa.list_(pa.float64(), 16)),
        # source's surface sample spacing, model units (0: exact); null in older rows
        pa.field("sampling", pa.float64()),
        pa.field("timings", pa.map_(pa.string(), pa.float64())),
        pa.field("build_seconds", pa.float64(), nullable=False),
        pa.field("created_at", _TS, nullable=False),
        pa.field("feature", pa.list_(pa.float32(), dim), nullable=False),
        # feature of the shape's sparse view (shapedb.geometry.view); null when the store keeps
        # no views, for sparse point clouds, and in rows older than it
        pa.field("view_feature", pa.list_(pa.float32(), dim)),
        # the balls' light fields (shapedb.signature.lightfield), (fields * 10 * d) row-major; null
        # unless the store's re-ranking scorer is "lightfield", and in rows older than it
        pa.field("light_field", pa.list_(pa.float32())),
        # the field vector (shapedb.signature.field_vector): depth buffers and harmonics of the
        # field's inside; null unless the store keeps them, and in rows older than it
        pa.field("field_vector", pa.list_(pa.float32())),
        # the surface words (shapedb.signature.surface_words): a histogram of local surface
        # features; null unless the store keeps them, and in rows older than it
        pa.field("surface_words", pa.list_(pa.float32())),
        # the view words (shapedb.signature.view_words): (VIEWS, WORDS) row-major, the words
        # of the shape seen from fixed directions; null unless the store keeps them, and in
        # rows older than it
        pa.field("view_words", pa.list_(pa.float32())),
    ]
    return pa.schema(fields, metadata={"shapedb.schema_version": str(SCHEMA_VERSION)})


BALLS_SCHEMA = pa.schema(
    [
        pa.field("shape_id", pa.int64(), nullable=False),
        pa.field("ball", pa.int32(), nullable=False),
        pa.field("x", pa.float64(), nullable=False),
        pa.field("y", pa.float64(), nullable=False),
        pa.field("z", pa.float64(), nullable=False),
        pa.field("r", pa.float64(), nullable=False),
        pa.field("r_norm", pa.float32(), nullable=False),
    ],
    metadata={"shapedb.schema_version": str(SCHEMA_VERSION)},
)

EDGES_SCHEMA = pa.schema(
    [
        pa.field("shape_id", pa.int64(), nullable=False),
        pa.field("i", pa.int32(), nullable=False),
        pa.field("j", pa.int32(), nullable=False),
    ],
    metadata={"shapedb.schema_version": str(SCHEMA_VERSION)},
)

FAILURES_SCHEMA = pa.schema(
    [
        pa.field("source", pa.string(), nullable=False),
        pa.field("error", pa.string(), nullable=False),
        pa.field("message", pa.string(), nullable=False),
        pa.field("time", _TS, nullable=False),
    ],
    metadata={"shapedb.schema_version": str(SCHEMA_VERSION)},
)


def schema_for(table: str, dim: int) -> pa.Schema:
    """Schema of one of :data:`TABLES`."""
    if table == "shapes":
        return shapes_schema(dim)
    return {"balls": BALLS_SCHEMA, "edges": EDGES_SCHEMA, "failures": FAILURES_SCHEMA}[table]


def safe_text(text: str) -> str:
    """``text`` as valid Unicode: undecodable bytes of a file name become ``\\xNN``.

    Python decodes file names that are not UTF-8 with surrogate escapes, which
    Parquet (and a UTF-8 terminal) cannot store; every string column goes through
    this function.
    """
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        pass
    try:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:
        return text.encode("utf-8", "backslashreplace").decode("utf-8")


def _text(value: str | None) -> str | None:
    return None if value is None else safe_text(str(value))


def _now() -> datetime:
    return datetime.now(timezone.utc)


@dataclass(frozen=True, eq=False)
class ShapeRecord:
    """One stored shape: who it is, where it came from, its MDBD and its feature.

    Attributes
    ----------
    name : str
        User-facing name (by default the file stem).
    decomposition : Decomposition
        The balls and contact graph.
    feature : (config.dim,) float32
        The Eq. 1 vector.
    config : Config
        Configuration the record was built with.
    content_hash : str
        sha256 of the source file bytes (or of the arrays of an in-memory shape).
    representation : str
        "mesh", "pointcloud", "voxels", "implicit" or "brep".
    label : str or None
        Class label, if known.
    metadata : dict[str, str]
        Free-form string metadata (e.g. the extra CSV columns).
    source : str or None
        Absolute path of the source file; None for in-memory shapes.
    build_seconds : float
        Wall time of load + decomposition + features.
    created_at : datetime
        UTC time the record was built.
    id : int or None
        Assigned by the store when the record is committed.
    view_feature : (config.dim,) float32 or None
        Feature of the shape's sparse view (:mod:`shapedb.geometry.view`), when the store
        keeps views (``CloudConfig.view_cells > 0``) and the shape is not itself a
        sparse point cloud; None otherwise.
    light_field : (fields, 10, d) float32 or None
        The balls' light fields (:func:`shapedb.signature.lightfield.ball_light_field` under
        ``config.light_field``), when the store keeps them
        (``config.stores_light_fields``); None otherwise and in rows older than them.
    field_vector : (d,) float32 or None
        The field vector (:func:`shapedb.signature.field_vector.field_vector` of the
        decomposition's inside under ``config.field_vector``, ``d =
        field_vector_dim(config)``), when the store keeps them
        (``config.stores_field_vectors``); None otherwise and in rows older than them.
    surface_words : (WORDS,) float32 or None
        The surface words (:func:`shapedb.signature.surface_words.surface_words` of the
        shape's surface, summing to 1), when the store keeps them
        (``config.stores_surface_words``); None otherwise and in rows older than them.
    view_words : (VIEWS, WORDS) float32 or None
        The view words (:func:`shapedb.signature.view_words.view_words`: the words of the
        shape seen from each of the fixed directions, each row summing to 1 or all zeros),
        when the store keeps them (``config.stores_view_words``); None otherwise and in
        rows older than them.
    """

    name: str
    decomposition: Decomposition
    feature: NDArray[np.float32]
    config: Config
    content_hash: str
    representation: str
    label: str | None = None
    metadata: Mapping[str, str] = field(default_factory=dict)
    source: str | None = None
    build_seconds: float = 0.0
    created_at: datetime = field(default_factory=_now)
    id: int | None = None
    view_feature: NDArray[np.float32] | None = None
    light_field: NDArray[np.float32] | None = None
    field_vector: NDArray[np.float32] | None = None
    surface_words: NDArray[np.float32] | None = None
    view_words: NDArray[np.float32] | None = None

    @property
    def n_balls(self) -> int:
        """Number of balls."""
        return self.decomposition.n_balls

    @property
    def n_edges(self) -> int:
        """Number of contact-graph edges."""
        return int(len(self.decomposition.edges))

    def __repr__(self) -> str:
        return (
            f"ShapeRecord(id={self.id}, name={self.name!r}, label={self.label!r}, "
            f"representation={self.representation!r}, n_balls={self.n_balls})"
        )


@dataclass(frozen=True)
class Failure:
    """An input that could not be ingested.

    Attributes
    ----------
    source : str
        The path (or name of an in-memory shape).
    error : str
        Exception class name, e.g. ``"NonFiniteGeometryError"``.
    message : str
        The reason, as the exception said it.
    time : datetime
        When it failed (UTC).
    """

    source: str
    error: str
    message: str
    time: datetime = field(default_factory=_now)

    @classmethod
    def from_exception(cls, source: str, exc: BaseException) -> Failure:
        """Build a failure from an exception raised while ingesting ``source``."""
        reason = getattr(exc, "reason", None) or str(exc) or repr(exc)
        return cls(source=str(source), error=type(exc).__name__, message=str(reason))


def _require_ids(records: Sequence[ShapeRecord]) -> list[int]:
    ids = [r.id for r in records]
    if any(i is None for i in ids):
        raise ValueError("records must have ids before they are converted to a table")
    return [int(i) for i in ids]  # type: ignore[arg-type]


def shapes_table(records: Sequence[ShapeRecord], dim: int) -> pa.Table:
    """Rows of the ``shapes`` table, one per record (ids must be assigned).

    Parameters
    ----------
    records : sequence of ShapeRecord
    dim : int
        Feature length; every record's feature must have it.
    """
    ids = _require_ids(records)
    feats = np.zeros((len(records), dim), dtype=np.float32)
    for k, r in enumerate(records):
        f = np.asarray(r.feature, dtype=np.float32).ravel()
        if f.shape != (dim,):
            raise ValueError(f"record {r.name!r}: feature has length {f.size}, expected {dim}")
        feats[k] = f
    views = [None if r.view_feature is None else _checked(r, r.view_feature, dim) for r in records]
    bounds = np.array(
        [np.asarray(r.decomposition.bounds, dtype=np.float64).reshape(6) for r in records]
    ).reshape(-1)
    frames = np.array(
        [np.asarray(r.decomposition.frame, dtype=np.float64).reshape(16) for r in records]
    ).reshape(-1)
    cols: dict[str, Any] = {
        "id": ids,
        "name": [safe_text(r.name) for r in records],
        "label": [_text(r.label) for r in records],
        "metadata": [
            sorted((safe_text(str(k)), safe_text(str(v))) for k, v in r.metadata.items())
            for r in records
        ],
        "representation": [r.representation for r in records],
        "source": [_text(r.source) for r in records],
        "content_hash": [r.content_hash for r in records],
        "config": [r.config.to_json() for r in records],
        "config_fingerprint": [r.config.fingerprint for r in records],
        "n_balls": [r.n_balls for r in records],
        "n_edges": [r.n_edges for r in records],
        "spacing": [float(r.decomposition.spacing) for r in records],
        "bounds": pa.FixedSizeListArray.from_arrays(pa.array(bounds, pa.float64()), 6),
        "frame": pa.FixedSizeListArray.from_arrays(pa.array(frames, pa.float64()), 16),
        "sampling": [float(r.decomposition.sampling) for r in records],
        "timings": [
            sorted((str(k), float(v)) for k, v in r.decomposition.timings.items()) for r in records
        ],
        "build_seconds": [float(r.build_seconds) for r in records],
        "created_at": [r.created_at for r in records],
        "feature": pa.FixedSizeListArray.from_arrays(pa.array(feats.ravel()), dim),
        "view_feature": views,
        "light_field": [
            None if r.light_field is None else np.asarray(r.light_field, np.float32).ravel()
            for r in records
        ],
        "field_vector": [
            None if r.field_vector is None else _field_vector(r, r.field_vector) for r in records
        ],
        "surface_words": [
            None if r.surface_words is None else _surface_words(r, r.surface_words) for r in records
        ],
        "view_words": [
            None if r.view_words is None else _view_words(r, r.view_words) for r in records
        ],
    }
    schema = shapes_schema(dim)
    arrays = [
        c if isinstance(c, pa.Array) else pa.array(c, type=schema.field(n).type)
        for n, c in cols.items()
    ]
    return pa.Table.from_arrays(arrays, schema=schema)


def _checked(record: ShapeRecord, view: Any, dim: int) -> list[float]:
    v = np.asarray(view, dtype=np.float32).ravel()
    if v.shape != (dim,) or not np.all(np.isfinite(v)):
        raise ValueError(f"record {record.name!r}: view feature must be {dim} finite values")
    return v.tolist()


def _field_vector(record: ShapeRecord, vector: Any) -> NDArray[np.float32]:
    from shapedb.signature.field_vector import field_vector_dim

    v = np.asarray(vector, dtype=np.float32).ravel()
    d = field_vector_dim(record.config)
    if v.shape != (d,) or not np.all(np.isfinite(v)):
        raise ValueError(f"record {record.name!r}: field vector must be {d} finite values")
    return v


def _surface_words(record: ShapeRecord, words: Any) -> NDArray[np.float32]:
    from shapedb.signature.surface_words import WORDS

    v = np.asarray(words, dtype=np.float32).ravel()
    if v.shape != (WORDS,) or not np.all(np.isfinite(v)) or (v < 0).any():
        raise ValueError(
            f"record {record.name!r}: surface words must be {WORDS} finite values >= 0"
        )
    return v


def _view_words(record: ShapeRecord, words: Any) -> NDArray[np.float32]:
    from shapedb.signature.surface_words import WORDS
    from shapedb.signature.view_words import VIEWS

    v = np.asarray(words, dtype=np.float32).ravel()
    if v.shape != (VIEWS * WORDS,) or not np.all(np.isfinite(v)) or (v < 0).any():
        raise ValueError(
            f"record {record.name!r}: view words must be {VIEWS} x {WORDS} finite values >= 0"
        )
    return v


def balls_table(records: Sequence[ShapeRecord]) -> pa.Table:
    """Rows of the ``balls`` table for the records (ids must be assigned)."""
    ids = _require_ids(records)
    parts_id, parts_k, parts_c, parts_r, parts_rn = [], [], [], [], []
    for sid, r in zip(ids, records, strict=True):
        d = r.decomposition
        n = d.n_balls
        radii = np.asarray(d.radii, dtype=np.float64)
        parts_id.append(np.full(n, sid, dtype=np.int64))
        parts_k.append(np.arange(n, dtype=np.int32))
        parts_c.append(np.asarray(d.centers, dtype=np.float64).reshape(n, 3))
        parts_r.append(radii)
        r1 = float(radii[0]) if n and radii[0] > 0 else 1.0
        parts_rn.append((radii / r1).astype(np.float32))
    if not records:
        return BALLS_SCHEMA.empty_table()
    c = np.concatenate(parts_c)
    return pa.Table.from_arrays(
        [
            pa.array(np.concatenate(parts_id)),
            pa.array(np.concatenate(parts_k)),
            pa.array(c[:, 0]),
            pa.array(c[:, 1]),
            pa.array(c[:, 2]),
            pa.array(np.concatenate(parts_r)),
            pa.array(np.concatenate(parts_rn)),
        ],
        schema=BALLS_SCHEMA,
    )


def edges_table(records: Sequence[ShapeRecord]) -> pa.Table:
    """Rows of the ``edges`` table for the records (ids must be assigned)."""
    ids = _require_ids(records)
    if not records:
        return EDGES_SCHEMA.empty_table()
    parts_id, parts_e = [], []
    for sid, r in zip(ids, records, strict=True):
        e = np.asarray(r.decomposition.edges, dtype=np.int32).reshape(-1, 2)
        parts_id.append(np.full(len(e), sid, dtype=np.int64))
        parts_e.append(e)
    e = np.concatenate(parts_e)
    return pa.Table.from_arrays(
        [pa.array(np.concatenate(parts_id)), pa.array(e[:, 0]), pa.array(e[:, 1])],
        schema=EDGES_SCHEMA,
    )


def failures_table(failures: Sequence[Failure]) -> pa.Table:
    """Rows of the ``failures`` table."""
    return pa.Table.from_pylist(
        [
            {
                "source": safe_text(f.source),
                "error": safe_text(f.error),
                "message": safe_text(f.message),
                "time": f.time,
            }
            for f in failures
        ],
        schema=FAILURES_SCHEMA,
    )


def _pairs(value: Any) -> dict[str, Any]:
    if value is None:
        return {}
    if isinstance(value, dict):
        return value
    return dict(value)


def _frame(value: Any) -> NDArray[np.float64]:
    """(4, 4) frame from a ``frame`` cell; identity when absent (rows older than it)."""
    if value is None:
        return np.eye(4)
    return np.asarray(value, dtype=np.float64).reshape(4, 4)


def record_from_rows(row: Mapping[str, Any], balls: pa.Table, edges: pa.Table) -> ShapeRecord:
    """Rebuild a :class:`ShapeRecord` from its ``shapes`` row and its balls and edges.

    Parameters
    ----------
    row : mapping
        One row of the ``shapes`` table, as from ``Table.to_pylist()``.
    balls, edges : pa.Table
        The rows of the ``balls`` and ``edges`` tables for this shape only.
    """
    config = Config.from_json(row["config"])
    order = np.argsort(balls.column("ball").to_numpy()) if balls.num_rows else np.zeros(0, int)
    centers = np.column_stack(
        [balls.column(a).to_numpy().astype(np.float64)[order] for a in ("x", "y", "z")]
    ).reshape(-1, 3)
    radii = balls.column("r").to_numpy().astype(np.float64)[order]
    if edges.num_rows:
        e = np.column_stack([edges.column("i").to_numpy(), edges.column("j").to_numpy()])
        e = e[np.lexsort((e[:, 1], e[:, 0]))].astype(np.int32)
    else:
        e = np.zeros((0, 2), dtype=np.int32)
    decomposition = Decomposition(
        centers=centers,
        radii=radii,
        edges=e,
        spacing=float(row["spacing"]),
        bounds=np.asarray(row["bounds"], dtype=np.float64).reshape(2, 3),
        config=config.mdbd,
        representation=row["representation"],
        sampling=float(row.get("sampling") or 0.0),
        timings={k: float(v) for k, v in _pairs(row.get("timings")).items()},
        frame=_frame(row.get("frame")),
    )
    return ShapeRecord(
        name=row["name"],
        decomposition=decomposition,
        feature=np.asarray(row["feature"], dtype=np.float32),
        config=config,
        content_hash=row["content_hash"],
        representation=row["representation"],
        label=row.get("label"),
        metadata={str(k): str(v) for k, v in _pairs(row.get("metadata")).items()},
        source=row.get("source"),
        build_seconds=float(row["build_seconds"]),
        created_at=row["created_at"],
        id=int(row["id"]),
        view_feature=(
            None
            if row.get("view_feature") is None
            else np.asarray(row["view_feature"], dtype=np.float32)
        ),
        light_field=_light_field(row.get("light_field"), config),
        field_vector=(
            None
            if row.get("field_vector") is None
            else np.asarray(row["field_vector"], dtype=np.float32)
        ),
        surface_words=(
            None
            if row.get("surface_words") is None
            else np.asarray(row["surface_words"], dtype=np.float32)
        ),
        view_words=_view_words_cell(row.get("view_words")),
    )


def _view_words_cell(value: Any) -> NDArray[np.float32] | None:
    """(VIEWS, WORDS) float32 from a ``view_words`` cell; None when absent."""
    if value is None:
        return None
    from shapedb.signature.surface_words import WORDS

    return np.asarray(value, dtype=np.float32).reshape(-1, WORDS)


def _light_field(value: Any, config: Config) -> NDArray[np.float32] | None:
    """(fields, 10, d) float32 from a ``light_field`` cell; None when absent."""
    if value is None:
        return None
    return np.asarray(value, dtype=np.float32).reshape(config.light_field.n_fields, 10, -1)
