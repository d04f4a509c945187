"""The paper's graph CNN (section 3.1) as a scikit-learn-style classifier of contact graphs.

:class:`GraphClassifier` is an estimator over contact graphs
(:class:`~shapedb.mdbd.decomposition.Decomposition`, :class:`~shapedb.mdbd.graph.ContactGraph` or
records): ``fit(graphs, labels) -> self``, ``predict``, ``predict_proba``,
``save`` / ``load``. With ``descriptor=True`` the network also reads each shape's
descriptor (standardised on the training graphs) as a graph-level input; ``fit``
and ``predict_proba`` then take ``descriptors`` (n, d) beside the graphs.

A model remembers the fingerprint of the store configuration its graphs were built
with and refuses graphs built with another one (:class:`ConfigError`).

torch and torch_geometric (the ``learn`` extra) are imported only when a model is
built, trained or loaded; without them a :class:`MissingDependencyError` says
``pip install 'shapedb[learn]'``.
"""

from __future__ import annotations

import logging
import math
import os
import pickle
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from query.learn.training_data import stratified_split
from shapedb.config.core import Config, MDBDConfig
from shapedb.errors import ConfigError, InvalidShapeError, LoadError, NotFittedError

__all__ = ["GraphClassifier", "fingerprint_of", "FORMAT", "Callback"]

log = logging.getLogger(__name__)

