"""The product's re-ranking stage per set, against the descriptor alone and the mesh LFD.

Usage (from the repository root)::

    python -m bench.studies.rerank_stage --split test --mesh-lfd        # the six sets and their mixes
    python -m bench.studies.rerank_stage --split test --datasets webplus figures people   # held out

Every bench set's split (meshes; the cached balls of :func:`bench.support.cached.load`,
nothing decomposed) is a store of its own, and so are the mixes of
:data:`bench.support.stores.MIXES` among the sets named (web + figures, web + people,
generic + parts, all six). In each store every shape queries the others: its ``K = 100``
nearest by version 4's stored distance (ties by ascending id, as
``query.search.rerank.search`` hands them over; with the product's field vectors, and
the union with their ``K2`` nearest) are re-ranked by the product's ``"lightfield"``
stage at the product's numbers (:class:`query.search.rerank_lightfield.LightFieldFusion`
at :data:`query.search.tuning.PRODUCT`, its gate the product's own), and scored (NN /
1-T / DCG) per set inside the store.

Rows, in the same run: version 4 alone (the descriptor, no stage); the stage's distance
alone; an ungated rank fusion; on the fused distance, the stage before the field
vectors; with ``--mesh-lfd``, the mesh light field descriptor ranking every shape: the
published method of Chen et al. 2003 (filled-polygon silhouettes at 256 px, 10 light
fields, Zernike and Fourier bytes: :func:`bench.support.lightfield_peer.peer_split_matrix`),
and with ``--mesh-lfd-splat`` also the earlier, simplified splat peer
(:func:`bench.support.lightfield.lfd_split_matrix`); the stage without and with its shared-neighbour term
(:data:`bench.support.stores.STAGE_NOW`: the product, :data:`query.search.tuning.PRODUCT`).
A row's "worst" is its largest loss against version 4, in queries of one set. Written to
bench/results/rerank_<split>.json (``--out``). The grids and the gates before the
product's are :mod:`bench.studies.lightfield_gate`.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import write_json
from bench.support.cached import load
from bench.support.stores import (
    CHOICES,
    SETS,
    Split,
    Store,
    gate_weights,
    product_split,
    rows_table,
    score_row,
    shared_rows,
    split_stores,
)
from query.search.tuning import PRODUCT

__all__ = ["mesh_lfd_row", "baseline_rows", "measure", "parser", "main"]

RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


def mesh_lfd_row(split: Split, sets: Sequence[str], names: dict[str, tuple[str, ...]],
                 base: dict[str, dict[str, dict[str, float]]], *,
                 matrix: Callable[[list[Any]], np.ndarray] | None = None) -> dict[str, Any]:  # fmt: skip
    """The mesh light field descriptor's row: every shape of each store ranked by it
    alone, scored like the stage's rows. ``matrix`` gives the (n, n) distances of the
    sets' models; by default the published method
    (:func:`bench.support.lightfield_peer.peer_split_matrix`); the earlier splat peer is
    :func:`bench.support.lightfield.lfd_split_matrix`."""
    import copy

    from bench.support.lightfield_peer import peer_split_matrix

    models = [m for s in sets for m in load(s, split.split)[0].models]
    peer = copy.copy(split)
    peer.dl = (matrix or peer_split_matrix)(models)
    peer.dv = None
    stores = {
        k: Store(peer, peer.store(v), candidates=len(peer.store(v))) for k, v in names.items()
    }
    return score_row(stores, {k: np.full(len(st.rows), np.inf) for k, st in stores.items()}, base)


def baseline_rows(split: Split, datasets: Sequence[str], *, mesh_lfd: bool = False,
                  mesh_lfd_splat: bool = False) -> tuple[
    dict[str, Store], dict[str, Any], dict[str, dict[str, Any]]
]:  # fmt: skip
    """The stores of ``split`` and the rows every run of the stage scores them against.

    Rows (:func:`score_row`): version 4 alone (no stage); the stage's distance alone
    among the candidates; an ungated rank fusion at weight 0.5; on a fused split, the
    stage before the field vectors (the light field distance, K alone, at the product's
    gate); with ``mesh_lfd``, the published mesh light field descriptor ranking every
    shape; with ``mesh_lfd_splat``, the earlier splat peer likewise.

    Returns the stage's stores, the rule's base and the rows.
    """
    import copy

    names, stores, v4, base = split_stores(split, datasets)
    stage = getattr(split, "stage", None)
    k2 = stage.candidates if stage is not None else 0
    zero = {k: np.zeros(len(st.rows)) for k, st in stores.items()}
    rows: dict[str, dict[str, Any]] = {
        "v4 (no stage)": score_row(v4, zero, base),
        ("light fields alone (K = 100)" if stage is None else
         f"the stage's distance alone (K = 100, K2 = {k2})"): score_row(
            stores, {k: np.full(len(st.rows), np.inf) for k, st in stores.items()}, base),
        "rank fusion 0.5, ungated": score_row(
            stores, {k: np.full(len(st.rows), 0.5) for k, st in stores.items()}, base),
    }  # fmt: skip
    if stage is not None:  # the product before the field vectors, in the same run
        before = copy.copy(split)
        before.dl, before.dv = split.light, None
        plain = {k: Store(before, before.store(v)) for k, v in names.items()}
        rows["the stage before the field vectors (light field distance, K = 100)"] = score_row(
            plain, {k: gate_weights(st, PRODUCT) for k, st in plain.items()}, base
        )
    if mesh_lfd:  # the peer: every shape ranked by the published mesh LFD
        rows["mesh light field descriptor, published (every shape ranked)"] = mesh_lfd_row(
            split, datasets, names, base
        )
    if mesh_lfd_splat:
        from bench.support.lightfield import lfd_split_matrix

        rows["mesh light field descriptor, splats (every shape ranked)"] = mesh_lfd_row(
            split, datasets, names, base, matrix=lfd_split_matrix
        )
    return stores, base, rows


def measure(split_name: str, datasets: Sequence[str], *, mesh_lfd: bool = False,
            mesh_lfd_splat: bool = False) -> dict[str, Any]:  # fmt: skip
    """The stage's rows on every store of ``datasets``' split; prints the table.

    Returns the JSON written by :func:`main`: the split, the rows (:func:`score_row`
    entries by label), the product's stage numbers, its field vectors' stage and the
    stores' sizes.
    """
    t0 = time.perf_counter()
    split = product_split(split_name, datasets)
    stores, base, rows = baseline_rows(
        split, datasets, mesh_lfd=mesh_lfd, mesh_lfd_splat=mesh_lfd_splat
    )
    print(f"  {len(split.sets)} shapes, {len(stores)} stores ({time.perf_counter() - t0:.0f} s)")
    default = PRODUCT
    rows.update(shared_rows(stores, split, default, base))
    print(rows_table(
        f"the lightfield stage, {split_name} splits, each set and mix a store (NN / 1-T / DCG)",
        rows, stores,
    ))  # fmt: skip
    stage = getattr(split, "stage", None)
    return {"split": split_name, "rows": rows, "defaults": dataclasses.asdict(default),
            "field_stage": None if stage is None else dataclasses.asdict(stage),
            "sizes": {k: len(st.rows) for k, st in stores.items()}}  # fmt: skip


def parser() -> argparse.ArgumentParser:
    """The command line of :func:`main`."""
    ap = argparse.ArgumentParser(
        prog="python -m bench.studies.rerank_stage", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--split", default="test", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(SETS), choices=CHOICES)
    ap.add_argument(
        "--mesh-lfd",
        action="store_true",
        help="the peer's row: every shape ranked by the published mesh light field "
        "descriptor (Chen et al. 2003)",
    )
    ap.add_argument("--mesh-lfd-splat", action="store_true",
                    help="also the earlier splat peer's row (bench.support.lightfield)")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    args = parser().parse_args(argv)
    result = measure(
        args.split, args.datasets, mesh_lfd=args.mesh_lfd, mesh_lfd_splat=args.mesh_lfd_splat
    )
    out = args.out or RESULTS / f"rerank_{args.split}.json"
    write_json(out, result)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
