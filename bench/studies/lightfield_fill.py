"""Filled silhouettes of the balls: where the balls' light fields lose to the mesh's.

Three parts, each from the cached decompositions (:func:`bench.support.cached.load`):

* ``--diagnose N``: for the first N web validation models (one per class first), the
  mesh's silhouette (dense surface splats closed by a pixel, as ``bench/lightfield.py``
  renders them) and the balls' silhouette for the same 30 views *in the same frame*
  (the balls' volume centroid, the farthest ball's far side at radius 1; the mesh's
  samples moved into it), per fill of ``--fills``; per view the IoU and where the
  pixels differ: ``holes`` (mesh pixels in an enclosed hole of the balls' silhouette),
  ``missing`` (mesh pixels more than one pixel from any ball pixel, not in a hole: thin
  or lost parts), ``rim`` (the rest of the mesh-only pixels) and ``extra`` (ball pixels
  the mesh does not cover), as shares of the mesh's pixels. Also the grid's inside
  (cells where the decomposition's signed field is >= 0, thickened shell included) in
  the same frame. A few images side by side go to ``--images`` (PNG: white both, red
  mesh only, blue balls only).
* ``--voxels``: the light field descriptor of the grid's inside (each inside cell a
  ball of half a cell) on the web validation split: an upper bound of what a packing
  of that field can give.
* default: the balls' light fields alone per fill (``--fills``) on each set's split,
  with the mesh light field descriptor (10 fields, descriptors cached) in the same run;
  with ``--n-balls N`` the split is decomposed with N balls (cached) instead;
* ``--fused --n-balls N``: version 4 of today's balls fused with the light fields of
  today's balls and of the N-ball packing (the product's gated rank fusion, at
  the numbers of :data:`query.search.tuning.PRODUCT`).

Fills are ``plain``, ``edges`` (each contact edge fills the convex hull of its two
balls), ``dilate<p>`` (discs grow by p pixels), ``close<p>`` (closing by a disc of p
pixels), joined by ``+`` (e.g. ``edges+close1``); every one at 64 px, 3 light fields.
In the ranking only, ``top<n>`` keeps the packing's first n balls (``top256+edges``).
Usage::

    python -m bench.studies.lightfield_fill --diagnose 40 --images /tmp/lffill
    python -m bench.studies.lightfield_fill --voxels
    python -m bench.studies.lightfield_fill --fills plain edges dilate1 close1 edges+close1

Distance matrices are cached under ``$SHAPEDB_BENCH_CACHE/lightfield_fill`` (keyed by the
set's models, the fill and the code of shapedb/signature/lightfield.py). Results go to
bench/results/studies/lightfield_fill_<part>_<split>.json.
"""

from __future__ import annotations

import argparse
import hashlib
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bench.common import Balls, format_table, per_query, retrieval_scores, write_json
from bench.sets.datasets import CACHE_DIR, Dataset, mesh_arrays
from bench.studies.lightfield_balls import fill_config
from bench.support.cached import SETS, load
from bench.support.packings import longer
from bench.support.tuning import unit_of
from shapedb.config.core import MDBDConfig
from shapedb.config.lightfield import product_light_field
from shapedb.signature.lightfield import (
    ball_light_field,
    field_directions,
    light_field_distance,
    render_discs,
)

FloatArray = NDArray[np.float64]
OUT = Path(__file__).resolve().parents[1] / "results" / "studies"


def _load(name: str, split: str, n_balls: int) -> tuple[Dataset, list[Balls]]:
    """The split's cached balls, or (``n_balls`` > 0) decompositions with that many balls."""
    if not n_balls:
        return load(name, split)
    from bench.common import decompose_all

    ds, _ = load(name, split)
    got = decompose_all(ds.models, "mesh", MDBDConfig(n_balls=n_balls), workers=1)
    keep = [i for i, b in enumerate(got) if b is not None]
    return Dataset(ds.name, tuple(ds.models[i] for i in keep)), [got[i] for i in keep]  # type: ignore[misc]


def _frame(b: Balls) -> tuple[FloatArray, float]:
    """The balls' light field frame: volume centroid and the farthest far side."""
    r = b.radii[b.radii > 0]
    c = b.centers[b.radii > 0]
    v = r**3 / (r**3).sum()
    o = v @ c
    return o, float(np.max(np.linalg.norm(c - o, axis=1) + r))


