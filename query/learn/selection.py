"""Choosing a classifier on validation data, within a time budget: never worse than 1-NN.

:func:`select_classifier` scores the candidates on a validation split of the
training data only (stratified), or by stratified k-fold cross-validation when the
smallest class is small, then refits the best on all the training data. Candidates,
cheapest and simplest first (ties go to the simplest):

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

Since 1-NN is always scored and the best validation accuracy wins, the chosen model
is never worse than 1-NN on validation. The graph CNNs choose their epoch on a
further split of each training part, never on the validation fold.

With a time budget (:class:`~query.learn.budget.Budget`) a candidate is started only
when its remaining folds, predicted from what has run (its own finished folds or
epochs, else the epochs of the graph CNNs before it), and the final fit of the best
graph CNN still fit; a running graph CNN is stopped between epochs once its
projection overruns. Candidates in ``required`` (and 1-NN) run whatever the budget.
Finished folds go to a :class:`~query.learn.checkpoint.Checkpoint`, so a later run
with the same settings continues where this one stopped.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from query.learn.budget import Budget, OutOfBudget, Progress, ProgressLog
from query.learn.checkpoint import Checkpoint, FoldScore
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
#: Every candidate, cheapest and simplest first (the order breaks ties).
CANDIDATES = DESCRIPTOR_CANDIDATES + GRAPH_CANDIDATES
#: Below this many shapes in the smallest class, validation is k-fold cross-validation.
SMALL_CLASS = 20
#: How a candidate's scoring ended (``CandidateScore.status``).
STATUSES = ("scored", "resumed", "skipped", "stopped", "failed")


@dataclass(frozen=True)
class CandidateScore:
    """Validation result of one candidate.

    Attributes
    ----------
    name : str
    correct, total : int
        Validation shapes classified correctly, and validated (pooled over folds).
    seconds : float
        Wall time of its fits and predictions (earlier runs' folds included).
    error : str or None
        Why it has no score (a missing optional dependency, the time budget).
    status : str
        "scored"; "resumed" (every fold scored by an earlier run); "skipped" (not
        started: predicted to overrun the budget); "stopped" (stopped by the budget);
        "failed" (a missing dependency).
    """

    name: str
    correct: int
    total: int
    seconds: float
    error: str | None = None
    status: str = "scored"

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
        In candidate order (cheapest first).
    budget : float or None
        Time budget in seconds (None: no limit).
    seconds : float
        Wall time of the scoring (before the final fit).
    """

    chosen: str
    protocol: str
    folds: int
    n_train: int
    scores: tuple[CandidateScore, ...]
    budget: float | None = None
    seconds: float = 0.0

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
            f"{s.name} {s.accuracy:.3f}"
            if s.error is None
            else f"{s.name} n/a" + (f" ({s.status})" if s.status in ("skipped", "stopped") else "")
            for s in self.scores
        ]
        best = self.score_of(self.chosen)
        budget = (
            "" if self.budget is None else f"; {self.seconds:.0f} s of a {self.budget:.0f} s budget"
        )
        return (
            f"chose {self.chosen}: validation accuracy {best.accuracy:.3f} "
            f"({best.correct}/{best.total}, {how}; ties go to the simplest); "
            + ", ".join(parts)
            + budget
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (stored in the model file)."""
        out = asdict(self)
        out["scores"] = [{**asdict(s), "accuracy": s.accuracy} for s in self.scores]
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Selection:
        """Inverse of :meth:`to_dict` (also reads reports written before the budget)."""
        scores = tuple(
            CandidateScore(**{k: v for k, v in s.items() if k != "accuracy"}) for s in d["scores"]
        )
        budget = d.get("budget")
        return cls(
            *(d["chosen"], d["protocol"], int(d["folds"]), int(d["n_train"]), scores),
            budget=None if budget is None else float(budget),
            seconds=float(d.get("seconds", 0.0)),
        )


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


@dataclass
class _Run:
    """The state of one selection: data, folds, budget, and the costs measured so far."""

    graphs: list[Any]
    x: NDArray[np.float64]
    y: NDArray[Any]
    parts: list[Any]
    seed: int
    graph_options: dict[str, Any] | None
    budget: Budget
    checkpoint: Checkpoint
    required: set[str]
    order: list[str]
    report: Callable[[Progress], None] = lambda p: None
    prepared: list[Any] | None = None  # graph tensors, built once for every fold and CNN
    epoch_seconds: dict[str, float] = field(default_factory=dict)
    fold_seconds: dict[str, float] = field(default_factory=dict)
    best_correct: int = -1  # validation hits of the best candidate so far
    best_refit: float = 0.0  # and the predicted seconds of its final fit

    def model(self, name: str) -> Any:
        return make_candidate(name, seed=self.seed, graph_options=self.graph_options)

    def inputs(self, model: Any) -> list[Any]:
        """What ``model`` reads: graph tensors (converted once) for a graph CNN."""
        if not _is_graph(model) or not hasattr(model, "prepare"):
            return self.graphs
        if self.prepared is None:
            self.prepared = model.prepare(self.graphs)
        return self.prepared

    def progress(
        self, name: str, fold: int, epoch: int, epochs: int, done: list[FoldScore]
    ) -> None:
        correct, total = sum(d[0] for d in done), sum(d[1] for d in done)
        self.report(
            Progress(
                *(name, self.order.index(name) + 1, len(self.order), fold, len(self.parts)),
                *(epoch, epochs, correct / total if total else math.nan),
                *(self.budget.spent(), self.budget.left()),
            )
        )

    def fold_cost(self, name: str, epochs: int) -> float | None:
        """Predicted seconds of one validation fold of ``name`` (None: nothing to go by)."""
        if name in self.fold_seconds:
            return self.fold_seconds[name]
        per_epoch = self.epoch_seconds.get(name) or max(self.epoch_seconds.values(), default=0)
        return per_epoch * epochs if epochs and per_epoch else None

    def fits(self, name: str, seconds: float, fold: float) -> bool:
        """Whether ``seconds`` more of ``name`` and a final fit still end in the budget.

        The final fit reserved is that of ``name`` (a graph CNN: a fold's ``fold``
        seconds scaled to all the training shapes) or of the best candidate so far.
        """
        if name in self.required:
            return True
        refit = (
            fold * len(self.y) / max(len(self.parts[0][0]), 1) if name in GRAPH_CANDIDATES else 0
        )
        return self.budget.allows(seconds + max(refit, self.best_refit))


def _fold(run: _Run, name: str, fold: int, done: list[FoldScore]) -> FoldScore:
    """Fit ``name`` on one training part and score it on its validation part."""
    train, val = run.parts[fold]
    model = run.model(name)
    epochs = int(getattr(model, "epochs", 0)) if _is_graph(model) else 0
    folds_after = len(run.parts) - fold - 1
    inputs = run.inputs(model)  # graph tensors: built once, before the fold's clock starts
    t0 = run.budget.spent()
    run.progress(name, fold + 1, 0, epochs, done)
    ends: list[float] = []  # the end of every epoch; the first also holds the fold's set-up

    def on_epoch(epoch: int, total: int, metrics: dict[str, float]) -> None:
        ends.append(run.budget.spent())
        run.progress(name, fold + 1, epoch, total, done)
        if len(ends) < 2:  # no epoch time yet: stop only once over the budget
            if not run.fits(name, 0.0, 0.0):
                raise OutOfBudget(name)
            return
        per_epoch = run.epoch_seconds[name] = (ends[-1] - ends[0]) / (len(ends) - 1)
        rest = per_epoch * (total - epoch + total * folds_after)
        if epoch < total and not run.fits(name, rest, per_epoch * total):
            raise OutOfBudget(name)

    pick = lambda idx, xs: [xs[i] for i in idx]  # noqa: E731
    fit_candidate(model, pick(train, inputs), run.x[train], run.y[train].tolist(), on_epoch)
    proba = predict_candidate(model, pick(val, inputs), run.x[val])
    pred = np.asarray(model.classes_)[proba.argmax(axis=1)]
    seconds = run.budget.spent() - t0
    run.fold_seconds[name] = seconds
    return int((pred == run.y[val]).sum()), len(val), seconds


def _score(run: _Run, name: str) -> CandidateScore:
    """Score ``name`` on the folds not scored yet, while the budget allows."""
    done = run.checkpoint.done(name)[: len(run.parts)]
    before, t0 = len(done), run.budget.spent()
    epochs = int(getattr(run.model(name), "epochs", 0)) if name in GRAPH_CANDIDATES else 0
    status, error = "scored", None
    try:
        while len(done) < len(run.parts):
            cost = run.fold_cost(name, epochs)
            left = len(run.parts) - len(done)
            if cost is None and run.budget.left() <= 0 and name not in run.required:
                cost = math.inf
            if cost is not None and not run.fits(name, cost * left, cost):
                status = "skipped" if len(done) == before else "stopped"
                break
            done.append(_fold(run, name, len(done), done))
            run.checkpoint.add_fold(name, done[-1])
    except OutOfBudget:
        status = "stopped"
    except ImportError as exc:  # an optional dependency (torch, scikit-learn)
        status, error = "failed", str(exc).splitlines()[0]
    if status in ("skipped", "stopped"):
        error = f"{status} by the time budget after {len(done)}/{len(run.parts)} folds"
    elif status == "scored" and before == len(run.parts):
        status = "resumed"
    seconds = sum(d[2] for d in done[:before]) + run.budget.spent() - t0
    correct, total = sum(d[0] for d in done), sum(d[1] for d in done)
    score = CandidateScore(name, correct, total, seconds, error, status)
    if score.error is None and score.correct > run.best_correct:  # the final fit to reserve
        fold = run.fold_seconds.get(name, max((d[2] for d in done), default=0.0))
        graph = name in GRAPH_CANDIDATES
        run.best_correct = score.correct
        run.best_refit = fold * len(run.y) / max(len(run.parts[0][0]), 1) if graph else 0.0
    run.report(
        Progress(
            candidate=name,
            index=run.order.index(name) + 1,
            candidates=len(run.order),
            fold=len(done),
            folds=len(run.parts),
            epoch=0,
            epochs=epochs,
            score=score.accuracy,
            spent=run.budget.spent(),
            left=run.budget.left(),
            done=status,
        )
    )
    return score


def _refit(
    run: _Run, name: str, callback: Callable[[int, int, dict[str, float]], None] | None
) -> Any:
    """Fit the chosen candidate on all the training shapes (never stopped by the budget)."""
    model = run.model(name)
    every = np.arange(len(run.y))

    def on_epoch(epoch: int, epochs: int, metrics: dict[str, float]) -> None:
        run.progress(name, 0, epoch, epochs, [])
        if callback is not None:
            callback(epoch, epochs, metrics)

    run.progress(name, 0, 0, int(getattr(model, "epochs", 0)) if _is_graph(model) else 0, [])
    # the graph tensors carry no configuration: the shapes' own graphs unless it is given
    known = (run.graph_options or {}).get("config") is not None and run.prepared is not None
    graphs = run.inputs(model) if known else run.graphs
    fit_candidate(model, graphs, run.x[every], run.y.tolist(), callback=on_epoch)
    return model


def _start(
    graphs: Sequence[Any],
    descriptors: Any,
    labels: Sequence[Any],
    candidates: Sequence[str] | None,
    required: Sequence[str],
    budget: float | Budget | None,
    **settings: Any,
) -> _Run:
    """Check the inputs and candidates; the run's folds, budget and checkpoint."""
    names = [str(v) for v in labels]
    x = np.asarray(descriptors, dtype=np.float64)
    if len(x) != len(names) or len(graphs) != len(names):
        raise ConfigError(f"{len(graphs)} graphs, {len(x)} descriptors and {len(names)} labels")
    wanted = list(CANDIDATES if candidates is None else candidates)
    for c in [*wanted, *required]:
        make_candidate(c)  # unknown names fail before any work
    order = [c for c in CANDIDATES if c == "1-nn" or c in wanted]
    order += [c for c in wanted if c not in order]
    y = np.asarray(names)
    seed = int(settings["seed"])
    return _Run(
        graphs=list(graphs),
        x=x,
        y=y,
        parts=_parts(y, settings["folds"], settings["validation"], seed),
        seed=seed,
        graph_options=settings["graph_options"],
        budget=budget if isinstance(budget, Budget) else Budget(budget, clock=settings["clock"]),
        checkpoint=settings["checkpoint"] or Checkpoint(None, {}),
        required={"1-nn", *required},
        order=order,
    )


def _selection(run: _Run, scores: list[CandidateScore]) -> Selection:
    """The report: the best validation accuracy wins, ties to the first (simplest)."""
    valid = [s for s in scores if s.error is None]
    best = max(valid, key=lambda s: s.correct)  # max keeps the first (simplest) of ties
    return Selection(
        chosen=best.name,
        protocol="k-fold" if len(run.parts) > 1 else "holdout",
        folds=len(run.parts),
        n_train=len(run.y),
        scores=tuple(scores),
        budget=run.budget.seconds,
        seconds=run.budget.spent(),
    )


def select_classifier(
    graphs: Sequence[Any],
    descriptors: Any,
    labels: Sequence[Any],
    *,
    candidates: Sequence[str] | None = None,
    required: Sequence[str] = (),
    folds: int | str = "auto",
    validation: float = 0.2,
    seed: int = 0,
    graph_options: dict[str, Any] | None = None,
    refit: bool = True,
    callback: Callable[[int, int, dict[str, float]], None] | None = None,
    budget: float | Budget | None = None,
    clock: Callable[[], float] | None = None,
    progress: Callable[[Progress], None] | None = None,
    checkpoint: Checkpoint | None = None,
) -> tuple[Selection, Any]:
    """Score the candidates on validation data within a budget, refit the best on everything.

    Parameters
    ----------
    graphs : sequence of n contact graphs (Decomposition, ContactGraph, StoredGraph)
        Read by the graph CNNs only; may be None entries when no graph CNN runs.
    descriptors : (n, d) float
        The shapes' descriptors (the store's feature vectors).
    labels : sequence of n labels
    candidates : sequence of str, optional
        Names from :data:`CANDIDATES`; default all of them ("1-nn" is always added).
    required : sequence of str
        Candidates scored whatever the budget (1-NN always is).
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
        ``callback(epoch, epochs, metrics)`` per epoch of the final graph-CNN fit.
    budget : float (seconds) or Budget, optional
        Time for the scoring and the final fit; None: no limit.
    clock : callable, optional
        Monotonic seconds of the budget and the progress log (default ``time.monotonic``).
    progress : callable, optional
        Called with a :class:`~query.learn.budget.Progress` at every fold, epoch and
        candidate end (progress is also logged, at least every 10 s).
    checkpoint : Checkpoint, optional
        Folds scored by an earlier run (reused) and where this run's go.

    Returns
    -------
    (Selection, fitted estimator or None)
    """
    settings: dict[str, Any] = {"folds": folds, "validation": validation, "seed": seed}
    settings["clock"] = clock
    settings.update(graph_options=graph_options, checkpoint=checkpoint)
    run = _start(graphs, descriptors, labels, candidates, required, budget, **settings)
    with ProgressLog(clock=run.budget.clock) as progress_log:

        def report(p: Progress) -> None:
            progress_log(p)
            if progress is not None:
                progress(p)

        run.report = report
        scores = [_score(run, name) for name in run.order]
        selection = _selection(run, scores)
        log.info("%s", selection.reason())
        return selection, _refit(run, selection.chosen, callback) if refit else None
