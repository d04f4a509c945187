"""Ingest files, folders and in-memory shapes into a database, in parallel.

``ingest(db, inputs)`` expands folders, hashes every file, skips what the store
already holds (same content, same configuration), computes the decompositions and
features in parallel (a process pool on this machine, or a Dask cluster when a
scheduler is given), and commits the results in batches. Each batch is one atomic
commit, so a crash loses at most the batch in flight and a re-run completes it.
Failures never stop the run: they are recorded in the store and in the report.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ingest.inputs import COMPANION_SUFFIXES, content_hash, expand, geometry_hash
from ingest.labels import LabelEntry, LabelTable, folder_label, read_labels, summarise_matches
from ingest.ledger import Ledger
from ingest.loaders import AS_OPTIONS, load
from ingest.progress import Progress, ProgressOption
from ingest.workers import executor, result, wait_any
from shapedb.config.core import Config
from shapedb.errors import ConfigError, DegenerateGeometryError, LoadError, ShapeDBError
from shapedb.geometry.base import Geometry
from shapedb.results import IngestReport  # defined there, re-exported here
from shapedb.store.schema import Failure, ShapeRecord, safe_text

if TYPE_CHECKING:
    from shapedb.store.store import CommitResult, Store


class IngestTarget(Protocol):
    """What ingest needs of a database (``query.database.Database`` is one): its store, its
    configuration, and a commit that also brings the derived state up to date."""

    @property
    def store(self) -> Store: ...

    @property
    def config(self) -> Config: ...

    def commit(
        self,
        records: Sequence[ShapeRecord] = (),
        *,
        failures: Sequence[Failure] = (),
        delete: Iterable[int] = (),
    ) -> tuple[CommitResult, list[ShapeRecord]]: ...


__all__ = [
    "ingest",
    "IngestReport",
    "build_record",
    "content_hash",
    "geometry_hash",
    "expand",
    "COMPANION_SUFFIXES",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class _Item:
    """One unit of work, small enough to send to a worker."""

    index: int
    source: str
    name: str
    content_hash: str
    path: str | None = None
    geometry: Geometry | None = None
    as_: str | None = None
    label: str | None = None
    label_key: str | None = None
    metadata: Mapping[str, str] = field(default_factory=dict)
    max_bytes: int | None = None
    max_faces: int | None = None


# ---------------------------------------------------------------- the work
def build_record(item: _Item, config: Config) -> ShapeRecord | Failure:
    """Load, decompose and featurise one item (runs in a worker).

    Never raises for a bad input: returns a :class:`Failure` instead.
    """
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.kernel import features

    t0, c0 = time.perf_counter(), time.process_time()
    try:
        geometry = (
            item.geometry
            if item.geometry is not None
            else load(
                item.path,  # type: ignore[arg-type]
                as_=item.as_,
                max_bytes=item.max_bytes,
                max_faces=item.max_faces,
            )
        )
        t_load = time.perf_counter() - t0
        decomposition = decompose(
            geometry, config=config.mdbd, tail_balls=config.light_field_tail,
            keep_inside=config.light_field_inside,
        )  # fmt: skip
        if decomposition.n_balls == 0:
            from shapedb.errors import DegenerateGeometryError

            raise DegenerateGeometryError(
                "no ball fits inside: the solid has no volume", source=item.source
            )
        t1 = time.perf_counter()
        feature = np.asarray(features(decomposition, config), dtype=np.float32)
        t2 = time.perf_counter()
        view = _view_feature(geometry, decomposition, config)
        timings = dict(decomposition.timings)
        if view is not None:
            timings["view"] = time.perf_counter() - t2
        stage = _stage_signatures(geometry, decomposition, config, timings)
        timings["load"] = t_load
        timings["features"] = t2 - t1
        timings["cpu"] = time.process_time() - c0  # this process's CPU seconds
        # the inside served the light fields and the field vector: the record does not carry it
        decomposition = replace(decomposition, timings=timings, inside=None)
    except Exception as exc:  # any bad input becomes a recorded failure, never a crash
        if not isinstance(exc, ShapeDBError):
            log.debug("unexpected error ingesting %s", item.source, exc_info=True)
        return Failure.from_exception(item.source, exc)
    return ShapeRecord(
        name=item.name,
        decomposition=decomposition,
        feature=feature,
        config=config,
        content_hash=item.content_hash,
        representation=decomposition.representation,
        label=item.label,
        metadata=dict(item.metadata),
        source=item.source if item.path is not None else None,
        build_seconds=time.perf_counter() - t0,
        view_feature=view,
        **stage,
    )


def _stage_signatures(
    geometry: Any, decomposition: Any, config: Config, timings: dict[str, float]
) -> dict[str, Any]:
    """The record's signatures for the re-ranking stage, as ``ShapeRecord`` fields: its
    light fields, field vector, surface words and view words, each None when the store
    keeps none (the view words also when the shape has no surface to see: logged, its
    scans are then ranked by their silhouettes); each one's seconds added to ``timings``."""
    out: dict[str, Any] = {
        "light_field": None, "field_vector": None, "surface_words": None, "view_words": None,
    }  # fmt: skip
    if config.stores_light_fields:
        from shapedb.signature.lightfield import decomposition_light_field

        t = time.perf_counter()
        out["light_field"] = decomposition_light_field(decomposition, config.light_field)
        timings["light_field"] = time.perf_counter() - t
    if config.stores_field_vectors:
        from shapedb.signature.field_vector import decomposition_field_vector

        t = time.perf_counter()
        out["field_vector"] = decomposition_field_vector(decomposition, config.field_vector)
        timings["field_vector"] = time.perf_counter() - t
    if config.stores_surface_words:
        from shapedb.signature.surface_words import surface_points, surface_words

        t = time.perf_counter()
        out["surface_words"] = surface_words(surface_points(geometry, decomposition.spacing))
        timings["surface_words"] = time.perf_counter() - t
    if config.stores_view_words:
        from shapedb.signature.view_words import view_words

        t = time.perf_counter()
        try:
            out["view_words"] = view_words(geometry, decomposition.spacing)
        except DegenerateGeometryError as exc:
            log.warning("%s: no view words (%s)", getattr(geometry, "name", "shape"), exc)
        timings["view_words"] = time.perf_counter() - t
    return out


