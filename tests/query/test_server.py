"""The JSON API of ``shapedb serve`` (query.serve.server), through FastAPI's TestClient."""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi", reason="the serve extra is not installed")
pytest.importorskip("httpx", reason="TestClient needs httpx (dev extra)")

from server_helpers import OPTIONS, build_store, client, write_models  # noqa: E402

from query.serve.server import create_app, is_loopback, serve  # noqa: E402
from shapedb.errors import ConfigError  # noqa: E402

HIT_KEYS = {"id", "name", "label", "similarity"}


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, dict[str, Path]]:
    return build_store(tmp_path_factory.mktemp("server"))


@pytest.fixture(scope="module")
def api(store: tuple[Any, dict[str, Path]]) -> Any:
    return client(create_app(store[0]))


@pytest.fixture()
def private_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Uploads land here: the test sees what is left behind."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def test_info_is_the_stores(api, store):
    db, _ = store
    r = api.get("/api/info")
    assert r.status_code == 200
    assert r.json() == json.loads(json.dumps(db.info()))
    assert r.json()["labels"] == {"box": 2, "capsule": 2, "cylinder": 2}
    assert float(r.headers["server-timing"].removeprefix("app;dur=")) > 0


def test_search_by_id_and_by_name(api, store):
    db, _ = store
    sid = db.store.resolve("capsule0")
    by_id = api.get("/api/search", params={"id": str(sid), "k": 4}).json()
    by_name = api.get("/api/search", params={"id": "capsule0", "k": 4}).json()
    assert by_id == by_name
    assert [set(h) for h in by_id] == [HIT_KEYS] * 4
    assert by_id[0]["id"] == sid and by_id[0]["similarity"] == pytest.approx(1.0)
    expected = db.search(sid, k=4)
    assert [h["id"] for h in by_id] == [h.id for h in expected]
    assert [h["similarity"] for h in by_id] == pytest.approx([h.similarity for h in expected])


def test_search_errors_are_json(api):
    r = api.get("/api/search", params={"id": "no-such-shape"})
    assert r.status_code == 404 and "no-such-shape" in r.json()["error"]
    assert api.get("/api/search", params={"id": "99999"}).status_code == 404
    r = api.get("/api/search", params={"id": "1", "k": "0"})
    assert r.status_code == 400 and r.json()["error"].startswith("k:")
    r = api.get("/api/search")
    assert r.status_code == 400 and "id" in r.json()["error"]
    r = api.get("/api/search", params={"id": "1", "where": "no_such_column = 1"})
    assert r.status_code == 400 and "Traceback" not in r.text


def test_search_never_reads_a_server_path(api, store):
    _, models = store
    # a path on the server is not a shape name: no file is ever loaded from a query string
    r = api.get("/api/search", params={"id": str(models["box0"])})
    assert r.status_code == 404


def test_upload_search_matches_the_library_and_cleans_up(api, store, private_tmp):
    db, models = store
    path = models["cylinder1"]
    with open(path, "rb") as fh:
        r = api.post("/api/search", params={"k": 3}, files={"file": ("cyl.obj", fh)})
    assert r.status_code == 200, r.text
    expected = db.search(path, k=3)
    assert [h["id"] for h in r.json()] == [h.id for h in expected]
    assert [h["similarity"] for h in r.json()] == pytest.approx([h.similarity for h in expected])
    assert list(private_tmp.iterdir()) == []  # the upload folder is gone
    query = api.get(f"/api/queries/{r.headers['X-Query']}").json()
    assert query["name"] == "cyl.obj"
    assert len(query["radii"]) == db.get("cylinder1").decomposition.n_balls
    assert query["surface"]["kind"] == "mesh" and len(query["surface"]["faces"]) > 0


def test_upload_errors_name_the_file_not_the_temporary_path(api, private_tmp):
    r = api.post("/api/search", files={"file": ("notes.txt", b"not a model")})
    assert r.status_code == 400
    assert r.json()["error"].startswith("notes.txt: unsupported file type")
    assert str(private_tmp) not in r.text and "shapedb-upload" not in r.text
    r = api.post("/api/search", files={"file": ("broken.obj", b"v 0 0 0\nf 1 2 3\n")})
    assert r.status_code == 400 and "broken.obj" in r.json()["error"]
    assert list(private_tmp.iterdir()) == []
    assert api.get("/api/queries/nope").status_code == 404


def test_size_limit(store, private_tmp):
    _, models = store
    api = client(create_app(store[0], max_upload_bytes=200))
    with open(models["box0"], "rb") as fh:
        data = fh.read()
    assert len(data) > 200
    r = api.post("/api/search", files={"file": ("box.obj", data)})
    assert r.status_code == 413 and "limit is 200 bytes" in r.json()["error"]
    big = b"#" * 200_000  # over the limit and its multipart slack: refused by Content-Length
    assert api.post("/api/search", files={"file": ("x.obj", big)}).status_code == 413
    assert list(private_tmp.iterdir()) == []


