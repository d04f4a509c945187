"""Shape classification with a graph CNN on the MDBD contact graph (paper, section 3.1).

:class:`GraphClassifier` is a scikit-learn-style estimator over contact graphs
(:class:`~shapedb.mdbd.Decomposition` or :class:`~shapedb.graph.ContactGraph`):
``fit(graphs, labels) -> self``, ``predict``, ``predict_proba``, ``save`` / ``load``.
A model remembers the fingerprint of the store configuration its graphs were built
with and refuses graphs (and stores) built with another one (:class:`ConfigError`).

:func:`train_classifier` and :func:`classify` are the ``Database`` extensions
``db.train_classifier(...)`` and ``db.classify(...)``.

torch and torch_geometric (the ``learn`` extra) are imported only when a model is
built, trained or loaded; without them a :class:`MissingDependencyError` says
``pip install 'shapedb[learn]'``.
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

from query.gnn import plot_history, stored_graphs, stratified_split
from shapedb.config import Config, MDBDConfig
from shapedb.errors import ConfigError, InvalidShapeError, LoadError, NotFittedError
from shapedb.results import Classification  # defined there, re-exported here

if TYPE_CHECKING:
    from shapedb.database import Database

__all__ = [
    "GraphClassifier",
    "Classification",
    "train_classifier",
    "classify",
    "fingerprint_of",
]

log = logging.getLogger(__name__)

FORMAT = "shapedb.graph-classifier/1"
Callback = Callable[[int, int, dict[str, float]], None]
"""``callback(epoch, epochs, metrics)`` after every epoch (the CLI's progress bar)."""


def fingerprint_of(graph: Any) -> str | None:
    """Configuration fingerprint of a Decomposition (or record), None when unknown."""
    cfg = getattr(graph, "config", None)
    if isinstance(cfg, Config):
        return cfg.fingerprint
    if isinstance(cfg, MDBDConfig):
        return Config(mdbd=cfg).fingerprint
    decomposition = getattr(graph, "decomposition", None)
    return fingerprint_of(decomposition) if decomposition is not None else None


def _as_graph(graph: Any) -> Any:
    """The object holding centers / radii / edges (a record's decomposition)."""
    if hasattr(graph, "decomposition") and not hasattr(graph, "centers"):
        return graph.decomposition
    if not all(hasattr(graph, a) for a in ("centers", "radii", "edges")):
        raise InvalidShapeError(
            f"expected a Decomposition or ContactGraph, got {type(graph).__name__}"
        )
    return graph


class GraphClassifier:
    """The Figure 3 graph CNN as a scikit-learn-style classifier of contact graphs.

    Parameters
    ----------
    conv : {"tag", "arma", "spline"}
        Graph convolution (see :mod:`query.gnn`).
    epochs : int
        Training epochs; the weights of the epoch with the best validation accuracy
        (lowest validation loss on ties) are kept.
    lr : float
        Peak learning rate of Adam (after the linear warm-up).
    rotate : bool
        Augment every training graph with a random rotation every epoch.
    device : str, optional
        torch device; default "cuda" when available, else "cpu".
    seed : int
        Seed of the weights, the batches, the rotations and the validation split.
    batch_size : int
    hidden : int
        Channels of each graph convolution (the shape vector has 2 * hidden).
    dropout : float
    weight_decay : float
    warmup : int
        Epochs of linear warm-up before the cosine annealing.
    validation : float
        Fraction of the training graphs held out for model selection when ``fit``
        gets no ``validation_data``; 0 keeps the last epoch.
    config : Config, optional
        Configuration the graphs were built with (when they do not carry one, e.g.
        ContactGraphs); Decompositions carry theirs.

    Attributes
    ----------
    classes_ : list of str
        Label names; column k of ``predict_proba`` is ``classes_[k]``.
    fingerprint_ : str or None
        ``Config.fingerprint`` of the graphs it was trained on.
    history_ : dict[str, list[float]]
        Per epoch: "loss", "accuracy", "val_loss", "val_accuracy", "lr", "seconds".
    best_epoch_ : int
    n_parameters_ : int
    test_accuracy_ : float
        Set by :func:`train_classifier`: accuracy on its held-out test split.
    """

    classes_: list[str]
    fingerprint_: str | None
    config_json_: str | None
    history_: dict[str, list[float]]
    best_epoch_: int
    n_parameters_: int
    model_: Any
    test_accuracy_: float
    split_: dict[str, int]

    def __init__(
        self,
        conv: str = "tag",
        *,
        epochs: int = 100,
        lr: float = 1e-3,
        rotate: bool = True,
        device: str | None = None,
        seed: int = 0,
        batch_size: int = 16,
        hidden: int = 128,
        dropout: float = 0.5,
        weight_decay: float = 1e-4,
        warmup: int = 5,
        validation: float = 0.15,
        config: Config | None = None,
    ) -> None:
        self.conv = conv
        self.epochs = epochs
        self.lr = lr
        self.rotate = rotate
        self.device = device
        self.seed = seed
        self.batch_size = batch_size
        self.hidden = hidden
        self.dropout = dropout
        self.weight_decay = weight_decay
        self.warmup = warmup
        self.validation = validation
        self.config = config

    # ------------------------------------------------------------------ helpers
    def get_params(self) -> dict[str, Any]:
        """Constructor settings (not the learned state)."""
        keys: tuple[str, ...] = ("conv", "epochs", "lr", "rotate", "device", "seed")
        keys += ("batch_size", "hidden", "dropout", "weight_decay", "warmup", "validation")
        return {k: getattr(self, k) for k in keys}

    def _device(self) -> Any:
        from query.gnn import import_torch

        torch, _ = import_torch()
        if self.device is not None:
            return torch.device(self.device)
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")

    def _check_fitted(self) -> None:
        if not hasattr(self, "model_"):
            raise NotFittedError(
                "this GraphClassifier is not fitted yet: call fit(graphs, labels) or "
                "GraphClassifier.load(path) first"
            )

    def _check_config(self, graphs: Sequence[Any]) -> None:
        for k, g in enumerate(graphs):
            fp = fingerprint_of(g)
            if fp is not None and self.fingerprint_ is not None and fp != self.fingerprint_:
                raise ConfigError(
                    f"graph {k} was built with configuration {fp}, but the model was "
                    f"trained on graphs of configuration {self.fingerprint_}: decompose it "
                    "with the store's configuration, or train a model on such graphs",
                    source=getattr(g, "name", None),
                )

    def _to_dataset(self, graphs: Sequence[Any], y: NDArray[np.int64] | None) -> list[Any]:
        from query.gnn import to_data

        out = []
        for k, g in enumerate(graphs):
            if hasattr(g, "edge_index"):  # already a torch_geometric Data
                d = g.clone()
            else:
                d = to_data(_as_graph(g))
            if y is not None:
                import torch

                d.y = torch.tensor([int(y[k])], dtype=torch.long)
            out.append(d)
        return out

    # --------------------------------------------------------------------- API
    def fit(
        self,
        graphs: Sequence[Any],
        labels: Sequence[Any],
        *,
        validation_data: tuple[Sequence[Any], Sequence[Any]] | None = None,
        callback: Callback | None = None,
    ) -> GraphClassifier:
        """Train on contact graphs.

        Parameters
        ----------
        graphs : sequence of Decomposition / ContactGraph / ShapeRecord, length n
        labels : sequence of str or int, length n
        validation_data : (graphs, labels), optional
            Held-out graphs for model selection; by default ``validation`` of the
            training graphs (stratified) are held out.
        callback : callable, optional
            ``callback(epoch, epochs, metrics)`` after every epoch.

        Returns
        -------
        self
        """
        from query.gnn import build_network, count_parameters, import_torch, train_network

        torch, _ = import_torch()
        graphs, labels = list(graphs), list(labels)
        if len(graphs) != len(labels):
            raise ConfigError(f"{len(graphs)} graphs but {len(labels)} labels")
        names = [str(v) for v in labels]
        classes = sorted(set(names))
        if len(classes) < 2:
            raise ConfigError(f"need at least 2 classes to train, got {classes}")
        fps = {fingerprint_of(g) for g in graphs} - {None}
        if len(fps) > 1:
            raise ConfigError(
                f"training graphs come from several configurations: {sorted(map(str, fps))}"
            )
        self.fingerprint_ = fps.pop() if fps else (self.config.fingerprint if self.config else None)
        self.config_json_ = self.config.to_json() if self.config is not None else None
        self.classes_ = classes
        index = {c: k for k, c in enumerate(classes)}
        y = np.array([index[c] for c in names], dtype=np.int64)

        if validation_data is not None:
            vg, vl = list(validation_data[0]), [str(v) for v in validation_data[1]]
            unknown = set(vl) - set(classes)
            if unknown:
                raise ConfigError(f"validation labels {sorted(unknown)} are not training classes")
            train_idx = np.arange(len(graphs))
            val_set = self._to_dataset(vg, np.array([index[c] for c in vl]))
        elif self.validation > 0:
            train_idx, val_idx = stratified_split(
                y, (1 - self.validation, self.validation), seed=self.seed
            )
            val_set = self._to_dataset([graphs[i] for i in val_idx], y[val_idx])
        else:
            train_idx, val_set = np.arange(len(graphs)), []
        train_set = self._to_dataset([graphs[i] for i in train_idx], y[train_idx])

        torch.manual_seed(self.seed)
        device = self._device()
        self.model_ = build_network(
            self.conv, len(classes), hidden=self.hidden, dropout=self.dropout
        ).to(device)
        self.n_parameters_ = count_parameters(self.model_)
        log.info(
            "training %s network (%d parameters) on %d graphs, %d validation, %d classes, %s",
            *(self.conv, self.n_parameters_, len(train_set), len(val_set), len(classes), device),
        )
        self.history_, self.best_epoch_ = train_network(
            self.model_,
            train_set,
            val_set,
            **{k: getattr(self, k) for k in ("epochs", "lr", "weight_decay", "warmup")},
            **{k: getattr(self, k) for k in ("batch_size", "rotate", "seed")},
            callback=callback,
        )
        log.info(
            "best epoch %d: validation accuracy %.3f",
            self.best_epoch_ + 1,
            self.history_["val_accuracy"][self.best_epoch_],
        )
        return self

    def predict_proba(self, graphs: Sequence[Any]) -> NDArray[np.float64]:
        """Class probabilities: (n, n_classes) float64, columns in the order of ``classes_``.

        ``graphs``: n Decompositions, ContactGraphs or ShapeRecords.
        """
        self._check_fitted()
        import torch

        from query.gnn import import_torch

        _, pyg = import_torch()
        graphs = list(graphs)
        self._check_config(graphs)
        if not graphs:
            return np.zeros((0, len(self.classes_)))
        loader = pyg.loader.DataLoader(self._to_dataset(graphs, None), batch_size=64)
        dev = next(self.model_.parameters()).device
        self.model_.eval()
        out = []
        with torch.no_grad():
            for batch in loader:
                out.append(torch.softmax(self.model_(batch.to(dev)), dim=1).cpu().double().numpy())
        return np.concatenate(out, axis=0)

    def predict(self, graphs: Sequence[Any]) -> list[str]:
        """Most probable label of each graph (length n list of str)."""
        proba = self.predict_proba(graphs)
        return [self.classes_[k] for k in proba.argmax(axis=1)]

    def score(self, graphs: Sequence[Any], labels: Sequence[Any]) -> float:
        """Accuracy on labelled graphs."""
        pred = self.predict(graphs)
        return (
            float(np.mean([p == str(t) for p, t in zip(pred, labels, strict=True)]))
            if pred
            else math.nan
        )

    def embed(self, graphs: Sequence[Any]) -> NDArray[np.float32]:
        """The 256-long shape vectors after global max pooling, (n, 2 * hidden)."""
        self._check_fitted()
        import torch

        from query.gnn import import_torch

        _, pyg = import_torch()
        graphs = list(graphs)
        self._check_config(graphs)
        loader = pyg.loader.DataLoader(self._to_dataset(graphs, None), batch_size=64)
        dev = next(self.model_.parameters()).device
        with torch.no_grad():
            parts = [self.model_.embed(b.to(dev)).cpu().numpy() for b in loader]
        return np.concatenate(parts) if parts else np.zeros((0, 2 * self.hidden), np.float32)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the weights, settings, label names and configuration fingerprint."""
        self._check_fitted()
        from query.gnn import import_torch

        torch, _ = import_torch()
        params = self.get_params()
        params["device"] = None
        state: dict[str, Any] = {
            "format": FORMAT,
            "params": params,
            "classes": list(self.classes_),
            "fingerprint": self.fingerprint_,
            "config": self.config_json_,
            "history": self.history_,
            "best_epoch": int(self.best_epoch_),
            "state_dict": {k: v.detach().cpu() for k, v in self.model_.state_dict().items()},
        }
        for extra in ("test_accuracy_",):
            if hasattr(self, extra):
                state[extra.rstrip("_")] = float(getattr(self, extra))
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        torch.save(state, path)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, device: str | None = None) -> GraphClassifier:
        """Read a model written by :meth:`save` (weights only, no pickled code)."""
        from query.gnn import build_network, count_parameters, import_torch

        torch, _ = import_torch()
        try:
            state = torch.load(Path(path), map_location="cpu", weights_only=True)
        except (OSError, RuntimeError, EOFError) as exc:
            raise LoadError(f"cannot read a classifier: {exc}", source=str(path)) from exc
        if not isinstance(state, dict) or state.get("format") != FORMAT:
            raise LoadError(
                f"not a shapedb classifier (expected format {FORMAT})", source=str(path)
            )
        params = dict(state["params"], device=device)
        self = cls(**params)
        self.classes_ = list(state["classes"])
        self.fingerprint_ = state["fingerprint"]
        self.config_json_ = state.get("config")
        if self.config_json_:
            self.config = Config.from_json(self.config_json_)
        self.history_ = state.get("history", {})
        self.best_epoch_ = int(state.get("best_epoch", -1))
        if "test_accuracy" in state:
            self.test_accuracy_ = float(state["test_accuracy"])
        model = build_network(
            self.conv, len(self.classes_), hidden=self.hidden, dropout=self.dropout
        )
        model.load_state_dict(state["state_dict"])
        self.model_ = model.to(self._device()).eval()
        self.n_parameters_ = count_parameters(model)
        return self

    def __repr__(self) -> str:
        fitted = f", classes={len(self.classes_)}" if hasattr(self, "classes_") else ""
        return f"GraphClassifier(conv={self.conv!r}, epochs={self.epochs}{fitted})"


# ------------------------------------------------------------------ Database extensions
def _labelled(db: Database, label: str) -> tuple[list[int], list[str]]:
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


def train_classifier(
    db: Database,
    *,
    label: str = "label",
    conv: str = "tag",
    out: str | os.PathLike[str] | None = None,
    plot: str | os.PathLike[str] | None = None,
    test: float = 0.15,
    validation: float = 0.15,
    callback: Callback | None = None,
    **options: Any,
) -> GraphClassifier:
    """Train a graph CNN on the labelled shapes of a database (``db.train_classifier``).

    The labelled shapes are split, class by class, into train / validation / test;
    the epoch kept is chosen on validation only, and the test accuracy of that model
    is logged and stored in ``model.test_accuracy_``.

    Parameters
    ----------
    db : Database
    label : str
        The ``label`` column, or a metadata key holding the class.
    conv : {"tag", "arma", "spline"}
    out : path, optional
        Where to save the model (and, unless ``plot`` is given, its training curve
        next to it with the suffix ``.png``).
    plot : path, optional
        Training-curve PNG.
    test, validation : float
        Fractions held out for testing and for model selection.
    callback : callable, optional
        ``callback(epoch, epochs, metrics)`` after every epoch (progress bars).
    **options
        :class:`GraphClassifier` settings (epochs, lr, rotate, seed, ...).

    Returns
    -------
    GraphClassifier
        Fitted; ``test_accuracy_`` is NaN when ``test`` is 0.
    """
    ids, labels = _labelled(db, label)
    seed = int(options.get("seed", 0))
    fractions = [1 - test - validation, validation] + ([test] if test > 0 else [])
    parts = stratified_split(labels, fractions, seed=seed)
    graphs = stored_graphs(db, ids)
    pick = lambda idx, xs: [xs[i] for i in idx]  # noqa: E731
    model = GraphClassifier(conv, config=db.config, validation=validation, **options)
    model.fit(
        pick(parts[0], graphs),
        pick(parts[0], labels),
        validation_data=(pick(parts[1], graphs), pick(parts[1], labels)),
        callback=callback,
    )
    model.test_accuracy_ = (
        model.score(pick(parts[2], graphs), pick(parts[2], labels)) if test > 0 else math.nan
    )
    model.split_ = {
        "train": len(parts[0]),
        "validation": len(parts[1]),
        "test": len(parts[2]) if test > 0 else 0,
    }
    log.info(
        "%s classifier on %r: test accuracy %.3f (%s)",
        conv,
        label,
        model.test_accuracy_,
        model.split_,
    )
    if out is not None:
        model.save(out)
        log.info("saved the model to %s", out)
    if plot is None and out is not None:
        plot = Path(out).with_suffix(".png")
    if plot is not None:
        plot_history(model.history_, plot, title=f"{conv} on {label!r}")
    return model


def classify(
    db: Database,
    model_or_path: GraphClassifier | str | os.PathLike[str],
    geometry_or_path: Any,
) -> Classification:
    """The class of a shape of any representation (``db.classify``).

    Parameters
    ----------
    db : Database
        Supplies the configuration the shape is decomposed with.
    model_or_path : GraphClassifier or path of a saved one
        Must have been trained on graphs of the database's configuration.
    geometry_or_path : path, Geometry, Decomposition, or a stored shape's id / name

    Returns
    -------
    Classification
    """
    model = (
        model_or_path
        if isinstance(model_or_path, GraphClassifier)
        else GraphClassifier.load(model_or_path)
    )
    model._check_fitted()
    fp = db.config.fingerprint
    if model.fingerprint_ is not None and model.fingerprint_ != fp:
        raise ConfigError(
            f"the model was trained on graphs of configuration {model.fingerprint_}, but this "
            f"database uses {fp}: train a model on this database",
            source=str(db.path),
        )
    source = geometry_or_path
    if isinstance(source, (str, os.PathLike)) and Path(source).is_file():
        graph = _decompose(db, db.load(source))
    elif isinstance(source, (int, np.integer, str)):
        graph = db.get(int(source) if isinstance(source, np.integer) else source).decomposition
    elif hasattr(source, "centers"):
        graph = source
    else:
        graph = _decompose(db, source)
    proba = model.predict_proba([graph])[0]
    order = np.argsort(-proba, kind="stable")
    return Classification(
        label=model.classes_[order[0]],
        probability=float(proba[order[0]]),
        probabilities={model.classes_[k]: float(proba[k]) for k in order},
        source=str(source) if isinstance(source, (str, os.PathLike, int, np.integer)) else None,
    )


def _decompose(db: Database, geometry: Any) -> Any:
    from shapedb.mdbd import decompose

    return decompose(geometry, config=db.config.mdbd)
