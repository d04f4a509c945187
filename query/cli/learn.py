"""Subcommands of the classifiers (``shapedb[learn]``): ``train``, ``classify``."""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING, Any

from query.cli.common import (
    Subparsers,
    add_command,
    add_db_argument,
    existing_store,
    print_json,
    query_arg,
)
from shapedb.results import ShapeRef

if TYPE_CHECKING:
    from query.learn.budget import Progress

__all__ = ["register", "train", "classify"]

#: Default of ``shapedb train --budget`` (query.learn.budget.DEFAULT_BUDGET, 300 s).
DEFAULT_BUDGET = "5m"
#: Candidate classifiers, simplest first (query.learn.selection.CANDIDATES; kept here so that
#: building the parser does not import query).
METHODS = ("1-nn", "3-nn", "5-nn", "linear", "boosting", "tag", "arma", "spline", "tag+descriptor")


def register(subparsers: Subparsers) -> None:
    """Add ``train`` and ``classify``."""
    s = add_command(
        subparsers,
        "train",
        train,
        help="train the classifier that validates best: k-NN, linear, boosting or a graph CNN "
        "(needs shapedb[learn])",
    )
    add_db_argument(s)
    s.add_argument("--label", default="label", help="column or metadata key of the class")
    s.add_argument(
        "--methods",
        nargs="+",
        choices=METHODS,
        metavar="M",
        help=f"candidates (default all; 1-nn always): {', '.join(METHODS)}",
    )
    s.add_argument(
        "--conv",
        choices=["tag", "arma", "spline"],
        help="only 1-nn and this graph CNN (the earlier interface)",
    )
    s.add_argument(
        "--folds", default="auto", help="validation folds (1: one holdout split; default auto)"
    )
    s.add_argument("--test", type=float, default=0.15, help="fraction held out for testing")
    s.add_argument("--epochs", type=int, metavar="N", help="graph-CNN training epochs")
    s.add_argument("--no-rotate", action="store_true", help="no random-rotation augmentation")
    s.add_argument(
        "--budget",
        default=DEFAULT_BUDGET,
        type=_duration,
        metavar="TIME",
        help="time to choose and fit, e.g. 90s, 5m, 1h (default %(default)s); the graph CNNs "
        "run only while it allows, unless named in --methods",
    )
    s.add_argument(
        "--restart",
        action="store_true",
        help="ignore the folds an earlier run scored (OUT.selection.json)",
    )
    s.add_argument("--out", required=True, metavar="PT", help="where to save the model")
    s.add_argument(
        "--json", action="store_true", help="print the selection report (seconds per candidate)"
    )

    s = add_command(subparsers, "classify", classify, help="label models with a trained classifier")
    s.add_argument("model", nargs="+", metavar="MODEL", help="model files, or stored ids or names")
    add_db_argument(s)
    s.add_argument("--model", dest="classifier", required=True, metavar="PT", help="trained model")
    s.add_argument("--json", action="store_true", help="one JSON line per model")


def _duration(text: str) -> float:
    """``--budget``: seconds of "90s", "5m", "1h"."""
    from query.learn.budget import parse_duration
    from shapedb.errors import ConfigError

    try:
        return parse_duration(text)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc


class _Bar:
    """The progress of ``shapedb train`` on a terminal: a bar of the time budget.

    Off a terminal (or with ``--json``) the selection's log lines report instead:
    the ``query.learn`` loggers are raised to INFO so that they reach stderr.
    """

    def __init__(self, budget: float, quiet: bool) -> None:
        import logging

        from tqdm import tqdm

        self.terminal = not quiet and sys.stderr.isatty()
        total = None if math.isinf(budget) else round(budget)
        self.bar = tqdm(
            desc="training",
            total=total,
            bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} s{postfix}",
            disable=not self.terminal,
        )
        if not self.terminal:
            logging.getLogger("query.learn.budget").setLevel(logging.INFO)

    def __call__(self, p: Progress) -> None:
        self.bar.set_description(p.where())
        score = "n/a" if math.isnan(p.score) else f"{p.score:.3f}"
        left = "-" if math.isinf(p.left) else f"{max(p.left, 0):.0f}s"
        self.bar.set_postfix(val=score, left=left, refresh=False)
        self.bar.update(max(0, round(p.spent) - self.bar.n))

    def close(self) -> None:
        self.bar.close()


def train(args: argparse.Namespace) -> int:
    """``shapedb train``: a bar of the time budget on a terminal, log lines off it."""
    options: dict[str, Any] = {"out": args.out, "test": args.test, "budget": args.budget}
    if args.methods:
        options["methods"] = args.methods
    if args.conv:
        options["conv"] = args.conv
    options["folds"] = args.folds if args.folds == "auto" else int(args.folds)
    if args.epochs is not None:
        options["epochs"] = args.epochs
    if args.no_rotate:
        options["rotate"] = False
    bar = _Bar(args.budget, quiet=args.json)
    try:
        model = existing_store(args.db).train_classifier(
            label=args.label, progress=bar, resume=not args.restart, **options
        )
    finally:
        bar.close()
    classes = [str(c) for c in model.classes_]
    selection = getattr(model, "selection_", None)
    result = {
        "model": str(args.out),
        "kind": getattr(model, "kind", None),
        "classes": classes,
        "test_accuracy": model.test_accuracy_,
        "selection": None if selection is None else selection.to_dict(),
    }
    if args.json:
        print_json(result)
    else:
        if selection is not None:
            print(selection.reason())
        print(
            f"saved {args.out}: {result['kind']}, {len(classes)} classes, "
            f"test accuracy {result['test_accuracy']:.3f}"
        )
    return 0


def classify(args: argparse.Namespace) -> int:
    """``shapedb classify``: every model with one load of the classifier, in one process."""
    shapes: list[ShapeRef] = [query_arg(m) for m in args.model]
    results = existing_store(args.db).classify(args.classifier, shapes)
    for result in results if isinstance(results, list) else [results]:
        if args.json:
            print_json(result.to_dict())
        elif len(shapes) > 1:
            print(f"{result.source}\t{result.label}\t(p = {result.probability:.3f})")
        else:
            print(f"{result.label}  (p = {result.probability:.3f})")
    return 0
