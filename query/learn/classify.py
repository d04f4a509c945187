"""Shape classification: the classifier chosen on validation, trained on a store.

:func:`train_classifier` (``db.train_classifier``) reads the labelled shapes of a
store (contact graphs and descriptors), lets :func:`query.learn.selection.select_classifier`
choose among nearest neighbours, a linear model, gradient boosting and the graph
CNNs on a validation split of the training shapes only, and returns a
:class:`ShapeClassifier` holding the chosen model and why it was chosen.
:func:`classify` (``db.classify``) labels one shape or many with a saved or
in-memory classifier, loading it once.

A classifier remembers the fingerprint of the store configuration it was trained
on and refuses a store (or a decomposition) of another one (:class:`ConfigError`).
Files are :mod:`query.learn.model_file` archives; the torch files of earlier versions
(graph CNNs only) still load.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.learn.budget import DEFAULT_BUDGET, Budget, Progress
from query.learn.checkpoint import Checkpoint, checkpoint_path
from query.learn.descriptor_classifiers import DESCRIPTOR_KINDS
from query.learn.graphcnn import Callback, GraphClassifier, fingerprint_of
from query.learn.model_file import is_model_file, read_model, write_model
from query.learn.selection import GRAPH_CANDIDATES, Selection, predict_candidate, select_classifier
from query.learn.training_data import plot_history, stored_features, stored_graphs, stratified_split
from shapedb.errors import ConfigError, LoadError, NotFittedError
from shapedb.results import Classification  # defined there, re-exported here

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "GraphClassifier",
    "ShapeClassifier",
    "Classification",
    "train_classifier",
    "classify",
    "fingerprint_of",
]

log = logging.getLogger(__name__)


def _descriptor_class(kind: str) -> Any:
    return DESCRIPTOR_KINDS["knn" if kind.endswith("-nn") else kind]


class ShapeClassifier:
    """A fitted classifier of shapes (any candidate kind) and the report of its choice.

    Parameters
    ----------
    kind : str
        A candidate name of :mod:`query.learn.selection` ("1-nn", "linear", "tag", ...).
    model : fitted estimator
        :class:`~query.learn.descriptor_classifiers.NearestNeighbours`,
        ``LinearDescriptor``, ``BoostedDescriptor`` or
        :class:`~query.learn.graphcnn.GraphClassifier`.
    fingerprint : str, optional
        ``Config.fingerprint`` of the store it was trained on.
    selection : Selection, optional
        Validation accuracy of every candidate.

    Attributes
    ----------
    classes_ : list of str
    test_accuracy_ : float
        Set by :func:`train_classifier`: accuracy on its held-out test split (NaN
        without one).
    split_ : dict[str, int]
        Shapes used to train (and choose) and to test.
    """

    test_accuracy_: float
    split_: dict[str, int]

    def __init__(
        self,
        kind: str,
        model: Any,
        *,
        fingerprint: str | None = None,
        selection: Selection | None = None,
    ) -> None:
        self.kind = kind
        self.model_ = model
        self.fingerprint_ = fingerprint
        self.selection_ = selection

    @property
    def classes_(self) -> list[str]:
        return list(self.model_.classes_)

    @property
    def needs_graphs(self) -> bool:
        """Whether prediction reads the contact graphs (graph CNNs), not only descriptors."""
        return isinstance(self.model_, GraphClassifier)

    @property
    def history_(self) -> dict[str, list[float]]:
        """Training curve of a graph CNN ({} for the other kinds)."""
        return dict(getattr(self.model_, "history_", {}))

    def _check_fitted(self) -> None:
        if not hasattr(self.model_, "classes_"):
            raise NotFittedError(f"this {self.kind} classifier is not fitted")

    def predict_proba(self, graphs: Sequence[Any] | None, descriptors: Any) -> NDArray[np.float64]:
        """Class probabilities (n, n_classes), columns in the order of ``classes_``.

        Parameters
        ----------
        graphs : sequence of n contact graphs, or None for descriptor kinds
        descriptors : (n, d) float
        """
        self._check_fitted()
        x = np.asarray(descriptors, dtype=np.float64)
        x = x.reshape(1, -1) if x.ndim == 1 else x
        if self.needs_graphs and graphs is None:
            raise ConfigError(f"a {self.kind} classifier reads contact graphs: pass them")
        return predict_candidate(self.model_, list(graphs or [None] * len(x)), x)

    def predict(self, graphs: Sequence[Any] | None, descriptors: Any) -> list[str]:
        """Most probable label of each shape."""
        proba = self.predict_proba(graphs, descriptors)
        return [self.classes_[k] for k in proba.argmax(axis=1)]

    def score(self, graphs: Sequence[Any] | None, descriptors: Any, labels: Sequence[Any]) -> float:
        """Accuracy on labelled shapes (NaN for none)."""
        pred = self.predict(graphs, descriptors)
        hits = [p == str(t) for p, t in zip(pred, labels, strict=True)]
        return float(np.mean(hits)) if hits else math.nan

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the chosen model (k-NN: its training descriptors and labels) and its report."""
        self._check_fitted()
        meta, arrays = self.model_.state()
        manifest: dict[str, Any] = {
            "kind": self.kind,
            "model": meta,
            "fingerprint": self.fingerprint_,
            "selection": None if self.selection_ is None else self.selection_.to_dict(),
        }
        for name in ("test_accuracy_", "split_"):
            if hasattr(self, name):
                manifest[name.rstrip("_")] = getattr(self, name)
        return write_model(path, manifest, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, device: str | None = None) -> ShapeClassifier:
        """Read a file written by :meth:`save`, :meth:`GraphClassifier.save`, or an older version.

        Raises
        ------
        LoadError
            Unreadable, or not a shapedb classifier.
        """
        if not Path(path).is_file():
            raise LoadError("no such classifier file", source=str(path))
        if not is_model_file(path):  # a torch file of the first format (graph CNNs)
            graph = GraphClassifier.load(path, device=device)
            return cls._wrap(graph)
        manifest, arrays = read_model(path)
        kind = str(manifest.get("kind"))
        if kind == "graph":  # a GraphClassifier saved on its own
            return cls._wrap(GraphClassifier.from_state(manifest, arrays, device=device))
        if kind in GRAPH_CANDIDATES:
            model: Any = GraphClassifier.from_state(manifest["model"], arrays, device=device)
        else:
            try:
                model = _descriptor_class(kind).from_state(manifest["model"], arrays)
            except KeyError as exc:
                raise LoadError(f"unknown classifier kind {kind!r}", source=str(path)) from exc
        sel = manifest.get("selection")
        self = cls(
            kind,
            model,
            fingerprint=manifest.get("fingerprint"),
            selection=None if sel is None else Selection.from_dict(sel),
        )
        if "test_accuracy" in manifest:
            self.test_accuracy_ = float(manifest["test_accuracy"])
        if "split" in manifest:
            self.split_ = dict(manifest["split"])
        return self

    @classmethod
    def _wrap(cls, graph: GraphClassifier) -> ShapeClassifier:
        kind = graph.conv + ("+descriptor" if graph.descriptor else "")
        self = cls(kind, graph, fingerprint=graph.fingerprint_)
        if hasattr(graph, "test_accuracy_"):
            self.test_accuracy_ = graph.test_accuracy_
        return self

    def __repr__(self) -> str:
        n = len(self.classes_) if hasattr(self.model_, "classes_") else 0
        return f"ShapeClassifier(kind={self.kind!r}, classes={n})"


