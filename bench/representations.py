"""Representation agnosticism: does a sparse scan find its shape, and its person?

One table per set (``people``, ``capod``, ``figures``, ``parts``), all in one run.
Each method compares query clouds with the mesh database as a store does:

``mesh->mesh``
    meshes against the other meshes;
``cloud->mesh``
    the paper's clouds (a random 20 % of each mesh's vertices) against the meshes;
``noisy->mesh``
    those clouds with Gaussian noise of 0.3 % of the bounding-box diagonal;
``partial->mesh``
    the part of the cloud one horizontal depth camera sees (the far side missing,
    :func:`bench.sets.people.partial_cloud`);
``one-sided->mesh`` (``--kinds one-sided``)
    what one depth camera sees from a random viewpoint, with range and incidence
    fall-off and depth noise (:func:`bench.sets.scans.one_sided_scan`);
``cropped->mesh`` (``--kinds cropped``)
    half of the mesh, cut by a random plane (:func:`bench.sets.scans.cropped_mesh`);
``mixture``
    an even, seeded half of the models as clouds, the rest as meshes, all against all.

Every query leaves its own model out (PSB NN / first tier / DCG, :mod:`bench.common`);
``own-first`` is the fraction of cloud queries whose nearest mesh, their own
included, is their own (meaningful on sets without duplicates: people, figures,
parts; CAPOD holds re-posed copies and exact duplicates). Methods:

``default``
    today's default store: the descriptor of :mod:`shapedb.signature.descriptor`; a sparse
    cloud and a mesh are as far apart as the nearer of the cloud's own feature and
    its kept reconstruction's (:mod:`shapedb.mdbd.reconstruct`, :mod:`query.search.engine`),
    the descriptor alone: the product's search then re-ranks that list with the light
    fields in a store of meshes, which this bench does not (``python -m bench.quality
    --queries even vertex`` measures the product's path);
``paper``
    the paper's kernel (Eq. 1-3, ``KernelConfig(method="paper")``), own features;
``D2``
    Osada's D2 shape distribution (2^18 point pairs, surface samples of the mesh,
    points of the cloud), L1;

and the candidates a run adds (``--methods``): ``mean`` (the default store, a sparse
cloud's own and kept reconstruction's features averaged instead of the nearer of
the two taken), ``pose-free`` (the default descriptor without its pose blocks
``d2c_mean`` and ``inertia``), ``pose-free mean`` (both), ``v6`` (a store with
descriptor version 6: ``pose-free`` as a descriptor version, rescaled, same ranking),
``own`` / ``d8`` / ``d7`` (a store without reconstructions, or with them at Poisson
depth 8 / 7) and ``v6 own`` / ``v6 d8`` / ``v6 d7`` (the same with version 6).
Cost columns: median seconds of the cached decompositions' own stages per mesh and
per cloud query (the cloud's, plus its reconstruction's, Poisson solve included,
when the method uses it), and their ratio to the first method; they come from
different runs, so only the live cost rows below compare like with like.

Cost rows (``--cost N``, default 6): the first N models of each set through the
facade in one run (:mod:`bench.support.cost`): median wall seconds of ``db.ingest`` of
a mesh, ``db.search`` of a mesh and ``db.search`` of its 20 % cloud, and the
per-model ratio cloud / mesh query, for the default store and the cloud
configurations of :data:`COST_CONFIGS`.

Usage: ``python -m bench.representations [--sets people capod figures parts]
[--split test] [--kinds cloud noisy partial] [--methods default v6 ...] [--workers 2]
[--cost N] [--cached [--engine-commits C ...]] [--out PATH]``.
Decompositions come from :func:`bench.common.decompose_all` (cached).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import (
    Balls,
    decompose_all,
    existing_cache_path,
    format_table,
    load_balls,
    mdbd_config,
    recon_variant,
    retrieval_scores,
    variant_geometry,
    write_json,
)
from bench.sets.datasets import (
    PEOPLE_EXTRA_VALIDATION,
    Dataset,
    Model,
    articulated,
    capod,
    generic,
    mesh_arrays,
    parts,
    people,
)
from bench.support.baselines import D2Config, d2_descriptor
from bench.support.features import kernel_features, l1_matrix, mixture_mask
from shapedb.config.core import Config, KernelConfig, MDBDConfig

OUT = Path(__file__).resolve().parent / "results" / "representations.json"

#: Query kinds and the decomposition variants of their clouds and reconstructions
#: (at Poisson depth 8; :func:`kind_recon` for others).
KINDS = {
    "cloud": ("pointcloud", "pointcloud_recon"),
    "noisy": ("pointcloud_noisy", "pointcloud_noisy_recon"),
    "partial": ("pointcloud_partial", "pointcloud_partial_recon"),
    "one-sided": ("pointcloud_scan", "pointcloud_scan_recon"),
    "cropped": ("mesh_cropped", "mesh_cropped_recon"),  # a mesh: never reconstructed
}
#: The kinds a run measures unless ``--kinds`` says otherwise.
DEFAULT_KINDS = ("cloud", "noisy", "partial")


def kind_recon(kind: str, depth: int) -> str:
    """The decomposition variant of a ``kind``'s reconstructions at Poisson ``depth``."""
    return recon_variant(KINDS[kind][0], depth)


