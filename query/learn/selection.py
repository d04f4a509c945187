"""Choosing a classifier on validation data: never worse than 1-nearest-neighbour.

:func:`select_classifier` scores every candidate on a validation split of the
training data only (stratified), or by stratified k-fold cross-validation when the
smallest class is small, then refits the best on all the training data. Candidates,
simplest first (ties go to the simplest):

==================  ===========================================================
``1-nn``            nearest neighbour on the store's descriptor distance
``3-nn``, ``5-nn``  k nearest neighbours, votes weighted by 1/distance
``linear``          logistic regression on the standardised descriptor
``boosting``        gradient boosting on the descriptor
``tag``, ``arma``,  the paper's graph CNNs on the contact graph (no rotation
``spline``          augmentation)
``tag+descriptor``  the TAGConv network that also reads the descriptor as a
                    graph-level input
==================  ===========================================================

Since 1-NN is a candidate and the best validation accuracy wins, the chosen model
is never worse than 1-NN on validation. The graph CNNs choose their epoch on a
further split of each training part, never on the validation fold.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from query.learn.descriptor_classifiers import (
    BoostedDescriptor,
    LinearDescriptor,
    NearestNeighbours,
)
from query.learn.training_data import stratified_folds, stratified_split
from shapedb.errors import ConfigError

__all__ = [
    "CANDIDATES",
    "DESCRIPTOR_CANDIDATES",
    "GRAPH_CANDIDATES",
    "CandidateScore",
    "Selection",
    "make_candidate",
    "fit_candidate",
    "predict_candidate",
    "select_classifier",
]

log = logging.getLogger(__name__)

DESCRIPTOR_CANDIDATES = ("1-nn", "3-nn", "5-nn", "linear", "boosting")
GRAPH_CANDIDATES = ("tag", "arma", "spline", "tag+descriptor")
#: Every candidate, simplest first (the order breaks ties).
CANDIDATES = DESCRIPTOR_CANDIDATES + GRAPH_CANDIDATES
#: Below this many shapes in the smallest class, validation is k-fold cross-validation.
SMALL_CLASS = 20


@dataclass(frozen=True)
class CandidateScore:
    """Validation result of one candidate.

    Attributes
    ----------
    name : str
    correct, total : int
        Validation shapes classified correctly, and validated (pooled over folds).
    seconds : float
        Wall time of its fits and predictions.
    error : str or None
        Why it could not be scored (e.g. a missing optional dependency).
    """

    name: str
    correct: int
    total: int
    seconds: float
    error: str | None = None

    @property
    def accuracy(self) -> float:
        return self.correct / self.total if self.total and self.error is None else float("nan")


@dataclass(frozen=True)
class Selection:
    """Which candidate was chosen, and every candidate's validation accuracy.

    Attributes
    ----------
    chosen : str
    protocol : str
        "k-fold" or "holdout".
    folds : int
        Folds (1 for a holdout split).
    n_train : int
        Labelled training shapes the selection saw.
    scores : tuple of CandidateScore
        In candidate order (simplest first).
    """

    chosen: str
    protocol: str
    folds: int
    n_train: int
    scores: tuple[CandidateScore, ...]

    def score_of(self, name: str) -> CandidateScore:
        """The score of candidate ``name`` (KeyError if it was not a candidate)."""
        for s in self.scores:
            if s.name == name:
                return s
        raise KeyError(name)

    def reason(self) -> str:
        """One line: the chosen candidate and every candidate's validation accuracy."""
        how = f"{self.folds}-fold cross-validation" if self.protocol == "k-fold" else "holdout"
        parts = [
            f"{s.name} {s.accuracy:.3f}" if s.error is None else f"{s.name} n/a"
            for s in self.scores
        ]
        best = self.score_of(self.chosen)
        return (
            f"chose {self.chosen}: validation accuracy {best.accuracy:.3f} "
            f"({best.correct}/{best.total}, {how}; ties go to the simplest); " + ", ".join(parts)
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (stored in the model file)."""
        out = asdict(self)
        out["scores"] = [{**asdict(s), "accuracy": s.accuracy} for s in self.scores]
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Selection:
        scores = tuple(
            CandidateScore(**{k: v for k, v in s.items() if k != "accuracy"}) for s in d["scores"]
        )
        return cls(d["chosen"], d["protocol"], int(d["folds"]), int(d["n_train"]), scores)


def make_candidate(name: str, *, seed: int = 0, graph_options: dict[str, Any] | None = None) -> Any:
    """An unfitted estimator for candidate ``name`` (see the module table)."""
    if name.endswith("-nn") and name[:-3].isdigit():
        return NearestNeighbours(int(name[:-3]), weighted=True)
    if name == "linear":
        return LinearDescriptor()
    if name == "boosting":
        return BoostedDescriptor(seed=seed)
    conv, _, extra = name.partition("+")
    if conv in ("tag", "arma", "spline") and extra in ("", "descriptor"):
        from query.learn.graphcnn import GraphClassifier

        options = {"rotate": False, "seed": seed, **(graph_options or {})}
        return GraphClassifier(conv, descriptor=extra == "descriptor", **options)
    raise ConfigError(f"unknown classifier {name!r}: choose from {', '.join(CANDIDATES)}")


def _is_graph(model: Any) -> bool:
    return hasattr(model, "conv")


def fit_candidate(
    model: Any,
    graphs: Sequence[Any],
    descriptors: NDArray[np.float64],
    labels: Sequence[str],
    callback: Any = None,
) -> Any:
    """Fit a candidate on graphs (graph CNNs) or descriptors (the others); returns it."""
    if _is_graph(model):
        return model.fit(graphs, labels, descriptors=descriptors, callback=callback)
    return model.fit(descriptors, labels)


def predict_candidate(
    model: Any, graphs: Sequence[Any], descriptors: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Class probabilities (n, n_classes) of a fitted candidate."""
    if _is_graph(model):
        return np.asarray(model.predict_proba(graphs, descriptors=descriptors))
    return np.asarray(model.predict_proba(descriptors))


def _parts(y: NDArray[Any], folds: int | str, validation: float, seed: int) -> list[Any]:
    """(train, validation) index pairs."""
    smallest = int(np.unique(y, return_counts=True)[1].min())
    if smallest < 2:
        raise ConfigError("every class needs at least 2 labelled shapes to choose a classifier")
    k = (min(5, smallest) if smallest < SMALL_CLASS else 1) if folds == "auto" else int(folds)
    if k > 1:
        tests = stratified_folds(y, min(k, smallest), seed=seed)
        everything = np.arange(len(y))
        return [(np.setdiff1d(everything, t), t) for t in tests]
    train, val = stratified_split(y, (1 - validation, validation), seed=seed)
    return [(train, val)]


def select_classifier(
    graphs: Sequence[Any],
    descriptors: Any,
    labels: Sequence[Any],
    *,
    candidates: Sequence[str] | None = None,
    folds: int | str = "auto",
    validation: float = 0.2,
    seed: int = 0,
    graph_options: dict[str, Any] | None = None,
    refit: bool = True,
    callback: Callable[[int, int, dict[str, float]], None] | None = None,
) -> tuple[Selection, Any]:
    """Score the candidates on validation data, choose the best, refit it on everything.

    Parameters
    ----------
    graphs : sequence of n contact graphs (Decomposition, ContactGraph, StoredGraph)
        Read by the graph CNNs only; may be None entries when no graph CNN is a
        candidate.
    descriptors : (n, d) float
        The shapes' descriptors (the store's feature vectors).
    labels : sequence of n labels
    candidates : sequence of str, optional
        Names from :data:`CANDIDATES`; default all of them ("1-nn" is always added).
    folds : int or "auto"
        k-fold cross-validation with k folds; 1 for one holdout split of
        ``validation``; "auto": min(5, smallest class) folds when the smallest class
        has fewer than 20 shapes, else a holdout split.
    validation : float
        Fraction held out by a holdout split.
    seed : int
        Seed of the splits and of the candidates.
    graph_options : dict, optional
        :class:`~query.learn.graphcnn.GraphClassifier` settings for the graph CNNs.
    refit : bool
        Refit the chosen candidate on all n shapes (else return None as the model).
    callback : callable, optional
        Epoch progress of the final graph-CNN fit.

    Returns
    -------
    (Selection, fitted estimator or None)
    """
    names = [str(v) for v in labels]
    x = np.asarray(descriptors, dtype=np.float64)
    if len(x) != len(names) or len(graphs) != len(names):
        raise ConfigError(f"{len(graphs)} graphs, {len(x)} descriptors and {len(names)} labels")
    wanted = list(CANDIDATES if candidates is None else candidates)
    for c in wanted:
        make_candidate(c)  # unknown names fail before any work
    order = [c for c in CANDIDATES if c == "1-nn" or c in wanted]
    order += [c for c in wanted if c not in order]
    y = np.asarray(names)
    parts = _parts(y, folds, validation, seed)
    scores = []
    for name in order:
        t0 = time.perf_counter()
        correct = total = 0
        error = None
        try:
            for train, val in parts:
                model = make_candidate(name, seed=seed, graph_options=graph_options)
                pick = lambda idx, xs: [xs[i] for i in idx]  # noqa: E731
                fit_candidate(model, pick(train, graphs), x[train], pick(train, names))
                proba = predict_candidate(model, pick(val, graphs), x[val])
                pred = np.asarray(model.classes_)[proba.argmax(axis=1)]
                correct += int((pred == y[val]).sum())
                total += len(val)
        except ImportError as exc:  # an optional dependency (torch, scikit-learn)
            error = str(exc).splitlines()[0]
        score = CandidateScore(name, correct, total, time.perf_counter() - t0, error)
        scores.append(score)
        log.info(
            "candidate %s: validation accuracy %.3f (%d/%d, %.1f s)%s",
            *(name, score.accuracy, correct, total, score.seconds),
            f" [{error}]" if error else "",
        )
    valid = [s for s in scores if s.error is None]
    best = max(valid, key=lambda s: s.correct)  # max keeps the first (simplest) of ties
    selection = Selection(
        chosen=best.name,
        protocol="k-fold" if len(parts) > 1 else "holdout",
        folds=len(parts),
        n_train=len(names),
        scores=tuple(scores),
    )
    log.info("%s", selection.reason())
    if not refit:
        return selection, None
    model = make_candidate(best.name, seed=seed, graph_options=graph_options)
    return selection, fit_candidate(model, graphs, x, names, callback=callback)