def _labelled(db: StoreHandle, label: str) -> tuple[list[int], list[str]]:
    """Ids and labels of the stored shapes that have ``label`` (a column or metadata key)."""
    store = db.store
    fp = db.config.fingerprint
    t = store.shapes(["id", "label", "metadata", "config_fingerprint"])
    bad = sorted(set(t.column("config_fingerprint").to_pylist()) - {fp})
    if bad:
        raise ConfigError(f"the store holds shapes built with configurations {bad}, not {fp}")
    ids = t.column("id").to_pylist()
    if label == "label":
        values = t.column("label").to_pylist()
    else:
        values = [dict(m or {}).get(label) for m in t.column("metadata").to_pylist()]
    keep = [(i, str(v)) for i, v in zip(ids, values, strict=True) if v not in (None, "")]
    if not keep:
        raise ConfigError(f"no stored shape has a value for label {label!r}", source=str(db.path))
    return [k[0] for k in keep], [k[1] for k in keep]


def _training_data(
    db: StoreHandle, label: str, methods: Sequence[str] | None, test: float, seed: int
) -> dict[str, Any]:
    """Labels, descriptors and (when a graph CNN may run) graphs of the labelled shapes, split.

    Everything is read from the store in bulk (``stored_features``, ``stored_graphs``):
    nothing is decomposed or converted here.
    """
    ids, labels = _labelled(db, label)
    if test > 0:
        train_idx, test_idx = stratified_split(labels, (1 - test, test), seed=seed)
    else:
        train_idx, test_idx = np.arange(len(ids)), np.zeros(0, dtype=np.int64)
    graph_kinds = [m for m in (methods or GRAPH_CANDIDATES) if m in GRAPH_CANDIDATES]
    graphs: list[Any] = stored_graphs(db, ids) if graph_kinds else [None] * len(ids)
    return {
        "ids": ids,
        "labels": labels,
        "x": stored_features(db, ids),
        "graphs": graphs,
        "train": train_idx,
        "test": test_idx,
    }