#: Point pairs of the D2 baseline (fewer than Osada's 2^20: it ranks alike and is 4x faster).
D2_PAIRS = 1 << 18


@dataclass
class SetData:
    """One split of one set: its models, mesh balls and per-kind cloud balls.

    ``clouds[kind]`` and ``recons[depth][kind]`` (Poisson octree ``depth``) hold one
    entry per model; a recon entry is None where the store keeps no reconstruction
    (dense cloud, failed solve, volume disagreement).
    """

    ds: Dataset
    mesh: list[Balls]
    clouds: dict[str, list[Balls]]
    recons: dict[int, dict[str, list[Balls | None]]]

    @property
    def labels(self) -> NDArray[Any]:
        return self.ds.labels


#: Engines (git commits) whose cached decompositions ``--cached`` also reads
#: (``--engine-commits``; :func:`bench.common.existing_cache_path`).
ENGINE_COMMITS: list[str] = []


def cached_only(models: Sequence[Model], variant: str, mdbd: MDBDConfig) -> list[Balls | None]:
    """The cached decompositions of ``models`` in ``variant``; None where none is cached.

    Keys of the engines in :data:`ENGINE_COMMITS` are tried where today's has none.
    """
    paths = [existing_cache_path(m, variant, mdbd, ENGINE_COMMITS) for m in models]
    return [load_balls(p, mdbd.contact_tol_cells) if p.exists() else None for p in paths]


def load_set(
    ds: Dataset,
    mdbd: MDBDConfig,
    kinds: Sequence[str],
    workers: int,
    *,
    cached: bool = False,
    depths: Sequence[int] = (8,),
) -> SetData:
    """Decompose (or read from the cache) every variant the requested ``kinds`` need.

    Reconstructions at each Poisson octree depth of ``depths``. Models whose mesh or
    cloud decomposition failed (``cached``: is not in the cache) are left out of
    every row; with ``cached`` a reconstruction not in the cache counts as not kept.
    """
    from shapedb.geometry.view import is_sparse
    from shapedb.mdbd.reconstruct import volumes_agree

    def get(models: Sequence[Model], variant: str) -> list[Balls | None]:
        if cached:
            return cached_only(models, variant, mdbd)
        return decompose_all(models, variant, mdbd, workers=workers)

    mesh = get(ds.models, "mesh")
    raw = {k: get(ds.models, KINDS[k][0]) for k in kinds}
    keep = [
        i
        for i in range(len(ds))
        if mesh[i] is not None and all(raw[k][i] is not None for k in kinds)
    ]
    if len(keep) < len(ds):
        print(f"  {ds.name}: {len(ds) - len(keep)} model(s) left out (a decomposition failed)")
    sub = Dataset(ds.name, tuple(ds.models[i] for i in keep))
    recons: dict[int, dict[str, list[Balls | None]]] = {d: {} for d in depths}
    for k in kinds:
        sparse = [is_sparse(raw[k][i].sampling, raw[k][i].spacing) for i in keep]  # type: ignore[union-attr]
        todo = [m for m, s in zip(sub.models, sparse, strict=True) if s]
        for depth in depths:
            found = dict(zip([m.name for m in todo], get(todo, kind_recon(k, depth)), strict=True))
            out: list[Balls | None] = []
            for i, m in zip(keep, sub.models, strict=True):
                r = found.get(m.name)
                c = raw[k][i]
                ok = r is not None and c is not None and volumes_agree(c.radii, r.radii)
                out.append(r if ok else None)
            recons[depth][k] = out
    return SetData(
        sub,
        [mesh[i] for i in keep],  # type: ignore[misc]
        {k: [raw[k][i] for i in keep] for k in kinds},  # type: ignore[misc]
        recons,
    )


