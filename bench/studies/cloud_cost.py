"""Where a cloud query's time goes, against a mesh query's, stage by stage.

:func:`profile_cloud_query` splits a cloud query into its stages (the cloud's own
field, packing and refinement; the Poisson solve; the reconstruction's
decomposition; their features), as ``query.search.engine`` runs them;
``python -m bench.studies.cloud_cost [--sets ...] [--n 4]`` prints its medians per set.
The live cost of whole queries through the facade is ``python -m bench.representations
--cost`` (:func:`bench.support.cost.measure`).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from bench.sets.datasets import Model
from bench.support.cost import geometries

__all__ = ["main", "profile_cloud_query"]


def profile_cloud_query(model: Model, *, depth: int = 8) -> dict[str, float]:
    """Wall seconds of each stage of a cloud query of ``model``'s paper cloud (and its mesh's).

    Keys: ``mesh`` (the mesh's decomposition and feature), ``cloud frame``, ``cloud sdf``,
    ``cloud packing`` and ``cloud refine`` (its own decomposition), ``poisson``,
    ``recon decomposition``, ``features`` (the two features of the cloud).
    """
    from shapedb.mdbd.decomposition import decompose
    from shapedb.mdbd.reconstruct import reconstruct
    from shapedb.signature.kernel import features

    mesh, cloud, *_ = geometries(model)
    t0 = time.perf_counter()
    features(decompose(mesh))
    out = {"mesh": time.perf_counter() - t0}
    d = decompose(cloud)
    t = d.timings
    out.update(
        {
            "cloud frame": t.get("frame", 0.0),
            "cloud sdf": t["sdf"],
            "cloud packing": t["decompose"] - t["refine"],
            "cloud refine": t["refine"],
        }
    )
    frame = np.asarray(d.frame)
    rotation, centre = frame[:3, :3], frame[:3, 3]
    t0 = time.perf_counter()
    surface = reconstruct(cloud.transformed(rotation.T, -rotation.T @ centre), depth=depth)
    out["poisson"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    r = decompose(surface) if surface is not None else None
    out["recon decomposition"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    features(d)
    if r is not None:
        features(r)
    out["features"] = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> None:
    """Print the median stage seconds of cloud queries (:func:`profile_cloud_query`)."""
    import argparse

    from bench.common import format_table, write_json
    from bench.sets.datasets import articulated, capod, parts, people

    makers = {"people": people, "capod": capod, "figures": articulated, "parts": parts}

    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.cloud_cost",
        description="Where a cloud query's time goes, per set.",
    )
    ap.add_argument(
        "--sets",
        nargs="+",
        default=["people", "capod", "figures", "parts"],
        choices=["people", "capod", "figures", "parts"],
    )
    ap.add_argument("--split", default="validation", choices=("test", "validation"))
    ap.add_argument("--n", type=int, default=4, help="models per set")
    ap.add_argument("--depth", type=int, nargs="+", default=[8, 7])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    rows, out = [], {}
    for ds in (makers[name]().split(args.split) for name in args.sets):
        for depth in args.depth:
            runs = [profile_cloud_query(m, depth=depth) for m in ds.models[: args.n]]
            med = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
            cloud = sum(v for k, v in med.items() if k != "mesh")
            rows.append([ds.name, depth, *med.values(), cloud, cloud / med["mesh"]])
            out[f"{ds.name} depth {depth}"] = med
    keys = list(next(iter(out.values())))
    print(
        format_table(
            f"Stages of a cloud query, median wall s of {args.n} models per set (one thread)",
            ("set", "Poisson depth", *keys, "cloud query", "x mesh"),
            rows,
        )
    )
    write_json(args.out, {"split": args.split, "n": args.n, "stages": out})


#: Where :func:`main` writes its JSON.
OUT = Path(__file__).resolve().parents[1] / "results" / "studies" / "cloud_cost_profile.json"

if __name__ == "__main__":
    main()
