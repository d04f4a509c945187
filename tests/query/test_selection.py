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
