"""Subcommands of the classifiers (``shapedb[learn]``): ``train``, ``classify``."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from query.cli.common import (
    Subparsers,
    add_command,
    add_db_argument,
    existing_store,
    print_json,
    query_arg,
)
from shapedb.results import ShapeRef

__all__ = ["register", "train", "classify"]

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
    s.add_argument("--out", required=True, metavar="PT", help="where to save the model")
    s.add_argument("--json", action="store_true")

    s = add_command(subparsers, "classify", classify, help="label models with a trained classifier")
    s.add_argument("model", nargs="+", metavar="MODEL", help="model files, or stored ids or names")
    add_db_argument(s)
    s.add_argument("--model", dest="classifier", required=True, metavar="PT", help="trained model")
    s.add_argument("--json", action="store_true", help="one JSON line per model")


def train(args: argparse.Namespace) -> int:
    """``shapedb train``: a progress bar per epoch on a terminal."""
    from tqdm import tqdm

    options: dict[str, Any] = {"out": args.out, "test": args.test}
    if args.methods:
        options["methods"] = args.methods
    if args.conv:
        options["conv"] = args.conv
    options["folds"] = args.folds if args.folds == "auto" else int(args.folds)
    if args.epochs is not None:
        options["epochs"] = args.epochs
    if args.no_rotate:
        options["rotate"] = False
    bar = tqdm(desc="training", unit="epoch", disable=args.json or not sys.stderr.isatty())

    def progress(epoch: int, total: int, metrics: dict[str, float]) -> None:
        bar.total = total
        bar.update(1)
        bar.set_postfix(
            loss=f"{metrics.get('loss', math.nan):.3f}",
            acc=f"{metrics.get('accuracy', math.nan):.3f}",
            val=f"{metrics.get('val_accuracy', math.nan):.3f}",
        )

    try:
        model = existing_store(args.db).train_classifier(
            label=args.label, callback=progress, **options
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