# --------------------------------------------------------------------------------------
# Methods: a method turns a SetData into distance matrices
# --------------------------------------------------------------------------------------


@dataclass
class Distances:
    """What a method gives for one set: (n, n) distances and per-model costs.

    ``mesh`` meshes x meshes; ``cloud[kind]`` clouds (rows) x meshes; ``cloud_cloud``
    the paper's clouds x themselves (for the mixture); ``ingest`` / ``query[kind]``
    seconds per model.
    """

    mesh: NDArray[np.float64]
    cloud: dict[str, NDArray[np.float64]]
    cloud_cloud: NDArray[np.float64]
    ingest: NDArray[np.float64]
    query: dict[str, NDArray[np.float64]]


def _feature_seconds(balls: Sequence[Balls], config: KernelConfig | Config) -> float:
    t0 = time.perf_counter()
    kernel_features(balls[: min(8, len(balls))], config)
    return (time.perf_counter() - t0) / min(8, len(balls))


def cost(balls: Balls) -> float:
    """Seconds of a decomposition's own stages (not of making its input), wall clock."""
    return float(sum(balls.timings.values())) if balls.timings else balls.seconds


def pose_free_mask(config: KernelConfig) -> NDArray[np.float64]:
    """Column mask of the default descriptor without its pose blocks (``d2c_mean``, ``inertia``)."""
    from shapedb.signature.descriptor import LAYOUTS

    cols: list[float] = []
    for name, size, _typical, _weight in LAYOUTS[4]:
        cols += [0.0 if name in ("d2c_mean", "inertia") else 1.0] * size
    return np.asarray(cols)


def default_depth() -> int | None:
    """The Poisson depth of a default store's reconstructions; None when it keeps none."""
    cloud = Config().cloud
    return cloud.reconstruct_depth if cloud.reconstruct else None


def store_rule(
    data: SetData,
    config: KernelConfig | Config,
    *,
    reconstruct: bool = True,
    depth: int | None = None,
    combine: str = "nearest",
    mask: NDArray[np.float64] | None = None,
) -> Distances:
    """Distances as a store with ``config`` compares a cloud and its reconstruction.

    ``reconstruct``: whether clouds have reconstructions, at Poisson ``depth``
    (default: the default store's, :func:`default_depth`). ``combine`` ``"nearest"`` (the store's rule): the nearer of the cloud's own
    feature and its kept reconstruction's; ``"mean"``: the mean of the two features
    (two packings of the query averaged). ``mask`` (dim,) multiplies every feature
    (e.g. :func:`pose_free_mask`).
    """
    scale = np.ones(1) if mask is None else mask
    fm = kernel_features(data.mesh, config) * scale
    per = _feature_seconds(data.mesh, config)
    cloud, query = {}, {}
    for k, balls in data.clouds.items():
        fc = kernel_features(balls, config) * scale
        d = l1_matrix(fc, fm)
        secs = np.array([cost(b) + per for b in balls])
        if reconstruct:
            rec = data.recons[depth or default_depth() or 8][k]
            idx = [i for i, r in enumerate(rec) if r is not None]
            if idx:
                fr = kernel_features([rec[i] for i in idx], config) * scale  # type: ignore[misc]
                if combine == "mean":
                    d[idx] = l1_matrix(0.5 * (fc[idx] + fr), fm)
                else:
                    d[idx] = np.minimum(d[idx], l1_matrix(fr, fm))
            # every sparse cloud pays its reconstruction, kept or not
            # (the Poisson solve included: a reconstruction's input is made at query time)
            secs = secs + np.array([r.seconds + per if r is not None else 0.0 for r in rec])
        cloud[k], query[k] = d, secs
    fc = kernel_features(data.clouds["cloud"], config) * scale if "cloud" in data.clouds else fm
    return Distances(
        l1_matrix(fm, fm),
        cloud,
        l1_matrix(fc, fc),
        np.array([cost(b) + per for b in data.mesh]),
        query,
    )


