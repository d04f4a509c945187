"""Choosing a classifier on validation data (query.learn.selection, query.learn.descriptor_classifiers).

Synthetic descriptors with known structure: a case only neighbours can solve (XOR
clusters), one only a linear model can (an oblique boundary among noise), and the
guarantee that the choice is never worse than 1-NN on validation. scikit-learn
(the ``learn`` extra) is needed for the linear model and boosting; those tests skip
without it.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from query.learn.descriptor_classifiers import (
    BoostedDescriptor,
    LinearDescriptor,
    NearestNeighbours,
)
from query.learn.selection import CANDIDATES, Selection, make_candidate, select_classifier
from shapedb.errors import ConfigError, MissingDependencyError, NotFittedError

DESCRIPTOR = ["1-nn", "3-nn", "5-nn", "linear", "boosting"]


@pytest.fixture(scope="module")
def sklearn() -> None:
    pytest.importorskip("sklearn", reason="needs the learn extra: pip install 'shapedb[learn]'")


def xor_clusters(n: int = 80, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two classes, each two tight clusters at opposite corners: no line separates them."""
    rng = np.random.default_rng(seed)
    c = rng.integers(0, 4, n)
    corners = np.array([[0, 0], [5, 5], [0, 5], [5, 0]], dtype=float)
    x = corners[c] + rng.normal(scale=0.3, size=(n, 2))
    x = np.concatenate([x, rng.normal(scale=0.1, size=(n, 3))], axis=1)
    return x, np.where(c < 2, "a", "b")