def mesh_in_frame(
    vertices: FloatArray, faces: NDArray[np.int64], o: FloatArray, extent: float, n: int = 40000
) -> NDArray[np.float32]:
    """Dense surface samples (and vertices) moved into a light field frame."""
    from bench.support.baselines import sample_surface

    p = sample_surface(vertices, faces, n, rng=np.random.default_rng(0))
    p = np.vstack([p, vertices[np.unique(faces)]])
    return ((p - o) / extent).astype(np.float32)


def inside_cells(m: Any, cfg: MDBDConfig | None = None) -> tuple[FloatArray, float]:
    """Centres (model units) of the grid cells inside the solid the MDBD packs, and the cell."""
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.mdbd.decomposition import prepare_field

    prep = prepare_field(TriangleMesh(*mesh_arrays(m)), cfg or MDBDConfig())
    idx = np.argwhere(prep.F >= 0)
    local = prep.grid.to_point(idx) * prep.scale
    return local @ prep.frame[:3, :3].T + prep.frame[:3, 3], prep.scale * prep.grid.spacing


def _compare(mesh: NDArray[np.bool_], balls: NDArray[np.bool_]) -> dict[str, float]:
    """IoU and the differing pixels as shares of the mesh's, averaged over the views."""
    from scipy import ndimage

    rows = []
    for a, b in zip(mesh, balls, strict=True):
        na = max(int(a.sum()), 1)
        only = a & ~b
        outside, k = ndimage.label(~b)
        border = set(np.unique(np.concatenate([outside[0], outside[-1], outside[:, 0],
                                               outside[:, -1]]))) - {0}  # fmt: skip
        hole = ~b & ~np.isin(outside, list(border)) if k else np.zeros_like(b)
        near = ndimage.binary_dilation(b, np.ones((3, 3), bool))
        holes = only & hole
        missing = only & ~hole & ~near
        rim = only & ~hole & near
        rows.append([(a & b).sum() / max((a | b).sum(), 1), holes.sum() / na,
                     missing.sum() / na, rim.sum() / na, (b & ~a).sum() / na])  # fmt: skip
    m = np.asarray(rows).mean(axis=0)
    return dict(zip(("iou", "holes", "missing", "rim", "extra"), m.tolist(), strict=True))


def _save(path: Path, mesh: NDArray[np.bool_], panels: list[NDArray[np.bool_]]) -> None:
    from PIL import Image

    tiles = []
    for b in panels:
        rgb = np.zeros((*mesh.shape, 3), np.uint8)
        rgb[mesh & b] = 255
        rgb[mesh & ~b] = (220, 40, 40)
        rgb[~mesh & b] = (40, 80, 230)
        tiles.append(np.pad(rgb, ((2, 2), (2, 2), (0, 0)), constant_values=90))
    img = Image.fromarray(np.hstack(tiles)).resize(
        (len(tiles) * (mesh.shape[1] + 4) * 4, (mesh.shape[0] + 4) * 4), Image.NEAREST
    )
    img.save(path)


