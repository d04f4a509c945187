"""Quantitative part matching (paper 3.3, which showed it only in pictures).

**Articulated figures.** ``shapedb.examples.figure(subject, pose)`` is a union of
primitives (torso, head, shoulders, and per side upper arm, forearm, thigh, shin).
Every ball of a decomposition is labelled by the primitive it lies deepest in
(largest primitive SDF at its centre); left and right share a label, since MDBD
features are reflection invariant (the paper notes the same ambiguity). For every
model A and every primitive, the query is the neighbourhood G_A[N(v, 2)] of the
primitive's largest ball v; in every other model B the best-matching node u
(Algorithm 1 restricted to v, n_r = 10, K = 2) is found, and the match is correct
when u carries the same label. Reported: accuracy per part and mean, for implicit
solids, meshes, point clouds and mesh -> point cloud; the baseline, measured in the
same run, is chance (the fraction of B's balls with the query's label).

**Holes through the complement.** For plates from ``examples.part("plate", seed)``
(through holes and slots), the complement in the padded bounding box is decomposed;
its balls are labelled ``hole`` (inside a hole cylinder, within the plate's
thickness), ``slot`` (inside the slot) or ``outside``. Each hole's largest ball is a
query; accuracy is how often the best match in every other plate's complement is a
hole ball (and hole-or-slot), against chance. On the solid itself a hole has no ball
at all, so it cannot be queried there.

Run ``python -m bench.parts`` (about 3 minutes on 2 cores; decompositions are cached
in bench/results/cache/dec). Prints tables and writes ``bench/results/parts.json``.
"""

from __future__ import annotations

import argparse
import logging
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import Balls, decompose_all, format_table, write_json
from bench.datasets import Model
from shapedb import examples
from shapedb.complement import Complement
from shapedb.config import MDBDConfig, PartConfig
from shapedb.implicit import Box, Cylinder
from shapedb.kernel import weights
from shapedb.mdbd import decompose
from shapedb.subgraph import neighbourhood_features, neighbourhoods

logger = logging.getLogger(__name__)

RESULTS = Path(__file__).resolve().parent / "results"
#: Label of each primitive of ``examples.figure``, in construction order.
FIGURE_PARTS = ("torso", "head", "torso") + ("upper_arm", "forearm", "thigh", "shin") * 2
LABELS = ("head", "torso", "upper_arm", "forearm", "thigh", "shin")


def figure_labels(subject: int, pose: int, centers: NDArray[np.float64]) -> NDArray[np.str_]:
    """Part label of each ball centre (n, 3): the primitive it lies deepest in."""
    g = examples.figure(subject, pose)
    sdf = np.stack([c.signed_distance(centers) for c in g.children], axis=1)
    return np.asarray(FIGURE_PARTS, dtype=object)[np.argmax(sdf, axis=1)].astype(str)


class _Graph:
    """Balls, labels, part features and query nodes of one decomposed model."""

    def __init__(
        self, balls: Balls, labels: NDArray[np.str_], queries: list[int], cfg: PartConfig
    ) -> None:
        self.labels = labels
        self.queries = queries
        self.features = neighbourhood_features((balls.radii, balls.edges), cfg)
        self.members = neighbourhoods((balls.radii, balls.edges), cfg.hops)


def accuracy(
    queries: Sequence[_Graph], targets: Sequence[_Graph], cfg: PartConfig, *, same: bool
) -> dict[str, Any]:
    """Per-label accuracy of best matches (and chance), over all query/target pairs.

    ``same``: queries and targets are the same list (skip a model against itself).
    """
    w = weights(cfg.kernel)
    hit: dict[str, list[float]] = {}
    chance: dict[str, list[float]] = {}
    for a, qa in enumerate(queries):
        for b, tb in enumerate(targets):
            if same and a == b:
                continue
            for v in qa.queries:
                lab = qa.labels[v]
                u = int(np.argmin(np.abs(tb.features - qa.features[v]) @ w))
                hit.setdefault(lab, []).append(float(tb.labels[u] == lab))
                chance.setdefault(lab, []).append(float(np.mean(tb.labels == lab)))
    per = {k: float(np.mean(v)) for k, v in hit.items()}
    return {
        "per_part": per,
        "chance": {k: float(np.mean(v)) for k, v in chance.items()},
        "mean": float(np.mean(list(per.values()))),
        "chance_mean": float(np.mean([np.mean(v) for v in chance.values()])),
        "queries": int(sum(len(v) for v in hit.values())),
    }