def _checkpoint(
    db: StoreHandle,
    out: str | os.PathLike[str] | None,
    resume: bool,
    options: dict[str, Any],
    **settings: Any,
) -> Checkpoint:
    """The selection checkpoint next to ``out`` (in memory only without ``out``).

    Its key is the store (path, version, configuration) and every setting the
    validation scores depend on; ``resume=False`` discards an earlier file.
    """
    path = None if out is None else checkpoint_path(out)
    if path is not None and not resume:
        path.unlink(missing_ok=True)
    key = {
        "store": str(Path(db.path).resolve()),
        "version": db.store.version,
        "fingerprint": db.config.fingerprint,
        "options": {k: v for k, v in options.items() if k != "config"},
        **settings,
    }
    return Checkpoint(path, key)


def _finish(
    result: ShapeClassifier,
    data: dict[str, Any],
    label: str,
    out: str | os.PathLike[str] | None,
    plot: str | os.PathLike[str] | None,
) -> ShapeClassifier:
    """Test accuracy on the held-out split; save the model and a graph CNN's training curve."""
    pick = lambda idx, xs: [xs[i] for i in idx]  # noqa: E731
    test_idx = data["test"]
    result.test_accuracy_ = (
        result.score(
            pick(test_idx, data["graphs"]), data["x"][test_idx], pick(test_idx, data["labels"])
        )
        if len(test_idx)
        else math.nan
    )
    result.split_ = {"train": len(data["train"]), "test": len(test_idx)}
    log.info(
        "%s classifier on %r: test accuracy %.3f (%s)",
        *(result.kind, label, result.test_accuracy_, result.split_),
    )
    if out is not None:
        result.save(out)
        log.info("saved the classifier to %s", out)
    if plot is None and out is not None and result.needs_graphs:
        plot = Path(out).with_suffix(".png")
    if plot is not None and result.needs_graphs:
        plot_history(result.history_, plot, title=f"{result.kind} on {label!r}")
    return result


def _candidates(
    methods: Sequence[str] | None, conv: str | None
) -> tuple[Sequence[str] | None, list[str]]:
    """The candidates, and those to score whatever the budget (the ones named)."""
    if methods is None and conv is not None:
        return ["1-nn", conv], ["1-nn", conv]
    return methods, list(methods or [])


def train_classifier(
    db: StoreHandle,
    *,
    label: str = "label",
    methods: Sequence[str] | None = None,
    conv: str | None = None,
    out: str | os.PathLike[str] | None = None,
    plot: str | os.PathLike[str] | None = None,
    test: float = 0.15,
    validation: float = 0.2,
    folds: int | str = "auto",
    callback: Callback | None = None,
    budget: float | Budget | None = DEFAULT_BUDGET,
    progress: Callable[[Progress], None] | None = None,
    resume: bool = True,
    **options: Any,
) -> ShapeClassifier:
    """Choose and train a classifier on the labelled shapes of a database (``db.train_classifier``).

    The labelled shapes are split, class by class, into train and test; the
    candidates are scored, cheapest first and within ``budget``, on validation data
    from the training part only (:func:`query.learn.selection.select_classifier`);
    the best is refitted on the whole training part and tested on the test part.

    Parameters
    ----------
    db : StoreHandle
    label : str
        The ``label`` column, or a metadata key holding the class.
    methods : sequence of str, optional
        Candidates (:data:`query.learn.selection.CANDIDATES`), scored whatever the
        budget; default all of them, the graph CNNs only while the budget allows.
        1-NN is always a candidate.
    conv : {"tag", "arma", "spline"}, optional
        Earlier interface: with no ``methods``, the candidates are 1-NN and this CNN.
    out : path, optional
        Where to save the classifier (a graph CNN's training curve goes next to it
        with the suffix ``.png`` unless ``plot`` is given); the finished validation
        folds go to ``<out>.selection.json``.
    plot : path, optional
        Training-curve PNG (graph CNNs only).
    test : float
        Fraction held out for testing (0: train on every labelled shape).
    validation, folds
        Holdout fraction, or k folds ("auto": k-fold when a class has under 20 shapes).
    callback : callable, optional
        ``callback(epoch, epochs, metrics)`` per epoch of the final graph-CNN fit.
    budget : float, Budget or None
        Seconds for reading, choosing and fitting (default 300; None: no limit).
    progress : callable, optional
        ``progress(Progress)`` at every fold and epoch.
    resume : bool
        Reuse the folds that an earlier run with the same store and settings scored.
    **options
        :class:`~query.learn.graphcnn.GraphClassifier` settings (epochs, lr, seed, ...).

    Returns
    -------
    ShapeClassifier
        Fitted, with ``selection_``, ``test_accuracy_`` and ``split_``.
    """
    timer = budget if isinstance(budget, Budget) else Budget(budget)  # reading counts
    methods, required = _candidates(methods, conv)
    seed = int(options.get("seed", 0))
    data = _training_data(db, label, methods, test, seed)
    settings = {"label": label, "test": test, "validation": validation, "folds": folds}
    checkpoint = _checkpoint(db, out, resume, n=len(data["ids"]), options=options, **settings)
    options.setdefault("config", db.config)
    tr = data["train"]
    selection, model = select_classifier(
        [data["graphs"][i] for i in tr], data["x"][tr], [data["labels"][i] for i in tr],
        candidates=methods, required=required, folds=folds, validation=validation, seed=seed,
        graph_options=options, callback=callback, budget=timer, progress=progress,
        checkpoint=checkpoint,
    )  # fmt: skip
    result = ShapeClassifier(selection.chosen, model, fingerprint=db.config.fingerprint)
    result.selection_ = selection
    return _finish(result, data, label, out, plot)