def test_token_guards_uploads_ingest_and_sql(store):
    db, models = store
    api = client(create_app(db, token="s3cret"))
    assert api.get("/api/search", params={"id": "box0"}).status_code == 200
    r = api.post("/api/search", files={"file": ("a.obj", b"x")})
    assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
    assert api.post("/api/sql", json={"sql": "SELECT 1"}).status_code == 401
    assert api.post("/api/ingest", files={"file": ("a.obj", b"x")}).status_code == 401
    assert api.get("/api/search", params={"id": "box0", "where": "true"}).status_code == 401
    wrong = {"Authorization": "Bearer nope"}
    assert api.post("/api/sql", json={"sql": "SELECT 1"}, headers=wrong).status_code == 401
    good = {"Authorization": "Bearer s3cret"}
    r = api.post("/api/sql", json={"sql": "SELECT 1 AS one"}, headers=good)
    assert r.status_code == 200 and r.json()["rows"] == [[1]]
    with open(models["box1"], "rb") as fh:
        r = api.post("/api/search", files={"file": ("b.obj", fh)}, headers=good)
    assert r.status_code == 200 and r.json()[0]["name"] == "box1"
    assert api.get("/api/server").json()["token_required"] is True


def test_serve_refuses_other_hosts_without_a_token(store):
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0") and not is_loopback("example.org")
    with pytest.raises(ConfigError, match="token"):
        serve(store[0], host="0.0.0.0", port=0)


def test_cross_origin_writes_and_foreign_hosts_are_refused(store):
    db, _ = store
    api = client(create_app(db))
    body = {"query": "box0", "node": 0}
    r = api.post("/api/match", json=body, headers={"Origin": "http://evil.example"})
    assert r.status_code == 403
    assert (
        api.post("/api/match", json=body, headers={"Origin": "http://testserver"}).status_code
        == 200
    )
    local = client(create_app(db, allowed_hosts=["127.0.0.1", "localhost"]))
    assert local.get("/api/info").status_code == 400  # Host: testserver
    assert local.get("/api/info", headers={"Host": "localhost:8000"}).status_code == 200


def test_shapes_pages_and_facets(api, store):
    db, _ = store
    page = api.get("/api/shapes", params={"offset": 1, "limit": 2}).json()
    assert page["total"] == 6 and [s["id"] for s in page["shapes"]] == list(db.store.ids()[1:3])
    boxes = api.get("/api/shapes", params={"label": "box"}).json()
    assert boxes["total"] == 2 and {s["name"] for s in boxes["shapes"]} == {"box0", "box1"}
    assert api.get("/api/shapes", params={"limit": 0}).status_code == 400


def test_shape_record_balls_edges_and_surface(api, store):
    db, _ = store
    rec = db.get("box1")
    r = api.get(f"/api/shapes/{rec.id}").json()
    assert (r["name"], r["label"], r["n_balls"]) == ("box1", "box", rec.decomposition.n_balls)
    assert r["radii"] == pytest.approx(rec.decomposition.radii.tolist(), rel=1e-5)
    assert r["edges"] == rec.decomposition.edges.tolist()
    assert api.get("/api/shapes/box1").json()["id"] == rec.id
    surface = api.get(f"/api/shapes/{rec.id}/surface").json()
    assert surface["kind"] == "mesh" and len(surface["faces"]) == 12  # a box: 12 triangles
    assert api.get("/api/shapes/4242").status_code == 404


def test_a_commit_draws_thumbnails_and_a_failure_there_never_fails_it(
    tmp_path, monkeypatch, caplog
):
    import shapedb
    from query import thumbnails
    from query.serve.viewer import stored_record

    models = write_models(tmp_path / "models")
    db = shapedb.connect(tmp_path / "store", **OPTIONS)
    db.ingest([models["box0"]], workers=1, progress=False)
    sid = int(db.store.resolve("box0"))
    path = thumbnails.thumbnail_path(db.path, stored_record(db, sid))
    drawn = list(path.parent.glob(f"{sid}-*.png"))
    assert drawn == [path] and path.parent.parent == db.path / "thumbnails"
    assert drawn[0].read_bytes().startswith(b"\x89PNG")

    def broken(*args: Any) -> None:
        raise OSError("no space left on device")

    monkeypatch.setattr(thumbnails, "draw_committed", broken)
    db.ingest([models["box1"]], workers=1, progress=False)
    assert "drawing thumbnails failed" in caplog.text  # logged, and the commit stands:
    other = int(db.store.resolve("box1"))
    assert not list((db.path / "thumbnails").rglob(f"{other}-*.png"))
    monkeypatch.undo()
    assert thumbnails.thumbnail(
        db.path, stored_record(db, other)
    ).is_file()  # drawn at its first view instead
    db.delete("box0")
    assert not list((db.path / "thumbnails").rglob(f"{sid}-*.png"))


