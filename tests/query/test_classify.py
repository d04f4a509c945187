"""Shape classification: graph CNNs (query.learn.graphcnn, query.learn.gnn), the chosen classifier
and its file (query.learn.classify, query.learn.model_file).

The tests that train a graph CNN need the ``learn`` extra (torch + torch_geometric)
and are skipped cleanly without it; those of the linear model and boosting need
scikit-learn (also the ``learn`` extra); the others run everywhere.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest

from query.learn.classify import (
    GraphClassifier,
    ShapeClassifier,
    classify,
    fingerprint_of,
    train_classifier,
)
from query.learn.gnn import edge_arrays, node_features, stratified_split
from query.learn.selection import make_candidate
from shapedb.config.core import Config, MDBDConfig
from shapedb.errors import ConfigError, LoadError, MissingDependencyError, NotFittedError
from shapedb.mdbd.decomposition import Decomposition
from shapedb.signature.kernel import features


@pytest.fixture(scope="module")
def pyg() -> None:
    from query.learn.gnn import import_torch

    try:
        torch, _ = import_torch()
    except MissingDependencyError:
        pytest.skip("needs the learn extra: pip install 'shapedb[learn]'")
    torch.set_num_threads(1)  # tiny graphs: threads only add contention


@dataclass(frozen=True)
class Graph:
    centers: np.ndarray
    radii: np.ndarray
    edges: np.ndarray


def _graph(kind: int, rng: np.random.Generator, n: int = 24) -> tuple[np.ndarray, ...]:
    """Balls along a line (0), in a flat disc (1) or in a blob (2), with contacts."""
    scale = (np.array([4.0, 0.5, 0.5]), np.array([2.0, 2.0, 0.2]), np.array([1.0, 1.0, 1.0]))
    c = rng.normal(size=(n, 3)) * scale[kind]
    r = np.sort(rng.uniform(0.1, 0.6, n))[::-1]
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    i, j = np.nonzero(np.triu(d < 1.0, 1))
    return c, r, np.stack([i, j], 1).astype(np.int32)


def _decomposition(kind: int, rng: np.random.Generator, config: MDBDConfig) -> Decomposition:
    c, r, e = _graph(kind, rng)
    return Decomposition(
        centers=c,
        radii=r,
        edges=e,
        spacing=0.05,
        bounds=np.array([c.min(0), c.max(0)]),
        config=config,
        representation="implicit",
    )


@pytest.fixture(scope="module")
def tiny() -> tuple[list[Decomposition], list[str]]:
    rng = np.random.default_rng(0)
    labels = ["line", "disc", "blob"] * 8
    kinds = {"line": 0, "disc": 1, "blob": 2}
    graphs = [_decomposition(kinds[y], rng, MDBDConfig()) for y in labels]
    return graphs, labels


@pytest.fixture(scope="module")
def fitted(pyg: None, tiny: tuple[list[Decomposition], list[str]]) -> GraphClassifier:
    graphs, labels = tiny
    return GraphClassifier("tag", epochs=6, rotate=True, batch_size=8, hidden=16).fit(
        graphs, labels
    )


def test_import_stays_light() -> None:
    code = "import query.learn.classify, query.learn.gnn, sys; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize("module", ["torch", "torch_geometric"])
def test_missing_extra_gives_the_install_hint(
    monkeypatch: pytest.MonkeyPatch, module: str, tmp_path
) -> None:
    monkeypatch.setitem(sys.modules, module, None)  # import fails as if absent
    hint = rf"needs the optional dependency '{module}'.*pip install 'shapedb\[learn\]'"
    with pytest.raises(MissingDependencyError, match=hint):
        GraphClassifier("tag").fit([], [])
    with pytest.raises(MissingDependencyError, match=hint):
        GraphClassifier.load(tmp_path / "model.pt")


def test_node_features_are_normalised() -> None:
    rng = np.random.default_rng(1)
    c, r, e = _graph(2, rng)
    x = node_features(c * 7.0 + 100.0, r * 7.0)
    assert x.shape == (len(r), 4) and x.dtype == np.float32
    np.testing.assert_allclose(x, node_features(c, r), atol=1e-5)  # position and scale free
    assert x[0, 3] == 1.0 and np.linalg.norm(x[:, :3], axis=1).max() <= 1.0
    index, attr = edge_arrays(e, len(r))
    deg = np.bincount(e.ravel(), minlength=len(r))
    assert index.shape == (2, 2 * len(e))
    np.testing.assert_allclose(attr, 1.0 / deg[index[0]], rtol=1e-6)


def test_stratified_split_keeps_every_class_in_every_part() -> None:
    labels = ["a"] * 10 + ["b"] * 5 + ["c"] * 3
    parts = stratified_split(labels, (0.6, 0.2, 0.2), seed=3)
    assert sorted(np.concatenate(parts).tolist()) == list(range(len(labels)))
    for p in parts:
        assert {labels[i] for i in p} == {"a", "b", "c"}


def test_unfitted_use_raises() -> None:
    model = GraphClassifier("tag")
    with pytest.raises(NotFittedError, match="not fitted"):
        model.predict([])
    with pytest.raises(NotFittedError):
        model.save("never.pt")


@pytest.mark.parametrize("conv", ["tag", "arma", "spline"])
def test_few_steps_reduce_the_loss(pyg: None, tiny: tuple[list, list], conv: str) -> None:
    graphs, labels = tiny
    model = GraphClassifier(
        conv,
        epochs=12,
        lr=3e-3,
        rotate=False,
        batch_size=8,
        hidden=32,
        dropout=0.0,
        warmup=1,
        validation=0,
    ).fit(graphs, labels)
    loss = model.history_["loss"]
    assert np.mean(loss[-3:]) < 0.8 * np.mean(loss[:3]), loss
    proba = model.predict_proba(graphs[:5])
    assert proba.shape == (5, 3)
    np.testing.assert_allclose(proba.sum(1), 1.0, rtol=1e-6)


def test_model_selection_uses_the_validation_split_only(pyg: None, tiny: tuple[list, list]) -> None:
    graphs, labels = tiny
    val = ([graphs[k] for k in range(0, 24, 4)], [labels[k] for k in range(0, 24, 4)])
    model = GraphClassifier("tag", epochs=5, batch_size=8, hidden=16).fit(
        graphs[1:], labels[1:], validation_data=val
    )
    h = model.history_
    assert len(h["val_accuracy"]) == 5 and not np.isnan(h["val_accuracy"]).any()
    kept = (h["val_accuracy"][model.best_epoch_], -h["val_loss"][model.best_epoch_])
    assert kept == max(zip(h["val_accuracy"], [-v for v in h["val_loss"]], strict=True))
    assert model.score(*val) == pytest.approx(h["val_accuracy"][model.best_epoch_], abs=1e-9)


def test_accepts_contact_graphs_and_keeps_label_names(pyg: None, fitted: GraphClassifier) -> None:
    rng = np.random.default_rng(5)
    g = Graph(*_graph(0, rng))
    assert fitted.classes_ == ["blob", "disc", "line"]
    assert fitted.predict([g])[0] in fitted.classes_
    assert fitted.embed([g]).shape == (1, 32)


def test_saved_model_reloads_with_identical_predictions(
    pyg: None, fitted: GraphClassifier, tiny: tuple[list, list], tmp_path
) -> None:
    graphs, _ = tiny
    path = fitted.save(tmp_path / "model.pt")
    again = GraphClassifier.load(path)
    assert again.classes_ == fitted.classes_ and again.fingerprint_ == fitted.fingerprint_
    np.testing.assert_array_equal(again.predict_proba(graphs), fitted.predict_proba(graphs))
    assert again.predict(graphs) == fitted.predict(graphs)


def test_graph_of_another_config_is_refused(pyg: None, fitted: GraphClassifier) -> None:
    other = _decomposition(0, np.random.default_rng(2), MDBDConfig(resolution=64))
    with pytest.raises(ConfigError, match="configuration"):
        fitted.predict([other])


def test_mixed_configs_are_refused_in_training(pyg: None, tiny: tuple[list, list]) -> None:
    graphs, labels = tiny
    other = _decomposition(0, np.random.default_rng(2), MDBDConfig(resolution=64))
    with pytest.raises(ConfigError, match="several configurations"):
        GraphClassifier("tag", epochs=1).fit([*graphs, other], [*labels, "line"])


def _store_db(tmp_path, graphs: list[Decomposition], labels: list[str], config: Config):
    import query.database as database
    from shapedb.store.schema import ShapeRecord

    db = database.connect(tmp_path / "db", config=config)
    records = [
        ShapeRecord(
            name=f"s{k}",
            decomposition=g,
            feature=features(g, config).astype(np.float32),
            config=config,
            content_hash=f"h{k}",
            representation="implicit",
            label=y,
        )
        for k, (g, y) in enumerate(zip(graphs, labels, strict=True))
    ]
    db.store.commit(records)
    return db


def test_train_classifier_on_a_store_and_refuse_another_store(
    pyg: None, tiny: tuple[list, list], tmp_path
) -> None:
    graphs, labels = tiny
    db = _store_db(tmp_path, graphs, labels, Config())
    out = tmp_path / "m.pt"
    model = train_classifier(db, conv="tag", out=out, epochs=3, hidden=16, batch_size=8)
    assert out.is_file() and out.with_suffix(".png").is_file() == (model.kind == "tag")
    assert [s.name for s in model.selection_.scores] == ["1-nn", "tag"]
    assert model.kind == model.selection_.chosen
    assert model.fingerprint_ == db.config.fingerprint
    assert 0.0 <= model.test_accuracy_ <= 1.0 and sum(model.split_.values()) == len(graphs)
    result = classify(db, out, graphs[0])
    assert result.label in model.classes_ and abs(sum(result.probabilities.values()) - 1) < 1e-6
    other = Config().with_options(resolution=64)
    db2 = _store_db(tmp_path / "b", [], [], other)
    with pytest.raises(ConfigError, match="train a model on this database"):
        classify(db2, out, graphs[0])


@pytest.fixture(scope="module")
def descriptors(tiny: tuple[list, list]) -> np.ndarray:
    return np.stack([features(g, Config()) for g in tiny[0]])


def _skip_without(kind: str) -> None:
    if kind in ("linear", "boosting"):
        pytest.importorskip("sklearn", reason="needs the learn extra")
    if kind in ("tag", "arma", "spline", "tag+descriptor"):
        from query.learn.gnn import import_torch

        try:
            import_torch()[0].set_num_threads(1)
        except MissingDependencyError:
            pytest.skip("needs the learn extra: pip install 'shapedb[learn]'")


@pytest.mark.parametrize("kind", ["1-nn", "5-nn", "linear", "boosting", "tag", "tag+descriptor"])
def test_every_kind_saves_and_reloads_with_identical_predictions(
    kind: str, tiny: tuple[list, list], descriptors: np.ndarray, tmp_path
) -> None:
    _skip_without(kind)
    graphs, labels = tiny
    options = {"epochs": 2, "hidden": 16, "batch_size": 8}
    estimator = make_candidate(kind, graph_options=options)
    if kind in ("tag", "tag+descriptor"):
        estimator.fit(graphs, labels, descriptors=descriptors)
    else:
        estimator.fit(descriptors, labels)
    model = ShapeClassifier(kind, estimator, fingerprint=Config().fingerprint)
    model.test_accuracy_ = 0.5
    path = model.save(tmp_path / "model.bin")
    again = ShapeClassifier.load(path)
    assert again.kind == kind and again.classes_ == ["blob", "disc", "line"]
    assert again.fingerprint_ == model.fingerprint_ and again.test_accuracy_ == 0.5
    np.testing.assert_array_equal(
        again.predict_proba(graphs, descriptors), model.predict_proba(graphs, descriptors)
    )
    assert again.needs_graphs == (kind in ("tag", "tag+descriptor"))


def test_a_model_file_of_the_first_format_still_loads(
    pyg: None, fitted: GraphClassifier, tiny: tuple[list, list], tmp_path
) -> None:
    import torch

    params = {k: v for k, v in fitted.get_params().items() if k != "descriptor"}
    state = {
        "format": "shapedb.mdbd.graph-classifier/1",
        "params": {**params, "device": None},
        "classes": fitted.classes_,
        "fingerprint": fitted.fingerprint_,
        "config": None,
        "history": fitted.history_,
        "best_epoch": fitted.best_epoch_,
        "state_dict": {k: v.detach().cpu() for k, v in fitted.model_.state_dict().items()},
    }
    torch.save(state, tmp_path / "old.pt")
    graphs, _ = tiny
    again = ShapeClassifier.load(tmp_path / "old.pt")
    assert again.kind == "tag" and again.needs_graphs
    expected = fitted.predict_proba(graphs)
    np.testing.assert_array_equal(again.predict_proba(graphs, np.zeros((24, 0))), expected)
    np.testing.assert_array_equal(
        GraphClassifier.load(tmp_path / "old.pt").predict_proba(graphs), expected
    )
    (tmp_path / "junk.pt").write_bytes(b"not a model")
    with pytest.raises(LoadError):
        ShapeClassifier.load(tmp_path / "junk.pt")
    with pytest.raises(LoadError, match="no such"):
        ShapeClassifier.load(tmp_path / "missing.pt")


def test_the_network_can_read_the_descriptor(
    pyg: None, tiny: tuple[list, list], descriptors: np.ndarray
) -> None:
    graphs, labels = tiny
    model = GraphClassifier("tag", descriptor=True, epochs=2, hidden=16, batch_size=8)
    model.fit(graphs, labels, descriptors=descriptors)
    assert model.descriptor_mean_.shape == (descriptors.shape[1],)
    assert model.predict_proba(graphs, descriptors=descriptors).shape == (24, 3)
    with pytest.raises(ConfigError, match="descriptors"):
        model.predict(graphs)
    plain = GraphClassifier("tag", epochs=1, hidden=16, batch_size=8).fit(graphs, labels)
    assert model.n_parameters_ == plain.n_parameters_ + 16 * descriptors.shape[1]


def test_classify_many_shapes_with_one_load(tiny: tuple[list, list], tmp_path) -> None:
    graphs, labels = tiny
    db = _store_db(tmp_path, graphs, labels, Config())
    model = train_classifier(db, methods=["1-nn"], test=0, out=tmp_path / "nn.bin")
    assert model.kind == "1-nn" and model.split_ == {"train": 24, "test": 0}
    assert not (tmp_path / "nn.png").exists()  # no training curve for neighbours
    many = classify(db, tmp_path / "nn.bin", [1, "s1", graphs[2]])
    assert isinstance(many, list) and [r.source for r in many] == ["1", "s1", None]
    # a stored shape is its own nearest neighbour
    assert [r.label for r in many] == [labels[0], labels[1], labels[2]]
    assert all(r.probability == 1.0 for r in many)
    one = classify(db, model, 3)
    assert not isinstance(one, list) and one.label == labels[2]
    other = _decomposition(0, np.random.default_rng(2), MDBDConfig(resolution=64))
    with pytest.raises(ConfigError, match="configuration"):
        classify(db, model, [other])


def test_training_continues_from_its_checkpoint_until_the_store_changes(
    tiny: tuple[list, list], tmp_path
) -> None:
    graphs, labels = tiny
    db = _store_db(tmp_path, graphs, labels, Config())
    out = tmp_path / "nn.bin"
    first = train_classifier(db, methods=["1-nn", "3-nn"], test=0, out=out, budget=60.0)
    assert (tmp_path / "nn.bin.selection.json").is_file()
    assert [s.status for s in first.selection_.scores] == ["scored", "scored"]
    assert first.selection_.budget == 60.0
    again = train_classifier(db, methods=["1-nn", "3-nn"], test=0, out=out)
    assert [s.status for s in again.selection_.scores] == ["resumed", "resumed"]
    assert [s.correct for s in again.selection_.scores] == [
        s.correct for s in first.selection_.scores
    ]
    fresh = train_classifier(db, methods=["1-nn", "3-nn"], test=0, out=out, resume=False)
    assert [s.status for s in fresh.selection_.scores] == ["scored", "scored"]
    from shapedb.store.schema import ShapeRecord

    g = graphs[0]
    db.store.commit(
        [
            ShapeRecord(
                name="extra",
                decomposition=g,
                feature=features(g, Config()).astype(np.float32),
                config=Config(),
                content_hash="extra",
                representation="implicit",
                label=labels[0],
            )
        ]
    )
    changed = train_classifier(db, methods=["1-nn", "3-nn"], test=0, out=out)
    assert [s.status for s in changed.selection_.scores] == ["scored", "scored"]


def test_the_train_command_takes_a_budget_and_reports_seconds(
    tiny: tuple[list, list], tmp_path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    from query.cli import main

    graphs, labels = tiny
    _store_db(tmp_path, graphs, labels, Config())
    out = tmp_path / "m.bin"
    argv = ["train", "--db", str(tmp_path / "db"), "--methods", "1-nn", "5-nn"]
    assert main([*argv, "--budget", "90s", "--test", "0", "--out", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)["selection"]
    assert report["budget"] == 90.0 and report["seconds"] >= 0
    assert [(s["name"], s["status"]) for s in report["scores"]] == [
        ("1-nn", "scored"),
        ("5-nn", "scored"),
    ]
    assert all(s["seconds"] >= 0 for s in report["scores"])
    with pytest.raises(SystemExit):
        main([*argv, "--budget", "5 parsecs", "--out", str(out)])
    assert "budget '5 parsecs' is invalid" in capsys.readouterr().err


def test_graph_tensors_are_built_once_for_every_fold(
    pyg: None, tiny: tuple[list, list], descriptors: np.ndarray, monkeypatch: pytest.MonkeyPatch
) -> None:
    import dataclasses

    import query.learn.gnn as gnn
    import query.learn.selection as selection
    from query.learn.selection import select_classifier

    graphs, labels = tiny
    calls = []
    real, choose = gnn.to_data, selection._selection
    monkeypatch.setattr(gnn, "to_data", lambda g, *a, **k: calls.append(1) or real(g, *a, **k))
    # whatever validates best, the final fit is of a graph CNN here
    monkeypatch.setattr(
        selection, "_selection", lambda *a: dataclasses.replace(choose(*a), chosen="tag")
    )
    options = {"epochs": 1, "hidden": 8, "batch_size": 8, "config": Config()}
    sel, model = select_classifier(
        graphs, descriptors, labels, candidates=["tag", "tag+descriptor"], folds=3,
        graph_options=options, required=["tag"],
    )  # fmt: skip
    assert [s.status for s in sel.scores] == ["scored"] * 3
    assert len(calls) == len(graphs)  # not once per fold, fit, prediction and final fit
    assert model.fingerprint_ == fingerprint_of(graphs[0])
