"""Helpers of the server tests (not fixtures): a tiny store of mesh files, and a live server."""

from __future__ import annotations

import threading
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

#: Six small meshes in three classes, decomposed coarsely so the store builds in seconds.
OPTIONS = {"resolution": 24, "n_balls": 32}


def write_models(folder: Path) -> dict[str, Path]:
    """OBJ files of boxes, capsules and cylinders under ``folder/<label>/``; name -> path."""
    import trimesh

    shapes = {
        "box": [trimesh.creation.box((2, 1, 1)), trimesh.creation.box((3, 1, 0.8))],
        "capsule": [trimesh.creation.capsule(2.0, 0.4), trimesh.creation.capsule(3.0, 0.4)],
        "cylinder": [trimesh.creation.cylinder(0.5, 2.0), trimesh.creation.cylinder(0.8, 1.0)],
    }
    out = {}
    for label, meshes in shapes.items():
        (folder / label).mkdir(parents=True, exist_ok=True)
        for i, mesh in enumerate(meshes):
            path = folder / label / f"{label}{i}.obj"
            mesh.export(path)
            out[path.stem] = path
    return out


def build_store(root: Path) -> tuple[Any, dict[str, Path]]:
    """A store of :func:`write_models`, labelled by folder; returns (db, name -> path)."""
    import shapedb

    models = write_models(root / "models")
    db = shapedb.connect(root / "store", **OPTIONS)
    db.ingest([root / "models"], label_from_folder=True, workers=1)
    return db, models


def client(app: Any, **kwargs: Any) -> Any:
    """FastAPI's TestClient (its import warns about a future httpx rename)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient
    return TestClient(app, **kwargs)


@contextmanager
def live_server(app: Any) -> Iterator[str]:
    """Run ``app`` with uvicorn on a free loopback port in a thread; yields its URL."""
    import uvicorn

    config = uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning", lifespan="off")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            raise RuntimeError("uvicorn did not start")
        time.sleep(0.05)
    port = server.servers[0].sockets[0].getsockname()[1]
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=10)
