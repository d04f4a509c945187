"""Build the pinned store: a small default store whose search ranks a test holds fixed.

Run once from the repository root (``python tests/data/pinned/build.py``, needs the bench's
generators); what it writes is committed: ``store/`` (as ingest left it, before any search),
``models/`` (the small web-like meshes, re-ingested by the test), ``queries/`` and
``ranks.json``; a change to the query path alone re-pins the ranks of the same store with
``--ranks-only``. The models come from the bench's generators (web-like generic and web
models, people, jointed figures, machined parts), so the default re-ranking stage sees the
kinds it gates on; the store is built with the default configuration through the public
API, so it is what a user's store would be.
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))

K = 10
WEB_KINDS = ("bookshelf", "floor_lamp", "church")
GENERIC_KINDS = ("chair", "table", "house", "wheel", "sink", "airplane")
MODELS = [
    *[f"generic:{k}:{s}" for k in GENERIC_KINDS for s in (0, 1, 2)],
    *[f"web:{k}:{s}" for k in WEB_KINDS for s in (0, 1, 2)],
    *[f"person:{s}:{p}" for s in (0, 1) for p in (0, 1, 2)],
    *[f"figure:{s}:{p}" for s in (0, 1) for p in (0, 1, 2)],
    *[f"part:{k}:{s}" for k in ("bracket", "flange") for s in (0, 1, 2)],
]
#: Models small enough to commit (a few kB each); the test re-ingests them.
KEPT = ("generic:", "web:")
DERIVED = (
    "index",
    "index_lightfield",
    "index_neighbours",
    "index_field",
    "journal",
    "staging",
    ".lock",
)


def _label(source: str) -> str:
    kind, a = source.split(":")[:2]
    return a if kind in ("generic", "web", "part") else f"{kind}{a}"


def _write_models(models: Path) -> Path:
    from bench.sets import datasets
    from bench.sets.web_shapes import web_version

    labels = ["path,label"]
    for source in MODELS:
        full = f"{source}:{web_version()}" if source.startswith("web:") else source
        model = datasets.Model(name=source.replace(":", "_"), label=_label(source), source=full)
        v, f = datasets.mesh_arrays(model, cache=False)
        name = source.replace(":", "_") + ".ply"
        trimesh.Trimesh(v, f, process=False).export(models / name)
        labels.append(f"{name},{_label(source)}")
    csv = models.parent / "labels.csv"
    csv.write_text("\n".join(labels) + "\n")
    return csv


def _cloud_query(mesh: Path, out: Path) -> None:
    m = trimesh.load(mesh, force="mesh", process=False)
    points, _ = trimesh.sample.sample_surface_even(m, 1500, seed=7)
    np.savetxt(out, points, fmt="%.6f")


def ranks(store: Path, queries: dict[str, Path]) -> dict[str, list[list[float]]]:
    """Every stored shape's and every query file's top ``K`` ``[id, similarity]`` in a fresh copy."""
    import shapedb

    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "store"
        shutil.copytree(store, copy)
        db = shapedb.connect(copy, create=False)
        out: dict[str, list[list[float]]] = {}
        ids = sorted(int(i) for i in db.sql("SELECT id FROM shapes").column("id").to_pylist())
        for i in ids:
            out[str(i)] = [[h.id, h.similarity] for h in db.search(i, k=K)]
        for name, path in queries.items():
            out[f"file:{name}"] = [[h.id, h.similarity] for h in db.search(path, k=K)]
        return out


def main(argv: list[str] | None = None) -> None:
    """Rebuild the pin; ``--ranks-only``: keep the store, models and queries, recompute
    ``ranks.json`` (a change to the query path alone)."""
    args = sys.argv[1:] if argv is None else argv
    if args == ["--ranks-only"]:
        _write_ranks()
        return
    if args:
        raise SystemExit(f"usage: python {Path(__file__).name} [--ranks-only]")
    import shapedb

    for name in ("store", "models", "queries"):
        shutil.rmtree(HERE / name, ignore_errors=True)
    with tempfile.TemporaryDirectory() as tmp:
        models = Path(tmp) / "models"
        models.mkdir()
        csv = _write_models(models)
        built = Path(tmp) / "store"
        print(shapedb.connect(built).ingest([models], labels=csv))
        shutil.copytree(built, HERE / "store", ignore=shutil.ignore_patterns(*DERIVED))
        (HERE / "models").mkdir()
        (HERE / "queries").mkdir()
        for path in sorted(models.glob("*.ply")):
            if path.name.startswith(tuple(k.rstrip(":") for k in KEPT)):
                shutil.copy(path, HERE / "models" / path.name)
        shutil.copy(models / "person_1_2.ply", HERE / "queries" / "person_1_2.ply")
        _cloud_query(models / "generic_chair_1.ply", HERE / "queries" / "chair_cloud.xyz")
    _write_ranks()


def _write_ranks() -> None:
    queries = {p.name: p for p in sorted((HERE / "queries").iterdir())}
    (HERE / "ranks.json").write_text(json.dumps(ranks(HERE / "store", queries)) + "\n")


if __name__ == "__main__":
    main()