def diagnose(
    n: int,
    fills: Sequence[str],
    images: Path | None,
    n_balls: int = 0,
    split: str = "validation",
    classes: Sequence[str] = (),
) -> dict[str, Any]:
    """Per fill (and the grid's inside), mean per-view agreement with the mesh silhouette.

    ``n_balls`` > 512: the packing continued to that many (``bench.support.packings.longer``
    within 4096, as lightfield_pack); ``classes``: only those classes' models.
    """
    from bench.support.lightfield import render_silhouettes

    ds, balls = load("web", split)
    if n_balls > MDBDConfig().n_balls:
        ds, more, main = longer("web", split, 4096 - MDBDConfig().n_balls)
        balls = [Balls(b.centers[: max(n_balls, k)], b.radii[: max(n_balls, k)], b.edges,
                       b.spacing, 0.0) for b, k in zip(more, main, strict=True)]  # fmt: skip
    elif n_balls:
        ds, balls = _load("web", split, n_balls)
    labels = list(ds.labels)
    pool = [i for i in range(len(ds)) if not classes or labels[i] in classes]
    first = sorted({labels[i]: i for i in reversed(pool)}.values())
    order = (first + [i for i in pool if i not in set(first)])[:n]
    cfg = product_light_field()
    dirs = field_directions(cfg.n_fields, cfg.seed)
    res = cfg.resolution
    per: dict[str, list[dict[str, float]]] = {f: [] for f in (*fills, "grid inside")}
    if images:
        images.mkdir(parents=True, exist_ok=True)
    for k, i in enumerate(order):
        m, b = ds.models[i], balls[i]
        o, extent = _frame(b)
        v, f = mesh_arrays(m)
        mesh = render_silhouettes(mesh_in_frame(v, f, o, extent), dirs, res)
        panels = []
        for text in fills:
            c = fill_config(text)
            sil, _ = render_discs(b.centers, b.radii, dirs, res, edges=b.edges if c.edges else None,
                                  dilate_px=c.dilate_px, close_px=c.close_px)  # fmt: skip
            per[text].append(_compare(mesh, sil))
            panels.append(sil)
        cells, _ = inside_cells(m)
        # the cells' centres splatted in the balls' frame and closed by a pixel, as the
        # mesh's samples are (a cell is about half a pixel)
        sil = render_silhouettes(((cells - o) / extent).astype(np.float32), dirs, res)
        per["grid inside"].append(_compare(mesh, sil))
        panels.append(sil)
        if images and k < max(8, len(classes) * 2):
            for view in (0, 3, 7):
                _save(images / f"{k:02d}_{m.name}_{view}.png", mesh[view],
                      [p[view] for p in panels])  # fmt: skip
    out = {f: {key: float(np.mean([r[key] for r in rows])) for key in rows[0]}
           for f, rows in per.items()}  # fmt: skip
    table = [[f, *(f"{v[key]:.3f}" for key in ("iou", "holes", "missing", "rim", "extra"))]
             for f, v in out.items()]  # fmt: skip
    print(format_table(
        f"silhouettes of the balls against the mesh's, {len(order)} web {split} models x "
        f"{len(dirs)} views, same frame (shares of the mesh's pixels)",
        ("fill", "IoU", "holes", "missing", "rim", "extra"), table,
    ))  # fmt: skip
    return {"models": [ds.models[i].name for i in order], "fills": out}


def _scores(d: FloatArray, labels: Sequence[str]) -> dict[str, float]:
    return retrieval_scores(-d, np.asarray(labels))


def fill_matrix(
    name: str, ds: Dataset, balls: list[Balls], text: str, n_balls: int = 0
) -> tuple[FloatArray, float]:
    """Light field distances of a fill (cached) and CPU s per model of the light fields."""
    code = (
        Path(__file__).resolve().parents[2] / "shapedb" / "signature" / "lightfield.py"
    ).read_bytes()
    key = hashlib.sha256(
        code
        + text.encode()
        + "\n".join(m.name + m.source for m in ds.models).encode()
        + (f"n_balls={n_balls}".encode() if n_balls else b"")
    ).hexdigest()[:16]
    path = CACHE_DIR / "lightfield_fill" / f"{name}_{key}.npz"
    if path.exists():
        z = np.load(path)
        return z["d"], float(z["per_model"])
    parts = text.split("+")
    top = [int(p[3:]) for p in parts if p.startswith("top")]
    cfg = fill_config("+".join(p for p in parts if not p.startswith("top")) or "plain")
    if top:
        balls = [b.truncate(top[0]) for b in balls]
    t = time.process_time()
    lf = np.stack([ball_light_field(b.centers, b.radii, cfg, edges=b.edges) for b in balls])
    per_model = (time.process_time() - t) / len(balls)
    d = light_field_distance(lf)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, d=d, per_model=per_model)
    return d, per_model


