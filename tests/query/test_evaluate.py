"""PSB measures on hand-made rankings with known answers, and db.evaluate."""

from __future__ import annotations

import numpy as np
import pytest

from query.evaluate import RetrievalScores, evaluate, retrieval_scores
from shapedb.errors import QueryError
from shapedb.signature.kernel import kernel

# Six shapes, ids 0..5, labels A A A B B C. Row i ranks the others by distance;
# the diagonal (0, the best value) must be ignored, and C (one shape) is no query.
LABELS = ["A", "A", "A", "B", "B", "C"]
RANKINGS = {  # query -> results best first (query excluded)
    0: [3, 1, 5, 2, 4],
    1: [0, 2, 3, 4, 5],
    2: [0, 4, 3, 1, 5],  # 0 and 4 tie at distance 1: the smaller id comes first
    3: [5, 0, 4, 1, 2],
    4: [3, 0, 1, 2, 5],
    5: [0, 1, 2, 3, 4],
}


def hand_matrix() -> np.ndarray:
    d = np.zeros((6, 6))
    for q, ranking in RANKINGS.items():
        for rank, j in enumerate(ranking, start=1):
            d[q, j] = rank
    d[2, 4] = 1.0  # the tie with d[2, 0] = 1
    return d


# Worked by hand (n = 6, so every ranking has 5 results and the E-measure uses
# K = min(32, 5) = 5; DCG_1 = G_1, DCG_i = DCG_(i-1) + G_i / log2 i):
#   q0 (A, C-1=2): G = 0 1 0 1 0 -> NN 0, 1-T hits(2)/2 = 1/2, 2-T hits(4)/2 = 1,
#       E: P = 2/5, R = 2/2 -> 2/(5/2 + 1) = 4/7, DCG = (1/log2 2 + 1/log2 4) / (1 + 1) = 3/4
#   q1 (A): G = 1 1 0 0 0 -> NN 1, 1-T 1, 2-T 1, E 4/7, DCG (1 + 1)/2 = 1
#   q2 (A): G = 1 0 0 1 0 -> NN 1, 1-T 1/2, 2-T 1, E 4/7, DCG (1 + 1/2)/2 = 3/4
#   q3 (B, C-1=1): G = 0 0 1 0 0 -> NN 0, 1-T 0, 2-T hits(2) = 0,
#       E: P = 1/5, R = 1 -> 2/(5 + 1) = 1/3, DCG = (1/log2 3)/1
#   q4 (B): G = 1 0 0 0 0 -> NN 1, 1-T 1, 2-T 1, E 1/3, DCG 1
#   q5 (C, a class of one): skipped.
# Means over the 5 queries: NN 3/5, 1-T 3/5, 2-T 4/5, E (3 * 4/7 + 2/3)/5 = 10/21,
# DCG (3/4 + 1 + 3/4 + 1/log2 3 + 1)/5.
# Precision-recall (interpolated): q0 relevant at ranks 2, 4 -> 1/2 at every level;
# q1 -> 1; q2 ranks 1, 4 -> 1 up to recall 1/2, then 1/2; q3 rank 3 -> 1/3; q4 -> 1.
# At recall 0: (1/2 + 1 + 1 + 1/3 + 1)/5 = 23/30; at recall 1: (1/2 + 1 + 1/2 + 1/3 + 1)/5 = 2/3.
EXPECTED = {
    "queries": 5,
    "nn": 3 / 5,
    "first_tier": 3 / 5,
    "second_tier": 4 / 5,
    "e_measure": 10 / 21,
    "dcg": (3.5 + 1 / np.log2(3)) / 5,
}


