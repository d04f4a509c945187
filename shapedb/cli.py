"""The ``shapedb`` command line: one entry point, one subcommand per task.

::

    shapedb ingest PATH... --db DIR [--labels CSV] [--label-from-folder] [--as pointcloud|smooth_voxels]
                   [--resolution N] [--balls N] [--set KEY=VALUE]... [--workers N]
                   [--scheduler ADDR] [--force] [--json]
    shapedb info --db DIR [--json]
    shapedb delete ID_OR_NAME... --db DIR
    shapedb search QUERY --db DIR [-k 10] [--where SQL] [--metric JSON] [--json]
    shapedb sql "SELECT ..." --db DIR [--metric JSON] [--json | --csv]
    shapedb eval --db DIR [--label label] [--metric JSON] [--json] [--plot pr.png]
    shapedb fit-metric --db DIR [--label label] --out metric.json [--json]
    shapedb show MODEL --out PNG [--db DIR] [--complement]
    shapedb match QUERY --db DIR [--node N | --point X Y Z] [--hops K] [-k 10] [--json] [--out PNG]
    shapedb train --db DIR [--label label] [--conv tag|arma|spline] [--epochs N] --out model.pt
    shapedb classify MODEL --db DIR --model model.pt [--json]
    shapedb demo [--db DIR]

It only calls the :class:`~shapedb.database.Database` facade. Errors of shapedb are
printed as one line, ``shapedb: error: ...``, on stderr, with exit status 1 (2 for
usage errors). ``ingest`` also exits with 1 when some input failed.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from shapedb.errors import ShapeDBError

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``shapedb`` command."""
    p = argparse.ArgumentParser(
        prog="shapedb", description="3-D shape retrieval with maximal disjoint ball decompositions."
    )
    p.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def db_arg(sp: argparse.ArgumentParser, required: bool = True) -> None:
        sp.add_argument("--db", required=required, metavar="DIR", help="store directory")

    s = sub.add_parser("ingest", help="add model files or folders to a store")
    s.add_argument("paths", nargs="+", metavar="PATH", help="files or folders")
    db_arg(s)
    s.add_argument("--labels", metavar="CSV", help="CSV with path,label[,extra columns]")
    s.add_argument("--label-from-folder", action="store_true", help="label = parent folder")
    s.add_argument(
        "--as",
        dest="as_",
        choices=["mesh", "pointcloud", "smooth_voxels"],
        help="force representation (smooth_voxels: occupancy grids as smooth solids)",
    )
    s.add_argument("--resolution", type=int, metavar="N", help="grid cells (new store)")
    s.add_argument("--balls", type=int, metavar="N", help="max balls per shape (new store)")
    s.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="any configuration option of a new store, e.g. --set tie_cells=0 (repeatable)",
    )
    s.add_argument("--workers", type=int, metavar="N", help="worker processes (default: all cores)")
    s.add_argument("--scheduler", metavar="ADDR", help="Dask scheduler address, e.g. tcp://h:8786")
    s.add_argument("--batch-size", type=int, default=32, metavar="N", help="shapes per commit")
    s.add_argument("--force", action="store_true", help="rebuild shapes already stored")
    s.add_argument("--json", action="store_true", help="print the report as JSON")

    s = sub.add_parser("info", help="counts, labels, failures and configuration of a store")
    db_arg(s)
    s.add_argument("--json", action="store_true")

    s = sub.add_parser("delete", help="remove shapes by id or name")
    s.add_argument("targets", nargs="+", metavar="ID_OR_NAME")
    db_arg(s)

    s = sub.add_parser("search", help="the stored shapes most like QUERY")
    s.add_argument("query", metavar="QUERY", help="a model file, or a stored shape's id or name")
    db_arg(s)
    s.add_argument("-k", type=int, default=10, help="number of hits (default 10)")
    s.add_argument("--where", metavar="SQL", help="filter, e.g. \"label = 'Chair'\"")
    s.add_argument("--metric", metavar="JSON", help="a similarity saved by fit-metric")
    s.add_argument("--json", action="store_true")

    s = sub.add_parser("sql", help="run DuckDB SQL over the views shapes, balls, edges")
    s.add_argument("statement", metavar="SQL")
    db_arg(s)
    s.add_argument("--metric", metavar="JSON", help="weigh mdbd_distance / mdbd_kernel by it")
    fmt = s.add_mutually_exclusive_group()
    fmt.add_argument("--json", action="store_true")
    fmt.add_argument("--csv", action="store_true")

    s = sub.add_parser("eval", help="leave-one-out retrieval scores by label")
    db_arg(s)
    s.add_argument("--label", default="label", help="column or metadata key of the class")
    s.add_argument("--metric", metavar="JSON", help="a similarity saved by fit-metric")
    s.add_argument("--json", action="store_true")
    s.add_argument("--plot", metavar="PNG", help="save the precision-recall curve")

    s = sub.add_parser(
        "fit-metric", help="learn block weights of the similarity from the stored labels"
    )
    db_arg(s)
    s.add_argument("--label", default="label", help="column or metadata key of the class")
    s.add_argument("--out", required=True, metavar="JSON", help="where to save the metric")
    s.add_argument("--json", action="store_true")

    s = sub.add_parser("show", help="draw a model with its MDBD balls into a PNG")
    s.add_argument("model", metavar="MODEL", help="a model file, or a stored id or name (--db)")
    s.add_argument("--out", required=True, metavar="PNG", help="picture to write")
    db_arg(s, required=False)
    s.add_argument("--complement", action="store_true", help="decompose the complement instead")

    s = sub.add_parser("match", help="stored parts most like a part of QUERY (Algorithm 1)")
    s.add_argument("query", metavar="QUERY", help="a model file, or a stored shape's id or name")
    db_arg(s)
    where = s.add_mutually_exclusive_group()
    where.add_argument("--node", type=int, metavar="N", help="ball number of the query part")
    where.add_argument(
        "--point",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="a point on the model; its nearest ball is the part",
    )
    s.add_argument("--hops", type=int, default=2, metavar="K", help="neighbourhood range")
    s.add_argument("-k", type=int, default=10, help="number of matches (default 10)")
    s.add_argument("--where", metavar="SQL", help="restrict the shapes searched")
    s.add_argument("--complement", action="store_true", help="match concave features")
    s.add_argument("--json", action="store_true")
    s.add_argument("--out", metavar="PNG", help="draw the query and its matches")

    s = sub.add_parser("train", help="train a graph-CNN classifier (needs shapedb[learn])")
    db_arg(s)
    s.add_argument("--label", default="label", help="column or metadata key of the class")
    s.add_argument("--conv", choices=["tag", "arma", "spline"], default="tag")
    s.add_argument("--epochs", type=int, metavar="N", help="training epochs")
    s.add_argument("--no-rotate", action="store_true", help="no random-rotation augmentation")
    s.add_argument("--out", required=True, metavar="PT", help="where to save the model")
    s.add_argument("--json", action="store_true")

    s = sub.add_parser("classify", help="label a model with a trained classifier")
    s.add_argument("model", metavar="MODEL", help="a model file, or a stored id or name")
    db_arg(s)
    s.add_argument("--model", dest="classifier", required=True, metavar="PT", help="trained model")
    s.add_argument("--json", action="store_true")

    s = sub.add_parser("demo", help="ingest the built-in example shapes and search them")
    db_arg(s, required=False)
    s.add_argument("--workers", type=int, metavar="N", help="worker processes")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(_COMMANDS[args.command](args))
    except ShapeDBError as exc:
        print(f"shapedb: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("shapedb: interrupted", file=sys.stderr)
        return 130


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _open(path: str, **kwargs: Any) -> Any:
    from shapedb.database import connect

    return connect(path, **kwargs)


def _existing(path: str) -> Any:
    return _open(path, create=False)


# ---------------------------------------------------------------- commands
def _ingest(args: argparse.Namespace) -> int:
    from shapedb.config import parse_options

    options = parse_options(args.settings)
    if args.resolution is not None:
        options["resolution"] = args.resolution
    if args.balls is not None:
        options["n_balls"] = args.balls
    db = _open(args.db, **options)
    bar = _Bar(enabled=not args.json)
    try:
        report = db.ingest(
            args.paths,
            labels=args.labels,
            label_from_folder=args.label_from_folder,
            as_=args.as_,
            workers=args.workers,
            scheduler=args.scheduler,
            force=args.force,
            progress=bar,
            batch_size=args.batch_size,
        )
    finally:
        bar.close()
    if args.json:
        _print_json(report.to_dict())
    else:
        print(
            f"ingested {len(report.ingested)}, skipped {len(report.skipped)}, "
            f"failed {len(report.failed)} ({report.seconds:.1f} s)"
        )
        for path, error in report.failed:
            print(f"  failed: {path}: {error}")
    return 1 if report.failed else 0


class _Bar:
    """A tqdm progress bar on stderr, fed by the ingest's progress callback."""

    def __init__(self, *, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self._bar: Any = None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit="model", file=sys.stderr, dynamic_ncols=True)
        self._bar.update(done - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _info(args: argparse.Namespace) -> int:
    info = _existing(args.db).info()
    if args.json:
        _print_json(info)
        return 0
    print(f"store:    {os.path.abspath(args.db)}")
    print(f"shapes:   {info['shapes']}")
    labels = info["labels"]
    print(f"labels:   {len(labels)}" + (":" if labels else ""))
    for name, count in labels.items():
        print(f"  {count:6d}  {name}")
    mdbd, kernel = info["config"]["mdbd"], info["config"]["kernel"]
    print("config:   " + ", ".join(f"{k}={v}" for k, v in {**mdbd, **kernel}.items()))
    print(f"failures: {len(info['failures'])}")
    for f in info["failures"]:
        print(f"  {f['path']}: {f['error']}")
    return 0


def _delete(args: argparse.Namespace) -> int:
    n = _existing(args.db).delete(args.targets)
    print(f"deleted {n} shape(s)")
    return 0


def _query_arg(text: str) -> Any:
    """A path when such a file exists, an int id for digits, else a name."""
    if os.path.exists(text):
        return text
    return int(text) if text.strip().isdigit() else text


def _search(args: argparse.Namespace) -> int:
    db = _existing(args.db)
    hits = db.search(_query_arg(args.query), k=args.k, where=args.where, metric=args.metric)
    rows = [_hit(h) for h in hits]
    if args.json:
        _print_json(rows)
        return 0
    _print_rows(rows, ["id", "name", "label", "similarity", "distance"])
    return 0


def _hit(h: Any) -> dict[str, Any]:
    if hasattr(h, "to_dict"):
        return dict(h.to_dict())
    return {k: getattr(h, k) for k in ("id", "name", "label", "similarity", "distance")}


def _sql(args: argparse.Namespace) -> int:
    table = _existing(args.db).sql(args.statement, metric=args.metric)
    if args.csv:
        import io

        import pyarrow.csv as pacsv

        buf = io.BytesIO()
        pacsv.write_csv(table, buf)
        sys.stdout.write(buf.getvalue().decode())
        return 0
    rows = table.to_pylist()
    if args.json:
        _print_json(rows)
        return 0
    _print_rows(rows, table.column_names)
    return 0


def _eval(args: argparse.Namespace) -> int:
    db = _existing(args.db)
    scores = db.evaluate(label=args.label, plot=args.plot, metric=args.metric)
    out = scores.to_dict() if hasattr(scores, "to_dict") else dict(vars(scores))
    if args.json:
        _print_json(out)
        return 0
    print(f"queries: {out.get('queries')}")
    for key in ("nn", "first_tier", "second_tier", "e_measure", "dcg"):
        if key in out:
            print(f"{key:12s} {out[key]:.4f}")
    if args.plot:
        print(f"precision-recall curve: {args.plot}")
    return 0


def _fit_metric(args: argparse.Namespace) -> int:
    metric = _existing(args.db).fit_metric(label=args.label)
    path = metric.save(args.out)
    out = metric.to_dict()
    if args.json:
        _print_json(out)
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


def _demo(args: argparse.Namespace) -> int:
    from shapedb.examples import catalogue

    path = args.db or tempfile.mkdtemp(prefix="shapedb-demo-")
    db = _open(path, resolution=64, n_balls=256)
    bar = _Bar(enabled=True)
    try:
        report = db.ingest(catalogue(), workers=args.workers, progress=bar)
    finally:
        bar.close()
    print(
        f"demo store {path}: ingested {len(report.ingested)}, skipped {len(report.skipped)}, "
        f"failed {len(report.failed)}"
    )
    rows = db.shapes(["id", "name", "label"]).to_pylist()
    if not rows:
        return 1
    query = rows[0]
    print(f"\nshapes most like {query['name']!r} (label {query['label']!r}):")
    hits = db.search(int(query["id"]), k=5)
    _print_rows([_hit(h) for h in hits], ["id", "name", "label", "similarity", "distance"])
    scores = db.evaluate(label="label").to_dict()
    print(
        f"\nleave-one-out retrieval over {scores['queries']} shapes: "
        f"NN {scores['nn']:.3f}  1-T {scores['first_tier']:.3f}  "
        f"2-T {scores['second_tier']:.3f}  DCG {scores['dcg']:.3f}"
    )
    picture = db.show(int(query["id"]), Path(path) / "demo.png")
    print(f"{query['name']} and its balls: {picture}")
    print(f'\ntry:  shapedb sql "SELECT label, count(*) FROM shapes GROUP BY label" --db {path}')
    return 0


def _show(args: argparse.Namespace) -> int:
    if args.db:
        out = _existing(args.db).show(_query_arg(args.model), args.out, complement=args.complement)
    else:
        from shapedb.database import extension

        out = extension("show")(None, args.model, args.out, complement=args.complement)
    print(out)
    return 0


def _match(args: argparse.Namespace) -> int:
    db = _existing(args.db)
    query = _query_arg(args.query)
    matches = db.match(
        query,
        node=args.node,
        point=args.point,
        hops=args.hops,
        k=args.k,
        where=args.where,
        complement=args.complement,
    )
    rows = [
        {key: m.to_dict()[key] for key in ("id", "name", "label", "similarity", "nodes")}
        for m in matches
    ]
    if args.out:
        db.render_matches(query, matches, args.out, complement=args.complement)
    if args.json:
        _print_json(rows)
        return 0
    _print_rows(
        [{**r, "nodes": len(r["nodes"])} for r in rows],
        ["id", "name", "label", "similarity", "nodes"],
    )
    if args.out:
        print(f"picture: {args.out}")
    return 0


def _train(args: argparse.Namespace) -> int:
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
        model = _existing(args.db).train_classifier(label=args.label, callback=progress, **options)
    finally:
        bar.close()
    classes = [str(c) for c in getattr(model, "classes_", [])]
    result = {
        "model": str(args.out),
        "classes": classes,
        "test_accuracy": getattr(model, "test_accuracy_", None),
    }
    if args.json:
        _print_json(result)
    else:
        print(f"saved {args.out}: {len(classes)} classes, test accuracy {result['test_accuracy']}")
    return 0


def _classify(args: argparse.Namespace) -> int:
    result = _existing(args.db).classify(args.classifier, _query_arg(args.model))
    out = result.to_dict() if hasattr(result, "to_dict") else {"label": str(result)}
    if args.json:
        _print_json(out)
    else:
        print(f"{out.get('label')}  (p = {out.get('probability', math.nan):.3f})")
    return 0


_COMMANDS = {
    "fit-metric": _fit_metric,
    "ingest": _ingest,
    "info": _info,
    "delete": _delete,
    "search": _search,
    "sql": _sql,
    "eval": _eval,
    "show": _show,
    "match": _match,
    "train": _train,
    "classify": _classify,
    "demo": _demo,
}


# ---------------------------------------------------------------- output
def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, (str, int, float, bool)) or x is None:
        return x
    if hasattr(x, "tolist"):
        return _jsonable(x.tolist())
    if hasattr(x, "isoformat"):
        return x.isoformat()
    if isinstance(x, (bytes, Path)):
        return str(x)
    return str(x)


def _print_json(data: Any) -> None:
    print(json.dumps(_jsonable(data), indent=None))


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    text = "" if v is None else str(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _print_rows(rows: list[dict[str, Any]], columns: Sequence[str]) -> None:
    cells = [[_cell(r.get(c)) for c in columns] for r in rows]
    widths = [max([len(c)] + [len(row[k]) for row in cells]) for k, c in enumerate(columns)]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=True)).rstrip())
    for row in cells:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths, strict=True)).rstrip())
    if not rows:
        print("(no rows)")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