def voxels(split: str) -> dict[str, Any]:
    """LFD of the grid's inside on the web split, against the balls and the mesh."""
    from bench.support.lightfield import lfd_matrix

    ds, balls = load("web", split)
    cfg = product_light_field()
    path = CACHE_DIR / "lightfield_fill" / f"voxels_web_{split}_{len(ds)}.npy"
    if path.exists():
        lf = np.load(path)
    else:
        rows = []
        for m in ds.models:
            cells, h = inside_cells(m)
            rows.append(ball_light_field(cells, np.full(len(cells), 0.5 * h), cfg))
        lf = np.stack(rows)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, lf)
    mats = {"balls (plain)": fill_matrix("web", ds, balls, "plain")[0],
            "grid inside (cells as balls)": light_field_distance(lf),
            "mesh LFD (10 fields)": lfd_matrix(ds)}  # fmt: skip
    out = {k: _scores(d, ds.labels) for k, d in mats.items()}
    print(format_table(
        f"light fields, web {split} ({len(ds)} models), NN / 1-T / DCG", ("source", "web"),
        [[k, f"{v['nn']:.3f} / {v['first_tier']:.3f} / {v['dcg']:.3f}"] for k, v in out.items()],
    ))  # fmt: skip
    return out


def uncovered_cells(b: Balls, cells: FloatArray) -> NDArray[np.bool_]:
    """Which cell centres (m, 3) no ball of ``b`` contains (model units)."""
    from scipy.spatial import cKDTree

    keep = b.radii > 0
    c, r = b.centers[keep], b.radii[keep]
    if not len(r):
        return np.ones(len(cells), bool)
    near = cKDTree(c).query_ball_point(cells, float(r.max()))
    out = np.ones(len(cells), bool)
    for i, js in enumerate(near):
        if js and np.any(np.linalg.norm(c[js] - cells[i], axis=1) <= r[js]):
            out[i] = False
    return out


def residual(split: str, n_balls: int) -> FloatArray:
    """Light fields (cached) of the packing continued to ``n_balls`` plus the grid's inside
    cells no ball contains (each a ball of half a cell), web ``split``, in
    :func:`bench.support.packings.longer`'s model order; (n, n_fields, 10, dim)."""
    tail = 4096 - MDBDConfig().n_balls
    ds, more, main = longer("web", split, tail)
    path = CACHE_DIR / "lightfield_fill" / f"residual_web_{split}_{len(ds)}_{n_balls}.npy"
    if path.exists():
        return np.load(path)
    cfg = product_light_field()
    rows = []
    for m, b, k in zip(ds.models, more, main, strict=True):
        b = Balls(b.centers[: max(n_balls, k)], b.radii[: max(n_balls, k)], b.edges, b.spacing, 0.0)
        cells, h = inside_cells(m)
        rest = cells[uncovered_cells(b, cells)]
        c = np.vstack([b.centers, rest])
        r = np.concatenate([b.radii, np.full(len(rest), 0.5 * h)])
        rows.append(ball_light_field(c, r, cfg))
    lf = np.stack(rows)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, lf)
    return lf


