"""Partial-to-whole search: the shapes that contain a half, a scan or a part of them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
from query_helpers import solids

from shapedb.errors import QueryError
from shapedb.geometry.implicit import Box, Intersection, Sphere
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud

SHAPES = solids()


@pytest.fixture()
def db(solids_db: Any) -> Any:
    return solids_db


def _half(geometry: Any) -> Intersection:
    """The solid cut by the plane x = (its middle), the side x > middle kept."""
    lo, hi = geometry.bounds[0] - 0.1, geometry.bounds[1] + 0.1
    lo[0] = 0.5 * (geometry.bounds[0][0] + geometry.bounds[1][0])
    return Intersection(geometry, Box((lo + hi) / 2, hi - lo))


def _sphere_scan(n: int = 1500) -> PointCloud:
    """What a camera on the +x axis sees of the unit sphere."""
    p = np.random.default_rng(0).normal(size=(2 * n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return PointCloud(p[p[:, 0] > 0])


def test_half_a_shape_finds_its_whole_by_parts(db: Any) -> None:
    hits = db.search(_half(SHAPES["dumbbell"]), k=3, partial=True)
    assert hits[0].name == "dumbbell"
    assert all(h.path == "partial" for h in hits)
    assert all(0.0 < h.similarity <= 1.0 for h in hits)
    assert [h.similarity for h in hits] == sorted((h.similarity for h in hits), reverse=True)


def test_a_one_sided_scan_takes_the_partial_path_on_request(db: Any) -> None:
    hits = db.search(_sphere_scan(), k=3, partial=True)
    assert [h.path for h in hits] == ["partial"] * 3
    assert hits[0].name == "sphere"
    assert [h.path for h in db.search(_sphere_scan(), k=3, partial=False)] == ["whole"] * 3


def test_a_stored_shape_matches_itself_fully(db: Any) -> None:
    (hit, *_) = db.search("capsule", k=2, partial=True)
    assert hit.name == "capsule" and hit.similarity == pytest.approx(1.0)
    assert hit.distance == pytest.approx(0.0, abs=1e-9)
    assert np.copysign(1.0, hit.distance) == 1.0  # 0.0, not -0.0


def test_the_whole_path_is_todays_search(db: Any) -> None:
    from query.search.engine import search

    mesh = trimesh.creation.box(extents=(2.4, 1.2, 0.8))
    query = TriangleMesh(mesh.vertices, mesh.faces)
    auto = db.search(query, k=4)
    assert [h.path for h in auto] == ["whole"] * 4
    assert auto == db.search(query, k=4, partial=False) == search(db, query, k=4)
    assert db.search_batch([query, _sphere_scan()], k=2)[0] == auto[:2]


def test_where_restricts_the_partial_path(db: Any) -> None:
    hits = db.search(_half(SHAPES["dumbbell"]), k=5, partial=True, where="name <> 'dumbbell'")
    assert hits and "dumbbell" not in {h.name for h in hits}


@pytest.mark.parametrize(
    ("query", "options", "message"),
    [
        ("box", {"partial": "yes"}, "partial must be"),
        (np.zeros(8), {"partial": True}, "no parts"),
        ("box", {"partial": True, "metric": "metric.json"}, "learned metric"),
    ],
)
def test_bad_partial_searches_are_one_line_errors(
    db: Any, query: Any, options: dict[str, Any], message: str
) -> None:
    with pytest.raises(QueryError, match=message) as err:
        db.search(query, **options)
    assert "\n" not in str(err.value)


def test_cli_flags_choose_the_path(
    db: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from query.cli import main

    store = str(db.path)
    assert main(["search", "snowman", "--db", store, "-k", "2", "--partial", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["name"] == "snowman" and {r["path"] for r in rows} == {"partial"}
    assert main(["search", "snowman", "--db", store, "-k", "2", "--whole"]) == 0
    text = capsys.readouterr().out
    assert "path" in text.splitlines()[0] and "whole" in text
    with pytest.raises(SystemExit):
        main(["search", "snowman", "--db", store, "--partial", "--whole"])


def test_a_scan_file_is_searched_by_parts(
    db: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from query.cli import main

    scan = tmp_path / "scan.ply"
    trimesh.PointCloud(_sphere_scan().points).export(scan)
    assert main(["search", str(scan), "--db", str(db.path), "-k", "2", "--partial", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["name"] == "sphere" and rows[0]["path"] == "partial"


def test_a_mesh_cut_in_half_is_searched_as_half_a_solid(tmp_path: Path) -> None:
    """Cut open, a block's mesh bounds a shell one cell thick: its parts are a hollow
    block's. Closed over the cut (``TriangleMesh.capped``) it is half the block."""
    import shapedb
    from shapedb.geometry.implicit import Difference

    store = shapedb.connect(tmp_path / "store", resolution=32, n_balls=32)
    outer = Box([0, 0, 0], [2.4, 1.6, 1.2])
    shapes = {
        "block": outer,
        "hollow block": Difference(outer, Box([0, 0, 0], [2.1, 1.3, 0.9])),
        "ball": Sphere([0, 0, 0], 0.8),
    }
    store.ingest([(n, n, g) for n, g in shapes.items()], workers=1, progress=False)
    mesh = trimesh.creation.box(extents=(2.4, 1.6, 1.2)).subdivide().subdivide().subdivide()
    kept = mesh.faces[mesh.triangles_center[:, 0] > 0.0]
    used, faces = np.unique(kept.ravel(), return_inverse=True)
    half = TriangleMesh(mesh.vertices[used], faces.reshape(-1, 3))
    assert not half.closed
    assert store.search(half, k=1, partial=True)[0].name == "block"


