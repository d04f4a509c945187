"""Subcommands that measure and tune retrieval on the stored labels: ``eval``, ``fit-metric``."""

from __future__ import annotations

import argparse

from query.cli.common import (
    Subparsers,
    add_command,
    add_db_argument,
    existing_store,
    print_json,
)

__all__ = ["register", "evaluate", "fit_metric"]


def register(subparsers: Subparsers) -> None:
    """Add ``eval`` and ``fit-metric``."""
    s = add_command(subparsers, "eval", evaluate, help="leave-one-out retrieval scores by label")
    add_db_argument(s)
    s.add_argument("--label", default="label", help="column or metadata key of the class")
    s.add_argument("--metric", metavar="JSON", help="a similarity saved by fit-metric")
    s.add_argument("--json", action="store_true")
    s.add_argument("--plot", metavar="PNG", help="save the precision-recall curve")

    s = add_command(
        subparsers,
        "fit-metric",
        fit_metric,
        help="learn block weights of the similarity from the stored labels",
    )
    add_db_argument(s)
    s.add_argument("--label", default="label", help="column or metadata key of the class")
    s.add_argument("--out", required=True, metavar="JSON", help="where to save the metric")
    s.add_argument("--json", action="store_true")


def evaluate(args: argparse.Namespace) -> int:
    """``shapedb eval``."""
    db = existing_store(args.db)
    scores = db.evaluate(label=args.label, plot=args.plot, metric=args.metric)
    out = scores.to_dict()
    if args.json:
        print_json(out)
        return 0
    print(f"queries: {out.get('queries')}")
    for key in ("nn", "first_tier", "second_tier", "e_measure", "dcg"):
        if key in out:
            print(f"{key:12s} {out[key]:.4f}")
    if args.plot:
        print(f"precision-recall curve: {args.plot}")
    return 0


def fit_metric(args: argparse.Namespace) -> int:
    """``shapedb fit-metric``."""
    metric = existing_store(args.db).fit_metric(label=args.label)
    path = metric.save(args.out)
    out = metric.to_dict()
    if args.json:
        print_json(out)
        return 0
    print(
        f"{metric.n_shapes} shapes, {metric.n_classes} classes, "
        f"{metric.n_extra} sparse views as extra queries"
    )
    if metric.learned:
        print(f"cross-validated: reg {metric.reg:g}")
        for (name, _), w in zip(metric.blocks, metric.weights, strict=True):
            print(f"  {name:16s} {w:.3f}")
    else:
        print("cross-validation found no gain over the default: the metric is the identity")
    print(f"saved to {path}")
    return 0