def _shape_inputs(db: StoreHandle, shapes: Sequence[Any], graphs: bool) -> tuple[list[Any], Any]:
    """Contact graphs (or None entries) and descriptors (n, d) of the shapes to classify."""
    from shapedb.geometry.base import Geometry
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.kernel import features

    config = db.config
    out_graphs: list[Any] = [None] * len(shapes)
    x = np.zeros((len(shapes), config.dim))
    stored: dict[int, int] = {}
    for k, s in enumerate(shapes):
        if isinstance(s, (str, os.PathLike)) and Path(s).is_file():
            s = decompose(db.load(s), config=config.mdbd)
        elif isinstance(s, Geometry):
            s = decompose(s, config=config.mdbd)
        elif isinstance(s, (int, np.integer, str)):
            stored[k] = db.store.resolve(int(s) if isinstance(s, np.integer) else s)
            continue
        fp = fingerprint_of(s)
        if fp is not None and fp != config.fingerprint:
            raise ConfigError(
                f"shape was decomposed with configuration {fp}, not the store's "
                f"{config.fingerprint}",
                source=str(getattr(s, "name", k)),
            )
        out_graphs[k] = s
        x[k] = features(s, config)
    if stored:
        slots, sids = list(stored), list(stored.values())
        x[slots] = stored_features(db, sids)
        if graphs:
            for k, g in zip(slots, stored_graphs(db, sids), strict=True):
                out_graphs[k] = g
    return out_graphs, x


def classify(
    db: StoreHandle,
    model_or_path: ShapeClassifier | GraphClassifier | str | os.PathLike[str],
    shapes: Any,
) -> Classification | list[Classification]:
    """The class of one shape or of many, of any representation (``db.classify``).

    Parameters
    ----------
    db : StoreHandle
        Supplies the configuration the shapes are decomposed with.
    model_or_path : ShapeClassifier, GraphClassifier, or the path of a saved one
        Loaded once; must have been trained on a store of the database's
        configuration.
    shapes : a shape, or a list / tuple of shapes
        Each a path, a Geometry, a Decomposition, or a stored shape's id or name.

    Returns
    -------
    Classification, or a list of them (in the order of ``shapes``) for a list
    """
    if isinstance(model_or_path, ShapeClassifier):
        model = model_or_path
    elif isinstance(model_or_path, GraphClassifier):
        model = ShapeClassifier._wrap(model_or_path)
    else:
        model = ShapeClassifier.load(model_or_path)
    model._check_fitted()
    fp = db.config.fingerprint
    if model.fingerprint_ is not None and model.fingerprint_ != fp:
        raise ConfigError(
            f"the model was trained on graphs of configuration {model.fingerprint_}, but this "
            f"database uses {fp}: train a model on this database",
            source=str(db.path),
        )
    many = isinstance(shapes, (list, tuple))
    items = list(shapes) if many else [shapes]
    graphs, x = _shape_inputs(db, items, model.needs_graphs)
    proba = model.predict_proba(graphs, x)
    out = []
    for source, p in zip(items, proba, strict=True):
        order = np.argsort(-p, kind="stable")
        out.append(
            Classification(
                label=model.classes_[order[0]],
                probability=float(p[order[0]]),
                probabilities={model.classes_[k]: float(p[k]) for k in order},
                source=str(source)
                if isinstance(source, (str, os.PathLike, int, np.integer))
                else None,
            )
        )
    return out if many else out[0]