def _view_feature(geometry: Any, decomposition: Any, config: Config) -> NDArray[np.float32] | None:
    """The shape's second feature, or None.

    A sparse point cloud's reconstruction (:mod:`shapedb.mdbd.reconstruct`, when kept); a
    dense shape's sparse view (:mod:`shapedb.geometry.view`), when the store keeps views.
    """
    from shapedb.geometry.view import is_sparse, view_geometry
    from shapedb.mdbd.decomposition import decompose
    from shapedb.mdbd.reconstruct import reconstructed
    from shapedb.signature.kernel import features

    cells = config.cloud.view_cells
    sparse = is_sparse(decomposition.sampling, decomposition.spacing)
    if (sparse and not config.cloud.reconstruct) or not (cells or sparse):
        return None
    try:
        if sparse:
            found = reconstructed(
                geometry, decomposition, config.mdbd, depth=config.cloud.reconstruct_depth
            )
        else:
            view = view_geometry(geometry, decomposition.spacing, cells)
            found = None if view is None else decompose(view, config=config.mdbd)
    except ShapeDBError as exc:  # the shape itself is fine: stored without a view
        log.warning("%s: no sparse view (%s)", getattr(geometry, "name", None) or "shape", exc)
        return None
    if found is None or found.n_balls == 0:
        return None
    return np.asarray(features(found, config), dtype=np.float32)