def default_method(data: SetData) -> Distances:
    """Today's default store."""
    return store_rule(data, KernelConfig(), reconstruct=default_depth() is not None)


def recon_method(depth: int | None, descriptor: int = 4) -> Callable[[SetData], Distances]:
    """A store with descriptor ``descriptor`` and reconstructions at ``depth`` (None: none)."""

    def method(data: SetData) -> Distances:
        config = Config().with_options(descriptor=descriptor)
        return store_rule(data, config, reconstruct=depth is not None, depth=depth)

    method.__doc__ = f"descriptor {descriptor}, reconstructions at depth {depth}"
    return method


def mean_method(data: SetData) -> Distances:
    """The default store, a cloud's own and reconstruction's features averaged."""
    return store_rule(data, KernelConfig(), combine="mean")


def pose_free_method(data: SetData) -> Distances:
    """The default store without the pose blocks (``d2c_mean``, ``inertia``)."""
    return store_rule(data, KernelConfig(), mask=pose_free_mask(KernelConfig()))


def pose_free_mean_method(data: SetData) -> Distances:
    """Both: no pose blocks, a cloud's two features averaged."""
    return store_rule(data, KernelConfig(), combine="mean", mask=pose_free_mask(KernelConfig()))


def v6_method(data: SetData) -> Distances:
    """A store with descriptor version 6 (no pose blocks; opt-in)."""
    depth = default_depth()
    return store_rule(data, Config().with_options(descriptor=6), reconstruct=depth is not None)


def paper_method(data: SetData) -> Distances:
    """The paper's kernel on own features."""
    return store_rule(data, KernelConfig(method="paper"), reconstruct=False)


def d2_points(points: NDArray[np.float64], config: D2Config) -> NDArray[np.float64]:
    """D2 of a point set: distances between random pairs of its points, as a PDF."""
    rng = np.random.default_rng(config.seed)
    i = rng.integers(0, len(points), size=(config.n_pairs, 2))
    d = np.linalg.norm(points[i[:, 0]] - points[i[:, 1]], axis=1)
    d = d[d > 0]
    hist, _ = np.histogram(d / d.mean(), bins=config.bins, range=(0.0, config.max_ratio))
    pdf = hist.astype(np.float64).reshape(config.vertices, -1).sum(axis=1)
    return pdf / max(pdf.sum(), 1e-300)


def _d2_query(geometry: Any, cfg: D2Config) -> NDArray[np.float64]:
    """D2 of a query: a cloud's own points, a (cropped) mesh's surface samples."""
    points = getattr(geometry, "points", None)
    if points is not None:
        return d2_points(np.asarray(points), cfg)
    return d2_descriptor(np.asarray(geometry.vertices), np.asarray(geometry.faces), cfg)


def d2_method(data: SetData) -> Distances:
    """Osada's D2 (surface samples of meshes, the cloud's own points)."""
    cfg = D2Config(n_pairs=D2_PAIRS)
    mdbd = MDBDConfig()
    t0 = time.perf_counter()
    fm = np.stack([d2_descriptor(*mesh_arrays(m), cfg) for m in data.ds.models])
    per_mesh = (time.perf_counter() - t0) / len(fm)
    cloud, query = {}, {}
    for k in data.clouds:
        t0 = time.perf_counter()
        fc = np.stack([_d2_query(variant_geometry(m, KINDS[k][0], mdbd), cfg)
                       for m in data.ds.models])  # fmt: skip
        cloud[k] = l1_matrix(fc, fm)
        query[k] = np.full(len(fc), (time.perf_counter() - t0) / len(fc))
        if k == "cloud":
            fcc = fc
    cc = l1_matrix(fcc, fcc) if "cloud" in data.clouds else l1_matrix(fm, fm)
    return Distances(l1_matrix(fm, fm), cloud, cc, np.full(len(fm), per_mesh), query)


#: Methods by name; candidates register here.
METHODS: dict[str, Callable[[SetData], Distances]] = {
    "default": default_method,
    "mean": mean_method,
    "pose-free": pose_free_method,
    "pose-free mean": pose_free_mean_method,
    "paper": paper_method,
    "D2": d2_method,
    "v6": v6_method,
    "own": recon_method(None),
    "d8": recon_method(8),
    "d7": recon_method(7),
    "v6 own": recon_method(None, 6),
    "v6 d8": recon_method(8, 6),
    "v6 d7": recon_method(7, 6),
}


