"""The gate bench's field vectors: the union candidates and the fused distance."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bench.support.field_vectors import FieldStage, union_order
from bench.support.stores import Store, gate_weights
from query.search.tuning import PRODUCT


def _split(n: int = 40, seed: int = 5) -> SimpleNamespace:
    rng = np.random.default_rng(seed)
    x, y, z = rng.random((n, 3)), rng.random((n, 3)), rng.random((n, 3))
    d4, dl, dv = (np.abs(a[:, None] - a[None]).sum(-1) for a in (x, y, z))
    return SimpleNamespace(labels=np.arange(n) % 4, sets=np.zeros(n), d4=d4, dl=dl, dv=dv)


def test_the_union_is_the_k_then_the_field_vectors_extras_in_stored_order() -> None:
    split = _split()
    order = np.argsort(split.d4, axis=1, kind="stable")
    listing, count = union_order(order, split.dv, 10, 8)
    for i in range(len(order)):
        near = set(np.argsort(split.dv[i], kind="stable")[:8].tolist())
        union = set(order[i, :10].tolist()) | near
        assert count[i] == len(union)
        assert listing[i, :10].tolist() == order[i, :10].tolist()  # the K first, as they were
        extras = listing[i, 10 : count[i]]
        assert set(extras.tolist()) == near - set(order[i, :10].tolist())
        assert np.all(np.diff(split.d4[i, listing[i, : count[i]]]) >= 0)  # stored order
        rest = listing[i, count[i] :]
        assert np.all(np.diff(split.d4[i, rest]) >= 0) and not set(rest.tolist()) & union


def test_no_extras_leave_the_store_as_it_was() -> None:
    split = _split()
    f = PRODUCT
    plain = Store(split, np.arange(40), candidates=10)  # type: ignore[arg-type]
    within = Store(split, np.arange(40), candidates=10, field_candidates=0)  # type: ignore[arg-type]
    w = np.full(40, 4.0)
    assert np.array_equal(plain.rankings(w), within.rankings(w))
    assert np.array_equal(gate_weights(plain, f), gate_weights(within, f))


def test_an_extra_near_by_the_light_field_enters_the_head() -> None:
    split = _split()
    q = 0
    order = np.argsort(split.d4[q], kind="stable")
    far = int(order[-1])  # last by the stored distance, first by the other two
    split.dl[q, far] = split.dl[far, q] = 1e-6
    split.dv[q, far] = split.dv[far, q] = 1e-6
    cut = Store(split, np.arange(40), candidates=10)  # type: ignore[arg-type]
    union = Store(split, np.arange(40), candidates=10, field_candidates=3)  # type: ignore[arg-type]
    alone = np.full(40, np.inf)  # ranked by the light field alone among the candidates
    assert cut.rankings(alone)[q, -1] == far
    got = union.rankings(alone)[q]
    assert got[0] == far or (got[0] == q and got[1] == far)
    assert sorted(got.tolist()) == list(range(40))  # still a permutation of the store
    assert np.all(np.diff(split.d4[q, got[union.count[q] :]]) >= 0)


def test_the_stage_of_a_config_without_the_fields_is_none() -> None:
    assert FieldStage.of(SimpleNamespace(weight=8.0)) is None
    fields = SimpleNamespace(field_depth_weight=0.5, field_harmonic_weight=0.5, scale=2.0,
                             field_candidates=100)  # fmt: skip
    assert FieldStage.of(fields) == FieldStage(0.5, 0.5, 2.0, 100)
    # the research's weights at its scales: alpha = a m_l / m_b, gamma = c m_l / m_h
    assert FieldStage.at_scales(0.5, 0.25, 2.0, 4.0, 8.0, 7) == FieldStage(0.25, 0.0625, 3.5, 7)
    off = SimpleNamespace(**{**vars(fields), "field_depth_weight": 0.0,
                             "field_harmonic_weight": 0.0, "field_candidates": 0})  # fmt: skip
    assert FieldStage.of(off) is None


def test_the_analytic_gates_on_the_light_field_distance_are_the_product_s(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from bench.studies.gate_checks import analytic_gates, analytic_shapes, analytic_stores
    from bench.support.field_vectors import analytic_distance

    stores = analytic_stores(tmp_path)
    f = PRODUCT
    for name, db in stores.items():
        want = analytic_gates(db, f, {})  # the product's local spreads and gate
        got = analytic_gates(db, f, {}, lambda q, ids, dl: dl)  # the bench's, same distance
        assert np.array_equal(want[0], got[0]) and np.allclose(want[1], got[1]), name
    stage = FieldStage.at_scales(0.25, 0.25, 20.0, 6.0, 2.0, 200)
    fused = analytic_distance(stores["chain"], analytic_shapes()["chain"], stage)
    ids = np.sort(np.asarray(stores["chain"].store.shapes(["id"]).column("id").to_pylist()))
    a, b = int(ids[0]), int(ids[2])  # other poses (0 and 1 are mirror images)
    assert fused(a, np.array([a]), np.array([0.0]))[0] == 0.0
    assert (
        fused(a, np.array([b]), np.array([3.0]))[0] == fused(b, np.array([a]), np.array([3.0]))[0]
    )
    assert fused(a, np.array([b]), np.array([3.0]))[0] > 3.0  # the field vectors count


def test_a_run_s_stage_is_the_product_s_unless_flags_say_otherwise() -> None:
    from bench.studies.lightfield_gate import parser
    from bench.support.field_vectors import CHOSEN, SCALES, WEIGHTS, stage_of

    product = FieldStage.of(PRODUCT)
    assert stage_of(parser().parse_args([])) == product
    assert stage_of(parser().parse_args(["--no-field-vectors"])) is None
    got = stage_of(parser().parse_args(["--fv-candidates", "200", "--fv-weights", "0.25", "0.3"]))
    want = FieldStage.at_scales(0.25, 0.3, *SCALES, 200)
    assert got == want
    # the research's choice is the product's stage up to rounding
    assert product is not None and CHOSEN == FieldStage.at_scales(*WEIGHTS, *SCALES, 200)
    for name in ("depth_weight", "harmonic_weight", "scale"):
        assert np.isclose(getattr(CHOSEN, name), getattr(product, name), rtol=1e-15, atol=0)