def per_class(split: str, n_balls: int, residual_too: bool = False) -> dict[str, Any]:
    """Per web class, NN and 1-T of the mesh LFD, the light fields of the packing continued
    to ``n_balls`` (``bench.support.packings.longer`` within 4096, as lightfield_pack) and, when
    ``--voxels`` has cached it, the grid's inside; with ``residual_too`` (or when cached)
    the balls plus the inside cells they leave uncovered (:func:`residual`); with each
    class's median ball count."""
    from bench.studies.lightfield_pack import lf_matrix
    from bench.support.lightfield import lfd_matrix

    tail = 4096 - MDBDConfig().n_balls
    ds, balls, main = longer("web", split, tail)
    full, _ = load("web", split)
    labels = list(ds.labels)
    mats = {"mesh LFD": lfd_matrix(ds),
            f"balls {n_balls}": lf_matrix("web", split, ds, [
                Balls(b.centers[: max(n_balls, k)], b.radii[: max(n_balls, k)], b.edges,
                      b.spacing, 0.0) for b, k in zip(balls, main, strict=True)],
                f"n{n_balls}t{tail}")}  # fmt: skip
    vox = CACHE_DIR / "lightfield_fill" / f"voxels_web_{split}_{len(full)}.npy"
    if vox.exists() and len(full) == len(ds):
        mats["grid inside"] = light_field_distance(np.load(vox))
    res = CACHE_DIR / "lightfield_fill" / f"residual_web_{split}_{len(ds)}_{n_balls}.npy"
    if residual_too or res.exists():
        mats[f"balls {n_balls} + uncovered cells"] = light_field_distance(residual(split, n_balls))
    got = {k: per_query(d, labels) for k, d in mats.items()}
    lab = np.asarray(labels)
    n_tail = np.array([int((b.radii > 0).sum()) for b in balls])
    rows: list[dict[str, Any]] = []
    for c in sorted(set(labels)):
        idx = lab == c
        row: dict[str, Any] = {"class": c, "n": int(idx.sum()),
                               "main_balls": float(np.median(np.asarray(main)[idx])),
                               "balls": float(np.median(n_tail[idx]))}  # fmt: skip
        for k, (nn, tier) in got.items():
            row[k] = {"nn": float(nn[idx].mean()), "first_tier": float(tier[idx].mean()),
                      "nn_right": int(nn[idx].sum())}  # fmt: skip
        rows.append(row)
    key = f"balls {n_balls}"
    rows.sort(key=lambda r: r[key]["nn_right"] - r["mesh LFD"]["nn_right"])
    cols = list(mats)
    table = [[r["class"], str(r["n"]), f"{r['main_balls']:.0f}/{r['balls']:.0f}",
              *(f"{r[k]['nn']:.2f} / {r[k]['first_tier']:.2f}" for k in cols),
              str(r[key]["nn_right"] - r["mesh LFD"]["nn_right"])] for r in rows[:15]]  # fmt: skip
    print(format_table(
        f"web {split} per class ({len(ds)} of {len(full)} models), NN / 1-T, largest NN losses",
        ("class", "n", "balls main/all", *cols, "NN queries"), table,
    ))  # fmt: skip
    totals = {k: {"nn": float(nn.mean()), "first_tier": float(t.mean())}
              for k, (nn, t) in got.items()}  # fmt: skip
    print(totals)
    mesh_nn, balls_nn = got["mesh LFD"][0], got[key][0]
    short = n_tail < n_balls
    split_by = {
        "mesh right, balls wrong": mesh_nn & ~balls_nn,
        "balls right, mesh wrong": balls_nn & ~mesh_nn,
        "both right": mesh_nn & balls_nn,
        "both wrong": ~mesh_nn & ~balls_nn,
    }
    queries = {k: {"queries": int(q.sum()), "median_balls": float(np.median(n_tail[q])),
                   "packing_short": float(short[q].mean()),
                   "classes": len(set(lab[q].tolist()))}
               for k, q in split_by.items() if q.any()}  # fmt: skip
    print(format_table(
        f"NN queries by outcome, packing stopped before {n_balls} balls (share)",
        ("queries", "n", "median balls", "short", "classes"),
        [[k, str(v["queries"]), f"{v['median_balls']:.0f}", f"{v['packing_short']:.2f}",
          str(v["classes"])] for k, v in queries.items()],
    ))  # fmt: skip
    return {
        "models": len(ds),
        "of": len(full),
        "totals": totals,
        "classes": rows,
        "queries": queries,
    }


def rank_fills(
    split: str, datasets: Sequence[str], fills: Sequence[str], n_balls: int = 0
) -> dict[str, Any]:
    """The balls' light fields alone per fill, and the mesh LFD, per set."""
    from bench.support.lightfield import lfd_matrix

    table: dict[str, dict[str, Any]] = {f: {} for f in (*fills, "mesh LFD")}
    cpu: dict[str, dict[str, float]] = {}
    for name in datasets:
        t0 = time.perf_counter()
        ds, balls = _load(name, split, n_balls)
        cpu[name] = {}
        for text in fills:
            d, per_model = fill_matrix(name, ds, balls, text, n_balls)
            table[text][name] = _scores(d, ds.labels)
            cpu[name][text] = per_model
        if name != "people":
            table["mesh LFD"][name] = _scores(lfd_matrix(ds), ds.labels)
        print(f"  {name}: {len(ds)} models ({time.perf_counter() - t0:.0f} s)", flush=True)
    rows = []
    for f, per in table.items():
        rows.append([f, *(f"{per[n]['nn']:.3f}/{per[n]['first_tier']:.3f}/{per[n]['dcg']:.3f}"
                          if n in per else "" for n in datasets)])  # fmt: skip
    print(format_table(f"balls' light fields alone per fill, {split} (NN/1-T/DCG)",
                       ("fill", *datasets), rows))  # fmt: skip
    print(f"CPU s per model: {cpu}")
    return {"table": table, "cpu": cpu}


