"""The paper's Tables 2 and 3 on real and generated data, with baselines, in one run.

Usage (from the repository root)::

    python -m bench.retrieval --quick                  # small subsets, a few minutes
    python -m bench.retrieval                          # all three sets, test split
    python -m bench.retrieval --study                  # parameter study, validation split
    python -m bench.retrieval --stability              # = python -m bench.stability
    python -m bench.retrieval --baselines-only         # D2, SH, LFD only: no decomposition
    python -m bench.retrieval --peers --datasets generic --split validation

For each data set (generic, web, capod, articulated, parts) one table is printed, on the test split:
the MDBD kernel of Eq. 3 on meshes, on point clouds (20 % of the vertices), on an even
mixture, point-cloud queries against the mesh database; the GraKeL Shortest-Path,
WL-subtree and Pyramid Match kernels on the same MDBD graphs (labels r/r1 rounded to
1/25); D2, the spherical harmonic descriptor and the light field descriptor
(:mod:`bench.support.lightfield`) on the meshes; the seconds each method took; and the mean kernel value
between the mesh and the point cloud of the same model (paper: 0.996), beside the
same-class and other-class means. Everything is written to bench/results/retrieval.json.

``--peers`` prints one table per set of the published light field descriptor and its
simplified variants (:data:`bench.support.lightfield_peer.VARIANTS`): NN, 1-T, 2-T, DCG
and the seconds each took (descriptors and distances are cached, so a second run is
quick); written under ``"peers"`` in the JSON.

``--study`` varies the kernel and decomposition parameters one at a time on the
validation split; ``--stability`` runs :mod:`bench.stability`; :mod:`bench.studies.select_descriptors`
chooses one descriptor combination for all sets on their validation splits.

Decompositions are cached (bench/results/cache/, git-ignored) by source, representation
variant and :class:`~shapedb.config.core.MDBDConfig`; ``--no-refine`` turns off off-grid
refinement, which costs ~100 s per model on point clouds with the current PointCloud.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import (
    MEASURES,
    Balls,
    decompose_all,
    format_table,
    mdbd_config,
    retrieval_scores,
    write_json,
)
from bench.sets.datasets import Dataset, build_sets, mesh_arrays
from bench.support.baselines import (
    D2Config,
    SHConfig,
    d2_descriptor,
    grakel_similarity,
    l1_similarity,
    l2_similarity,
    sh_descriptor,
)
from bench.support.features import (
    complete,
    kernel_features,
    l1_matrix,
    mixture_mask,
    reconstructions,
)
from bench.support.lightfield import LFDConfig, lfd_descriptor, lfd_similarity
from shapedb.config.core import Config, DescriptorConfig, KernelConfig, MDBDConfig

RESULTS = Path(__file__).resolve().parent / "results"
COLUMNS = ("method", "NN", "1-T", "2-T", "E", "DCG", "seconds")


# --------------------------------------------------------------------------------------
# The paper's kernel (through the library when it is there)
# --------------------------------------------------------------------------------------


def kernel_matrix(
    fa: NDArray[np.float64], fb: NDArray[np.float64], lam: float
) -> NDArray[np.float64]:
    """Eq. 3, k = exp(-lam * d), between weighted feature rows."""
    return np.exp(-lam * l1_matrix(fa, fb))


def cloud_classes(
    meshes: NDArray[np.float64], clouds: NDArray[np.float64], labels: NDArray[Any]
) -> list[tuple[str, float, float]]:
    """NN by class of mesh queries and of cloud queries against the meshes.

    ``meshes`` and ``clouds`` are (n, n) similarities (row: the query; diagonal ignored,
    so a cloud query leaves its own mesh out). Returns ``(class, NN of meshes, NN of
    clouds)`` for every class of two or more, the clouds' largest loss first.
    """
    from query.evaluate import retrieval_scores as scores

    a, b = scores(meshes, labels).per_class, scores(clouds, labels).per_class
    rows = [(str(c), float(a[c]["nn"]), float(b[c]["nn"])) for c in a]
    return sorted(rows, key=lambda r: (r[2] - r[1], r[0]))


def _row(name: str, sim: NDArray[np.float64], labels: NDArray[Any], seconds: float) -> list[Any]:
    s = retrieval_scores(sim, labels)
    return [name, *(s[m] for m in MEASURES), seconds]


# --------------------------------------------------------------------------------------
# Tables 2 and 3
# --------------------------------------------------------------------------------------


def run_tables(
    ds: Dataset,
    mdbd: MDBDConfig,
    kcfg: KernelConfig,
    *,
    workers: int,
    grakel: bool,
    d2: D2Config,
    view_cells: float = 0.0,
    clouds: bool = True,
) -> dict[str, Any]:
    """One data set's table: MDBD kernel on every representation, and baselines.

    With ``view_cells`` the meshes' sparse views (:mod:`shapedb.geometry.view`) are decomposed
    too, and the cloud-query and mixture rows are repeated as a store with
    ``CloudConfig(view_cells=...)`` compares. Cloud-mesh pairs of shapedb's rows
    follow the store's rule (``query.search.engine``): the nearest of the own features, the
    cloud against the mesh's view (views rows) and the cloud's reconstruction against
    the mesh (``shapedb.mdbd.reconstruct``, variant ``pointcloud_recon``). The paper
    kernel's rows compare own features only, as the paper does. Without ``clouds``
    only the meshes are decomposed (no point-cloud rows). Beside shapedb's default
    descriptor the other of versions 4 and 5 is scored on the same balls.
    """
    t0 = time.perf_counter()
    mesh = decompose_all(ds.models, "mesh", mdbd, workers=workers)
    pc = decompose_all(ds.models, "pointcloud", mdbd, workers=workers) if clouds else mesh
    have_pc = any(b is not None for b in pc)
    if not clouds:
        have_pc = False
    elif not have_pc:
        print("  no point-cloud decomposition succeeded: point-cloud rows left out")
        pc = mesh
    view = mesh
    have_views = bool(view_cells) and have_pc
    if have_views:
        view = decompose_all(ds.models, f"view_{view_cells:g}", mdbd, workers=workers)
    recon = reconstructions(ds.models, pc, mdbd, workers=workers) if have_pc else pc
    ds, (mesh, pc, view, recon) = complete(ds, mesh, pc, view, recon)
    labels = ds.labels
    names = [m.name for m in ds.models]
    rows: list[list[Any]] = []

    same = labels[:, None] == labels[None, :]
    off = ~np.eye(len(labels), dtype=bool)
    mix = mixture_mask(names)
    calib: dict[str, dict[str, float]] = {}
    feat_s: dict[str, float] = {}
    # shapedb's default descriptor and the paper's kernel, side by side
    version = DescriptorConfig().version
    other = 4 if version == 5 else 5
    methods = [
        (f"shapedb v{version}", Config(kernel=kcfg)),
        (f"shapedb v{other}", Config(kernel=kcfg, descriptor=DescriptorConfig(version=other))),
        ("paper kernel", Config(kernel=dataclasses.replace(kcfg, method="paper"))),
    ]
    default_label = methods[0][0]
    by_class: list[tuple[str, float, float]] = []
    for label, full in methods:
        cfg = full.kernel
        t = time.perf_counter()
        fm = kernel_features(mesh, full)
        fp = kernel_features(pc, full)
        feat_s[label] = (time.perf_counter() - t) / 2
        k_mm = kernel_matrix(fm, fm, cfg.lam)
        k_pp = kernel_matrix(fp, fp, cfg.lam)
        k_pm = kernel_matrix(fp, fm, cfg.lam)
        fx = np.where(mix[:, None], fp, fm)
        k_xx = kernel_matrix(fx, fx, cfg.lam)
        one = mix[:, None] != mix[None, :]  # cloud-mesh pairs of the mixture
        if have_pc and label == default_label:  # the store's rule (query.search.engine)
            fr = kernel_features(recon, full)
            k_pm = np.maximum(k_pm, kernel_matrix(fr, fm, cfg.lam))
            k_rx = kernel_matrix(np.where(mix[:, None], fr, fm), fx, cfg.lam)
            k_xx = np.where(one, np.maximum(k_xx, np.maximum(k_rx, k_rx.T)), k_xx)
        rows.append(_row(f"{label}, meshes", k_mm, labels, feat_s[label]))
        if have_pc and label == default_label:
            by_class = cloud_classes(k_mm, k_pm, labels)
        if have_pc:
            rows.append(_row(f"{label}, point clouds", k_pp, labels, feat_s[label]))
            rows.append(_row(f"{label}, even mixture", k_xx, labels, feat_s[label]))
            rows.append(_row(f"{label}, pc query -> mesh db", k_pm, labels, feat_s[label]))
            if have_views and label == default_label:
                fv = kernel_features(view, full)
                k_pv = np.maximum(kernel_matrix(fp, fv, cfg.lam), k_pm)  # the nearest
                fy = np.where(mix[:, None], fp, fv)  # clouds, and the meshes' views
                k_xy = kernel_matrix(fx, fy, cfg.lam)  # own features against views
                k_yy = np.where(one, np.maximum(k_xx, np.maximum(k_xy, k_xy.T)), k_xx)
                name = f"{label}, views {view_cells:g} cells"
                rows.append(_row(f"{name}: pc query -> mesh db", k_pv, labels, feat_s[label]))
                rows.append(_row(f"{name}: even mixture", k_yy, labels, feat_s[label]))
                own_first = np.argmax(k_pv, axis=1) == np.arange(len(labels))
                calib["views"] = {"pc_query_own_mesh_ranked_first": float(own_first.mean())}
        calib[label] = {
            "same_model_mesh_vs_pc": float(np.diag(k_pm).mean()),
            "same_class_mesh_vs_mesh": float(k_mm[same & off].mean()),
            "other_class_mesh_vs_mesh": float(k_mm[~same].mean()),
            "pc_query_own_mesh_ranked_first": float(
                np.mean(np.argmax(k_pm, axis=1) == np.arange(len(labels)))
            ),
        }

    baselines: dict[str, float] = {}
    if grakel:
        runs = grakel_similarity([(b.radii, b.edges) for b in mesh])
        for name, run in runs.items():
            rows.append(_row(f"GraKeL {name}, meshes", run.matrix, labels, run.seconds))
            baselines[name] = run.seconds
    rows += mesh_baselines(ds, d2)

    if by_class:
        print()
        print(
            format_table(
                f"{ds.name}: NN by class, {default_label}, cloud queries against the meshes",
                ["class", "meshes", "pc query -> mesh db"],
                [list(r) for r in by_class],
            )
        )
    dec_mesh = float(np.mean([b.seconds for b in mesh]))
    dec_pc = float(np.mean([b.seconds for b in pc]))
    dec_view = float(np.mean([b.seconds for b in view])) if have_views else 0.0
    title = (
        f"{ds.name}: {len(ds)} models, {len(set(labels))} classes, res {mdbd.resolution}, "
        f"{mdbd.n_balls} balls, n_r {kcfg.n_r}"
    )
    print()
    print(format_table(title, COLUMNS, rows))
    for label, c in calib.items():
        if label == "views":
            first = c["pc_query_own_mesh_ranked_first"]
            print(f"views: pc query finds own mesh (its view) first {first:.3f}")
            continue
        print(
            f"{label}: mean k(mesh, pc) same model {c['same_model_mesh_vs_pc']:.3f} (paper 0.996); "
            f"same class {c['same_class_mesh_vs_mesh']:.3f}; other class "
            f"{c['other_class_mesh_vs_mesh']:.3f}; pc query finds own mesh first "
            f"{c['pc_query_own_mesh_ranked_first']:.3f}"
        )
    print(
        f"decomposition per model: mesh {dec_mesh:.2f} s, point cloud {dec_pc:.2f} s "
        f"(cached runs report the original time); features {feat_s[default_label] / len(ds) * 1e3:.2f} "
        f"ms/model (paper's Eq. 1: {feat_s['paper kernel'] / len(ds) * 1e3:.2f}); "
        f"mean balls {np.mean([len(b.radii) for b in mesh]):.0f}"
    )
    return {
        "models": len(ds),
        "classes": len(set(labels)),
        "config": {"mdbd": dataclasses.asdict(mdbd), "kernel": dataclasses.asdict(kcfg)},
        "table": [dict(zip(COLUMNS, r, strict=True)) for r in rows],
        "calibration": calib,
        "cloud_nn_by_class": {c: {"meshes": a, "pc_query_mesh_db": b} for c, a, b in by_class},
        "seconds_per_model": {
            "decompose_mesh": dec_mesh,
            "decompose_pointcloud": dec_pc,
            "decompose_view": dec_view,
            "features": feat_s[default_label] / len(ds),
            "features_paper": feat_s["paper kernel"] / len(ds),
        },
        "wall_seconds": time.perf_counter() - t0,
    }


def mesh_baselines(ds: Dataset, d2: D2Config) -> list[list[Any]]:
    """Rows of the descriptors computed from the meshes alone: D2, spherical harmonics, LFD.

    Each row is ``[name, NN, 1-T, 2-T, E, DCG, seconds]`` on ``ds`` (every model
    against every other); the seconds include the descriptors and the distances.
    """
    labels = ds.labels
    rows: list[list[Any]] = []
    t = time.perf_counter()
    dd = np.stack([d2_descriptor(*mesh_arrays(m), d2) for m in ds.models])
    rows.append(_row("D2 shape distribution, meshes", l1_similarity(dd), labels,
                     time.perf_counter() - t))  # fmt: skip
    t = time.perf_counter()
    sh = np.stack([sh_descriptor(*mesh_arrays(m), SHConfig()) for m in ds.models])
    rows.append(
        _row("spherical harmonics, meshes", l2_similarity(sh), labels, time.perf_counter() - t)
    )
    t = time.perf_counter()
    lfd = np.stack([lfd_descriptor(*mesh_arrays(m), LFDConfig()) for m in ds.models])
    lfd_s = time.perf_counter() - t
    t = time.perf_counter()
    rows.append(_row("light field descriptor, meshes", lfd_similarity(lfd), labels,
                     lfd_s + time.perf_counter() - t))  # fmt: skip
    print(f"  light fields: {lfd_s / len(ds) * 1e3:.0f} ms/model, distances "
          f"{time.perf_counter() - t:.0f} s")  # fmt: skip
    return rows


def run_baselines(ds: Dataset, d2: D2Config) -> dict[str, Any]:
    """One data set's table of :func:`mesh_baselines` only (no decomposition)."""
    t0 = time.perf_counter()
    rows = mesh_baselines(ds, d2)
    print()
    print(format_table(f"{ds.name}: {len(ds)} models, {len(set(ds.labels))} classes, "
                       "baselines only", COLUMNS, rows))  # fmt: skip
    return {
        "models": len(ds),
        "classes": len(set(ds.labels)),
        "table": [dict(zip(COLUMNS, r, strict=True)) for r in rows],
        "wall_seconds": time.perf_counter() - t0,
    }