# ---------------------------------------------------------------- driver
def ingest(
    db: IngestTarget,
    inputs: Any,
    *,
    labels: str | os.PathLike[str] | Mapping[str, str] | LabelTable | None = None,
    label_from_folder: bool = False,
    as_: str | None = None,
    names: Sequence[str] | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    force: bool = False,
    progress: ProgressOption = True,
    batch_size: int = 32,
    commit_seconds: float = 30.0,
    max_bytes: int | None = None,
    max_faces: int | None = None,
) -> IngestReport:
    """Add files, folders and in-memory shapes to ``db``.

    Every input ends in one outcome of the report: stored, unchanged (content already
    stored), failed (with the reason; one bad file never stops the others) or ignored.

    Parameters
    ----------
    db : shapedb.Database
        Target database; its configuration is used for every shape.
    inputs : path, Geometry, or a sequence / mapping of them
        Files, folders (walked recursively, symlinked folders followed once; hidden,
        companion and unsupported files ignored), Geometry objects,
        ``(name, geometry)`` pairs or a ``{name: geometry}`` mapping.
    labels : path, mapping or LabelTable, optional
        A labels CSV (``path,label,...``; extra columns become metadata), or
        ``{path: label}``; the matches are counted, the unmatched logged.
    label_from_folder : bool
        Label each file by its parent folder's name (when the CSV gives none).
    as_ : {None, "mesh", "pointcloud", "smooth_voxels"}
        Force the representation of files (see :func:`ingest.loaders.load`).
    names : sequence of str, optional
        Names of the inputs, one per input (not for folders); default: the file stem.
    workers : int, optional
        Worker processes, >= 1; default ``os.cpu_count()``; 1 runs in this process.
    scheduler : str or distributed.Client, optional
        Run on a Dask cluster instead (its address, e.g. ``"tcp://host:8786"``).
    force : bool
        Rebuild shapes already in the store (they keep their ids).
    progress : bool or callable
        True: a bar on a terminal, else log lines (:mod:`ingest.progress`); False:
        silent; a callable: ``progress(done, total)`` after each input.
    batch_size, commit_seconds : int, float
        Results per atomic commit; a partial batch is committed this long after the last.
    max_bytes, max_faces : int, optional
        Fail files of more bytes, or meshes of more faces (so one cannot take the memory).

    Returns
    -------
    IngestReport

    Raises
    ------
    ConfigError
        An argument is out of range (``workers`` < 1...); the labels match no input.
    """
    t_start = time.perf_counter()
    _check_arguments(as_, batch_size, workers, max_bytes, max_faces)
    ledger = Ledger()
    entries = _entries(inputs, names, ledger)
    table = _label_table(labels)
    limits = {"as_": as_, "max_bytes": max_bytes, "max_faces": max_faces}
    with db.store.writer():
        plan = _plan(entries, db.store.hashes(), ledger, table=table, names=names,
                     label_from_folder=label_from_folder, force=force, limits=limits)  # fmt: skip
        committer = _Committer(db, plan.present, batch_size, commit_seconds, ledger)
        committer.failures.extend(plan.failures)
        _build(plan, committer, db.config, (workers, scheduler), progress, len(entries))
        committer.flush()
    assert len(ledger) == len(entries), "every input has one outcome"
    report = ledger.report(time.perf_counter() - t_start, committer.notes, plan.labels_matched)
    log.info("ingest done: %r", report)
    return report


def _entries(
    inputs: Any, names: Sequence[str] | None, ledger: Ledger
) -> list[tuple[str, Path | Geometry, bool, str | None]]:
    """The inputs expanded (what folder walks leave out goes to the ledger as ignored)."""
    ignored: list[tuple[str, str]] = []
    entries = list(expand(inputs, ignored=ignored))
    if names is not None and len(names) != len(entries):
        raise ConfigError(
            f"names has {len(names)} entries but the inputs expand to "
            f"{len(entries)}; give one name per input file or shape"
        )
    for path, why in ignored:
        ledger.ignore(path, why)
    return entries


def _build(
    plan: _Plan,
    committer: _Committer,
    config: Config,
    where: tuple[int | None, Any],
    progress: ProgressOption,
    total: int,
) -> None:
    """Build the plan's items on ``where = (workers, scheduler)``, reporting progress."""
    workers, scheduler = where
    n_workers = min(int(workers or os.cpu_count() or 1), max(len(plan.items), 1))
    done = total - len(plan.items) - sum(len(t) for t in plan.twins.values())
    with Progress(total, done=done, progress=progress) as bar:
        for item, result in _dispatch(plan.items, config, n_workers, scheduler, plan.unchanged):
            twins = plan.twins.pop(item.content_hash, [])
            committer.add(item, result, twins)
            done += 1 + len(twins)
            bar.update(done)


def _check_arguments(
    as_: str | None,
    batch_size: int,
    workers: int | None,
    max_bytes: int | None,
    max_faces: int | None,
) -> None:
    if as_ not in AS_OPTIONS:
        raise ConfigError(f"as_={as_!r} is invalid: must be one of {list(AS_OPTIONS)}")
    for name, value, required in (
        ("batch_size", batch_size, True),
        ("workers", workers, False),
        ("max_bytes", max_bytes, False),
        ("max_faces", max_faces, False),
    ):
        if value is None and not required:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ConfigError(f"{name}={value!r} is invalid: must be an integer >= 1")


