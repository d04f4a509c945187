"""The user-facing facade: ``db = shapedb.connect(path)``.

:class:`Database` wraps a :class:`~shapedb.store.store.Store` and its configuration. The
stages it calls (ingest, search, SQL, matching, evaluation, learning) sit below it, in
``ingest`` and ``query``; each method imports the function it calls, so a reader follows
any call by its imports. After every commit the derived state that was already built
(the faiss indexes and the re-ranking stage's side tables) is brought up to date, and the
web page's thumbnails of the new shapes are drawn.
``shapedb.connect`` and ``shapedb.Database`` are lazy re-exports of this module.
"""

from __future__ import annotations

import logging
import os
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from query.sql import DEFAULT_MEMORY_LIMIT, DEFAULT_TIMEOUT, InterruptHandle
from shapedb.config.core import Config
from shapedb.config.part import PartConfig
from shapedb.errors import ConfigError, NotFoundError, StoreError
from shapedb.results import (
    Classification,
    Classifier,
    FailureInfo,
    Hit,
    IngestInputs,
    IngestReport,
    Metric,
    PartMatch,
    PartQuery,
    RetrievalScores,
    SearchQuery,
    ShapeRef,
    StoreInfo,
)
from shapedb.store.schema import Failure, ShapeRecord
from shapedb.store.store import CommitResult, Store

if TYPE_CHECKING:
    from shapedb.geometry.base import Geometry

__all__ = ["connect", "Database"]

log = logging.getLogger(__name__)


def connect(
    path: str | os.PathLike[str],
    *,
    create: bool = True,
    config: Config | None = None,
    lock_timeout: float = 10.0,
    **options: bool | int | float | str,
) -> Database:
    """Open the store in ``path``, creating it if needed.

    Parameters
    ----------
    path : str or Path
        Store directory.
    create : bool
        Create the store when ``path`` holds none; otherwise raise :class:`StoreError`.
    config : Config, optional
        Configuration of a new store. For an existing store it must equal the stored one.
    lock_timeout : float
        Seconds a write waits for another writer to finish.
    **options
        Flat configuration options (``resolution``, ``n_balls``, ``n_r``, ``descriptor``...,
        :data:`shapedb.config.core.OPTIONS`) applied on top of ``config``. For an existing store they must agree with its config.

    Returns
    -------
    Database

    Examples
    --------
    >>> db = shapedb.connect("shapes.db", resolution=64)  # doctest: +SKIP
    >>> db.ingest(["models/"])                             # doctest: +SKIP
    """
    root = Path(path)
    requested = None
    if config is not None or options:
        requested = (config or Config()).with_options(**options)
    if Store.exists(root):
        store = Store.open(root, lock_timeout=lock_timeout)
        if requested is not None and requested != store.config:
            raise ConfigError(
                f"the store was built with another configuration ({_diff(store.config, requested)}); "
                "open it without options, or ingest into a new store",
                source=str(root),
            )
    elif create:
        try:
            store = Store.create(root, requested, lock_timeout=lock_timeout)
        except StoreError:
            if not Store.exists(root):
                raise
            # another process created it first: open it (and compare configurations)
            return connect(root, create=False, config=config, lock_timeout=lock_timeout, **options)
    else:
        raise StoreError("no shapedb store here", source=str(root))
    return Database(store)


def _diff(have: Config, want: Config) -> str:
    a, b = have.options(), want.options()
    return "; ".join(f"{k}: store {a[k]!r}, requested {b[k]!r}" for k in a if a[k] != b[k])