def run_peers(ds: Dataset) -> dict[str, Any]:
    """One data set's table of the light field descriptor's variants (no decomposition)."""
    from bench.support.lightfield_peer import VARIANTS

    rows: list[list[Any]] = []
    for name, matrix in VARIANTS.items():
        t = time.perf_counter()
        d = matrix(list(ds.models))
        s = retrieval_scores(-d, ds.labels)
        rows.append([name, s["nn"], s["first_tier"], s["second_tier"], s["dcg"],
                     time.perf_counter() - t])  # fmt: skip
    columns = ("light field descriptor", "NN", "1-T", "2-T", "DCG", "seconds")
    print()
    print(format_table(f"{ds.name}: {len(ds)} models, {len(set(ds.labels))} classes, "
                       "the published LFD and its variants", columns, rows))  # fmt: skip
    return {"models": len(ds), "table": [dict(zip(columns, r, strict=True)) for r in rows]}


# --------------------------------------------------------------------------------------
# Parameter study (validation split only)
# --------------------------------------------------------------------------------------

STUDY = {
    "n_r": [4, 8, 16, 32, 64, 128, 256, 512],
    "t": [1, 3, 5, 10, 20, 50],
    "w": [0.5, 0.7, 0.9, 1.0],
    "la": [0.5, 0.75, 0.9, 0.95, 1.0],
    "lb": [0.5, 0.75, 0.9, 0.95, 1.0],
}