def test_hand_computed_case():
    s = retrieval_scores(hand_matrix(), LABELS, distance=True)
    out = s.to_dict()
    for key, value in EXPECTED.items():
        assert out[key] == pytest.approx(value, abs=1e-12), key
    assert set(out["per_class"]) == {"A", "B"}  # C has one shape: no query
    a, b = out["per_class"]["A"], out["per_class"]["B"]
    assert a == pytest.approx(
        {
            "queries": 3,
            "nn": 2 / 3,
            "first_tier": 2 / 3,
            "second_tier": 1.0,
            "e_measure": 4 / 7,
            "dcg": 2.5 / 3,
        }
    )
    assert b == pytest.approx(
        {
            "queries": 2,
            "nn": 0.5,
            "first_tier": 0.5,
            "second_tier": 0.5,
            "e_measure": 1 / 3,
            "dcg": (1 / np.log2(3) + 1) / 2,
        }
    )
    assert s.precision[0] == pytest.approx(23 / 30) and s.precision[-1] == pytest.approx(2 / 3)
    assert s.precision[5] == pytest.approx(23 / 30) and s.precision[6] == pytest.approx(2 / 3)


def test_similarity_and_distance_agree():
    d = hand_matrix()
    assert (
        retrieval_scores(-d, LABELS).to_dict()
        == retrieval_scores(d, LABELS, distance=True).to_dict()
    )


def test_ties_follow_ids():
    # with id 4 given a smaller id than 0, q2's tie puts shape 4 (label B) first
    ids = [10, 11, 12, 13, 4, 15]
    s = retrieval_scores(hand_matrix(), LABELS, ids=ids, distance=True)
    q2 = list(s.per_query["index"]).index(2)
    assert s.per_query["nn"][q2] == 0.0
    assert s.nn == pytest.approx(2 / 5)


def test_perfect_ranking_scores_one():
    labels = np.repeat(["a", "b", "c"], [4, 3, 5])
    same = (labels[:, None] == labels[None, :]).astype(float)
    s = retrieval_scores(same + 0.01 * np.eye(len(labels)), labels)
    for key in ("nn", "first_tier", "second_tier", "dcg"):
        assert getattr(s, key) == 1.0
    assert np.all(s.precision == 1.0)
    # E-measure at K = 11 with C-1 relevant: 2(C-1)/(11 + C - 1) per query
    assert s.e_measure == pytest.approx(
        np.mean([2 * (c - 1) / (11 + c - 1) for c in [4] * 4 + [3] * 3 + [5] * 5])
    )


def test_query_is_never_counted():
    # each shape is most similar to itself; without exclusion NN would be perfect
    labels = ["a", "a", "b", "b"]
    s = np.array([[9, 0, 1, 0], [0, 9, 0, 1], [1, 0, 9, 0], [0, 1, 0, 9]], float)
    assert retrieval_scores(s, labels).nn == 0.0
    assert retrieval_scores(s, labels).first_tier == 0.0


def test_unlabelled_and_bad_input():
    s = retrieval_scores(np.zeros((3, 3)), [None, "a", "a"])
    assert s.queries == 2
    with pytest.raises(QueryError):
        retrieval_scores(np.zeros((3, 2)), ["a", "a", "b"])


def test_evaluate_store(tmp_db, tmp_path):
    png = tmp_path / "pr.png"
    s = evaluate(tmp_db, plot=png)
    assert isinstance(s, RetrievalScores) and s.queries == len(tmp_db.store)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ids, x = tmp_db.store.features()
    labels = tmp_db.store.shapes(["label"]).column("label").to_pylist()
    sim = np.stack(
        [kernel(row, x.astype(np.float64), tmp_db.config.kernel) for row in x.astype(np.float64)]
    )
    ref = retrieval_scores(sim, labels, ids=ids).to_dict()
    got = s.to_dict()
    for key in ("nn", "first_tier", "second_tier", "e_measure", "dcg"):
        assert got[key] == pytest.approx(ref[key], abs=1e-12)
    assert set(got["per_class"]) == {"box", "capsule", "cylinder", "torus"}
    assert evaluate(tmp_db, label="family").to_dict() == got  # a metadata key
    with pytest.raises(QueryError, match="nolabel"):
        evaluate(tmp_db, label="nolabel")
    custom = evaluate(tmp_db, method=lambda f: -np.abs(f[:, None, 0] - f[None, :, 0]))
    assert custom.queries == s.queries
