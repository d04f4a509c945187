"""Ingest files, folders and in-memory shapes into a database, in parallel.

``ingest(db, inputs)`` expands folders, hashes every file, skips what the store
already holds (same content, same configuration), computes the decompositions and
features in parallel (a process pool on this machine, or a Dask cluster when a
scheduler is given), and commits the results in batches. Each batch is one atomic
commit, so a crash loses at most the batch in flight and a re-run completes it.
Failures never stop the run: they are recorded in the store and in the report.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import logging
import multiprocessing
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ingest.labels import LabelEntry, LabelTable, folder_label, read_labels
from ingest.loaders import AS_OPTIONS, SUPPORTED, load
from shapedb.config import Config
from shapedb.errors import ConfigError, LoadError, MissingDependencyError, ShapeDBError
from shapedb.geometry import Geometry
from shapedb.schema import Failure, ShapeRecord

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

COMPANION_SUFFIXES = frozenset(
    {
        ".mtl",
        ".png",
        ".jpg",
        ".jpeg",
        ".bmp",
        ".tga",
        ".tif",
        ".tiff",
        ".gif",
        ".bin",
        ".txt",
        ".md",
        ".csv",
        ".json",
        ".cla",
        ".pdf",
        ".html",
        ".log",
        ".ini",
        ".yaml",
        ".yml",
        ".db",
        ".parquet",
    }
)
"""Files skipped silently while walking a folder (materials, textures, docs, tables)."""


@dataclass(frozen=True)
class IngestReport:
    """What an ingest did.

    Attributes
    ----------
    ingested : tuple[int, ...]
        Ids of the shapes added, in input order.
    skipped : tuple[str, ...]
        Inputs already in the store (same content and configuration).
    failed : tuple[tuple[str, str], ...]
        ``(input, reason)`` of every input that could not be ingested.
    seconds : float
        Wall time.
    """

    ingested: tuple[int, ...] = ()
    skipped: tuple[str, ...] = ()
    failed: tuple[tuple[str, str], ...] = ()
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """``{"ingested": n, "skipped": n, "failed": [{"path", "error"}]}`` (the CLI's JSON)."""
        return {
            "ingested": len(self.ingested),
            "skipped": len(self.skipped),
            "failed": [{"path": p, "error": e} for p, e in self.failed],
        }

    def __repr__(self) -> str:
        return (
            f"IngestReport(ingested={len(self.ingested)}, skipped={len(self.skipped)}, "
            f"failed={len(self.failed)}, seconds={self.seconds:.1f})"
        )


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
    metadata: Mapping[str, str] = field(default_factory=dict)


# ---------------------------------------------------------------- hashing
def content_hash(path: str | os.PathLike[str], *, as_: str | None = None) -> str:
    """sha256 of a file's bytes (followed by ``\\0as=<as_>`` when a representation is forced)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    if as_ is not None:
        h.update(f"\0as={as_}".encode())
    return h.hexdigest()


def geometry_hash(geometry: Geometry) -> str:
    """sha256 of an in-memory shape: its arrays, or its distance on a fixed lattice."""
    from shapedb.pointcloud import PointCloud

    h = hashlib.sha256(type(geometry).__qualname__.encode())
    # a cloud's given normals only: asking for ``normals`` would estimate them here, in
    # the model's frame, and its decomposition would then reuse them (PointCloud.transformed)
    normals = "_given_normals" if isinstance(geometry, PointCloud) else "normals"
    arrays = [
        getattr(geometry, a, None)
        for a in ("vertices", "faces", "points", normals, "occupancy", "origin", "pitch")
    ]
    arrays = [a for a in arrays if a is not None]
    if arrays:
        for a in arrays:
            arr = np.ascontiguousarray(np.asarray(a))
            h.update(str((arr.dtype.str, arr.shape)).encode())
            h.update(arr.tobytes())
    else:  # implicit and other functional shapes: sample the distance
        b = np.asarray(geometry.bounds, dtype=np.float64)
        h.update(b.tobytes())
        t = np.linspace(0.0, 1.0, 9)
        g = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
        pts = b[0] + g * (b[1] - b[0])
        h.update(np.round(np.asarray(geometry.signed_distance(pts)), 9).tobytes())
    return h.hexdigest()


# ---------------------------------------------------------------- inputs
def expand(inputs: Any) -> Iterator[tuple[str, Path | Geometry, bool, str | None]]:
    """Yield ``(source, path_or_geometry, explicit, label)`` for files, folders and shapes.

    Inputs are paths, Geometry objects, ``(name, geometry)`` or
    ``(name, label, geometry)`` tuples, or a ``{name: geometry}`` mapping. Folders are
    walked recursively in sorted order; hidden files and companion files
    (:data:`COMPANION_SUFFIXES`) found there are skipped. ``explicit`` is False for
    files found by walking; ``label`` is set only by ``(name, label, geometry)``.
    """
    if isinstance(inputs, (str, os.PathLike, Geometry)):
        inputs = [inputs]
    elif isinstance(inputs, Mapping):  # {name: geometry}
        inputs = list(inputs.items())
    for entry in inputs:
        if isinstance(entry, Geometry):
            yield (getattr(entry, "name", None) or "", entry, True, None)
        elif isinstance(entry, tuple) and entry and isinstance(entry[-1], Geometry):
            label = str(entry[1]) if len(entry) == 3 and entry[1] is not None else None
            yield (str(entry[0]), entry[-1], True, label)
        else:
            p = Path(entry).absolute()
            if p.is_dir():
                for root, dirs, files in os.walk(p):
                    dirs[:] = sorted(d for d in dirs if not d.startswith("."))
                    for f in sorted(files):
                        q = Path(root) / f
                        if f.startswith(".") or q.suffix.lower() in COMPANION_SUFFIXES:
                            continue
                        yield (str(q), q, False, None)
            else:
                yield (str(p), p, True, None)


# ---------------------------------------------------------------- the work
def build_record(item: _Item, config: Config) -> ShapeRecord | Failure:
    """Load, decompose and featurise one item (runs in a worker).

    Never raises for a bad input: returns a :class:`Failure` instead.
    """
    from shapedb.kernel import features
    from shapedb.mdbd import decompose

    t0, c0 = time.perf_counter(), time.process_time()
    try:
        geometry = item.geometry if item.geometry is not None else load(item.path, as_=item.as_)  # type: ignore[arg-type]
        t_load = time.perf_counter() - t0
        decomposition = decompose(geometry, config=config.mdbd)
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
        timings["load"] = t_load
        timings["features"] = t2 - t1
        timings["cpu"] = time.process_time() - c0  # this process's CPU seconds
        decomposition = replace(decomposition, timings=timings)
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
        source=item.path,
        build_seconds=time.perf_counter() - t0,
        view_feature=view,
    )


def _view_feature(geometry: Any, decomposition: Any, config: Config) -> NDArray[np.float32] | None:
    """The shape's second feature, or None.

    A sparse point cloud's reconstruction (:mod:`shapedb.reconstruct`, when kept); a
    dense shape's sparse view (:mod:`shapedb.view`), when the store keeps views.
    """
    from shapedb.kernel import features
    from shapedb.mdbd import decompose
    from shapedb.reconstruct import reconstructed
    from shapedb.view import is_sparse, view_geometry

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


class _Serial:
    """A stand-in executor that runs each task in the calling process."""

    def submit(self, fn: Callable[..., Any], *args: Any) -> cf.Future[Any]:
        fut: cf.Future[Any] = cf.Future()
        try:
            fut.set_result(fn(*args))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            fut.set_exception(exc)
        return fut

    def shutdown(self) -> None:
        pass


def _executor(workers: int, scheduler: Any) -> tuple[Any, Callable[[], None], str]:
    """(submit-able executor, close function, description)."""
    if scheduler is not None:
        try:
            from distributed import Client
        except ImportError as exc:
            raise MissingDependencyError(
                f"ingesting on the Dask cluster {scheduler!r} needs the optional dependency "
                "dask[distributed]: install it with  pip install 'shapedb[distributed]'"
            ) from exc
        if isinstance(scheduler, Client):
            return scheduler, lambda: None, f"dask {scheduler.scheduler.address}"
        client = Client(scheduler)
        return client, client.close, f"dask {scheduler}"
    if workers <= 1:
        return _Serial(), lambda: None, "serial"
    # forkserver, not fork: the caller may run threads (progress bars, Dask). Workers
    # fork from a server that imported and warmed everything once (ingest._warmup).
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["__main__", "ingest.pipeline", "ingest._warmup"])
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_watch_parent)
    return pool, lambda: pool.shutdown(wait=True, cancel_futures=True), f"{workers} processes"


def _watch_parent() -> None:
    """Worker initializer: exit when the ingesting process dies (even by SIGKILL)."""
    import threading

    parent = multiprocessing.parent_process()
    if parent is None:  # pragma: no cover
        return

    def watch() -> None:
        parent.join()
        os._exit(70)

    threading.Thread(target=watch, name="shapedb-parent-watch", daemon=True).start()


def _wait_any(futures: Iterable[Any], dask: bool) -> set[Any]:
    if dask:
        from distributed import wait

        return set(wait(list(futures), return_when="FIRST_COMPLETED").done)
    done, _ = cf.wait(list(futures), return_when=cf.FIRST_COMPLETED)
    return done


# ---------------------------------------------------------------- driver
def ingest(
    db: Any,
    inputs: Any,
    *,
    labels: str | os.PathLike[str] | Mapping[str, str] | LabelTable | None = None,
    label_from_folder: bool = False,
    as_: str | None = None,
    names: Sequence[str] | None = None,
    workers: int | None = None,
    scheduler: Any = None,
    force: bool = False,
    progress: bool | Callable[[int, int], None] = False,
    batch_size: int = 32,
    commit_seconds: float = 30.0,
) -> IngestReport:
    """Add files, folders and in-memory shapes to ``db``.

    Parameters
    ----------
    db : shapedb.Database
        Target database; its configuration is used for every shape.
    inputs : path, Geometry, or a sequence / mapping of them
        Files, folders (walked recursively), Geometry objects, ``(name, geometry)``
        pairs or a ``{name: geometry}`` mapping.
    labels : path, mapping or LabelTable, optional
        A labels CSV (``path,label,...``; extra columns become metadata), or
        ``{path: label}``.
    label_from_folder : bool
        Label each file by its parent folder's name (when the CSV gives none).
    as_ : {None, "mesh", "pointcloud", "smooth_voxels"}
        Force the representation of files (see :func:`ingest.loaders.load`).
    names : sequence of str, optional
        Names of the inputs, one per input (not for folders); default: the file stem.
    workers : int, optional
        Worker processes; default ``os.cpu_count()``; 1 runs in this process.
    scheduler : str or distributed.Client, optional
        Run on a Dask cluster instead (its address, e.g. ``"tcp://host:8786"``).
    force : bool
        Rebuild shapes already in the store (they keep their ids).
    progress : bool or callable
        ``progress(done, total)`` after each input; True logs progress.
    batch_size : int
        Results per atomic commit.
    commit_seconds : float
        Commit a partial batch when this much time passed since the last commit.

    Returns
    -------
    IngestReport
    """
    t_start = time.perf_counter()
    if as_ not in AS_OPTIONS:
        raise ConfigError(f"as_={as_!r} is invalid: must be one of {list(AS_OPTIONS)}")
    if batch_size < 1:
        raise ConfigError(f"batch_size={batch_size!r} is invalid: must be >= 1")
    config: Config = db.config
    store = db.store
    table = _label_table(labels)
    entries = list(expand(inputs))
    if names is not None:
        if len(names) != len(entries):
            raise ConfigError(
                f"names has {len(names)} entries but the inputs expand to "
                f"{len(entries)}; give one name per input file or shape"
            )
    report_failed: list[tuple[str, str]] = []
    failures: list[Failure] = []
    items: list[_Item] = []
    seen: dict[str, str] = {}
    skipped: list[str] = []
    with store.writer():
        present = store.hashes()
        for k, (source, obj, explicit, given_label) in enumerate(entries):
            try:
                item = _make_item(
                    k,
                    source,
                    obj,
                    explicit,
                    given_label,
                    as_=as_,
                    table=table,
                    label_from_folder=label_from_folder,
                    name=names[k] if names is not None else None,
                )
            except (ShapeDBError, OSError) as exc:
                f = Failure.from_exception(source, exc)
                failures.append(f)
                report_failed.append((source, f"{f.error}: {f.message}"))
                continue
            if item.content_hash in seen or (item.content_hash in present and not force):
                skipped.append(source)
                continue
            seen[item.content_hash] = source
            items.append(item)
        n_workers = max(1, int(workers or os.cpu_count() or 1))
        n_workers = min(n_workers, max(len(items), 1))
        total = len(entries)
        done = len(entries) - len(items)
        notify = _progress(progress)
        notify(done, total)
        ingested: dict[int, int] = {}
        pending: list[tuple[int, ShapeRecord]] = []
        last_commit = time.monotonic()

        def flush() -> None:
            nonlocal last_commit, pending, failures
            if not pending and not failures:
                return
            pending.sort(key=lambda t: t[0])
            records = []
            replace_ids = []
            for _, rec in pending:
                old = present.get(rec.content_hash)
                if old is not None:  # force: rebuild in place, keeping the id
                    rec = _with_id(rec, old)
                    replace_ids.append(old)
                records.append(rec)
            _, committed = db.commit(records, failures=failures, delete=replace_ids)
            for (index, _), rec in zip(pending, committed, strict=True):
                ingested[index] = int(rec.id)  # type: ignore[arg-type]
            pending, failures = [], []
            last_commit = time.monotonic()

        if items:
            executor, close, how = _executor(n_workers, scheduler)
            log.info("ingesting %d input(s) with %s (%d skipped)", len(items), how, len(skipped))
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
                        inflight[_submit(executor, it, config, is_dask)] = it
                    if not inflight:
                        break
                    finished = _wait_any(inflight, is_dask)
                    # in input order: with one worker, batches are prefixes of the input
                    for fut in sorted(finished, key=lambda f: inflight[f].index):
                        it = inflight.pop(fut)
                        result = _result(fut, it)
                        if isinstance(result, Failure):
                            failures.append(result)
                            report_failed.append((it.source, f"{result.error}: {result.message}"))
                        else:
                            pending.append((it.index, result))
                        done += 1
                        notify(done, total)
                        if (
                            len(pending) + len(failures) >= batch_size
                            or time.monotonic() - last_commit > commit_seconds
                        ):
                            flush()
            finally:
                close()
        flush()
    order = [ingested[k] for k in sorted(ingested)]
    report = IngestReport(
        ingested=tuple(order),
        skipped=tuple(skipped),
        failed=tuple(report_failed),
        seconds=time.perf_counter() - t_start,
    )
    log.info("ingest done: %r", report)
    return report


def _with_id(rec: ShapeRecord, sid: int) -> ShapeRecord:
    return replace(rec, id=sid)


def _submit(executor: Any, item: _Item, config: Config, dask: bool) -> Any:
    if dask:
        return executor.submit(build_record, item, config, pure=False)
    return executor.submit(build_record, item, config)


def _result(fut: Any, item: _Item) -> ShapeRecord | Failure:
    try:
        return fut.result()  # type: ignore[no-any-return]
    except cf.process.BrokenProcessPool as exc:
        raise ShapeDBError(
            f"a worker process died while ingesting {item.source}; "
            "the batches committed so far are kept: re-run to continue"
        ) from exc
    except Exception as exc:  # an unexpected error inside the worker
        log.warning("ingesting %s failed unexpectedly", item.source, exc_info=True)
        return Failure.from_exception(item.source, exc)


def _progress(progress: bool | Callable[[int, int], None]) -> Callable[[int, int], None]:
    if callable(progress):
        return progress
    if progress:
        return lambda done, total: log.info("ingest: %d / %d", done, total)
    return lambda done, total: None


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
    as_: str | None,
    table: LabelTable | None,
    label_from_folder: bool,
    name: str | None,
) -> _Item:
    if isinstance(obj, Geometry):
        h = geometry_hash(obj)
        nm = name or source or f"shape-{h[:8]}"
        found = table.lookup(nm) if table is not None else None
        return _Item(
            index=index,
            source=nm,
            name=nm,
            content_hash=h,
            geometry=obj,
            label=given_label if given_label is not None else (found.label if found else None),
            metadata=dict(found.metadata) if found else {},
        )
    path = Path(obj)
    if not path.is_file():
        raise LoadError(
            "no such file" if not path.exists() else "not a regular file", source=str(path)
        )
    if not explicit and path.suffix.lower() not in SUPPORTED:
        from ingest.loaders import detect_format

        detect_format(path)  # raises UnsupportedFormatError unless the content tells
    entry: LabelEntry | None = table.lookup(path) if table is not None else None
    label = entry.label if entry is not None else None
    if label is None and label_from_folder:
        label = folder_label(path)
    return _Item(
        index=index,
        source=str(path),
        name=name or path.stem,
        content_hash=content_hash(path, as_=as_),
        path=str(path),
        as_=as_,
        label=label,
        metadata=dict(entry.metadata) if entry else {},
    )