@dataclass
class _Plan:
    """What to build, and what the labels matched.

    ``items`` go to the workers; ``twins`` holds, by content hash, later inputs with
    the same content as an item, which take that item's outcome (a second copy of a
    stored file is unchanged, of a failing file failed) without being built twice.
    """

    present: dict[str, int]
    items: list[_Item] = field(default_factory=list)
    twins: dict[str, list[_Item]] = field(default_factory=dict)
    failures: list[Failure] = field(default_factory=list)
    unchanged: int = 0
    looked_up: int = 0
    matched: set[str] = field(default_factory=set)
    unlabelled: list[str] = field(default_factory=list)
    labels_matched: int | None = None


def _plan(
    entries: list[tuple[str, Path | Geometry, bool, str | None]],
    present: dict[str, int],
    ledger: Ledger,
    *,
    table: LabelTable | None,
    label_from_folder: bool,
    names: Sequence[str] | None,
    force: bool,
    limits: Mapping[str, Any],
) -> _Plan:
    """Hash every input, mark what the store holds unchanged, fail unreadable inputs.

    Raises :class:`ConfigError` when a label table matches none of the inputs.
    """
    plan = _Plan(present=present)
    first: dict[str, _Item] = {}
    for k, (source, obj, explicit, given_label) in enumerate(entries):
        try:
            item = _make_item(k, source, obj, explicit, given_label, table=table,
                              label_from_folder=label_from_folder,
                              name=names[k] if names is not None else None, limits=limits)  # fmt: skip
        except Exception as exc:  # any bad input becomes a failure row, never a crash
            if not isinstance(exc, (ShapeDBError, OSError)):
                log.debug("unexpected error reading %s", safe_text(source), exc_info=True)
            f = Failure.from_exception(safe_text(source), exc)
            plan.failures.append(f)
            ledger.failed(k, f.source, f"{f.error}: {safe_text(f.message)}")
            continue
        if table is not None:
            plan.looked_up += 1
            if item.label_key is None:
                plan.unlabelled.append(item.source)
            else:
                plan.matched.add(item.label_key)
        if item.content_hash in present and not force:
            ledger.unchanged(k, item.source, "same content already stored")
            plan.unchanged += 1
        elif item.content_hash in first:
            plan.twins.setdefault(item.content_hash, []).append(item)
        else:
            first[item.content_hash] = item
            plan.items.append(item)
    if table is not None:  # raises when the labels match none of the inputs
        plan.labels_matched = summarise_matches(
            table, plan.looked_up, plan.matched, plan.unlabelled
        )
    return plan


def _dispatch(
    items: list[_Item], config: Config, n_workers: int, scheduler: Any, n_unchanged: int
) -> Iterator[tuple[_Item, ShapeRecord | Failure]]:
    """Build the items on workers; yield ``(item, record or failure)`` as they finish.

    Results of one wait are yielded in input order, so with one worker the batches
    are prefixes of the input.
    """
    if not items:
        return
    pool, close, how = executor(n_workers, scheduler)
    log.info("ingesting %d input(s) with %s (%d unchanged)", len(items), how, n_unchanged)
    is_dask = scheduler is not None
    try:
        queue = iter(items)
        inflight: dict[Any, _Item] = {}
        window = max(2 * n_workers, 4) if not is_dask else 256
        while True:
            while len(inflight) < window:
                it = next(queue, None)
                if it is None:
                    break
                inflight[_submit(pool, it, config, is_dask)] = it
            if not inflight:
                break
            finished = wait_any(inflight, is_dask)
            for fut in sorted(finished, key=lambda f: inflight[f].index):
                it = inflight.pop(fut)
                yield it, result(fut, it)
    finally:
        close()