def run_study(
    ds: Dataset, mdbd: MDBDConfig, kcfg: KernelConfig, *, workers: int, resolutions: Sequence[int]
) -> list[dict[str, Any]]:
    """One-at-a-time variation of the kernel and decomposition parameters, validation split.

    ``lam`` is not varied: exp(-lam d) is monotone in d, so it changes no ranking (it
    only sets the calibration of the values). ``n_balls`` is varied by truncating the
    decomposition (MDBD is greedy, largest ball first, so a prefix is the smaller MDBD).
    """
    val = ds.split("validation")
    mesh = decompose_all(val.models, "mesh", mdbd, workers=workers)
    pc = decompose_all(val.models, "pointcloud", mdbd, workers=workers)
    val, (mesh, pc) = complete(val, mesh, pc)
    labels = val.labels
    out: list[dict[str, Any]] = []

    def score(name: str, value: Any, m: list[Balls], p: list[Balls], k: KernelConfig) -> None:
        fm, fp = kernel_features(m, k), kernel_features(p, k)
        s = retrieval_scores(kernel_matrix(fm, fm, 1.0), labels)
        x = retrieval_scores(kernel_matrix(fp, fm, 1.0), labels)
        out.append({"param": name, "value": value, **s, "pc_to_mesh_nn": x["nn"]})

    score("default", "-", mesh, pc, kcfg)
    for name, values in STUDY.items():
        for v in values:
            if name in ("la", "lb") or v != getattr(kcfg, name):
                score(name, v, mesh, pc, dataclasses.replace(kcfg, **{name: v}))
    for n in (32, 64, 128, 256):
        if n < mdbd.n_balls:
            score("n_balls", n, [b.truncate(n) for b in mesh], [b.truncate(n) for b in pc], kcfg)
    for res in resolutions:
        if res == mdbd.resolution:
            continue
        cfg = dataclasses.replace(mdbd, resolution=res)
        m2 = decompose_all(val.models, "mesh", cfg, workers=workers)
        p2 = decompose_all(val.models, "pointcloud", cfg, workers=workers)
        if any(b is None for b in m2 + p2):
            print(f"  resolution {res}: some decompositions failed; skipped")
            continue
        score("resolution", res, m2, p2, kcfg)  # type: ignore[arg-type]
    rows = [
        [r["param"], r["value"], r["nn"], r["first_tier"], r["dcg"], r["pc_to_mesh_nn"]]
        for r in out
    ]
    print()
    print(
        format_table(
            f"parameter study, {ds.name} validation split ({len(val)} models)",
            ("param", "value", "NN", "1-T", "DCG", "pc->mesh NN"),
            rows,
        )
    )
    return out