class Database:
    """A shape database: a store plus the operations of every stage.

    Parameters
    ----------
    store : Store
        The store on disk.
    """

    def __init__(self, store: Store) -> None:
        self.store = store

    @property
    def config(self) -> Config:
        """The configuration of every shape in the database."""
        return self.store.config

    @property
    def path(self) -> Path:
        """The store directory."""
        return self.store.path

    def __len__(self) -> int:
        return len(self.store)

    def __repr__(self) -> str:
        return f"<Database {str(self.store.path)!r} shapes={len(self.store)}>"

    # ---------------------------------------------------------------- commits
    def close(self) -> None:
        """Release what this process keeps in memory for the store: its feature, field
        vector and part indexes, the memory-mapped arrays, the stage's side tables and the
        catalog. The store on disk is untouched and the handle stays usable: the next
        search loads what it needs again. A long-lived process (a server, a benchmark that
        grew a store) calls it before handing the memory to another.
        """
        import gc

        from query import sql
        from query.parts import store_index
        from query.search import (
            catalog,
            field_index,
            index,
            lightfield_neighbours,
            lightfield_spread,
            rerank_lightfield,
        )

        path = os.fspath(self.store.path)
        index.forget(self)
        store_index.forget(self)
        field_index.forget(path)
        rerank_lightfield.forget(path)  # and the array caches it reads
        lightfield_neighbours.forget(path)
        lightfield_spread.forget(path)
        catalog.forget(path)
        sql.forget(path)
        gc.collect()

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc: object) -> None:
        """``with shapedb.connect(path) as db:`` releases the memory at the end (:meth:`close`)."""
        self.close()

    def commit(
        self,
        records: Sequence[ShapeRecord] = (),
        *,
        failures: Sequence[Failure] = (),
        delete: Iterable[int] = (),
    ) -> tuple[CommitResult, list[ShapeRecord]]:
        """Commit to the store atomically and notify the ``on_commit`` extension.

        Returns the commit result and the committed records (with their ids).
        """
        committed: list[ShapeRecord] = []
        result = self.store.commit(records, failures=failures, delete=delete, assigned=committed)
        if result.added or result.deleted:
            self._notify(result)
            self._draw_thumbnails(committed, result.deleted)
        return result, committed

    def _draw_thumbnails(self, committed: Sequence[ShapeRecord], deleted: Sequence[int]) -> None:
        """Draw the web page's thumbnails of the committed shapes (derived state: a failure
        is logged and the commit stands; a few milliseconds a shape)."""
        from query.thumbnails import draw_committed

        try:
            draw_committed(self.path, committed, deleted)
        except Exception:  # noqa: BLE001 - the page draws a missing one at its first view
            log.warning("drawing thumbnails failed after a commit", exc_info=True)

    def _notify(self, result: CommitResult) -> None:
        """Bring the derived state already on disk up to date: the indexes, the array caches
        (:mod:`query.search.array_cache`), and the re-ranking stage's side tables (their
        writers: this and the end of :meth:`ingest`)."""
        from query.parts import store_index as parts_index
        from query.search import array_cache, index

        try:
            index.on_commit(self, result)
            parts_index.on_commit(self, result)
            array_cache.on_commit(self)
            self._write_side_tables(create=False)
        except Exception:  # derived state only: the commit itself stands
            log.warning(
                "updating the indexes failed after version %d", result.version, exc_info=True
            )

    def _write_side_tables(self, *, create: bool) -> None:
        """Compute and write the stage's side tables (spreads, shared-neighbour lists) at the
        store's version: those already written (``create`` False), or all of them."""
        from query.search import lightfield_neighbours, lightfield_spread
        from query.search.rerank_lightfield import stored_arrays
        from query.search.stage import scorer_for

        stage = scorer_for(self.config)
        if stage is None or not len(self.store):
            return
        lightfield_spread.on_commit(self, stored_arrays(self), create=create)
        lightfield_neighbours.on_commit(self, stored_arrays(self), stage, create=create)

    # ---------------------------------------------------------------- ingest
    def ingest(
        self,
        inputs: IngestInputs,
        *,
        labels: str | os.PathLike[str] | Mapping[str, str] | None = None,
        label_from_folder: bool = False,
        as_: str | None = None,
        names: Sequence[str] | None = None,
        workers: int | None = None,
        scheduler: str | object | None = None,
        force: bool = False,
        progress: bool | Callable[[int, int], None] = True,
        batch_size: int = 32,
        commit_seconds: float = 30.0,
        max_bytes: int | None = None,
        max_faces: int | None = None,
    ) -> IngestReport:
        """Decompose files, folders or in-memory shapes and store them.

        Parameters
        ----------
        inputs : path, Geometry, ``(name, [label,] geometry)``, or several of them
            Files, folders (walked recursively), shapes, or ``{name: geometry}``.
        labels : path or mapping, optional
            A labels CSV (``path,label,...``; extra columns become metadata), or
            ``{path: label}``.
        label_from_folder : bool
            Label each file by its parent folder's name (when the CSV gives none).
        as_ : {None, "mesh", "pointcloud", "smooth_voxels"}
            Force the representation of files.
        names : sequence of str, optional
            One name per input (not for folders); default: the file stem.
        workers : int, optional
            Worker processes; default ``os.cpu_count()``; 1 runs in this process.
        scheduler : str or distributed.Client, optional
            Run on a Dask cluster instead (its address, e.g. ``"tcp://host:8786"``).
        force : bool
            Rebuild shapes already in the store (they keep their ids).
        progress : bool or callable
            True: a progress bar on a terminal, else a log line every few seconds
            (count, rate, time left); False: silent; a callable:
            ``progress(done, total)`` after each input.
        batch_size : int
            Results per atomic commit.
        commit_seconds : float
            Commit a partial batch when this much time passed since the last commit.
        max_bytes, max_faces : int, optional
            Refuse (as a failure row) any file larger than this many bytes, or any mesh
            with more faces, so one giant file cannot take the machine's memory.

        Returns
        -------
        IngestReport
            One outcome per input: stored (ids), unchanged, failed (with reasons),
            ignored (with why) (:func:`ingest.pipeline.ingest`).
        """
        from ingest.pipeline import ingest

        report = ingest(
            self,
            inputs,
            labels=labels,
            label_from_folder=label_from_folder,
            as_=as_,
            names=names,
            workers=workers,
            scheduler=scheduler,
            force=force,
            progress=progress,
            batch_size=batch_size,
            commit_seconds=commit_seconds,
            max_bytes=max_bytes,
            max_faces=max_faces,
        )
        try:  # once per ingest, not per batch: the stage's tables for later processes
            self._write_side_tables(create=True)
        except Exception:  # derived state only: what was ingested stands
            log.warning("writing the re-ranking tables failed after ingest", exc_info=True)
        return cast(IngestReport, report)

    def delete(self, ids_or_names: int | str | Iterable[int | str]) -> int:
        """Remove shapes by id or name, in one commit; returns how many were removed.

        Raises :class:`NotFoundError` (and removes nothing) when one is unknown.
        """
        if isinstance(ids_or_names, (int, str)):
            ids_or_names = [ids_or_names]
        ids = {self.store.resolve(x) for x in ids_or_names}
        if not ids:
            return 0
        with self.store.writer():
            result, _ = self.commit(delete=ids)
        return len(result.deleted)

    # ---------------------------------------------------------------- reading
    def shapes(self, columns: Sequence[str] | None = None) -> pa.Table:
        """The ``shapes`` table as Arrow (all columns, or ``columns``)."""
        return self.store.shapes(columns)

    def get(self, id_or_name: int | str) -> ShapeRecord:
        """One shape, with its decomposition."""
        return self.store.get(id_or_name)

    def info(self) -> StoreInfo:
        """Summary, JSON-serialisable: ``{"shapes", "labels", "failures", "config"}``.

        ``shapes`` is the number of shapes; ``labels`` maps each label to its count
        (unlabelled shapes are not counted there); ``failures`` lists
        ``{"path", "error"}`` for every input that failed; ``config`` is the store's
        configuration (:class:`~shapedb.results.StoreInfo`).
        """
        labels = self.store.shapes(["label"]).column("label").to_pylist()
        counts = Counter(x for x in labels if x is not None)
        failures: list[FailureInfo] = [
            {"path": f["source"], "error": f"{f['error']}: {f['message']}"}
            for f in self.store.failures().to_pylist()
        ]
        return {
            "shapes": len(labels),
            "labels": dict(sorted(counts.items())),
            "failures": failures,
            "config": self.config.to_dict(),
        }

    def __contains__(self, id_or_name: object) -> bool:
        try:
            self.store.resolve(id_or_name)  # type: ignore[arg-type]
        except (NotFoundError, ValueError):
            return False
        return True

    # ---------------------------------------------------------------- query
    def search(
        self,
        query: SearchQuery,
        *,
        k: int = 10,
        where: str | None = None,
        metric: Metric | str | os.PathLike[str] | None = None,
        partial: bool | None = None,
    ) -> list[Hit]:
        """The ``k`` stored shapes most like ``query``, best first (``query.parts.partial.search``).

        Parameters
        ----------
        query : id, name, path, Geometry, Decomposition, ShapeRecord or (d,) feature
            What to look for.
        k : int
            Number of hits.
        where : str, optional
            SQL predicate over the ``shapes`` table (e.g. ``"label = 'Chair'"``); the
            search is then exhaustive.
        metric : Metric or path, optional
            A similarity fitted by :meth:`fit_metric` (or the file it was saved to);
            whole-shape search only.
        partial : bool or None
            True: the shapes that *contain* the query, by its parts against the store's
            part index (built on first use); False: the whole-shape search
            (``query.search.engine.search``); None: the whole-shape search (the part path
            measured no better for one-sided scans). Each hit's ``path`` says which one
            found it.

        Raises
        ------
        NotFoundError
            Unknown shape id or name.
        QueryError
            Malformed query, ``k``, ``where`` or ``partial``.
        """
        from query.parts.partial import search

        hits = search(self, query, k=k, where=where, metric=metric, partial=partial)
        return cast("list[Hit]", hits)

    def search_batch(
        self,
        queries: Sequence[SearchQuery],
        *,
        k: int = 10,
        where: str | None = None,
        metric: Metric | str | os.PathLike[str] | None = None,
        partial: bool | None = None,
    ) -> list[list[Hit]]:
        """:meth:`search` for many queries at once: one list of hits per query."""
        from query.parts.partial import search_batch

        hits = search_batch(self, queries, k=k, where=where, metric=metric, partial=partial)
        return cast("list[list[Hit]]", hits)

    def sql(
        self,
        statement: str,
        *,
        metric: Metric | str | os.PathLike[str] | None = None,
        timeout: float | None = DEFAULT_TIMEOUT,
        memory_limit: int = DEFAULT_MEMORY_LIMIT,
        interrupt: InterruptHandle | None = None,
    ) -> pa.Table:
        """Run a DuckDB statement over the views ``shapes``, ``balls``, ``edges``, ``failures``.

        ``metric`` weighs the macros ``mdbd_distance`` / ``mdbd_kernel`` by a learned
        similarity. ``timeout`` (seconds; None: no limit) and ``memory_limit`` (bytes)
        bound the statement, ``interrupt`` (``query.sql.InterruptHandle``) lets another
        thread stop it: a stopped statement is a one-line ``QueryError`` (``query.sql.sql``).
        """
        from query.sql import sql

        return cast(
            pa.Table,
            sql(
                self,
                statement,
                metric=metric,
                timeout=timeout,
                memory_limit=memory_limit,
                interrupt=interrupt,
            ),
        )

    def match(
        self,
        query: PartQuery,
        target: PartQuery | None = None,
        *,
        node: int | None = None,
        point: Sequence[float] | NDArray[np.float64] | None = None,
        hops: int = 2,
        top: int = 5,
        k: int = 10,
        config: PartConfig | None = None,
        where: str | None = None,
        per_shape: int = 1,
        complement: bool = False,
        overlap: float | None = 0.0,
    ) -> list[PartMatch]:
        """Stored parts most like a part of ``query`` (Algorithm 1, ``query.parts.match.match``).

        Parameters
        ----------
        query : shape or ContactGraph
            The model the part is taken from.
        target : shape or ContactGraph, optional
            Match against this one model instead of the store (its ``top`` best parts).
        node : int, optional
            Ball number of the query part's centre v (default: every part of ``query``,
            or the whole model).
        point : (3,) float, optional
            A point on the model; its nearest ball is ``node``.
        hops : int
            Neighbourhood range K.
        top : int
            Matches against a ``target``.
        k : int
            Matches from the store.
        config : PartConfig, optional
            Part kernel (default ``PartConfig()`` with ``hops``).
        where : str, optional
            SQL predicate restricting the stored shapes searched.
        per_shape : int
            Matches kept per stored shape.
        complement : bool
            Match the concave features (parts of the complement).
        overlap : float or None
            Largest node overlap between two matches of one shape (None: no suppression).
        """
        from query.parts.match import match

        matches = match(
            self,
            query,
            target,
            node=node,
            point=point,
            hops=hops,
            top=top,
            k=k,
            config=config,
            where=where,
            per_shape=per_shape,
            complement=complement,
            overlap=overlap,
        )
        return cast("list[PartMatch]", matches)

    def evaluate(
        self,
        *,
        label: str = "label",
        method: str | Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
        plot: str | os.PathLike[str] | None = None,
        metric: Metric | str | os.PathLike[str] | None = None,
    ) -> RetrievalScores:
        """Leave-one-out retrieval quality by ``label`` (``query.evaluate.evaluate``).

        Parameters
        ----------
        label : str
            The ``label`` column, or a metadata key holding the class.
        method : str or callable, optional
            Another similarity of the stored features (see ``query.evaluate.evaluate``).
        plot : path, optional
            Where to save the precision-recall curve (PNG).
        metric : Metric or path, optional
            A similarity fitted by :meth:`fit_metric`.
        """
        from query.evaluate import evaluate

        scores = evaluate(self, label=label, method=method, plot=plot, metric=metric)
        return cast(RetrievalScores, scores)

    def fit_metric(
        self,
        *,
        label: str = "label",
        regs: Sequence[float] | None = None,
        temperature: float | None = None,
        folds: int | None = None,
        max_shapes: int | None = None,
        seed: int = 0,
    ) -> Metric:
        """Fit block weights of the similarity on the stored labels (``query.learn.metric``).

        Parameters
        ----------
        label : str
            The ``label`` column, or a metadata key holding the class.
        regs, temperature, folds, max_shapes : optional
            Settings of the fit (None: ``query.learn.metric``'s defaults).
        seed : int
            Seed of the class-stratified sample and of the folds.

        Returns
        -------
        Metric
            For ``search(..., metric=)`` and ``evaluate(metric=)``; the identity when
            cross-validation finds no gain.
        """
        given = {"regs": regs, "temperature": temperature, "folds": folds, "max_shapes": max_shapes}
        options = {key: value for key, value in given.items() if value is not None}
        from query.learn.metric import fit_store_metric

        metric = fit_store_metric(self, label=label, seed=seed, **options)
        return cast(Metric, metric)

    def show(
        self,
        model: ShapeRef,
        out: str | os.PathLike[str],
        *,
        complement: bool = False,
        title: str | None = None,
    ) -> Path:
        """Draw ``model`` with its MDBD balls into the PNG ``out`` (``query.render.show``).

        ``complement`` draws the decomposition of its complement instead.
        """
        from query.render import show

        picture = show(self, model, out, complement=complement, title=title)
        return cast(Path, picture)

    def render_matches(
        self,
        query: PartQuery,
        matches: Sequence[PartMatch],
        out: str | os.PathLike[str],
        *,
        complement: bool = False,
        title: str | None = None,
    ) -> Path:
        """Draw ``query`` and the parts ``matches`` found by :meth:`match` into the PNG ``out``."""
        from query.render import render_part_matches

        picture = render_part_matches(self, query, matches, out, complement=complement, title=title)
        return cast(Path, picture)

    def train_classifier(
        self,
        *,
        label: str = "label",
        methods: Sequence[str] | None = None,
        conv: str | None = None,
        out: str | os.PathLike[str] | None = None,
        plot: str | os.PathLike[str] | None = None,
        test: float = 0.15,
        validation: float = 0.2,
        folds: int | str = "auto",
        callback: Callable[[int, int, dict[str, float]], None] | None = None,
        epochs: int | None = None,
        rotate: bool | None = None,
        seed: int | None = None,
        device: str | None = None,
        lr: float | None = None,
        batch_size: int | None = None,
        hidden: int | None = None,
        dropout: float | None = None,
        weight_decay: float | None = None,
        warmup: int | None = None,
        budget: float | None = 300.0,
        progress: Callable[..., None] | None = None,
        resume: bool = True,
    ) -> Classifier:
        """Train the classifier that validates best on the stored shapes (``shapedb[learn]``).

        Implemented by ``query.learn.classify.train_classifier``: nearest neighbours on the
        descriptor, a linear model, boosting and the graph CNNs are scored on
        validation data from the training shapes only; never worse than 1-NN there.

        Parameters
        ----------
        label : str
            The ``label`` column, or a metadata key holding the class.
        methods : sequence of str, optional
            Candidates (``query.learn.selection.CANDIDATES``); default all.
        conv : {"tag", "arma", "spline"}, optional
            With no ``methods``: compare 1-NN with this graph CNN only.
        out, plot : path, optional
            Where to save the model and a graph CNN's training curve.
        test, validation : float
            Fractions held out for testing and (holdout protocol) for validation.
        folds : int or "auto"
            Validation folds; "auto" cross-validates when a class has under 20 shapes.
        callback : callable, optional
            ``callback(epoch, epochs, metrics)`` after every epoch.
        epochs, rotate, seed, device, lr, batch_size, hidden, dropout, weight_decay, warmup
            Classifier settings (None: ``query.learn.classify.GraphClassifier``'s defaults).
        budget : float or None
            Seconds for choosing and fitting (``query.learn.budget.DEFAULT_BUDGET``;
            None: no limit): cheapest candidates first, the graph CNNs only while it
            allows unless named in ``methods``.
        progress : callable, optional
            ``progress(query.learn.budget.Progress)`` at every fold and epoch.
        resume : bool
            Continue from the folds an earlier run with the same store and settings
            scored (``<out>.selection.json``).

        Returns
        -------
        Classifier
            Fitted; ``test_accuracy_`` measured on the held-out test split.
        """
        from query.learn.classify import train_classifier

        given = dict(epochs=epochs, rotate=rotate, seed=seed, device=device, lr=lr,
                     batch_size=batch_size, hidden=hidden, dropout=dropout,
                     weight_decay=weight_decay, warmup=warmup)  # fmt: skip
        model = train_classifier(
            self, label=label, methods=methods, conv=conv, out=out, plot=plot, test=test,
            validation=validation, folds=folds, callback=callback, budget=budget,
            progress=progress, resume=resume,
            **{key: value for key, value in given.items() if value is not None},
        )  # fmt: skip
        return cast(Classifier, model)

    def classify(
        self, model: Classifier | str | os.PathLike[str], shape: ShapeRef | list[ShapeRef]
    ) -> Classification | list[Classification]:
        """Label ``shape`` (or each of a list, one load) with a trained ``model`` or its file."""
        from query.learn.classify import classify

        return cast(
            "Classification | list[Classification]",
            classify(self, model, shape),  # type: ignore[arg-type]
        )

    def load(self, path: str | os.PathLike[str], *, as_: str | None = None) -> Geometry:
        """Read a file into a Geometry with the ``ingest`` loaders."""
        from ingest.loaders import load

        return cast("Geometry", load(path, as_=as_))