FORMAT = "shapedb.mdbd.graph-classifier/1"
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
        Graph convolution (see :mod:`query.learn.gnn`).
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
    descriptor : bool
        Also read each shape's descriptor as a graph-level input (``descriptors``
        must then be given to ``fit``, ``predict_proba`` and friends).

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
    descriptor_mean_, descriptor_scale_ : (d,) float64
        Standardisation of the descriptor input (``descriptor=True`` only).
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
        descriptor: bool = False,
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
        self.descriptor = descriptor

    # ------------------------------------------------------------------ helpers
    def get_params(self) -> dict[str, Any]:
        """Constructor settings (not the learned state)."""
        keys: tuple[str, ...] = ("conv", "epochs", "lr", "rotate", "device", "seed")
        keys += ("batch_size", "hidden", "dropout", "weight_decay", "warmup", "validation")
        keys += ("descriptor",)
        return {k: getattr(self, k) for k in keys}

    def _device(self) -> Any:
        from query.learn.gnn import import_torch

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

    def _graph_inputs(self, graphs: Sequence[Any], descriptors: Any) -> NDArray[np.float32] | None:
        """Standardised descriptors (n, d) when the network reads them, else None."""
        if not self.descriptor:
            return None
        if descriptors is None:
            raise ConfigError("this GraphClassifier reads descriptors: pass descriptors=(n, d)")
        x = np.asarray(descriptors, dtype=np.float64).reshape(len(graphs), -1)
        if not hasattr(self, "descriptor_mean_"):
            self.descriptor_mean_ = x.mean(axis=0)
            self.descriptor_scale_ = np.where(x.std(axis=0) > 1e-12, x.std(axis=0), 1.0)
        if x.shape[1] != len(self.descriptor_mean_):
            raise ConfigError(
                f"descriptors have {x.shape[1]} entries, the model was trained on "
                f"{len(self.descriptor_mean_)}"
            )
        return ((x - self.descriptor_mean_) / self.descriptor_scale_).astype(np.float32)

    def _to_dataset(
        self, graphs: Sequence[Any], y: NDArray[np.int64] | None, u: Any = None
    ) -> list[Any]:
        from query.learn.gnn import to_data

        out = []
        for k, g in enumerate(graphs):
            if hasattr(g, "edge_index"):  # already a torch_geometric Data
                d = g.clone()
                if u is not None:
                    import torch

                    d.u = torch.as_tensor(np.asarray(u[k], dtype=np.float32).reshape(1, -1))
            else:
                d = to_data(_as_graph(g), u=None if u is None else u[k])
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
        validation_data: tuple[Any, ...] | None = None,
        callback: Callback | None = None,
        descriptors: Any = None,
    ) -> GraphClassifier:
        """Train on contact graphs.

        Parameters
        ----------
        graphs : sequence of Decomposition / ContactGraph / ShapeRecord, length n
        labels : sequence of str or int, length n
        validation_data : (graphs, labels) or (graphs, labels, descriptors), optional
            Held-out graphs for model selection; by default ``validation`` of the
            training graphs (stratified) are held out.
        callback : callable, optional
            ``callback(epoch, epochs, metrics)`` after every epoch.
        descriptors : (n, d) float, optional
            The shapes' descriptors; required when ``descriptor=True``.

        Returns
        -------
        self
        """
        from query.learn.gnn import count_parameters, import_torch, train_network

        torch, _ = import_torch()
        graphs, labels = list(graphs), list(labels)
        if len(graphs) != len(labels):
            raise ConfigError(f"{len(graphs)} graphs but {len(labels)} labels")
        names = [str(v) for v in labels]
        classes = sorted(set(names))
        if len(classes) < 2:
            raise ConfigError(f"need at least 2 classes to train, got {classes}")
        self._remember_config(graphs)
        self.classes_ = classes
        index = {c: k for k, c in enumerate(classes)}
        y = np.array([index[c] for c in names], dtype=np.int64)
        for attr in ("descriptor_mean_", "descriptor_scale_"):
            self.__dict__.pop(attr, None)
        train_set, val_set = self._datasets(graphs, y, descriptors, validation_data)

        torch.manual_seed(self.seed)
        device = self._device()
        self.model_ = self._network(len(classes)).to(device)
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

    def _remember_config(self, graphs: Sequence[Any]) -> None:
        """``fingerprint_`` and ``config_json_`` of the training graphs (one configuration)."""
        fps = {fingerprint_of(g) for g in graphs} - {None}
        if len(fps) > 1:
            raise ConfigError(
                f"training graphs come from several configurations: {sorted(map(str, fps))}"
            )
        self.fingerprint_ = fps.pop() if fps else (self.config.fingerprint if self.config else None)
        self.config_json_ = self.config.to_json() if self.config is not None else None

    def _datasets(
        self,
        graphs: list[Any],
        y: NDArray[np.int64],
        descriptors: Any,
        validation_data: tuple[Any, ...] | None,
    ) -> tuple[list[Any], list[Any]]:
        """Training and model-selection sets of torch_geometric Data (with ``y``, ``u``)."""
        u = self._graph_inputs(graphs, descriptors)
        index = {c: k for k, c in enumerate(self.classes_)}
        if validation_data is not None:
            vg, vl = list(validation_data[0]), [str(v) for v in validation_data[1]]
            unknown = set(vl) - set(self.classes_)
            if unknown:
                raise ConfigError(f"validation labels {sorted(unknown)} are not training classes")
            train_idx = np.arange(len(graphs))
            vd = validation_data[2] if len(validation_data) > 2 else None
            vu = self._graph_inputs(vg, vd)
            val_set = self._to_dataset(vg, np.array([index[c] for c in vl]), vu)
        elif self.validation > 0:
            train_idx, val_idx = stratified_split(
                y, (1 - self.validation, self.validation), seed=self.seed
            )
            vu = None if u is None else u[val_idx]
            val_set = self._to_dataset([graphs[i] for i in val_idx], y[val_idx], vu)
        else:
            train_idx, val_set = np.arange(len(graphs)), []
        tu = None if u is None else u[train_idx]
        return self._to_dataset([graphs[i] for i in train_idx], y[train_idx], tu), val_set

    @staticmethod
    def prepare(graphs: Sequence[Any]) -> list[Any]:
        """The graphs as torch_geometric Data, to convert once and fit or predict many times.

        ``fit`` and ``predict_proba`` accept the result in place of the graphs (each
        use copies a Data before setting its label and descriptor). Data carry no
        configuration: pass ``config`` to a model fitted on them.
        """
        from query.learn.gnn import to_data

        return [to_data(_as_graph(g)) for g in graphs]

    def _network(self, n_classes: int) -> Any:
        from query.learn.gnn import build_network

        d = len(self.descriptor_mean_) if self.descriptor else 0
        return build_network(
            self.conv, n_classes, hidden=self.hidden, dropout=self.dropout, graph_features=d
        )

    def predict_proba(
        self, graphs: Sequence[Any], *, descriptors: Any = None
    ) -> NDArray[np.float64]:
        """Class probabilities: (n, n_classes) float64, columns in the order of ``classes_``.

        ``graphs``: n Decompositions, ContactGraphs or ShapeRecords; ``descriptors``
        (n, d) when the model reads them.
        """
        self._check_fitted()
        import torch

        from query.learn.gnn import import_torch

        _, pyg = import_torch()
        graphs = list(graphs)
        self._check_config(graphs)
        if not graphs:
            return np.zeros((0, len(self.classes_)))
        u = self._graph_inputs(graphs, descriptors)
        loader = pyg.loader.DataLoader(self._to_dataset(graphs, None, u), batch_size=64)
        dev = next(self.model_.parameters()).device
        self.model_.eval()
        out = []
        with torch.no_grad():
            for batch in loader:
                out.append(torch.softmax(self.model_(batch.to(dev)), dim=1).cpu().double().numpy())
        return np.concatenate(out, axis=0)

    def predict(self, graphs: Sequence[Any], *, descriptors: Any = None) -> list[str]:
        """Most probable label of each graph (length n list of str)."""
        proba = self.predict_proba(graphs, descriptors=descriptors)
        return [self.classes_[k] for k in proba.argmax(axis=1)]

    def score(
        self, graphs: Sequence[Any], labels: Sequence[Any], *, descriptors: Any = None
    ) -> float:
        """Accuracy on labelled graphs."""
        pred = self.predict(graphs, descriptors=descriptors)
        return (
            float(np.mean([p == str(t) for p, t in zip(pred, labels, strict=True)]))
            if pred
            else math.nan
        )

    def embed(self, graphs: Sequence[Any], *, descriptors: Any = None) -> NDArray[np.float32]:
        """The 256-long shape vectors after global max pooling, (n, 2 * hidden)."""
        self._check_fitted()
        import torch

        from query.learn.gnn import import_torch

        _, pyg = import_torch()
        graphs = list(graphs)
        self._check_config(graphs)
        u = self._graph_inputs(graphs, descriptors)
        loader = pyg.loader.DataLoader(self._to_dataset(graphs, None, u), batch_size=64)
        dev = next(self.model_.parameters()).device
        self.model_.eval()
        with torch.no_grad():
            parts = [self.model_.embed(b.to(dev)).cpu().numpy() for b in loader]
        return np.concatenate(parts) if parts else np.zeros((0, 2 * self.hidden), np.float32)

    def state(self) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
        """The fitted model as plain data: a JSON-ready dict and named arrays.

        The arrays are the network weights (``w/<name>``) and, for ``descriptor=True``,
        ``descriptor_mean`` / ``descriptor_scale``; :meth:`from_state` inverts it.
        """
        self._check_fitted()
        params = self.get_params()
        params["device"] = None
        meta: dict[str, Any] = {
            "kind": "graph",
            "params": params,
            "classes": list(self.classes_),
            "fingerprint": self.fingerprint_,
            "config": self.config_json_,
            "history": self.history_,
            "best_epoch": int(self.best_epoch_),
        }
        if hasattr(self, "test_accuracy_"):
            meta["test_accuracy"] = float(self.test_accuracy_)
        arrays = {f"w/{k}": v.detach().cpu().numpy() for k, v in self.model_.state_dict().items()}
        if self.descriptor:
            arrays["descriptor_mean"] = np.asarray(self.descriptor_mean_)
            arrays["descriptor_scale"] = np.asarray(self.descriptor_scale_)
        return meta, arrays

    @classmethod
    def from_state(
        cls, meta: dict[str, Any], arrays: dict[str, Any], *, device: str | None = None
    ) -> GraphClassifier:
        """Rebuild a fitted model from :meth:`state` (or an older file's dict)."""
        from query.learn.gnn import count_parameters, import_torch

        torch, _ = import_torch()
        self = cls(**dict(meta["params"], device=device))
        self.classes_ = list(meta["classes"])
        self.fingerprint_ = meta["fingerprint"]
        self.config_json_ = meta.get("config")
        if self.config_json_:
            self.config = Config.from_json(self.config_json_)
        self.history_ = meta.get("history", {})
        self.best_epoch_ = int(meta.get("best_epoch", -1))
        if "test_accuracy" in meta:
            self.test_accuracy_ = float(meta["test_accuracy"])
        if self.descriptor:
            self.descriptor_mean_ = np.asarray(arrays["descriptor_mean"], dtype=np.float64)
            self.descriptor_scale_ = np.asarray(arrays["descriptor_scale"], dtype=np.float64)
        weights = {
            k[2:]: torch.as_tensor(np.asarray(v)) if isinstance(v, np.ndarray) else v
            for k, v in arrays.items()
            if k.startswith("w/")
        }
        model = self._network(len(self.classes_))
        model.load_state_dict(weights)
        self.model_ = model.to(self._device()).eval()
        self.n_parameters_ = count_parameters(model)
        return self

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the weights, settings, label names and configuration fingerprint.

        The file is a :mod:`query.learn.model_file` archive (no pickled code).
        """
        from query.learn.model_file import write_model

        meta, arrays = self.state()
        return write_model(path, meta, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, device: str | None = None) -> GraphClassifier:
        """Read a model written by :meth:`save`, or a torch file of the first format.

        Raises
        ------
        LoadError
            Unreadable, or not a graph-CNN classifier.
        """
        from query.learn.gnn import import_torch
        from query.learn.model_file import is_model_file, read_model

        torch, _ = import_torch()
        if is_model_file(path):
            meta, arrays = read_model(path)
            if meta.get("kind") != "graph":
                raise LoadError(
                    f"a {meta.get('kind')!r} classifier, not a graph CNN: "
                    "load it with query.learn.classify.ShapeClassifier.load",
                    source=str(path),
                )
            return cls.from_state(meta, arrays, device=device)
        try:
            state = torch.load(Path(path), map_location="cpu", weights_only=True)
        except (OSError, RuntimeError, EOFError, ValueError, pickle.UnpicklingError) as exc:
            raise LoadError(f"cannot read a classifier: {exc}", source=str(path)) from exc
        if not isinstance(state, dict) or state.get("format") != FORMAT:
            raise LoadError(
                f"not a shapedb classifier (expected format {FORMAT})", source=str(path)
            )
        weights = {f"w/{k}": v for k, v in state["state_dict"].items()}
        return cls.from_state(state, weights, device=device)

    def __repr__(self) -> str:
        fitted = f", classes={len(self.classes_)}" if hasattr(self, "classes_") else ""
        return f"GraphClassifier(conv={self.conv!r}, epochs={self.epochs}{fitted})"
