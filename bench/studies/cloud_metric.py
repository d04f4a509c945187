"""The opt-in learned metric for point clouds: fitted with or without clouds, held out.

Usage (from the repository root)::

    python -m bench.studies.cloud_metric [--sets people figures] [--fit-kinds none vertex]

``db.fit_metric`` (:mod:`query.learn.metric`) learns the descriptor's block weights from
a labelled store; every labelled shape queries the others, a cloud against a mesh as the
search compares them. Here it is fitted on each family's validation split at the test's
class size (:func:`bench.studies.class_size.large_validation`), in a store of its meshes
alone (``none``) or of its meshes and a cloud of each (a fit kind of
:data:`bench.support.scan_queries.QUERY_KINDS`, stored under ``<model>~<kind>``), and
scored on the test split's store of meshes: its meshes (``db.evaluate``) and the clouds
of every kind asked for, searched through ``db.search(..., metric=)``, against the
default (no metric) in the same run. Written to
``bench/results/studies/cloud_metric.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.common import format_table, write_json

__all__ = ["fit_store", "WithMetric", "main"]

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
KINDS = ("vertex", "even", "falloff")


def fit_store(family: str, kind: str, *, workers: int = 2) -> Any:
    """The store the metric is fitted on (built once, cached beside the bench's stores):
    the large validation split's meshes and, unless ``kind`` is ``"none"``, one cloud of
    that kind of each model, labelled as its model."""
    import shapedb
    from bench.sets.datasets import mesh_arrays
    from bench.studies.class_size import large_validation
    from bench.support.product_stores import STORES_DIR, store_key
    from bench.support.scan_queries import query_geometry
    from shapedb.geometry.mesh import TriangleMesh

    ds = large_validation(family)
    path = STORES_DIR / f"metricfit_{ds.name}_{kind}_{store_key(ds, {})}"
    done = path / "built.json"
    if done.exists():
        return shapedb.connect(path, create=False)
    t = time.perf_counter()
    db = shapedb.connect(path)
    items: list[Any] = [
        (m.name, m.label, TriangleMesh(*mesh_arrays(m), name=m.name)) for m in ds.models
    ]
    if kind != "none":
        items += [(f"{m.name}~{kind}", m.label, query_geometry(m, kind)) for m in ds.models]
    report = db.ingest(items, workers=workers, progress=False)
    done.write_text(json.dumps({"shapes": len(items), "failed": len(report.failed)}))
    print(f"  fit store {path.name}: {len(items)} shapes, {time.perf_counter() - t:.0f} s")
    return db


class WithMetric:
    """A store whose searches use ``metric`` (what :func:`kind_scores` needs of a store)."""

    def __init__(self, db: Any, metric: Any) -> None:
        self.db, self.metric, self.store = db, metric, db.store

    def search(self, query: Any, *, k: int = 10, partial: bool | None = None) -> Any:
        return self.db.search(query, k=k, partial=partial, metric=self.metric)


def _row(s: Any) -> dict[str, float]:
    """NN, 1-T and DCG of a scores dict or a ``RetrievalScores``."""
    keys = ("nn", "first_tier", "dcg")
    if isinstance(s, dict):
        return {key: float(s[key]) for key in keys}
    return {key: float(getattr(s, key)) for key in keys}


def main(argv: Sequence[str] | None = None) -> int:
    from bench.quality import family_split
    from bench.support.product_stores import split_store, store_scores
    from bench.support.scan_queries import kind_scores

    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.cloud_metric", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--sets", nargs="+", default=["people"])
    ap.add_argument("--fit-kinds", nargs="+", default=["none", "vertex"])
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "cloud_metric.json")
    args = ap.parse_args(argv)
    report: dict[str, Any] = {}
    for family in args.sets:
        test = family_split(family, "test")
        db = split_store(test, {}, workers=args.workers)
        rows = {"default": {"mesh": _row(store_scores(db))}}
        rows["default"].update({k: _row(kind_scores(db, test, k)) for k in args.kinds})
        for fit in args.fit_kinds:
            metric = fit_store(family, fit, workers=args.workers).fit_metric(label="label")
            name = f"fitted on meshes{'' if fit == 'none' else f' + {fit} clouds'}"
            row = {"mesh": _row(db.evaluate(metric=metric))}
            row.update({k: _row(kind_scores(WithMetric(db, metric), test, k)) for k in args.kinds})
            row["learned"] = bool(metric.learned)  # type: ignore[assignment]
            rows[name] = row
            print(f"  {family}: {name} done", flush=True)
        body = [
            [name, *(f"{r[k]['nn']:.3f} / {r[k]['first_tier']:.3f} / {r[k]['dcg']:.3f}"
                     for k in ("mesh", *args.kinds))]
            for name, r in rows.items()
        ]  # fmt: skip
        print(format_table(f"{family} test, NN / 1-T / DCG", ["metric", "mesh", *args.kinds], body))
        report[family] = rows
    write_json(args.out, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