def method_depths(methods: Sequence[str]) -> list[int]:
    """The Poisson depths whose reconstructions ``methods`` read."""
    out = {default_depth() or 8}
    for m in methods:
        if m.endswith(("d8", "d7")):
            out.add(int(m[-1]))
    return sorted(out)


# --------------------------------------------------------------------------------------
# Scores
# --------------------------------------------------------------------------------------


def score_rows(name: str, dist: Distances, labels: NDArray[Any]) -> list[list[Any]]:
    """Table rows of one method: one per query kind, then the mixture (labels (n,))."""

    def scores(d: NDArray[np.float64]) -> list[float]:
        s = retrieval_scores(-d, labels)
        return [s["nn"], s["first_tier"], s["dcg"]]

    n = len(labels)
    rows = [[name, "mesh->mesh", *scores(dist.mesh), None, float(np.median(dist.ingest))]]
    for k, d in dist.cloud.items():
        own = float(np.mean(np.argmin(d, axis=1) == np.arange(n)))
        rows.append([name, f"{k}->mesh", *scores(d), own, float(np.median(dist.query[k]))])
    if "cloud" in dist.cloud:
        pc = mixture_mask([str(i) for i in range(n)])  # only the count matters
        mix = np.where(
            pc[:, None] & pc[None, :],
            dist.cloud_cloud,
            np.where(~pc[:, None] & ~pc[None, :], dist.mesh, 0.0),
        )
        cross = dist.cloud["cloud"]  # cloud rows x mesh columns
        mix = np.where(pc[:, None] & ~pc[None, :], cross, mix)
        mix = np.where(~pc[:, None] & pc[None, :], cross.T, mix)
        rows.append([name, "mixture", *scores(mix), None, None])
    return rows


def build(names: Sequence[str], split: str) -> list[Dataset]:
    """The requested sets' ``split``."""
    makers: dict[str, Callable[[], Dataset]] = {
        "people": people,
        "people-xl": lambda: people(extra_validation=PEOPLE_EXTRA_VALIDATION),
        "capod": capod,
        "figures": articulated,
        "parts": parts,
        "generic": generic,
    }
    return [makers[n]().split(split) for n in names]


#: Store configurations whose query cost ``--cost`` measures (``shapedb.connect`` options).
COST_CONFIGS: dict[str, dict[str, Any]] = {
    "default": {},
    "reconstruct_depth=8": {"reconstruct": True, "reconstruct_depth": 8},
    "reconstruct_depth=7": {"reconstruct": True, "reconstruct_depth": 7},
    "reconstruct=False": {"reconstruct": False},
}


def cost_table(ds: Dataset, n: int) -> tuple[str, list[list[Any]]]:
    """Live cost rows (:func:`bench.support.cost.measure`) of the first ``n`` models of ``ds``.

    Per configuration of :data:`COST_CONFIGS` (those equal to the default left out):
    median wall seconds of a mesh ingest, a mesh query and a cloud query, the median
    and largest per-model ratio cloud / mesh query, the cloud query's median against
    the default's, then a one-sided scan's and a half mesh's query and their median
    ratios to the mesh query.
    """
    from bench.support.cost import measure

    base = Config()
    configs = {
        k: v
        for k, v in COST_CONFIGS.items()
        if k == "default" or Config().with_options(**v) != base
    }
    got = measure(ds.models[:n], configs)
    rows: list[list[Any]] = []
    ref = float(np.median(got["default"]["cloud"]))
    for name, t in got.items():
        mesh = np.asarray(t["mesh"])
        ratio = {k: np.asarray(t[k]) / mesh for k in ("cloud", "one-sided", "cropped")}
        cloud = float(np.median(t["cloud"]))
        rows.append(
            [
                name,
                float(np.median(t["ingest"])),
                float(np.median(mesh)),
                cloud,
                float(np.median(ratio["cloud"])),
                float(np.max(ratio["cloud"])),
                cloud / ref,
                float(np.median(t["one-sided"])),
                float(np.median(ratio["one-sided"])),
                float(np.median(t["cropped"])),
                float(np.median(ratio["cropped"])),
            ]
        )
    title = (
        f"{ds.name}: cost of the first {n} models through the facade, one run, wall s "
        "(db.ingest of a mesh; db.search of a mesh, of its 20 % cloud, of a one-sided "
        "scan of it and of its half)"
    )
    return title, rows


