"""Retrieval quality of the product's store, set by set, against the view-based peer.

Usage (from the repository root)::

    python -m bench.quality --split validation                  # default store, every family
    python -m bench.quality --split validation --set sheet_rule=enclosed --against sheet_rule=local
    python -m bench.quality --split test --peer                 # with the light field descriptor

Each set's split (meshes) is ingested through :meth:`query.database.Database.ingest` into a
store of its own, with the store options of ``--set`` (the default store without), and
scored with :meth:`Database.evaluate`: every shape queries the others exactly as
``db.search`` ranks them (:mod:`bench.support.product_stores`; stores are cached by
models, options and code). ``--against`` builds a second store per set with other options
in the same run; ``--peer`` ranks the same meshes with the light field descriptor
(Chen et al. 2003, as published: :func:`bench.support.lightfield_peer.peer_split_matrix`).

``--queries`` searches other representations of every model against the store of the
split's meshes (:mod:`bench.support.scan_queries`: clouds sampled evenly, at 20 % of
the vertices or falling off with distance, one-sided depth scans, cropped halves), its
own mesh left out of its hits; the mesh -> mesh row (``db.evaluate``) is the baseline::

    python -m bench.quality --split validation --datasets capod --queries mesh one-sided cropped

``--partial on|off`` forces ``db.search``'s part path on or off (``auto``: the search
decides). Written to ``bench/results/quality_<split>_queries.json``.

A *family* is one of the bench's sets; the objective is the macro average over the families
of ``(NN + 1-T + DCG) / 3``, and a change must not cost any family more than
:data:`MAX_FAMILY_LOSS` NN. Written to ``bench/results/quality_<split>.json`` (``--out``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import format_table, write_json
from bench.support.scan_queries import QUERY_KINDS

__all__ = [
    "FAMILIES",
    "HELD_OUT",
    "MAX_FAMILY_LOSS",
    "parse_options",
    "family_split",
    "family_rows",
    "query_rows",
    "main",
]

RESULTS = Path(__file__).resolve().parent / "results"
#: The families a design change is judged on (every set with a validation split).
FAMILIES = ("generic", "web", "enclosures", "capod", "parts", "figures", "people")
#: Sets with a test split only: never chosen on, read on request (``--datasets webplus``).
HELD_OUT = ("webplus",)
#: Largest NN a family may lose to a change (the design rule the objective is held to).
MAX_FAMILY_LOSS = 0.02

_DATASET = {"figures": "articulated"}
_PARTIAL = {"auto": None, "on": True, "off": False}


def parse_options(pairs: Sequence[str]) -> dict[str, Any]:
    """``["k=v", ...]`` as store options, numbers parsed (``SystemExit`` on a bad pair)."""
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise SystemExit(f"--set/--against: expected key=value, got {pair!r}")
        for kind in (int, float):
            try:
                out[key] = kind(value)
                break
            except ValueError:
                continue
        else:
            out[key] = {"true": True, "false": False}.get(value.lower(), value)
    return out


def family_split(name: str, split: str) -> Any:
    """The validation or test split of a family (``SystemExit`` when it has none)."""
    from bench.sets.datasets import load_dataset

    ds = load_dataset(_DATASET.get(name, name)).split(split)
    if not len(ds):
        raise SystemExit(f"{name} has no {split} split")
    return ds


def _peer_scores(ds: Any) -> dict[str, Any]:
    from bench.common import retrieval_scores
    from bench.support.lightfield_peer import peer_split_matrix

    d = peer_split_matrix(list(ds.models))
    s = retrieval_scores(-d, ds.labels)
    return {k: s[k] for k in ("nn", "first_tier", "second_tier", "dcg")}


def family_rows(
    names: Sequence[str], split: str, options: dict[str, Any], against: dict[str, Any] | None,
    peer: bool,
) -> dict[str, dict[str, Any]]:  # fmt: skip
    """Per family: ``{"store": scores, "against": scores?, "peer": scores?}``."""
    from bench.support.product_stores import split_store, store_scores

    rows: dict[str, dict[str, Any]] = {}
    for name in names:
        ds = family_split(name, split)
        print(f"{name} ({split}, {len(ds)} models)", flush=True)
        row = {"store": store_scores(split_store(ds, options))}
        if against is not None:
            row["against"] = store_scores(split_store(ds, against))
        if peer:
            row["peer"] = _peer_scores(ds)
        rows[name] = row
    return rows


def query_rows(
    names: Sequence[str], split: str, options: dict[str, Any], kinds: Sequence[str],
    partial: bool | None,
) -> dict[str, dict[str, Any]]:  # fmt: skip
    """Per family, per query kind: its scores (``mesh``: the store's ``db.evaluate``)."""
    from bench.support.product_stores import split_store, store_scores
    from bench.support.scan_queries import kind_scores

    rows: dict[str, dict[str, Any]] = {}
    for name in names:
        ds = family_split(name, split)
        print(f"{name} ({split}, {len(ds)} models)", flush=True)
        db = split_store(ds, options)
        row: dict[str, Any] = {"mesh": {**store_scores(db), "median_ms": None}}
        for kind in kinds:
            if kind != "mesh":
                print(f"  {kind} queries", flush=True)
                row[kind] = kind_scores(db, ds, kind, partial=partial)
        rows[name] = row
    return rows


def _query_table(rows: dict[str, dict[str, Any]], kinds: Sequence[str]) -> str:
    names = list(rows)
    header = ["query", *(c for n in names for c in (f"{n} NN / 1-T / DCG", f"{n} ms"))]
    body = []
    for kind in kinds:
        cells: list[Any] = [f"{kind} -> mesh"]
        for n in names:
            s = rows[n][kind]
            ms = s["median_ms"]
            cells += [
                f"{s['nn']:.3f} / {s['first_tier']:.3f} / {s['dcg']:.3f}",
                None if ms is None else f"{ms:.0f}",
            ]
        body.append(cells)
    return format_table("NN / 1-T / DCG and median search ms, per query kind", header, body)


def _objective(s: dict[str, Any]) -> float:
    return (s["nn"] + s["first_tier"] + s["dcg"]) / 3


def _table(rows: dict[str, dict[str, Any]], columns: Sequence[str]) -> str:
    def cell(s: dict[str, Any]) -> str:
        return f"{s['nn']:.3f} / {s['first_tier']:.3f} / {s['dcg']:.3f}"

    body = [[name, *(cell(r[c]) for c in columns)] for name, r in rows.items()]
    macro = {c: float(np.mean([_objective(r[c]) for r in rows.values()])) for c in columns}
    body.append(["macro objective", *(f"{macro[c]:.4f}" for c in columns)])
    return format_table("NN / 1-T / DCG", ["family", *columns], body)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m bench.quality", description=__doc__.split("\n")[0])
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(FAMILIES), choices=FAMILIES + HELD_OUT)
    ap.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="store options of the measured store (default: the default store)",
    )
    ap.add_argument(
        "--against",
        nargs="*",
        default=None,
        metavar="KEY=VALUE",
        help="store options of a second store per set, in the same run",
    )
    ap.add_argument("--peer", action="store_true", help="rank with the light field descriptor too")
    ap.add_argument(
        "--queries",
        nargs="+",
        default=["mesh"],
        choices=QUERY_KINDS,
        help="query kinds searched against the meshes' store (mesh: the leave-one-out alone)",
    )
    ap.add_argument(
        "--partial",
        default="auto",
        choices=sorted(_PARTIAL),
        help="db.search's partial= in --queries mode (auto: the search decides)",
    )
    ap.add_argument("--out", type=Path, default=None)
    return ap  # fmt: skip