def fused_longer(split: str, datasets: Sequence[str], n_balls: int) -> dict[str, Any]:
    """Version 4 of today's balls fused (``adrank 8``, the product's gate) with the light
    fields of a longer packing (``n_balls``), against the same fusion with today's."""
    from bench.studies.lightfield_balls import fuse, v4_distances
    from query.search.tuning import PRODUCT

    f = PRODUCT
    table: dict[str, dict[str, Any]] = {"v4": {}, "fused, 512 balls": {},
                                        f"fused, {n_balls} balls": {}}  # fmt: skip
    for name in datasets:
        ds, balls = load(name, split)
        dl, _ = fill_matrix(name, ds, balls, "plain")
        longer, more = _load(name, split, n_balls)
        keep = {m.name: i for i, m in enumerate(longer.models)}
        idx = [i for i, m in enumerate(ds.models) if m.name in keep]
        ds = Dataset(ds.name, tuple(ds.models[i] for i in idx))
        balls = [balls[i] for i in idx]
        dl = dl[np.ix_(idx, idx)]
        dm, _ = fill_matrix(name, longer, more, "plain", n_balls)
        order = [keep[m.name] for m in ds.models]
        dm = dm[np.ix_(order, order)]
        d4 = v4_distances(balls)
        args = (unit_of(f), f.neighbours, 0.0, f.ceiling, f.ramp)  # the product's power: 0
        table["v4"][name] = _scores(d4, ds.labels)
        table["fused, 512 balls"][name] = _scores(
            fuse("adrank", f.weight, d4, dl, *args), ds.labels
        )
        table[f"fused, {n_balls} balls"][name] = _scores(
            fuse("adrank", f.weight, d4, dm, *args), ds.labels
        )
        print(f"  {name}: {len(ds)} models", flush=True)
    rows = [[k, *(f"{v[n]['nn']:.3f}/{v[n]['first_tier']:.3f}/{v[n]['dcg']:.3f}" for n in datasets)]
            for k, v in table.items()]  # fmt: skip
    print(format_table(f"v4 fused with the balls' light fields, {split} (NN/1-T/DCG)",
                       ("row", *datasets), rows))  # fmt: skip
    return table


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.lightfield_fill")
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=list(SETS), choices=SETS)
    ap.add_argument("--fills", nargs="+", default=["plain", "edges", "dilate1", "close1",
                                                    "edges+close1"])  # fmt: skip
    ap.add_argument("--diagnose", type=int, default=0, help="compare N web silhouettes")
    ap.add_argument("--residual", action="store_true",
                    help="--per-class: also the balls plus the inside cells they leave uncovered")  # fmt: skip
    ap.add_argument("--classes", nargs="+", default=[], help="only these classes (--diagnose)")
    ap.add_argument("--images", type=Path, default=None, help="folder of PNGs (--diagnose)")
    ap.add_argument("--voxels", action="store_true", help="LFD of the grid's inside (web)")
    ap.add_argument("--per-class", action="store_true",
                    help="web per class: mesh LFD, --n-balls (2048) light fields, grid inside")  # fmt: skip
    ap.add_argument("--n-balls", type=int, default=0,
                    help="decompose with this many balls (cached) instead of the defaults'")  # fmt: skip
    ap.add_argument("--fused", action="store_true",
                    help="v4 fused with the light fields of --n-balls balls")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None, help="JSON path (default by part and split)")
    args = ap.parse_args(argv)
    if args.diagnose:
        got = diagnose(args.diagnose, args.fills, args.images, args.n_balls, args.split,
                       args.classes)  # fmt: skip
        write_json(args.out or OUT / f"lightfield_fill_diagnose_{args.split}.json", got)
    elif args.fused:
        got = fused_longer(args.split, args.datasets, args.n_balls)
        write_json(args.out or OUT / f"lightfield_fill_fused_{args.split}.json", got)
    elif args.per_class:
        got = per_class(args.split, args.n_balls or 2048, args.residual)
        write_json(args.out or OUT / f"lightfield_fill_per_class_{args.split}.json", got)
    elif args.voxels:
        write_json(OUT / f"lightfield_fill_voxels_{args.split}.json", voxels(args.split))
    else:
        got = rank_fills(args.split, args.datasets, args.fills, args.n_balls)
        write_json(args.out or OUT / f"lightfield_fill_{args.split}.json", got)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
