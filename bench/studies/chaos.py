"""How far the default descriptor moves when the solid, or only the grid, barely moves.

The greedy MDBD packing is chaotic: after its first few dozen balls, which gap the next
ball fills depends on where the previous ones landed to a fraction of a cell, so any
change of the sampled field, however small, reshuffles the tail of the packing and its
contact graph. Meshes and their moved, rotated or scaled copies are decomposed
identically (canonical frame, local coordinates, tie rules: the stability bench's
shift / rotate columns are 1.0), but every *other* perturbation meets the chaos. This
bench measures its size against the distances that retrieval has to tell apart.

For ``--n`` models per set (spread over the split) it decomposes:

``grid turned <deg>``
    the mesh rotated by 0.01, 0.5 or 2 degrees, with ``canonical_frame=False`` (so the
    grid stays put and turns against the solid), against the unturned mesh decomposed
    the same way: a pure sampling perturbation, no change of the solid;
``subdivided``
    every triangle split in four (the same solid, other triangles), canonical frame;
``decimated``
    decimated to 25 % of its faces (the stability bench's re-meshing);
``point cloud``
    the paper's cloud (20 % of the vertices) against its mesh;
``two cloud draws``
    two independent clouds of the same mesh against each other;

and reports, per perturbation, the median default-descriptor distance (L1; unrelated
shapes sit near ln 10 = 2.3), its ratio to the median distance from a model to its
nearest same-class neighbour in the split, the per-block medians, and how often the
perturbed copy is still nearer to its original than to every other model of the split.

Usage: ``python -m bench.studies.chaos [--n 12] [--split validation] [--workers 2] [--out PATH]``.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import Balls, decompose_all, format_table, mdbd_config, write_json
from bench.sets.datasets import articulated, capod, parts
from shapedb.signature.descriptor import LAYOUTS, VERSION, describe

OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "chaos.json"
SETS = {"capod": capod, "articulated": articulated, "parts": parts}
TURNS = ("0.01", "0.5", "2")
BLOCKS = tuple(b[0] for b in LAYOUTS[VERSION])


def _descriptors(balls: list[Balls | None]) -> list[NDArray[np.float64] | None]:
    return [None if b is None else describe(b.decomposition().graph) for b in balls]


def _blocks(diff: NDArray[np.float64]) -> list[float]:
    """Per-block L1 of a descriptor difference (the blocks are already weighted)."""
    out, at = [], 0
    for _, size, _, _ in LAYOUTS[VERSION]:
        out.append(float(np.abs(diff[at : at + size]).sum()))
        at += size
    return out


def measure_set(name: str, split: str, n: int, workers: int) -> dict[str, Any]:
    """Perturbation distances of ``n`` models of one set."""
    cfg = mdbd_config()
    free = dataclasses.replace(cfg, canonical_frame=False)
    sub = SETS[name]().split(split)
    labels = np.asarray(sub.labels)
    mesh = _descriptors(decompose_all(sub.models, "mesh", cfg, workers=workers))
    ok = np.array([f is not None for f in mesh])
    fm = np.stack([f if f is not None else np.zeros_like(mesh[0]) for f in mesh])
    step = max(1, len(sub) // n)
    probe = [i for i in range(0, len(sub), step) if ok[i]][:n]
    models = [sub.models[i] for i in probe]

    def run(variant: str, config: Any = cfg) -> list[NDArray[np.float64] | None]:
        return _descriptors(decompose_all(models, variant, config, workers=workers))

    base_free = run("mesh", free)
    pairs: dict[str, tuple[list[Any], list[Any]]] = {
        f"grid turned {t} deg": (base_free, run(f"mesh_turn_{t}", free)) for t in TURNS
    }
    own = [fm[i] for i in probe]
    pairs["subdivided (same solid)"] = (own, run("mesh_subdivide"))
    pairs["decimated to 25 %"] = (own, run("mesh_decimate"))
    cloud = run("pointcloud")
    pairs["point cloud (20 %)"] = (own, cloud)
    pairs["two cloud draws"] = (cloud, run("pointcloud_b"))

    # reference: nearest same-class and other-class models (meshes of the split)
    dist = np.abs(fm[:, None, :] - fm[None, :, :]).sum(-1)
    dist[:, ~ok] = np.inf
    np.fill_diagonal(dist, np.inf)
    same = labels[:, None] == labels[None, :]
    near_same = np.where(same, dist, np.inf).min(1)[probe]
    near_other = np.where(~same, dist, np.inf).min(1)[probe]
    scale = float(np.median(near_same))

    rows = []
    for label, (a, b) in pairs.items():
        keep = [k for k in range(len(probe)) if a[k] is not None and b[k] is not None]
        if not keep:
            continue
        diffs = np.stack([b[k] - a[k] for k in keep])
        total = np.abs(diffs).sum(1)
        # still nearer to its original than to any other model of the split?
        others = np.stack(
            [
                np.where(np.arange(len(fm)) == probe[k], np.inf,
                         np.where(ok, np.abs(fm - b[k]).sum(1), np.inf)).min()
                for k in keep
            ]
        )  # fmt: skip
        per_block = np.median(np.stack([_blocks(d) for d in diffs]), axis=0)
        rows.append(
            [name, label, len(keep), float(np.median(total)), float(np.median(total)) / scale,
             float(np.mean(total < others)), *map(float, per_block)]
        )  # fmt: skip
    for label, values in (
        ("nearest same-class model", near_same),
        ("nearest other-class model", near_other),
    ):
        rows.append(
            [name, label, len(probe), float(np.median(values)), float(np.median(values)) / scale,
             None, *([None] * len(BLOCKS))]
        )  # fmt: skip
    return {"rows": rows, "probe": [m.name for m in models]}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.chaos", description=__doc__.split("\n", 1)[0]
    )
    ap.add_argument("--n", type=int, default=12, help="models per set")
    ap.add_argument("--split", default="validation")
    ap.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    columns = ["set", "perturbation", "n", "median d", "/ nearest same-class", "still own first",
               *BLOCKS]  # fmt: skip
    rows: list[list[Any]] = []
    probes = {}
    for name in args.sets:
        res = measure_set(name, args.split, args.n, args.workers)
        rows += res["rows"]
        probes[name] = res["probe"]
    print(
        format_table(f"Descriptor distance under small perturbations ({args.split})", columns, rows)
    )
    out = {
        "split": args.split,
        "config": dataclasses.asdict(mdbd_config()),
        "descriptor": VERSION,
        "columns": columns,
        "table": rows,
        "probes": probes,
    }
    write_json(args.out, out)
    return out


if __name__ == "__main__":
    main()
