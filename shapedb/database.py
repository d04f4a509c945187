"""The user-facing facade: ``db = shapedb.connect(path)``.

:class:`Database` wraps a :class:`~shapedb.store.Store` and its configuration. The
stages that sit downstream of the core (ingest, search, SQL, matching, evaluation)
live in the ``ingest`` and ``query`` packages, which the core never imports: their
functions are found through the ``shapedb.extensions`` entry points declared in
``pyproject.toml`` (:func:`_extension`), and each takes the database as its first
argument. After every commit the optional ``on_commit`` extension is called so that
derived state (the faiss index) follows the store.
"""

from __future__ import annotations

import logging
import os
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from functools import cache
from pathlib import Path
from typing import Any

import pyarrow as pa

from shapedb.config import Config
from shapedb.errors import ConfigError, MissingDependencyError, NotFoundError, StoreError
from shapedb.schema import Failure, ShapeRecord
from shapedb.store import CommitResult, Store

__all__ = ["connect", "Database"]

log = logging.getLogger(__name__)

_GROUP = "shapedb.extensions"
_PROVIDERS = {
    "ingest": "ingest",
    "load": "ingest",
    "search": "query",
    "search_batch": "query",
    "sql": "query",
    "match": "query",
    "evaluate": "query",
    "fit_metric": "query",
    "on_commit": "query",
    "show": "query",
    "render_matches": "query",
    "train_classifier": "query",
    "classify": "query",
}


def extension(name: str) -> Callable[..., Any]:
    """The downstream function registered as ``shapedb.extensions`` entry point ``name``."""
    return _extension(name)


@cache
def _extension(name: str) -> Callable[..., Any]:
    """The function registered as entry point ``name`` of group ``shapedb.extensions``.

    Raises
    ------
    MissingDependencyError
        When no installed distribution provides it, or its module cannot be imported.
    """
    from importlib.metadata import entry_points

    found = list(entry_points(group=_GROUP, name=name))
    package = _PROVIDERS.get(name, "an extension package")
    if not found:
        raise MissingDependencyError(
            f"no '{name}' extension is installed (entry point group {_GROUP!r}); "
            f"install shapedb with its {package!r} package, e.g.  pip install -e ."
        )
    try:
        return found[0].load()  # type: ignore[no-any-return]
    except ImportError as exc:
        raise MissingDependencyError(
            f"the '{name}' extension ({found[0].value}) cannot be imported: {exc}; "
            f"reinstall shapedb with its {package!r} package"
        ) from exc


def connect(
    path: str | os.PathLike[str],
    *,
    create: bool = True,
    config: Config | None = None,
    lock_timeout: float = 10.0,
    **options: Any,
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
        :data:`shapedb.config.OPTIONS`) applied on top of ``config``. For an existing store they must agree with its config.

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
        return result, committed

    def _notify(self, result: CommitResult) -> None:
        try:
            hook = _extension("on_commit")
        except MissingDependencyError:
            return
        try:
            hook(self, result)
        except Exception:  # derived state only: the commit itself stands
            log.warning("on_commit hook failed after version %d", result.version, exc_info=True)

    # ---------------------------------------------------------------- ingest
    def ingest(
        self,
        paths: Any,
        *,
        labels: Any = None,
        label_from_folder: bool = False,
        as_: str | None = None,
        names: Sequence[str] | None = None,
        workers: int | None = None,
        scheduler: Any = None,
        force: bool = False,
        progress: Any = False,
        **options: Any,
    ) -> Any:
        """Decompose files, folders or in-memory shapes and store them.

        See :func:`ingest.pipeline.ingest` for the parameters; returns an
        ``IngestReport`` (ingested ids, skipped paths, failed paths with reasons).
        """
        return _extension("ingest")(
            self,
            paths,
            labels=labels,
            label_from_folder=label_from_folder,
            as_=as_,
            names=names,
            workers=workers,
            scheduler=scheduler,
            force=force,
            progress=progress,
            **options,
        )

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

    def info(self) -> dict[str, Any]:
        """Summary, JSON-serialisable: ``{"shapes", "labels", "failures", "config"}``.

        ``shapes`` is the number of shapes; ``labels`` maps each label to its count
        (unlabelled shapes are not counted there); ``failures`` lists
        ``{"path", "error"}`` for every input that failed; ``config`` is the store's
        configuration.
        """
        labels = self.store.shapes(["label"]).column("label").to_pylist()
        counts = Counter(x for x in labels if x is not None)
        failures = [
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
    def search(self, query: Any, *, k: int = 10, where: str | None = None, **options: Any) -> Any:
        """The ``k`` stored shapes most like ``query`` (a path, a shape, or an id).

        Implemented by ``query.engine.search``; returns hits best first.
        """
        return _extension("search")(self, query, k=k, where=where, **options)

    def search_batch(
        self, queries: Sequence[Any], *, k: int = 10, where: str | None = None, **options: Any
    ) -> Any:
        """:meth:`search` for many queries at once."""
        return _extension("search_batch")(self, queries, k=k, where=where, **options)

    def sql(self, statement: str, **options: Any) -> pa.Table:
        """Run a DuckDB statement over the views ``shapes``, ``balls``, ``edges``."""
        return _extension("sql")(self, statement, **options)  # type: ignore[no-any-return]

    def match(self, *args: Any, **options: Any) -> Any:
        """Substructure matching (``query.substructure.match``)."""
        return _extension("match")(self, *args, **options)

    def evaluate(self, *, label: str = "label", **options: Any) -> Any:
        """Leave-one-out retrieval quality by ``label`` (``query.evaluate.evaluate``)."""
        return _extension("evaluate")(self, label=label, **options)

    def fit_metric(self, *, label: str = "label", **options: Any) -> Any:
        """Fit block weights of the similarity on the stored labels (``query.metric``).

        Returns a ``LearnedMetric`` for ``search(..., metric=)`` and
        ``evaluate(metric=)``; the identity when cross-validation finds no gain.
        """
        return _extension("fit_metric")(self, label=label, **options)

    def show(self, model: Any, out: str | os.PathLike[str], **options: Any) -> Path:
        """Draw ``model`` with its MDBD balls into the PNG ``out`` (``query.render.show``)."""
        return _extension("show")(self, model, out, **options)  # type: ignore[no-any-return]

    def render_matches(
        self, query: Any, matches: Sequence[Any], out: str | os.PathLike[str], **options: Any
    ) -> Path:
        """Draw ``query`` and the parts ``matches`` found by :meth:`match` into ``out``."""
        return _extension("render_matches")(self, query, matches, out, **options)  # type: ignore[no-any-return]

    def train_classifier(self, *, label: str = "label", **options: Any) -> Any:
        """Train a graph-CNN classifier on the stored contact graphs (``shapedb[learn]``).

        Implemented by ``query.classify.train_classifier``; returns a fitted
        ``GraphClassifier`` whose ``test_accuracy_`` was measured on a held-out split.
        """
        return _extension("train_classifier")(self, label=label, **options)

    def classify(self, model: Any, shape: Any) -> Any:
        """Label ``shape`` (a path, Geometry or stored id) with a trained ``model`` or its file."""
        return _extension("classify")(self, model, shape)

    def load(self, path: str | os.PathLike[str], *, as_: str | None = None) -> Any:
        """Read a file into a Geometry with the ``ingest`` loaders."""
        return _extension("load")(path, as_=as_)