# --------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.retrieval", description=__doc__.split("\n")[0]
    )
    ap.add_argument(
        "--datasets",
        nargs="+",
        default=["generic", "capod", "articulated", "parts"],
        help="any of capod, articulated, people, parts, generic, web, webplus, enclosures",
    )
    ap.add_argument("--quick", action="store_true", help="small subsets and a coarse grid")
    ap.add_argument("--split", default="test", choices=["test", "validation", "all"])
    ap.add_argument("--resolution", type=int, default=None)
    ap.add_argument("--n-balls", type=int, default=None)
    ap.add_argument("--n-r", type=int, default=None)
    ap.add_argument(
        "--no-refine", action="store_true", help="MDBDConfig(refine=False): no off-grid refinement"
    )
    ap.add_argument("--subjects", type=int, default=15, help="articulated set: subjects")
    ap.add_argument("--poses", type=int, default=20, help="articulated set: poses per subject")
    ap.add_argument("--per-kind", type=int, default=12, help="parts set: models per kind")
    ap.add_argument("--probes", type=int, default=30, help="stability: models copied")
    ap.add_argument(
        "--study-resolutions", type=int, nargs="*", default=None, help="grid sizes in the study"
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-grakel", action="store_true")
    ap.add_argument(
        "--meshes-only", action="store_true", help="decompose meshes only: no point-cloud rows"
    )
    ap.add_argument(
        "--d2-pairs", type=int, default=None, help="D2 point pairs (default 1024**2; --quick 2**18)"
    )
    ap.add_argument(
        "--baselines-only",
        action="store_true",
        help="only the mesh descriptors D2, spherical harmonics and LFD (no decomposition)",
    )
    ap.add_argument(
        "--peers",
        action="store_true",
        help="only the published light field descriptor and its variants (no decomposition)",
    )
    ap.add_argument("--study", action="store_true", help="parameter study on the validation split")
    ap.add_argument("--stability", action="store_true", help="shift / rotation / decimation")
    ap.add_argument(
        "--views",
        type=float,
        default=4.0,
        help="also rows with sparse views every VIEWS grid cells (0: none)",
    )
    ap.add_argument("--out", type=Path, default=RESULTS / "retrieval.json")
    args = ap.parse_args(argv)

    base = MDBDConfig(resolution=64, n_balls=256) if args.quick else MDBDConfig()
    mdbd = mdbd_config(
        base, resolution=args.resolution, n_balls=args.n_balls, no_refine=args.no_refine
    )
    kcfg = KernelConfig() if args.n_r is None else KernelConfig(n_r=args.n_r)
    d2 = D2Config(n_pairs=args.d2_pairs or (2**18 if args.quick else 1024**2))
    report: dict[str, Any] = {"quick": args.quick, "split": args.split, "datasets": {}}
    for ds in build_sets(args.datasets, args.quick, args.subjects, args.poses, args.per_kind):
        entry: dict[str, Any] = {}
        if args.study:
            res = [48, 64, 96] if args.quick else [64, 96, 128]
            if args.study_resolutions is not None:
                res = args.study_resolutions
            entry["study"] = run_study(ds, mdbd, kcfg, workers=args.workers, resolutions=res)
        if args.stability:
            from bench.stability import run_stability

            entry["stability"] = run_stability(
                ds,
                mdbd,
                kcfg,
                workers=args.workers,
                probes=12 if args.quick else args.probes,
                view_cells=args.views,
            )
        if args.peers:
            entry["peers"] = run_peers(ds.split(args.split))
        elif args.baselines_only:
            entry["baselines"] = run_baselines(ds.split(args.split), d2)
        elif not (args.study or args.stability or args.peers):
            entry["tables"] = run_tables(
                ds.split(args.split),
                mdbd,
                kcfg,
                workers=args.workers,
                grakel=not args.no_grakel,
                d2=d2,
                view_cells=args.views,
                clouds=not args.meshes_only,
            )
        report["datasets"][ds.name] = entry
        out = args.out
        if out.exists():  # keep other data sets' results from earlier runs
            import json

            old = json.loads(out.read_text())
            old_sets = old.get("datasets", {})
            for k, v in old_sets.items():
                if k not in report["datasets"]:
                    report["datasets"][k] = v
                elif k == ds.name:
                    report["datasets"][k] = {**v, **entry}
        write_json(out, report)
    print(f"\nwritten {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
