"""Choose the weight of a block added to descriptor version 4, on validation splits.

Blocks: ``union`` (spherical-harmonic energies of the ball union, :mod:`shapedb.signature.union`:
descriptor version 5) and ``views`` (silhouettes and depth images of the ball union,
:mod:`shapedb.signature.union_views`: version 7).

Usage (from the repository root)::

    python -m bench.studies.union_select                         # union block, four sets, validation
    python -m bench.studies.union_select --block views --datasets generic capod articulated parts web
    python -m bench.studies.union_select --split test --weights 0 8   # report two weights on test
    python -m bench.studies.union_select --cost 8      # CPU per model: decomposition, v4, v5, v7

For each set's split (meshes), the version-4 descriptor of :mod:`shapedb.signature.descriptor`
and the block are computed from the cached decompositions; the block's typical L1
distance is the geometric mean over the sets of its median pairwise distance (as
``bench/select_descriptors.py`` measures the others'), and the combined distance is
version 4's plus ``weight / typical`` times the block's, in version 4's units (which
is what versions 5 and 7 compute, up to one overall factor that changes no ranking).
Per weight the table lists NN / 1-T / 2-T / DCG per set and the objective, the mean
over the sets of (NN + 1-T + DCG) / 3; with ``--block views`` the rows ``v5`` (version
5 as shipped) and ``views only`` are measured in the same run. The chosen weight is
the best objective among those with no set's NN, 1-T or DCG more than two queries'
worth below weight 0. Written to bench/results/<block>_select_<split>.json.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import decompose_all, format_table, retrieval_scores, write_json
from bench.sets.datasets import Dataset, articulated, capod, generic, parts, web
from shapedb.config.core import Config, DescriptorConfig, MDBDConfig
from shapedb.signature.descriptor import LAYOUTS, UNION_TYPICAL, UNION_WEIGHT
from shapedb.signature.union import union_features
from shapedb.signature.union_views import view_features

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"
WEIGHTS = (0.0, 1.0, 2.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0)


def _l1(x: np.ndarray) -> np.ndarray:
    out = np.empty((len(x), len(x)))
    for i in range(len(x)):
        out[i] = np.abs(x - x[i]).sum(axis=1)
    return out


#: Block name -> feature of (centres, radii).
BLOCKS = {"union": union_features, "views": view_features}


def set_matrices(
    ds: Dataset, mdbd: MDBDConfig, workers: int, block: str = "union"
) -> dict[str, Any]:
    """Version-4, ball-union and (``block="views"``) view distance matrices of one split."""
    from bench.retrieval import kernel_features

    balls = decompose_all(ds.models, "mesh", mdbd, workers=workers)
    keep = [i for i, b in enumerate(balls) if b is not None]
    if len(keep) < len(ds):
        print(f"  {ds.name}: {len(ds) - len(keep)} model(s) left out (decomposition failed)")
    bs = [balls[i] for i in keep]
    labels = ds.labels[keep]
    v4 = kernel_features(bs, Config(descriptor=DescriptorConfig(version=4)))  # type: ignore[arg-type]
    cal4 = np.log(10.0) / sum(b[3] for b in LAYOUTS[4])
    t0 = time.process_time()
    u = np.stack([union_features(b.centers, b.radii) for b in bs])  # type: ignore[union-attr]
    sec = (time.process_time() - t0) / max(len(bs), 1)
    out = {"labels": labels, "d4": _l1(v4) / cal4, "du": _l1(u), "union_cpu_s": sec}
    if block == "views":
        t0 = time.process_time()
        x = np.stack([view_features(b.centers, b.radii) for b in bs])  # type: ignore[union-attr]
        out["views_cpu_s"] = (time.process_time() - t0) / max(len(bs), 1)
        out["dv"] = _l1(x)
    return out


def cost(per_set: int = 8) -> dict[str, dict[str, float]]:
    """Median CPU seconds per model: decomposition, descriptor v4, v5 and v7 (CAPOD, generic)."""
    from bench.sets.datasets import mesh_arrays
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.mdbd.decomposition import decompose
    from shapedb.mdbd.graph import ContactGraph
    from shapedb.signature.descriptor import describe

    out = {}
    for ds in (capod().split("validation"), generic().split("validation")):
        rows = []
        for m in ds.head(per_class=1).models[:per_set]:
            t = time.process_time()
            d = decompose(TriangleMesh(*mesh_arrays(m)))
            td = time.process_time() - t
            g = ContactGraph(d.centers, d.radii, d.edges)
            t = time.process_time()
            describe(g, 4)
            t4 = time.process_time() - t
            t = time.process_time()
            describe(g, 5)
            t5 = time.process_time() - t
            t = time.process_time()
            describe(g, 7)
            rows.append((td, t4, t5, time.process_time() - t))
        td, t4, t5, t7 = np.median(np.asarray(rows), axis=0)
        out[ds.name] = {
            "decompose": td, "v4": t4, "v5": t5, "v7": t7,
            "extra_v5": (t5 - t4) / (td + t4), "extra_v7": (t7 - t4) / (td + t4),
        }  # fmt: skip
        print(f"{ds.name}: median CPU s decompose {td:.3f}, v4 {t4:.4f}, v5 {t5:.4f} "
              f"(+{(t5 - t4) / (td + t4):.1%}), v7 {t7:.4f} (+{(t7 - t4) / (td + t4):.1%})")  # fmt: skip
    return out


def read_older_cache(commit: str) -> None:
    """Make :func:`bench.common.decompose_all` fall back to ``commit``'s cache keys."""
    import bench.common as common

    today = common.cache_path

    def path(model: Any, variant: str, config: MDBDConfig, **kw: Any) -> Path:
        p = today(model, variant, config, **kw)
        return p if p.exists() else today(model, variant, config, engine_commit=commit)

    common.cache_path = path  # type: ignore[assignment]


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.union_select", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--block", default="union", choices=sorted(BLOCKS))
    ap.add_argument("--datasets", nargs="+", default=["generic", "capod", "articulated", "parts"])
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--weights", type=float, nargs="+", default=list(WEIGHTS))
    ap.add_argument(
        "--typical", type=float, default=None, help="block typical distance (default: measured)"
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--engine-commit",
        default=None,
        help="read decompositions an older engine cached (its code at this commit) where "
        "today's are missing",
    )
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--cost", type=int, default=0, help="only time N models per set")
    args = ap.parse_args(argv)
    if args.cost:
        write_json(RESULTS / "union_cost.json", cost(args.cost))
        return 0
    makers = {
        "generic": generic, "capod": capod, "articulated": articulated, "parts": parts, "web": web
    }  # fmt: skip
    if args.engine_commit:
        read_older_cache(args.engine_commit)
    mats = {}
    for name in args.datasets:
        ds = makers[name]().split(args.split)
        mats[name] = set_matrices(ds, MDBDConfig(), args.workers, args.block)
    key = "dv" if args.block == "views" else "du"
    medians = {
        n: float(np.median(m[key][np.triu_indices(len(m[key]), 1)])) for n, m in mats.items()
    }
    typical = args.typical or float(np.exp(np.mean(np.log(list(medians.values())))))
    rows, table = [], []
    base: dict[str, dict[str, float]] = {}
    extra: list[tuple[str, Any]] = []
    if args.block == "views":
        extra = [("v5", "v5"), ("views only", "only")]
    for w in [*args.weights, *(e[0] for e in extra)]:
        entry: dict[str, Any] = {"weight": w}
        obj = []
        for name, m in mats.items():
            if w == "v5":
                d = m["d4"] + (UNION_WEIGHT / UNION_TYPICAL) * m["du"]
            elif w == "views only":
                d = m["dv"]
            else:
                d = m["d4"] + (w / typical) * m[key]
            s = retrieval_scores(-d, m["labels"])
            entry[name] = s
            obj.append((s["nn"] + s["first_tier"] + s["dcg"]) / 3)
        entry["objective"] = float(np.mean(obj))
        if w == 0.0:
            base = {n: entry[n] for n in mats}
        table.append(entry)
        rows.append(
            [
                w,
                *(
                    f"{entry[n]['nn']:.3f}/{entry[n]['first_tier']:.3f}/{entry[n]['second_tier']:.3f}/{entry[n]['dcg']:.3f}"
                    for n in mats
                ),
                entry["objective"],
            ]
        )
    chosen = None
    if base:
        ok = []
        for e in table:
            if isinstance(e["weight"], str):
                continue
            fine = all(
                e[n][k] >= base[n][k] - 2.0 / len(mats[n]["labels"])
                for n in mats
                for k in ("nn", "first_tier", "dcg")
            )
            if fine:
                ok.append(e)
        chosen = max(ok, key=lambda e: e["objective"])["weight"] if ok else None
    print()
    print(format_table(
        f"{args.block} block weight, {args.split} splits (NN/1-T/2-T/DCG), typical {typical:.4g}",
        ("weight", *mats, "objective"), rows,
    ))  # fmt: skip
    cpu = {n: round(m[f"{args.block}_cpu_s"], 4) for n, m in mats.items()}
    print(f"block medians {medians}; {args.block} block CPU s/model {cpu}; chosen weight {chosen}")
    out = args.out or RESULTS / f"{args.block}_select_{args.split}.json"
    write_json(out, {"block": args.block, "split": args.split, "typical": typical,
                     "medians": medians, "table": table, "chosen": chosen,
                     f"{args.block}_cpu_s": cpu})  # fmt: skip
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