def figures(
    subjects: int, poses: int, mdbd: MDBDConfig, cfg: PartConfig, workers: int
) -> dict[str, Any]:
    models = [
        Model(name=f"s{s:02d}_p{p:02d}", label=f"subject{s:02d}", source=f"figure:{s}:{p}")
        for s in range(subjects)
        for p in range(poses)
    ]
    sets: dict[str, list[_Graph]] = {}
    t0 = time.perf_counter()
    for variant in ("implicit", "mesh", "pointcloud"):
        if variant == "implicit":
            balls: list[Balls | None] = []
            for m in models:
                _, s, p = m.source.split(":")
                d = decompose(examples.figure(int(s), int(p)), config=mdbd)
                balls.append(Balls(d.centers, d.radii, d.edges.astype(np.int64), d.spacing, 0.0))
        else:
            balls = decompose_all(models, variant, mdbd, workers=workers, progress=None)
        graphs = []
        for m, b in zip(models, balls, strict=True):
            if b is None:
                raise RuntimeError(f"decomposition of {m.name} ({variant}) failed")
            _, s, p = m.source.split(":")
            g = examples.figure(int(s), int(p))
            labels = figure_labels(int(s), int(p), b.centers)
            sdf = np.stack([c.signed_distance(b.centers) for c in g.children], axis=1)
            owner = np.argmax(sdf, axis=1)
            queries = []
            for k in range(len(g.children)):
                idx = np.flatnonzero(owner == k)
                if len(idx) and k != 2:  # every primitive but the shoulder bar
                    queries.append(int(idx[np.argmax(b.radii[idx])]))
            graphs.append(_Graph(b, labels, queries, cfg))
        sets[variant] = graphs
    logger.info("figures decomposed in %.1f s", time.perf_counter() - t0)
    out = {
        "implicit": accuracy(sets["implicit"], sets["implicit"], cfg, same=True),
        "mesh": accuracy(sets["mesh"], sets["mesh"], cfg, same=True),
        "pointcloud": accuracy(sets["pointcloud"], sets["pointcloud"], cfg, same=True),
        "mesh->pointcloud": accuracy(sets["mesh"], sets["pointcloud"], cfg, same=True),
    }
    n_balls = {k: float(np.mean([len(g.labels) for g in v])) for k, v in sets.items()}
    return {"models": len(models), "mean_balls": n_balls, "results": out}


def _plate_labels(g: Any, centers: NDArray[np.float64]) -> NDArray[np.str_]:
    """hole / slot / outside for complement balls of ``examples.part("plate", s)``."""
    body, tools = g.children
    plate = body.children[0] if hasattr(body, "children") else body
    assert isinstance(plate, Box)
    t = 2 * plate.half[2]
    tool_list = tools.children if hasattr(tools, "children") else (tools,)
    slot_box = [c for c in tool_list if isinstance(c, Box)]
    lab = np.full(len(centers), "outside", dtype=object)
    within = (centers[:, 2] > 0) & (centers[:, 2] < t)
    for c in tool_list:
        inside = (c.signed_distance(centers) > 0) & within
        kind = "hole"
        if isinstance(c, Box):
            kind = "slot"
        elif isinstance(c, Cylinder) and slot_box:
            sb = slot_box[0]
            if (
                abs(c.a[1] - sb.center[1]) < 1e-9
                and abs(abs(c.a[0] - sb.center[0]) - sb.half[0]) < 1e-9
            ):
                kind = "slot"
        lab[inside & (lab == "outside")] = kind
    return lab.astype(str)


