"""Classifiers of shape descriptors: nearest neighbours, a linear model, gradient boosting.

Each reads the descriptor the store searches with (``KernelConfig``'s feature
vector, (n, d) float) and follows the scikit-learn contract: ``__init__`` stores
settings, ``fit(X, labels) -> self``, learned state ends in ``_``, ``predict_proba``
columns follow ``classes_``. ``state()`` / ``from_state`` give the fitted model as
plain data (a JSON-ready dict and arrays) for :mod:`query.learn.model_file`.

- :class:`NearestNeighbours`: k-NN on the store's own similarity, the L1 distance
  of the descriptors (Eq. 3's kernel is exp(-lam d), so the order is the search's);
  votes weighted by 1/d for k > 1. Keeps its training descriptors and labels.
  numpy only.
- :class:`LinearDescriptor`: multinomial logistic regression on standardised
  descriptors (scikit-learn to fit; predicting needs numpy only).
- :class:`BoostedDescriptor`: histogram gradient boosting (scikit-learn). Its trees
  are not written out: the file keeps the training descriptors and labels, and
  loading refits with the same settings and seed (deterministic for one
  scikit-learn version).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import ConfigError, NotFittedError, require

__all__ = ["NearestNeighbours", "LinearDescriptor", "BoostedDescriptor", "DESCRIPTOR_KINDS"]

FloatArray = NDArray[np.float64]


def _matrix(x: Any, name: str = "descriptors") -> FloatArray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name} must be a finite (n, d) array, got shape {a.shape}")
    return a


class _DescriptorModel:
    """Shared label handling, prediction and scoring."""

    classes_: list[str]
    kind = ""

    def _labels(self, x: FloatArray, labels: Sequence[Any]) -> NDArray[np.int64]:
        names = [str(v) for v in labels]
        if len(names) != len(x):
            raise ConfigError(f"{len(x)} descriptors but {len(names)} labels")
        self.classes_ = sorted(set(names))
        if len(self.classes_) < 2:
            raise ConfigError(f"need at least 2 classes to train, got {self.classes_}")
        index = {c: k for k, c in enumerate(self.classes_)}
        return np.array([index[c] for c in names], dtype=np.int64)

    def _check_fitted(self) -> None:
        if not hasattr(self, "classes_"):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet: call fit first")

    def predict_proba(self, descriptors: Any) -> FloatArray:  # pragma: no cover - abstract
        raise NotImplementedError

    def predict(self, descriptors: Any) -> list[str]:
        """Most probable label of each row (ties: the first class)."""
        proba = self.predict_proba(descriptors)
        return [self.classes_[k] for k in proba.argmax(axis=1)]

    def score(self, descriptors: Any, labels: Sequence[Any]) -> float:
        """Accuracy on labelled descriptors."""
        pred = self.predict(descriptors)
        return float(np.mean([p == str(t) for p, t in zip(pred, labels, strict=True)]))


class NearestNeighbours(_DescriptorModel):
    """k nearest neighbours on the L1 distance of the descriptors.

    Parameters
    ----------
    k : int
        Neighbours voting (at most the number of training shapes).
    weighted : bool
        Weight each vote by 1/d (an exact match outvotes everything); with k = 1
        it makes no difference.

    Attributes
    ----------
    X_ : (m, d) float64
        Training descriptors.
    y_ : (m,) int64
        Their class indices into ``classes_``.
    """

    kind = "knn"

    def __init__(self, k: int = 1, *, weighted: bool = True) -> None:
        self.k = k
        self.weighted = weighted

    def fit(self, descriptors: Any, labels: Sequence[Any]) -> NearestNeighbours:
        """Remember the training descriptors and labels; returns self."""
        if self.k < 1:
            raise ConfigError(f"k={self.k} is invalid: must be at least 1")
        x = _matrix(descriptors)
        self.y_ = self._labels(x, labels)
        self.X_ = x
        return self

    def predict_proba(self, descriptors: Any) -> FloatArray:
        """Vote shares (n, n_classes); nearest-first ties keep the lower training index."""
        self._check_fitted()
        q = _matrix(descriptors).reshape(-1, self.X_.shape[1])
        k = min(self.k, len(self.X_))
        out = np.zeros((len(q), len(self.classes_)))
        for s in range(0, len(q), 256):  # (256, m, d) at a time
            d = np.abs(q[s : s + 256, None, :] - self.X_[None]).sum(axis=2)
            near = np.argsort(d, axis=1, kind="stable")[:, :k]
            dist = np.take_along_axis(d, near, axis=1)
            w = 1.0 / (dist + 1e-12) if self.weighted and k > 1 else np.ones_like(dist)
            rows = np.repeat(np.arange(len(near)), k)
            np.add.at(out[s : s + 256], (rows, self.y_[near].ravel()), w.ravel())
        return out / out.sum(axis=1, keepdims=True)

    def state(self) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
        """Settings and classes, and the arrays ``X``, ``y``."""
        self._check_fitted()
        meta = {"k": self.k, "weighted": self.weighted, "classes": self.classes_}
        return meta, {"X": self.X_, "y": self.y_}

    @classmethod
    def from_state(cls, meta: dict[str, Any], arrays: dict[str, Any]) -> NearestNeighbours:
        self = cls(int(meta["k"]), weighted=bool(meta["weighted"]))
        self.classes_ = list(meta["classes"])
        self.X_ = np.asarray(arrays["X"], dtype=np.float64)
        self.y_ = np.asarray(arrays["y"], dtype=np.int64)
        return self


class LinearDescriptor(_DescriptorModel):
    """Multinomial logistic regression on standardised descriptors.

    Parameters
    ----------
    C : float
        Inverse L2 regularisation strength (scikit-learn's ``C``).
    max_iter : int
        L-BFGS iterations.

    Attributes
    ----------
    mean_, scale_ : (d,) float64
        Standardisation.
    coef_ : (c, d) float64
        Class weights (c = 1 for two classes: the second class's log-odds).
    intercept_ : (c,) float64
    """

    kind = "linear"

    def __init__(self, *, C: float = 1.0, max_iter: int = 5000) -> None:
        self.C = C
        self.max_iter = max_iter

    def fit(self, descriptors: Any, labels: Sequence[Any]) -> LinearDescriptor:
        """Fit with scikit-learn (the ``learn`` extra); returns self."""
        require("sklearn", extra="learn", feature="descriptor classifiers")
        from sklearn.linear_model import LogisticRegression

        x = _matrix(descriptors)
        y = self._labels(x, labels)
        std = x.std(axis=0)
        self.mean_, self.scale_ = x.mean(axis=0), np.where(std > 1e-12, std, 1.0)
        model = LogisticRegression(C=self.C, max_iter=self.max_iter)
        model.fit((x - self.mean_) / self.scale_, y)
        self.coef_ = np.asarray(model.coef_, dtype=np.float64)
        self.intercept_ = np.asarray(model.intercept_, dtype=np.float64)
        return self

    def predict_proba(self, descriptors: Any) -> FloatArray:
        """Softmax of the class scores (n, n_classes)."""
        self._check_fitted()
        x = (_matrix(descriptors).reshape(-1, len(self.mean_)) - self.mean_) / self.scale_
        z = x @ self.coef_.T + self.intercept_
        if z.shape[1] == 1:  # two classes: one log-odds column
            z = np.concatenate([np.zeros_like(z), z], axis=1)
        z = z - z.max(axis=1, keepdims=True)
        e = np.exp(z)
        return e / e.sum(axis=1, keepdims=True)

    def state(self) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
        """Settings and classes, and the arrays ``mean``, ``scale``, ``coef``, ``intercept``."""
        self._check_fitted()
        meta = {"C": self.C, "max_iter": self.max_iter, "classes": self.classes_}
        arrays = {"mean": self.mean_, "scale": self.scale_, "coef": self.coef_}
        return meta, {**arrays, "intercept": self.intercept_}

    @classmethod
    def from_state(cls, meta: dict[str, Any], arrays: dict[str, Any]) -> LinearDescriptor:
        self = cls(C=float(meta["C"]), max_iter=int(meta["max_iter"]))
        self.classes_ = list(meta["classes"])
        for name in ("mean", "scale", "coef", "intercept"):
            setattr(self, f"{name}_", np.asarray(arrays[name], dtype=np.float64))
        return self


def _one_thread() -> Any:
    """OpenMP limited to one thread: on hundreds of shapes, threads only add contention."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="openmp")


class BoostedDescriptor(_DescriptorModel):
    """Histogram gradient boosting of shallow trees on the descriptors.

    Parameters
    ----------
    max_iter : int
        Boosting rounds (one tree per class per round).
    learning_rate : float
    max_leaf_nodes : int
    seed : int
        Seed of scikit-learn's random state.

    Attributes
    ----------
    X_, y_ : training descriptors (m, d) and class indices (m,): the file keeps them
        and loading refits.
    model_ : sklearn.ensemble.HistGradientBoostingClassifier
    """

    kind = "boosting"

    def __init__(
        self,
        *,
        max_iter: int = 100,
        learning_rate: float = 0.1,
        max_leaf_nodes: int = 15,
        seed: int = 0,
    ) -> None:
        self.max_iter = max_iter
        self.learning_rate = learning_rate
        self.max_leaf_nodes = max_leaf_nodes
        self.seed = seed

    def fit(self, descriptors: Any, labels: Sequence[Any]) -> BoostedDescriptor:
        """Fit with scikit-learn (the ``learn`` extra); returns self."""
        require("sklearn", extra="learn", feature="descriptor classifiers")
        from sklearn.ensemble import HistGradientBoostingClassifier

        x = _matrix(descriptors)
        y = self._labels(x, labels)
        model = HistGradientBoostingClassifier(
            max_iter=self.max_iter,
            learning_rate=self.learning_rate,
            max_leaf_nodes=self.max_leaf_nodes,
            early_stopping=False,
            random_state=self.seed,
        )
        with _one_thread():
            self.model_ = model.fit(x, y)
        self.X_, self.y_ = x, y
        return self

    def predict_proba(self, descriptors: Any) -> FloatArray:
        """Class probabilities (n, n_classes)."""
        self._check_fitted()
        x = _matrix(descriptors).reshape(-1, self.X_.shape[1])
        proba = np.zeros((len(x), len(self.classes_)))
        with _one_thread():
            proba[:, self.model_.classes_] = self.model_.predict_proba(x)
        return proba

    def state(self) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
        """Settings and classes, and the training arrays ``X``, ``y``."""
        self._check_fitted()
        meta = {
            "max_iter": self.max_iter,
            "learning_rate": self.learning_rate,
            "max_leaf_nodes": self.max_leaf_nodes,
            "seed": self.seed,
            "classes": self.classes_,
        }
        return meta, {"X": self.X_, "y": self.y_}

    @classmethod
    def from_state(cls, meta: dict[str, Any], arrays: dict[str, Any]) -> BoostedDescriptor:
        """Refit on the stored training descriptors (same settings and seed)."""
        self = cls(
            max_iter=int(meta["max_iter"]),
            learning_rate=float(meta["learning_rate"]),
            max_leaf_nodes=int(meta["max_leaf_nodes"]),
            seed=int(meta["seed"]),
        )
        classes = list(meta["classes"])
        y = np.asarray(arrays["y"], dtype=np.int64)
        self.fit(np.asarray(arrays["X"], dtype=np.float64), [classes[i] for i in y])
        self.classes_ = classes
        return self


DESCRIPTOR_KINDS: dict[str, type[_DescriptorModel]] = {
    "knn": NearestNeighbours,
    "linear": LinearDescriptor,
    "boosting": BoostedDescriptor,
}