def _query_main(args: argparse.Namespace, options: dict[str, Any]) -> int:
    if args.against is not None or args.peer:
        raise SystemExit("--queries: --against and --peer are not measured in this mode")
    kinds = ["mesh", *(k for k in dict.fromkeys(args.queries) if k != "mesh")]
    partial = _PARTIAL[args.partial]
    rows = query_rows(args.datasets, args.split, options, kinds, partial)
    print(_query_table(rows, kinds))
    for name, row in rows.items():
        for kind in kinds:
            if row[kind].get("paths"):
                print(f"{name} {kind}: search paths {row[kind]['paths']}")
    out = {
        "split": args.split,
        "options": options,
        "queries": kinds,
        "partial": args.partial,
        "families": rows,
    }
    write_json(args.out or RESULTS / f"quality_{args.split}_queries.json", out)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    options = parse_options(args.set)
    if args.queries != ["mesh"]:
        return _query_main(args, options)
    against = None if args.against is None else parse_options(args.against)
    rows = family_rows(args.datasets, args.split, options, against, args.peer)
    columns = [
        "store",
        *(["against"] if against is not None else []),
        *(["peer"] if args.peer else []),
    ]
    print(_table(rows, columns))
    out: dict[str, Any] = {
        "split": args.split,
        "options": options,
        "against": against,
        "families": rows,
    }
    if against is not None:
        loss = {n: r["against"]["nn"] - r["store"]["nn"] for n, r in rows.items()}
        worst = max(loss, key=loss.__getitem__)
        out["worst_family_nn_loss"] = {"family": worst, "loss": loss[worst]}
        ok = loss[worst] <= MAX_FAMILY_LOSS
        print(f"worst family: {worst} loses {loss[worst]:+.3f} NN ({'within' if ok else 'over'} "
              f"the {MAX_FAMILY_LOSS} allowed)")  # fmt: skip
    write_json(args.out or RESULTS / f"quality_{args.split}.json", out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
