"""A cloud ranks as its proxy: does it only help when the store holds the scanned model?

Usage (from the repository root)::

    python -m bench.studies.cloud_proxy --split validation

``db.search`` ranks a point cloud as a search for its proxy ranks the store
(:mod:`query.search.cloud_proxy`: the stored shape its light fields find nearest; on the
view path the shape of the nearest view). The scans table (``python -m bench.quality
--queries ...``) searches a store that holds every query's own mesh (left out of the
hits), where the proxy is mostly that mesh. Here each class of a family's split is
halved (every other model, in the set's order): the store holds one half's meshes (the
gallery), the other half's models query it as meshes and as clouds of each kind, so no
query's model is stored. Each row is scored against the gallery's classes (NN / 1-T /
DCG: first tier over the query's class size in the gallery), with the proxy and without
it (``StageTuning.proxy``), and the meshes of the same models as the baseline. Written
to ``bench/results/studies/cloud_proxy_<split>.json``.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json
from bench.quality import family_split
from bench.sets.datasets import Dataset
from query.search.tuning import PRODUCT, tuned

__all__ = ["halves", "ranked_scores", "main"]

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
KINDS = ("even", "vertex", "falloff", "one-sided")
SETS = ("capod", "parts", "enclosures", "generic")


def halves(ds: Dataset) -> tuple[Dataset, Dataset]:
    """(gallery, probes): every other model of each class, in the set's order."""
    seen: Counter[str] = Counter()
    gallery, probes = [], []
    for m in ds.models:
        (gallery if seen[m.label] % 2 == 0 else probes).append(m)
        seen[m.label] += 1
    return Dataset(f"{ds.name}-gallery", tuple(gallery)), Dataset(ds.name, tuple(probes))


def ranked_scores(
    ranked: Sequence[Sequence[str]], labels: Sequence[str], sizes: Counter[str]
) -> dict[str, float]:
    """NN, first tier and DCG (PSB's) of ranked gallery labels, one list per query;
    ``sizes`` the gallery's class sizes (a query whose class is not in it is left out)."""
    nn, tier, dcg = [], [], []
    for row, label in zip(ranked, labels, strict=True):
        c = sizes[label]
        if not c:
            continue
        rel = np.array([x == label for x in row], bool)
        gain = 1.0 / np.log2(np.maximum(np.arange(1, len(rel) + 1), 2))
        nn.append(float(rel[0]))
        tier.append(float(rel[:c].sum()) / c)
        dcg.append(float(gain[rel].sum() / gain[:c].sum()))
    return {
        "nn": float(np.mean(nn)),
        "first_tier": float(np.mean(tier)),
        "dcg": float(np.mean(dcg)),
        "queries": len(nn),
    }


def _rows(db: Any, probes: Dataset, kind: str, proxy: bool) -> list[list[str]]:
    from bench.support.scan_queries import query_geometry

    out = []
    with tuned(replace(PRODUCT, proxy=proxy)):
        for m in probes.models:
            hits = db.search(query_geometry(m, kind), k=len(db.store))
            out.append([str(h.label) for h in hits])
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.studies.cloud_proxy")
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--sets", nargs="+", default=list(SETS))
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    from bench.support.product_stores import split_store

    out: dict[str, Any] = {"split": args.split, "sets": {}}
    table = []
    for name in args.sets:
        gallery, probes = halves(family_split(name, args.split))
        db = split_store(gallery, {})
        sizes = Counter(m.label for m in gallery.models)
        labels = [m.label for m in probes.models]
        rows: dict[str, Any] = {
            "mesh": ranked_scores(_rows(db, probes, "mesh", True), labels, sizes)
        }
        for kind in args.kinds:
            for proxy in (False, True):
                key = f"{kind}, {'proxy' if proxy else 'own row'}"
                rows[key] = ranked_scores(_rows(db, probes, kind, proxy), labels, sizes)
                print(f"{name} {key}: {rows[key]['nn']:.3f}", flush=True)
        out["sets"][name] = rows
        for key, s in rows.items():
            table.append([name, key, f"{s['nn']:.3f} / {s['first_tier']:.3f} / {s['dcg']:.3f}"])
    print(
        format_table(
            f"No query's model stored ({args.split})", ["set", "query", "NN / 1-T / DCG"], table
        )
    )
    path = args.out or RESULTS / f"cloud_proxy_{args.split}.json"
    write_json(path, out)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