COST_COLUMNS = (
    "store",
    "mesh ingest",
    "mesh query",
    "cloud query",
    "cloud/mesh (median)",
    "cloud/mesh (max)",
    "x default",
    "one-sided query",
    "one-sided/mesh",
    "cropped query",
    "cropped/mesh",
)


def run(
    datasets: Sequence[Dataset],
    methods: Sequence[str],
    kinds: Sequence[str],
    *,
    mdbd: MDBDConfig,
    workers: int,
    cached: bool = False,
    cost_models: int = 0,
    cost_only: bool = False,
) -> dict[str, Any]:
    """Every set's table (printed) and the JSON-ready results.

    ``cost_models`` > 0 adds each set's live cost rows (:func:`cost_table`);
    ``cost_only``: those rows alone, no retrieval table.
    """
    out: dict[str, Any] = {}
    columns = ("method", "query", "NN", "1-T", "DCG", "own-first", "cost s", "x default")
    for ds in datasets:
        if cost_only:
            title, crows = cost_table(ds, cost_models)
            print(format_table(title, COST_COLUMNS, crows))
            out[ds.name] = {"cost": {"columns": list(COST_COLUMNS), "table": crows}}
            continue
        data = load_set(ds, mdbd, kinds, workers, cached=cached, depths=method_depths(methods))
        rows: list[list[Any]] = []
        base: dict[str, float] = {}
        for name in methods:
            for r in score_rows(name, METHODS[name](data), data.labels):
                if name == methods[0] and r[6] is not None:
                    base[r[1]] = r[6]
                ratio = r[6] / base[r[1]] if r[6] is not None and base.get(r[1]) else None
                rows.append([*r, ratio])
        print(
            format_table(
                f"{ds.name} ({len(data.ds)} models, {len(set(data.labels))} classes): "
                "queries against the mesh database; cost = mesh ingest / cloud query",
                columns,
                rows,
            )
        )
        print()
        out[ds.name] = {"n": len(data.ds), "columns": list(columns), "table": rows}
        if cost_models > 0:
            title, crows = cost_table(data.ds, cost_models)
            print(format_table(title, COST_COLUMNS, crows))
            print()
            out[ds.name]["cost"] = {"columns": list(COST_COLUMNS), "table": crows}
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--sets",
        nargs="+",
        default=["people", "capod", "figures", "parts"],
        help="also people-xl (validation: 12 more subjects) and generic",
    )
    ap.add_argument("--split", default="test", choices=("all", "test", "validation"))
    ap.add_argument("--kinds", nargs="+", default=list(DEFAULT_KINDS), choices=list(KINDS))
    ap.add_argument("--methods", nargs="+", default=["default", "paper", "D2"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--cost",
        type=int,
        default=6,
        metavar="N",
        help="live cost rows on the first N models of each set (0: none)",
    )
    ap.add_argument(
        "--cost-only", action="store_true", help="the live cost rows alone (no retrieval)"
    )
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument(
        "--cached", action="store_true", help="decompose nothing: use what is in the cache"
    )
    ap.add_argument(
        "--engine-commits",
        nargs="*",
        default=[],
        help="with --cached: also read what the engines of these commits cached",
    )
    args = ap.parse_args(argv)
    ENGINE_COMMITS[:] = args.engine_commits
    unknown = [m for m in args.methods if m not in METHODS]
    if unknown:
        raise SystemExit(f"unknown method(s) {unknown}: choose from {sorted(METHODS)}")
    mdbd = mdbd_config()
    results = run(
        build(args.sets, args.split),
        args.methods,
        args.kinds,
        mdbd=mdbd,
        workers=args.workers,
        cached=args.cached,
        cost_models=args.cost,
        cost_only=args.cost_only,
    )
    write_json(
        args.out,
        {
            "split": args.split,
            "kinds": args.kinds,
            "methods": args.methods,
            "mdbd": dataclasses.asdict(mdbd),
            "sets": results,
        },
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