def holes(n_plates: int, mdbd: MDBDConfig, cfg: PartConfig) -> dict[str, Any]:
    graphs = []
    for s in range(n_plates):
        g = examples.part("plate", s)
        d = decompose(Complement(g, padding=0.05), config=mdbd)
        labels = _plate_labels(g, d.centers)
        queries = []
        for c in g.children[1].children:  # the largest ball of each hole / slot tool
            inside = np.flatnonzero((c.signed_distance(d.centers) > 0) & (labels != "outside"))
            if len(inside):
                queries.append(int(inside[np.argmax(d.radii[inside])]))
        b = Balls(d.centers, d.radii, d.edges.astype(np.int64), d.spacing, 0.0)
        graphs.append(_Graph(b, labels, sorted(set(queries)), cfg))
    res = accuracy(graphs, graphs, cfg, same=True)
    # a looser criterion: a hole matched to any through feature (hole or slot)
    w = weights(cfg.kernel)
    through, chance = [], []
    for a, qa in enumerate(graphs):
        for b, tb in enumerate(graphs):
            if a == b:
                continue
            for v in qa.queries:
                if qa.labels[v] != "hole":
                    continue
                u = int(np.argmin(np.abs(tb.features - qa.features[v]) @ w))
                through.append(tb.labels[u] != "outside")
                chance.append(np.mean(tb.labels != "outside"))
    # set level: the matched neighbourhood N(u, K) contains a hole ball
    covers, covers_chance = [], []
    for a, qa in enumerate(graphs):
        for b, tb in enumerate(graphs):
            if a == b:
                continue
            has_hole = np.asarray(tb.members @ (tb.labels == "hole").astype(np.float32)).ravel() > 0
            for v in qa.queries:
                if qa.labels[v] != "hole":
                    continue
                u = int(np.argmin(np.abs(tb.features - qa.features[v]) @ w))
                covers.append(bool(has_hole[u]))
                covers_chance.append(float(np.mean(has_hole)))
    res["hole->part_containing_hole"] = float(np.mean(covers)) if covers else None
    res["hole->part_containing_hole_chance"] = float(np.mean(covers_chance)) if covers else None
    res["hole->through_feature"] = float(np.mean(through)) if through else None
    res["hole->through_feature_chance"] = float(np.mean(chance)) if chance else None
    res["plates"] = n_plates
    res["mean_balls"] = float(np.mean([len(g.labels) for g in graphs]))
    return res


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--subjects", type=int, default=2)
    ap.add_argument("--poses", type=int, default=8)
    ap.add_argument("--plates", type=int, default=8)
    ap.add_argument("--resolution", type=int, default=80)
    ap.add_argument("--n-balls", type=int, default=256)
    ap.add_argument("--hops", type=int, default=2)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "parts.json")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    mdbd = MDBDConfig(resolution=args.resolution, n_balls=args.n_balls)
    cfg = PartConfig(hops=args.hops)
    fig = figures(args.subjects, args.poses, mdbd, cfg, args.workers)
    rows = []
    for setting, r in fig["results"].items():
        rows.append(
            [setting]
            + [r["per_part"].get(lab) for lab in LABELS]
            + [r["mean"], r["chance_mean"], r["queries"]]
        )
    logger.info(
        "\n%s",
        format_table(
            f"Part matching, figures ({fig['models']} models: {args.subjects} subjects x "
            f"{args.poses} poses; res {args.resolution}, K={args.hops}, n_r={cfg.n_r}): "
            "best match on the same part",
            ["setting", *LABELS, "mean", "chance", "queries"],
            rows,
        ),
    )
    hole = holes(args.plates, mdbd, cfg)
    rows = [
        [lab, hole["per_part"].get(lab), hole["chance"].get(lab)]
        for lab in ("hole", "slot")
        if lab in hole["per_part"]
    ]
    rows.append(
        [
            "hole->part with a hole",
            hole["hole->part_containing_hole"],
            hole["hole->part_containing_hole_chance"],
        ]
    )
    rows.append(
        ["hole->hole|slot", hole["hole->through_feature"], hole["hole->through_feature_chance"]]
    )
    logger.info(
        "\n%s",
        format_table(
            f"Holes through the complement ({args.plates} plates, res {args.resolution})",
            ["query", "accuracy", "chance"],
            rows,
        ),
    )
    write_json(
        args.out,
        {"config": {"mdbd": mdbd.__dict__, "part": cfg.__dict__}, "figures": fig, "holes": hole},
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