def oblique(n: int = 120, d: int = 20, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The sign of a dense linear form in 20 dimensions: far neighbours, one hyperplane."""
    rng = np.random.default_rng(seed)
    w = rng.normal(size=d)
    x = rng.normal(size=(n, d))
    return x, np.where(x @ w > 0, "pos", "neg")


def test_nearest_neighbours_vote_by_inverse_distance() -> None:
    x = np.array([[0.0], [1.0], [3.0], [10.0]])
    model = NearestNeighbours(3).fit(x, ["a", "a", "b", "b"])
    # query 2.5: neighbours b at 0.5, a at 1.5 and 2.5 -> weights 2 vs 1/1.5 + 1/2.5
    p = model.predict_proba([[2.5]])[0]
    wa, wb = 1 / 1.5 + 1 / 2.5, 1 / 0.5
    np.testing.assert_allclose(p, [wa / (wa + wb), wb / (wa + wb)])
    assert model.predict([[2.5], [0.2]]) == ["b", "a"]
    assert NearestNeighbours(1).fit(x, ["a", "a", "b", "b"]).predict([[1.9]]) == ["a"]
    # an exact match decides however many neighbours vote
    assert NearestNeighbours(4).fit(x, ["a", "a", "b", "b"]).predict([[10.0]]) == ["b"]


def test_unfitted_and_bad_input_raise() -> None:
    with pytest.raises(NotFittedError):
        NearestNeighbours(1).predict([[0.0]])
    with pytest.raises(ConfigError, match="at least 2 classes"):
        NearestNeighbours(1).fit([[0.0], [1.0]], ["a", "a"])
    with pytest.raises(ConfigError, match="unknown classifier"):
        make_candidate("7-means")


def test_neighbours_win_where_no_line_separates(sklearn: None) -> None:
    x, y = xor_clusters()
    sel, model = select_classifier([None] * len(y), x, y, candidates=DESCRIPTOR)
    assert sel.score_of("1-nn").accuracy == 1.0
    assert sel.score_of("linear").accuracy < 0.8
    assert sel.chosen == "1-nn"  # 3-NN and 5-NN tie at 1.0: the simplest wins
    assert isinstance(model, NearestNeighbours) and model.k == 1
    assert "chose 1-nn" in sel.reason() and "linear" in sel.reason()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_linear_model_wins_on_an_oblique_boundary(sklearn: None, seed: int) -> None:
    x, y = oblique(seed=seed)
    sel, model = select_classifier([None] * len(y), x, y, candidates=DESCRIPTOR, seed=seed)
    assert sel.chosen == "linear", sel.reason()
    assert sel.score_of("linear").correct > sel.score_of("1-nn").correct
    assert isinstance(model, LinearDescriptor)
    test_x, test_y = oblique(n=400, seed=seed)  # the same hyperplane, more points
    assert model.score(test_x[120:], test_y[120:]) > 0.85


@pytest.mark.parametrize("seed", range(6))
def test_never_worse_than_one_neighbour_on_validation(sklearn: None, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(45, 6))
    y = rng.choice(["a", "b", "c"], size=45)  # no signal: any candidate may win
    sel, _ = select_classifier(
        [None] * 45, x, y, candidates=["linear", "boosting"], seed=seed, refit=False
    )
    names = [s.name for s in sel.scores]
    assert names == ["1-nn", "linear", "boosting"]  # 1-NN is always a candidate
    assert sel.score_of(sel.chosen).correct >= sel.score_of("1-nn").correct
    assert sel.protocol == "k-fold" and sel.folds == 5  # classes below 20 shapes
    assert sel.score_of("1-nn").total == 45  # every shape validated once


def test_identical_scores_go_to_the_simplest(sklearn: None) -> None:
    x = np.repeat(np.eye(3) * 10, 10, axis=0)  # three points, ten copies each
    y = np.repeat(["a", "b", "c"], 10)
    sel, _ = select_classifier([None] * 30, x, y, candidates=DESCRIPTOR[:4], refit=False)
    assert [s.accuracy for s in sel.scores] == [1.0] * 4
    assert sel.chosen == "1-nn"


def test_holdout_when_classes_are_large() -> None:
    x, y = xor_clusters(n=200)
    sel, _ = select_classifier([None] * 200, x, y, candidates=["3-nn"], refit=False)
    assert sel.protocol == "holdout" and sel.folds == 1
    assert 30 <= sel.score_of("1-nn").total <= 50  # 20 % of 200
    assert [s.name for s in sel.scores] == ["1-nn", "3-nn"]


def test_a_candidate_without_its_dependency_is_reported_not_chosen(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(sys.modules, "sklearn", None)
    with pytest.raises(MissingDependencyError, match=r"pip install 'shapedb\[learn\]'"):
        LinearDescriptor().fit([[0.0], [1.0]], ["a", "b"])
    x, y = oblique()
    sel, model = select_classifier([None] * len(y), x, y, candidates=["1-nn", "linear"])
    assert sel.score_of("linear").error is not None and sel.chosen == "1-nn"
    assert "linear n/a" in sel.reason() and isinstance(model, NearestNeighbours)


def test_selection_report_round_trips_through_a_dict() -> None:
    x, y = xor_clusters()
    sel, _ = select_classifier([None] * len(y), x, y, candidates=["5-nn"], refit=False)
    again = Selection.from_dict(sel.to_dict())
    assert again == sel and again.reason() == sel.reason()
    older = sel.to_dict()  # a report written before the time budget
    del older["budget"], older["seconds"]
    for s in older["scores"]:
        del s["status"]
    assert Selection.from_dict(older).score_of("5-nn").status == "scored"


def test_every_candidate_name_builds() -> None:
    kinds = {name: type(make_candidate(name)).__name__ for name in CANDIDATES}
    assert kinds["1-nn"] == "NearestNeighbours" and kinds["boosting"] == "BoostedDescriptor"
    assert {kinds[c] for c in ("tag", "arma", "spline", "tag+descriptor")} == {"GraphClassifier"}
    assert make_candidate("tag+descriptor").descriptor and not make_candidate("tag").rotate


def test_boosting_refits_identically_from_its_state(sklearn: None) -> None:
    x, y = oblique(n=60)
    model = BoostedDescriptor(max_iter=20).fit(x, y)
    again = BoostedDescriptor.from_state(*model.state())
    np.testing.assert_array_equal(again.predict_proba(x), model.predict_proba(x))


# --------------------------------------------------------------------------------------
# The time budget, on a fake clock: a fake slow graph CNN, the checkpoint, the progress log
# --------------------------------------------------------------------------------------


class FakeClock:
    """Seconds that pass only when a fake model says so."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class FakeCNN:
    """Stands in for a graph CNN: ``epochs`` epochs of ``per_epoch(fit)`` fake seconds each.

    It reads its "graphs" as the labels themselves, so it is always right.
    """

    def __init__(self, clock: FakeClock, fits: list[str], name: str, per_epoch, epochs=10):
        self.conv, self.clock, self.fits, self.name = name, clock, fits, name
        self.per_epoch, self.epochs = per_epoch, epochs

    def fit(self, graphs, labels, descriptors=None, callback=None):
        self.classes_ = sorted(set(labels))
        seconds = self.per_epoch(len(self.fits))
        self.fits.append(self.name)
        for epoch in range(1, self.epochs + 1):
            self.clock.t += seconds
            if callback is not None:
                callback(epoch, self.epochs, {})
        return self

    def predict_proba(self, graphs, descriptors=None):
        return np.asarray([[float(g == c) for c in self.classes_] for g in graphs])


@pytest.fixture()
def fake_cnns(monkeypatch: pytest.MonkeyPatch):
    """Graph CNNs replaced by FakeCNNs of 5 s per epoch (``plan`` may change that)."""
    import query.learn.selection as selection

    clock, fits = FakeClock(), []
    plan = {"per_epoch": lambda fit: 5.0}
    real = selection.make_candidate

    def make(name, *, seed=0, graph_options=None):
        if name in selection.GRAPH_CANDIDATES:
            return FakeCNN(clock, fits, name, lambda fit: plan["per_epoch"](fit))
        return real(name, seed=seed, graph_options=graph_options)

    monkeypatch.setattr(selection, "make_candidate", make)
    return clock, fits, plan


def noise(n: int = 80, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two classes and descriptors without signal: only the fake CNN (reading labels) is right."""
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 4)), np.repeat(["a", "b"], n // 2)


def _select(clock: FakeClock, budget: float, **kwargs):
    x, y = noise()
    options = {"candidates": ["1-nn", "3-nn", "tag", "arma"], "folds": 4, "clock": clock}
    return select_classifier(list(y), x, y, budget=budget, **{**options, **kwargs})


def test_parse_duration() -> None:
    from query.learn.budget import parse_duration

    assert [parse_duration(t) for t in ("90s", "5m", "1h", "1.5h", "45", " 2 min")] == [
        90.0, 300.0, 3600.0, 5400.0, 45.0, 120.0
    ]  # fmt: skip
    for bad in ("5x", "0", "-1m", "", "m"):
        with pytest.raises(ConfigError, match="budget"):
            parse_duration(bad)


def test_a_slow_graph_cnn_is_stopped_and_the_next_not_started(fake_cnns) -> None:
    clock, fits, _ = fake_cnns
    # 4 folds x 10 epochs x 5 s = 200 s per CNN: over a 100 s budget
    sel, model = _select(clock, 100.0)
    assert [s.status for s in sel.scores] == ["scored", "scored", "stopped", "skipped"]
    assert sel.score_of("tag").error and "budget" in sel.score_of("tag").error
    assert sel.chosen in ("1-nn", "3-nn") and not isinstance(model, FakeCNN)
    assert fits == ["tag"] and clock.t == 10.0  # stopped after its second epoch
    assert clock.t <= 1.1 * 100 and sel.budget == 100.0
    assert "tag n/a (stopped)" in sel.reason() and "arma n/a (skipped)" in sel.reason()


def test_a_graph_cnn_runs_when_the_budget_allows_it_and_its_final_fit(fake_cnns) -> None:
    clock, fits, _ = fake_cnns
    seen = []
    sel, model = _select(clock, 400.0, progress=seen.append)
    # tag: 200 s of folds + 67 s reserved for its final fit; arma would need as much again
    assert [s.status for s in sel.scores] == ["scored", "scored", "scored", "skipped"]
    assert sel.chosen == "tag" and isinstance(model, FakeCNN)
    assert sel.score_of("tag").accuracy == 1.0 and sel.score_of("tag").seconds == 200.0
    assert fits == ["tag"] * 5 and clock.t == 250.0 <= 1.1 * 400  # 4 folds and the final fit
    # progress: candidate, fold, epoch, score so far, time spent and left
    p = next(p for p in seen if (p.candidate, p.fold, p.epoch) == ("tag", 2, 3))
    assert (p.folds, p.epochs, p.score) == (4, 10, 1.0)
    assert (p.spent, p.left) == (65.0, 335.0) and p.index == 3 and p.candidates == 4
    assert [p.done for p in seen if p.done] == ["scored", "scored", "scored", "skipped"]
    assert seen[-1].fold == 0 and seen[-1].epoch == 10  # the final fit


def test_named_candidates_run_whatever_the_budget(fake_cnns) -> None:
    clock, fits, _ = fake_cnns
    sel, _ = _select(clock, 100.0, required=["tag", "arma"], refit=False)
    assert [s.status for s in sel.scores] == ["scored"] * 4 and clock.t == 400.0


def test_without_a_budget_every_candidate_runs(fake_cnns) -> None:
    clock, fits, _ = fake_cnns
    sel, _ = _select(clock, None, refit=False)
    assert [s.status for s in sel.scores] == ["scored"] * 4 and sel.budget is None


def test_a_second_run_continues_where_the_first_stopped(fake_cnns, tmp_path) -> None:
    from query.learn.checkpoint import Checkpoint

    clock, fits, plan = fake_cnns
    path = tmp_path / "model.selection.json"
    # tag's third fold is four times slower: the budget stops it after two folds
    plan["per_epoch"] = lambda fit: 5.0 if fit < 2 else 20.0
    sel, _ = _select(clock, 300.0, checkpoint=Checkpoint(path, {"v": 1}), refit=False)
    assert sel.score_of("tag").status == "stopped" and len(fits) == 3
    assert "after 2/4 folds" in str(sel.score_of("tag").error)
    plan["per_epoch"] = lambda fit: 5.0
    fits.clear()
    clock.t = 0.0
    again, _ = _select(clock, 300.0, checkpoint=Checkpoint(path, {"v": 1}), refit=False)
    assert [s.status for s in again.scores[:3]] == ["resumed", "resumed", "scored"]
    assert len(fits) == 2  # only tag's last two folds
    assert again.score_of("tag").total == 80 and again.score_of("tag").accuracy == 1.0
    assert again.score_of("1-nn") == sel.score_of("1-nn").__class__(
        **{**sel.score_of("1-nn").__dict__, "status": "resumed"}
    )
    clock.t = 0.0
    other, _ = _select(clock, 300.0, checkpoint=Checkpoint(path, {"v": 2}), refit=False)
    assert other.score_of("1-nn").status == "scored"  # other settings: afresh


def test_the_progress_log_speaks_at_least_every_interval(caplog) -> None:
    from query.learn.budget import Progress, ProgressLog

    clock = FakeClock()
    plog = ProgressLog(10.0, clock=clock)

    def at(t: float, done: str = "") -> None:
        clock.t = t
        plog(Progress("tag", 6, 9, 1, 5, int(t), 40, float("nan"), t, 300 - t, done))

    lines: list[float] = []
    with caplog.at_level("INFO", logger="query.learn.budget"):
        for t in (0, 3, 6, 9, 10, 12):
            at(t)
        at(13, done="scored")  # the end of a candidate is always logged
        at(22)
        at(23)
        for t in (30, 33):  # an epoch longer than the interval: the heartbeat speaks
            clock.t = t
            plog.tick()
        lines = [float(r.message.split("; ")[-1].split()[0]) for r in caplog.records]
    assert lines == [0, 10, 13, 23, 33]  # seconds spent, as logged
    assert "tag (6/9) fold 1/5 epoch 23/40: validation n/a; 33 s spent, 267 s left" in (
        caplog.records[-1].message
    )


def test_the_progress_log_cadence_on_a_stream() -> None:
    """Snapshots every 3 s and a heartbeat every second: never 10 s without a line."""
    from query.learn.budget import Progress, ProgressLog

    clock, said = FakeClock(), []

    class Logger:
        def info(self, fmt: str, line: str) -> None:
            said.append(clock.t)

    plog = ProgressLog(10.0, clock=clock, logger=Logger())  # type: ignore[arg-type]
    for step in range(120):
        clock.t = float(step)
        if step % 7 == 0:
            plog(Progress("arma", 7, 9, 1, 5, step, 40, 0.5, step, 100.0))
        plog.tick()
    assert said[0] == 0 and max(np.diff(said)) <= 10 and min(np.diff(said)) >= 10


def test_no_function_in_query_learn_is_over_80_lines() -> None:
    import ast
    from pathlib import Path

    import query.learn

    long = []
    for path in sorted(Path(query.learn.__file__).parent.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > 80:
                    long.append(f"{path.name}:{node.name} {n} lines")
    assert long == []


def test_learning_curves_report_accuracy_against_training_time() -> None:
    from bench.classify_curves import TIME_CURVE, size_rows, time_curve

    def result(name: str, correct: int, test: float, val_s: float, fit_s: float) -> dict:
        return {
            "candidate": name,
            "validation_correct": correct,
            "validation_accuracy": correct / 10,
            "test_mesh": test,
            "test_points": test - 0.1,
            "validation_seconds": val_s,
            "fit_seconds": fit_s,
            "train_seconds": val_s + fit_s,
            "seconds": val_s + fit_s + 1.0,
        }

    split = [result("1-nn", 6, 0.60, 1.0, 0.0), result("tag", 9, 0.90, 100.0, 20.0)]
    rows = size_rows([split])
    assert [r["candidate"] for r in rows] == ["1-nn", "tag", "chosen"]
    assert rows[2]["chosen"] == ["tag"] and rows[2]["train_seconds"] == 121.0
    curve = time_curve({10: rows})
    assert len(TIME_CURVE) == len(curve[0]) and "train s" in TIME_CURVE
    by_name = {r[0]: r for r in curve}
    assert by_name["tag"][1:4] == [10, 0.90, 120.0]
    assert by_name["tag"][4] == pytest.approx(0.30)
    assert by_name["tag"][5] == pytest.approx(0.30 / (119.0 / 60))  # gain per extra minute
    assert np.isnan(by_name["1-nn"][5]) and [r[0] for r in curve] == ["1-nn", "tag", "chosen"]


def test_between_candidates_the_heartbeat_does_not_repeat_a_finished_line(caplog) -> None:
    from query.learn.budget import Progress, ProgressLog

    clock = FakeClock()
    plog = ProgressLog(10.0, clock=clock)
    with caplog.at_level("INFO", logger="query.learn.budget"):
        plog(Progress("boosting", 5, 9, 5, 5, 0, 0, 0.667, 8.0, 82.0, "scored"))
        clock.t = 11.0  # e.g. importing torch before the first graph CNN
        assert plog.tick()
    said = [r.message for r in caplog.records]
    assert said[0] == "boosting (5/9) 5/5 folds: validation 0.667 [scored]; 8 s spent, 82 s left"
    assert said[1] == "working after boosting (5/9) 5/5 folds [scored]; 19 s spent, 71 s left"