class _Committer:
    """Collects results and commits them in batches (the store's lock held by the caller)."""

    def __init__(
        self,
        db: IngestTarget,
        present: dict[str, int],
        batch_size: int,
        commit_seconds: float,
        ledger: Ledger,
    ) -> None:
        self.db = db
        self.present = present
        self.batch_size = batch_size
        self.commit_seconds = commit_seconds
        self.ledger = ledger
        self.pending: list[tuple[_Item, ShapeRecord]] = []
        self.failures: list[Failure] = []
        self.notes: list[tuple[str, str]] = []
        self.last_commit = time.monotonic()

    def add(self, item: _Item, result: ShapeRecord | Failure, twins: Sequence[_Item] = ()) -> None:
        """Queue one result (and its twins'); commit when the batch is full or old enough."""
        if isinstance(result, Failure):
            reason = f"{result.error}: {safe_text(result.message)}"
            for it in (item, *twins):
                self.failures.append(replace(result, source=it.source))
                self.ledger.failed(it.index, it.source, reason)
        else:
            self.pending.append((item, result))
            for twin in twins:
                self.ledger.unchanged(twin.index, twin.source, f"same content as {item.source}")
            note = _note(item, result)
            if note:
                self.notes.append((item.source, note))
        if (
            len(self.pending) + len(self.failures) >= self.batch_size
            or time.monotonic() - self.last_commit > self.commit_seconds
        ):
            self.flush()

    def flush(self) -> None:
        """Commit what is queued, as one atomic commit."""
        if not self.pending and not self.failures:
            return
        self.pending.sort(key=lambda t: t[0].index)
        records, replace_ids = [], []
        for _, rec in self.pending:
            old = self.present.get(rec.content_hash)
            if old is not None:  # force: rebuild in place, keeping the id
                rec = _with_id(rec, old)
                replace_ids.append(old)
            records.append(rec)
        _, committed = self.db.commit(records, failures=self.failures, delete=replace_ids)
        for (item, _), rec in zip(self.pending, committed, strict=True):
            assert rec.id is not None  # the store numbers every record it commits
            self.ledger.stored(item.index, item.source, int(rec.id))
        self.pending, self.failures = [], []
        self.last_commit = time.monotonic()


_FACED = frozenset({".obj", ".off", ".stl", ".glb", ".gltf"})


def _note(item: _Item, record: ShapeRecord) -> str | None:
    """What the report should say about a stored shape, beyond "stored"."""
    if (
        item.path is not None
        and item.as_ is None
        and record.representation == "pointcloud"
        and Path(item.path).suffix.lower() in _FACED
    ):
        suffix = Path(item.path).suffix.upper()[1:]
        return (
            f"the {suffix} file has vertices and no faces (cut short?): "
            "stored as a point cloud of its vertices"
        )
    return None


def _with_id(rec: ShapeRecord, sid: int) -> ShapeRecord:
    return replace(rec, id=sid)


def _submit(executor: Any, item: _Item, config: Config, dask: bool) -> Any:
    if dask:
        return executor.submit(build_record, item, config, pure=False)
    return executor.submit(build_record, item, config)


def _label_table(labels: Any) -> LabelTable | None:
    if labels is None or isinstance(labels, LabelTable):
        return labels
    if isinstance(labels, Mapping):
        return LabelTable.from_mapping({str(k): str(v) for k, v in labels.items()})
    return read_labels(labels)


def _make_item(
    index: int,
    source: str,
    obj: Path | Geometry,
    explicit: bool,
    given_label: str | None,
    *,
    table: LabelTable | None,
    label_from_folder: bool,
    name: str | None,
    limits: Mapping[str, Any],
) -> _Item:
    if isinstance(obj, Geometry):
        h = geometry_hash(obj)
        nm = safe_text(name or source or f"shape-{h[:8]}")
        key = table.match(nm) if table is not None else None
        found = table.lookup(nm) if key is not None and table is not None else None
        return _Item(
            index=index,
            source=nm,
            name=nm,
            content_hash=h,
            geometry=obj,
            label=given_label if given_label is not None else (found.label if found else None),
            label_key=key,
            metadata=dict(found.metadata) if found else {},
        )
    path = Path(obj)
    src = safe_text(str(path))
    if not path.is_file():
        raise LoadError("no such file" if not path.exists() else "not a regular file", source=src)
    max_bytes = limits.get("max_bytes")
    if max_bytes is not None and path.stat().st_size > max_bytes:
        raise LoadError(
            f"file has {path.stat().st_size} bytes, above the cap max_bytes={max_bytes}",
            source=src,
        )
    key = table.match(path) if table is not None else None
    entry: LabelEntry | None = table.lookup(path) if key is not None and table is not None else None
    label = entry.label if entry is not None else None
    if label is None and label_from_folder:
        label = folder_label(path)
    as_ = limits.get("as_")
    return _Item(
        index=index,
        source=src,
        name=safe_text(name or path.stem),
        content_hash=content_hash(path, as_=as_),
        path=str(path),
        as_=as_,
        label=None if label is None else safe_text(label),
        label_key=key,
        metadata=dict(entry.metadata) if entry else {},
        max_bytes=max_bytes,
        max_faces=limits.get("max_faces"),
    )