def test_a_bulk_commit_leaves_thumbnails_to_the_page(tmp_path, monkeypatch):
    """More than DRAWN_AT_COMMIT shapes in one commit: none drawn there (one folder a
    thousand ids), each drawn at its first view."""
    from dataclasses import replace

    import shapedb
    from query import thumbnails
    from query.serve.viewer import stored_record

    models = write_models(tmp_path / "models")
    db = shapedb.connect(tmp_path / "store", **OPTIONS)
    db.ingest([models["box0"]], workers=1, progress=False)
    record = db.get("box0")
    monkeypatch.setattr(thumbnails, "DRAWN_AT_COMMIT", 2)
    copies = [replace(record, id=None, name=f"copy{i}", content_hash=f"c{i}") for i in range(3)]
    _, committed = db.commit(copies)
    assert not any(
        thumbnails.thumbnail_path(db.path, stored_record(db, int(r.id))).exists() for r in committed
    )
    path = thumbnails.thumbnail(db.path, stored_record(db, int(committed[0].id)))
    assert path.is_file() and path.parent.name == f"{int(committed[0].id) // 1000:05d}"


def test_a_thumbnail_is_the_balls_filling_the_picture():
    from query.thumbnails import SIZE, render_balls

    assert (render_balls(np.zeros((0, 3)), np.zeros(0)) == 255).all()
    one = render_balls([[1.0, 2.0, 3.0]], [0.5])
    assert one.shape == (SIZE, SIZE, 3) and one.dtype == np.uint8
    ink = (one < 235).any(axis=2)
    rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    assert (rows[-1] - rows[0]) / SIZE > 0.9 and (cols[-1] - cols[0]) / SIZE > 0.9
    centre = one[SIZE // 2, SIZE // 2].astype(int)
    assert centre[2] > centre[0] + 60  # blue, as the balls of the 3-D view


def test_thumbnail_is_drawn_once_and_cached_beside_the_store(api, store):
    db, _ = store
    sid = int(db.store.resolve("capsule1"))
    r = api.get(f"/api/shapes/{sid}/thumbnail.png")
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.content.startswith(b"\x89PNG")
    cached = list((db.path / "thumbnails").rglob(f"{sid}-*.png"))
    assert len(cached) == 1
    stamp = cached[0].stat().st_mtime_ns
    assert api.get(f"/api/shapes/{sid}/thumbnail.png").content == r.content
    assert cached[0].stat().st_mtime_ns == stamp
    assert api.get("/api/shapes/4242/thumbnail.png").status_code == 404


def test_match_in_targets_and_in_the_store(api, store):
    db, _ = store
    ids = [int(i) for i in db.store.ids()]
    q = ids[0]
    r = api.post("/api/match", json={"query": q, "node": 0, "hops": 1, "targets": ids[1:4]})
    assert r.status_code == 200, r.text
    data = r.json()
    assert [m["id"] for m in data["matches"]] == ids[1:4]
    expected = db.match(q, ids[2], node=0, hops=1, top=1)[0]
    assert data["matches"][1]["nodes"] == list(expected.nodes)
    assert data["matches"][1]["similarity"] == pytest.approx(expected.similarity)
    assert 0 in data["query_nodes"]
    whole = api.post("/api/match", json={"query": "box0", "point": [0, 0, 0], "k": 3}).json()
    assert len(whole["matches"]) == 3 and whole["matches"][0]["similarity"] <= 1.0
    assert api.post("/api/match", json={"query": q}).status_code == 400
    assert api.post("/api/match", json={"query": q, "node": 999}).status_code == 404
    assert api.post("/api/match", json={"query": "upload:zzz", "node": 0}).status_code == 404
    assert api.post("/api/match", json={"query": q, "point": [0, 0]}).status_code == 400


def test_match_an_uploaded_query(api, store):
    _, models = store
    with open(models["capsule1"], "rb") as fh:
        key = api.post("/api/search", files={"file": ("c.obj", fh)}).headers["X-Query"]
    r = api.post("/api/match", json={"query": f"upload:{key}", "node": 1, "hops": 1, "k": 2})
    assert r.status_code == 200 and r.json()["matches"][0]["name"] == "capsule1"


def test_sql_and_eval(api, store):
    db, _ = store
    r = api.post(
        "/api/sql", json={"sql": "SELECT label, count(*) AS n FROM shapes GROUP BY 1 ORDER BY 1"}
    )
    assert r.json()["rows"] == [["box", 2], ["capsule", 2], ["cylinder", 2]]
    r = api.post("/api/sql", json={"sql": "SELECT id FROM shapes ORDER BY id", "limit": 2})
    assert r.json()["truncated"] is True and len(r.json()["rows"]) == 2
    r = api.post("/api/sql", json={"sql": "SELEC nothing"})
    assert r.status_code == 400 and "Parser" in r.json()["error"]
    e = api.get("/api/eval").json()
    expected = db.evaluate().to_dict()
    assert e["nn"] == pytest.approx(expected["nn"]) and e["queries"] == 6
    assert set(e["per_class"]) == {"box", "capsule", "cylinder"}
    assert len(e["recall"]) == len(e["precision"]) > 2


def test_unexpected_errors_hide_their_trace(store, monkeypatch):
    db, _ = store
    api = client(create_app(db), raise_server_exceptions=False)

    def boom() -> None:
        raise RuntimeError("secret internals")

    monkeypatch.setattr(db, "info", boom)
    r = api.get("/api/info")
    assert r.status_code == 500 and r.json()["error"].startswith("internal error")
    assert "secret" not in r.text and "Traceback" not in r.text


def test_ingest_by_upload_and_a_new_version_from_another_process(tmp_path, private_tmp):
    from server_helpers import OPTIONS, write_models

    import shapedb

    models = write_models(tmp_path / "models")
    db = shapedb.connect(tmp_path / "store", **OPTIONS)
    db.ingest([models["box0"], models["capsule0"]], workers=1)
    api = client(create_app(db))
    assert api.get("/api/info").json()["shapes"] == 2
    files = [("file", (p.name, p.read_bytes())) for p in (models["box1"], models["cylinder0"])]
    r = api.post("/api/ingest", files=files, data={"label": "new"})
    assert r.status_code == 202, r.text
    job = r.json()["job"]
    for _ in range(600):
        state = api.get(f"/api/ingest/{job}").json()
        if state["state"] != "running":
            break
        time.sleep(0.1)
    assert state["state"] == "done", state
    assert state["done"] == state["total"] == 2 and state["report"]["ingested"] == 2
    assert api.get("/api/shapes", params={"label": "new"}).json()["total"] == 2
    assert list(private_tmp.iterdir()) == []
    # another writer (a separate connection, as another process would be) commits
    other = shapedb.connect(tmp_path / "store")
    other.ingest([models["cylinder1"]], workers=1)
    assert api.get("/api/info").json()["shapes"] == 5
    hits = api.get("/api/search", params={"id": "cylinder1", "k": 1}).json()
    assert hits[0]["name"] == "cylinder1"
    assert api.get("/api/ingest/unknown").status_code == 404


def test_stored_record_is_db_get_without_features(store):
    import numpy as np

    from query.serve.viewer import stored_record

    db, _ = store
    sid = int(db.store.resolve("cylinder0"))
    full, light = db.get(sid), stored_record(db, sid)
    assert (light.id, light.name, light.label, light.source) == (
        sid,
        "cylinder0",
        "cylinder",
        full.source,
    )
    assert light.content_hash == full.content_hash and light.created_at == full.created_at
    for a in ("centers", "radii", "edges", "bounds", "frame"):
        np.testing.assert_array_equal(
            getattr(light.decomposition, a), getattr(full.decomposition, a)
        )
    assert light.decomposition.spacing == full.decomposition.spacing
    assert len(light.feature) == 0 and light.view_feature is None


def test_the_openapi_page_needs_no_cdn(api):
    page = api.get("/docs")
    assert page.status_code == 200 and "cdn" not in page.text
    assert api.get("/static/vendor/swagger-ui/swagger-ui-bundle.js").status_code == 200
    paths = api.get("/openapi.json").json()["paths"]
    for path in ("/api/info", "/api/search", "/api/shapes", "/api/shapes/{id}", "/api/match"):
        assert path in paths
    assert {"get", "post"} <= set(paths["/api/search"])


@pytest.mark.parametrize(
    "statement",
    ["SELECT * FROM read_csv('/etc/passwd')", "SELECT 1; SELECT 2", "COPY shapes TO 'x.csv'"],
)
def test_sql_is_the_stores_sandbox(api, statement):
    r = api.post("/api/sql", json={"sql": statement})
    assert r.status_code == 400 and "root:" not in r.text


def test_where_cannot_escape_its_predicate(api):
    r = api.get("/api/search", params={"id": "box0", "where": "true) UNION SELECT 42 --"})
    assert r.status_code == 400 and "where=" in r.json()["error"]