def test_fused_similarity_is_the_reciprocal_ranks_over_their_largest() -> None:
    from query.parts.partial import fused_similarity

    parts = np.array([0.9, 0.5, 0.1])  # ranks 0, 1, 2
    words = np.array([0.3, 0.1, 0.2])  # ranks 2, 0, 1
    got = fused_similarity(parts, words, offset=4.0, weight=0.5)
    want = np.array([1 / 6 + 0.5 / 4, 1 / 4 + 0.5 / 5, 1 / 5 + 0.5 / 6]) * 4 / 1.5
    np.testing.assert_allclose(got, want)
    assert fused_similarity(np.array([1.0]), np.array([0.0]))[0] == pytest.approx(1.0)


def test_in_a_words_store_the_hits_are_ordered_by_words_and_parts(db: Any) -> None:
    from query.parts.partial import fused_similarity, partial_candidates

    half = _half(SHAPES["dumbbell"])
    found = partial_candidates(db, half, k=6)
    assert found.words is not None and len(found.ids) == len(SHAPES)
    assert np.all(np.diff(found.ids) > 0) and np.all((found.parts >= 0) & (found.parts <= 1))
    hits = db.search(half, k=6, partial=True)
    fused = dict(zip(found.ids.tolist(), fused_similarity(found.parts, found.words), strict=True))
    assert [h.similarity for h in hits] == pytest.approx([fused[h.id] for h in hits])
    assert [h.distance for h in hits] == pytest.approx([-np.log(h.similarity) for h in hits])
    assert all(np.copysign(1.0, h.distance) == 1.0 for h in hits)


def test_the_words_bring_shapes_the_votes_missed(
    db: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One voting part asking for one shape finds one candidate; the words add the rest.
    A store without words (``rerank="none"``) keeps to the voted shapes and their scores."""
    import shapedb
    from query.parts import partial

    monkeypatch.setattr(partial, "VOTING_PARTS", 1)
    monkeypatch.setattr(partial, "SHAPES_PER_PART", 1)
    monkeypatch.setattr(partial, "CANDIDATES", 1)
    half = _half(SHAPES["dumbbell"])
    assert len(db.search(half, k=6, partial=True)) == len(SHAPES)
    plain = shapedb.connect(tmp_path / "plain", resolution=32, n_balls=32, rerank="none")
    plain.ingest([(n, n, g) for n, g in SHAPES.items()], workers=1, progress=False)
    found = partial.partial_candidates(plain, half, k=6)
    assert found.words is None and len(found.ids) == 1
    hits = plain.search(half, k=6, partial=True)
    assert [h.id for h in hits] == found.ids.tolist()
    assert hits[0].similarity == pytest.approx(found.parts[0])
    monkeypatch.undo()
    every = partial.partial_candidates(plain, half, k=6)
    assert len(every.ids) > 1 and np.all(np.diff(every.ids) > 0)  # ascending, as documented
