"""Subcommands of the graph-CNN classifier (``shapedb[learn]``): ``train``, ``classify``."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from shapedb.cli.common import (
    Subparsers,
    add_command,
    add_db_argument,
    existing_store,
    print_json,
    query_arg,
)

__all__ = ["register", "train", "classify"]


def register(subparsers: Subparsers) -> None:
    """Add ``train`` and ``classify``."""
    s = add_command(
        subparsers, "train", train, help="train a graph-CNN classifier (needs shapedb[learn])"
    )
    add_db_argument(s)
    s.add_argument("--label", default="label", help="column or metadata key of the class")
    s.add_argument("--conv", choices=["tag", "arma", "spline"], default="tag")
    s.add_argument("--epochs", type=int, metavar="N", help="training epochs")
    s.add_argument("--no-rotate", action="store_true", help="no random-rotation augmentation")
    s.add_argument("--out", required=True, metavar="PT", help="where to save the model")
    s.add_argument("--json", action="store_true")

    s = add_command(
        subparsers, "classify", classify, help="label a model with a trained classifier"
    )
    s.add_argument("model", metavar="MODEL", help="a model file, or a stored id or name")
    add_db_argument(s)
    s.add_argument("--model", dest="classifier", required=True, metavar="PT", help="trained model")
    s.add_argument("--json", action="store_true")


def train(args: argparse.Namespace) -> int:
    """``shapedb train``: a progress bar per epoch on a terminal."""
    from tqdm import tqdm

    options: dict[str, Any] = {"conv": args.conv, "out": args.out}
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
    classes = [str(c) for c in getattr(model, "classes_", [])]
    result = {
        "model": str(args.out),
        "classes": classes,
        "test_accuracy": getattr(model, "test_accuracy_", None),
    }
    if args.json:
        print_json(result)
    else:
        print(f"saved {args.out}: {len(classes)} classes, test accuracy {result['test_accuracy']}")
    return 0


def classify(args: argparse.Namespace) -> int:
    """``shapedb classify``."""
    result = existing_store(args.db).classify(args.classifier, query_arg(args.model))
    out = result.to_dict() if hasattr(result, "to_dict") else {"label": str(result)}
    if args.json:
        print_json(out)
    else:
        print(f"{out.get('label')}  (p = {out.get('probability', math.nan):.3f})")
    return 0
