"""Subcommands that measure and tune retrieval on the stored labels: ``eval``, ``fit-metric``."""

from __future__ import annotations

import argparse
from typing import Any

from query.cli.common import add_db_argument, existing_store, format_table, print_json

__all__ = [
    "evaluate_arguments",
    "fit_metric_arguments",
    "evaluate",
    "fit_metric",
    "scores_line",
    "SCORE_COLUMNS",
]

#: The measures in tables, by key of ``RetrievalScores.to_dict()``, with their short names.
SCORE_COLUMNS = {"nn": "NN", "first_tier": "1-T", "second_tier": "2-T", "dcg": "DCG"}


def evaluate_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``eval``."""
    add_db_argument(s)
    s.add_argument(
        "--label", default="label", help="column or metadata key of the class (default label)"
    )
    s.add_argument("--metric", metavar="JSON", help="a similarity saved by fit-metric")
    s.add_argument("--json", action="store_true")
    s.add_argument("--plot", metavar="PNG", help="save the precision-recall curve")


def fit_metric_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``fit-metric``."""
    add_db_argument(s)
    s.add_argument(
        "--label", default="label", help="column or metadata key of the class (default label)"
    )
    s.add_argument("--out", required=True, metavar="JSON", help="where to save the metric")
    s.add_argument("--json", action="store_true")


def scores_line(scores: dict[str, Any]) -> str:
    """One line of the mean scores, e.g. ``NN 0.667  1-T 0.833  2-T 0.917  DCG 0.922``."""
    return "  ".join(f"{short} {scores[key]:.3f}" for key, short in SCORE_COLUMNS.items())


def evaluate(args: argparse.Namespace) -> int:
    """``shapedb eval``."""
    db = existing_store(args.db)
    scores = db.evaluate(label=args.label, plot=args.plot, metric=args.metric)
    out = scores.to_dict()
    if args.json:
        print_json(out)
        return 0
    per_class = out["per_class"]
    print(
        f"leave-one-out retrieval by {args.label!r}: {out['queries']} queries "
        f"in {len(per_class)} classes"
    )
    print(f"{scores_line(out)}  E {out['e_measure']:.3f}")
    print()
    columns = ["class", "queries", *SCORE_COLUMNS]
    rows = [{"class": name, **row} for name, row in per_class.items()]
    rows.append({"class": "(all)", **out})
    for row in rows:
        row["queries"] = int(row["queries"])
    headers = ["class", "queries", *SCORE_COLUMNS.values()]
    for line in format_table(rows, columns, headers=headers, floats=".3f"):
        print(line)
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
