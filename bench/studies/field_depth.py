"""Depth buffers and spherical harmonics of the field's inside, beside its light fields.

Usage (from the repository root)::

    export SHAPEDB_BENCH_CACHE=/work/bench_cache
    nice -n 5 python -m bench.studies.field_depth --fill --datasets web --split validation
    nice -n 5 python -m bench.studies.field_depth                     # web validation study
    nice -n 5 python -m bench.studies.field_depth --split test --datasets web webplus \
        --only "DBD 64 px, k 8" "SHD 32 x 16, grid" --triple 0.5 0.5   # the chosen fusion

For each model of a split (those :func:`bench.cached.load` has): the field of
:func:`shapedb.mdbd.prepare_field` and its inside (:func:`shapedb.inside.field_inside`,
its shell cells), cached under ``$SHAPEDB_BENCH_CACHE/field_depth``. From the shell:

- :func:`depth_buffer_descriptor` (Vranic's DBD): the cells in their principal frame,
  six orthographic depth images (+-x, +-y, +-z), low-frequency 2D Fourier magnitudes,
  made invariant to the frame's sign flips (mirror-symmetrised magnitudes; opposite views
  paired by sum and absolute difference).
- :func:`harmonic_descriptor` (Kazhdan's SHD): spherical-harmonic energies of the shell
  cells on concentric spheres about the volume centroid (rotation invariant);
  :func:`harmonic_descriptor_grid` the same with directions snapped to an angle grid and
  the harmonics evaluated once (a twentieth of the cost).

Both are compared by L1 (indexable). Measured alone and fused with the cached field
light fields (:func:`bench.inside_fields.light_fields`, 3 x 128 px) and the mesh light
field descriptor (:func:`bench.rerank_select.lfd_matrix`), in the same run: fusion is
the sum of distances each divided by its median off-diagonal distance, the second
weighted. Results go to bench/results/studies/field_depth_<split>.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bench.cached import CHOICES, ENGINE_COMMITS, load
from bench.common import cache_path, format_table, retrieval_scores, write_json
from bench.datasets import CACHE_DIR, Dataset
from bench.inside_fields import model_inside
from shapedb.config import MDBDConfig

FloatArray = NDArray[np.float64]
#: Bump when the cached shells change.
VERSION = "v1"
FOLDER = CACHE_DIR / "field_depth"
RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


# --------------------------------------------------------------------------------------
# Cached shells of the field's inside
# --------------------------------------------------------------------------------------


def _paths(model: Any) -> list[Path]:
    """Today's cache path of a model's shell, then those of the older engines
    (:data:`bench.cached.ENGINE_COMMITS`, whose fields are today's)."""
    cfg = MDBDConfig()
    keys = [cache_path(model, "mesh", cfg).stem]
    keys += [cache_path(model, "mesh", cfg, engine_commit=c).stem for c in ENGINE_COMMITS]
    return [FOLDER / f"{k}_{VERSION}.npz" for k in keys]


def _path(model: Any) -> Path:
    """The model's cached shell if any engine's exists, else today's path."""
    paths = _paths(model)
    return next((p for p in paths if p.exists()), paths[0])


def _compute(args: tuple[Any, str]) -> str | None:
    """Worker: the model's field and its inside's shell, written to ``path``."""
    model, path = args
    try:
        inside, field_cpu = model_inside(model)
        tmp = f"{path}.{os.getpid()}.tmp.npz"
        np.savez_compressed(
            tmp, shell=inside.shell.astype(np.float32), cell=np.float64(inside.cell),
            centroid=inside.centroid, count=np.int64(inside.count),
            field_cpu=np.float64(field_cpu),
        )  # fmt: skip
        Path(tmp).replace(path)
    except Exception as exc:  # noqa: BLE001 - reported per model, the run goes on
        return f"{model.name}: {type(exc).__name__}: {exc}"
    return None


def fill(ds: Dataset, *, workers: int = 2) -> None:
    """Compute the shells the cache lacks for ``ds``'s models."""
    from concurrent.futures import ProcessPoolExecutor

    FOLDER.mkdir(parents=True, exist_ok=True)
    todo = [(m, str(_path(m))) for m in ds.models if not _path(m).exists()]
    if not todo:
        return
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for err in pool.map(_compute, todo, chunksize=2):
            if err:
                print(f"  failed {err}", flush=True)
    print(f"  {len(todo)} shells computed ({time.perf_counter() - t0:.0f} s)", flush=True)


def shells(ds: Dataset, *, workers: int = 2) -> list[dict[str, Any]]:
    """Per model of ``ds``: its cached shell (``shell`` (s, 3), ``cell``, ``centroid``,
    ``count``, ``field_cpu``), computing what the cache lacks."""
    fill(ds, workers=workers)
    out = []
    for m in ds.models:
        p = _path(m)
        if not p.exists():
            raise ValueError(f"no field shell for {m.name}")
        with np.load(p) as z:
            out.append({k: np.asarray(z[k]) for k in z.files})
    return out


# --------------------------------------------------------------------------------------
# Descriptors of a shell
# --------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class DepthConfig:
    """Depth buffer descriptor settings.

    Attributes
    ----------
    resolution : int
        Pixels along each side of the six depth images, >= 8.
    frequencies : int
        Fourier coefficients kept: ``0 <= u, v`` with ``u + v <= frequencies``.
    """

    resolution: int = 64
    frequencies: int = 8


def principal_coordinates(shell: ArrayLike, centroid: ArrayLike) -> tuple[FloatArray, float]:
    """The shell's cells about ``centroid`` in their principal frame, scaled into the unit cube.

    Parameters
    ----------
    shell : (s, 3) float
        Cell centres, model units; s >= 1.
    centroid : (3,) float
        The solid's volume centroid, model units.

    Returns
    -------
    (s, 3) float64, float
        Coordinates along the principal axes (largest variance first), divided by the
        largest absolute coordinate so they lie in [-1, 1]; and that divisor (model units).
        Axis signs are arbitrary: the descriptors are invariant to them.

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    x = np.asarray(shell, dtype=np.float64) - np.asarray(centroid, dtype=np.float64)
    if len(x) == 0:
        raise ValueError("empty shell: no inside cell")
    w, v = np.linalg.eigh(x.T @ x / len(x))
    y = x @ v[:, ::-1]
    s = float(np.abs(y).max())
    if not s > 0:
        raise ValueError("degenerate shell: every cell on the centroid")
    return y / s, s


def depth_images(coords: ArrayLike, half_cell: float, resolution: int) -> NDArray[np.float64]:
    """Six orthographic depth images of cells (cubes of ``2 * half_cell`` splatted as squares).

    Parameters
    ----------
    coords : (s, 3) float
        Cell centres in [-1, 1].
    half_cell : float
        Half a cell's edge in the same units.
    resolution : int
        Pixels per side.

    Returns
    -------
    (6, resolution, resolution) float64
        Views from +x, -x, +y, -y, +z, -z; image axes are the two other coordinates in
        increasing order (no mirroring between opposite views). A pixel holds the
        nearest surface's height above the far face of the unit cube, in [0, 1]
        (0: nothing seen).
    """
    c = np.asarray(coords, dtype=np.float64)
    n = int(resolution)
    pix = 2.0 / n
    r = int(np.ceil(max(half_cell - pix / 2, 0.0) / pix))
    out = np.zeros((6, n * n))
    for axis in range(3):
        a, b = [k for k in range(3) if k != axis]
        iu = np.floor((c[:, a] + 1.0) / pix).astype(np.int64)
        iv = np.floor((c[:, b] + 1.0) / pix).astype(np.int64)
        for sign, view in ((1.0, 2 * axis), (-1.0, 2 * axis + 1)):
            depth = (1.0 + sign * c[:, axis]) / 2.0
            img = out[view]
            for du in range(-r, r + 1):
                for dv in range(-r, r + 1):
                    u = np.clip(iu + du, 0, n - 1)
                    v = np.clip(iv + dv, 0, n - 1)
                    np.maximum.at(img, u * n + v, depth)
    return out.reshape(6, n, n)


def _flip_invariant(img: FloatArray, k: int) -> FloatArray:
    """Fourier magnitudes of an image made invariant to flipping either image axis."""
    f = np.abs(np.fft.fft2(img)) / img.size
    feats = []
    for u in range(k + 1):
        for v in range(k + 1 - u):
            a, b = f[u, v], f[-u, v]  # |F(u, v)|, |F(-u, v)| = |F(u, -v)|
            feats.append(a + b)
            if u and v:
                feats.append(abs(a - b))
    return np.asarray(feats)


def depth_buffer_descriptor(
    shell: ArrayLike, centroid: ArrayLike, cell: float, config: DepthConfig | None = None
) -> FloatArray:
    """Vranic's depth buffer descriptor of a solid's shell cells: (d,) float64.

    The cells in their principal frame (:func:`principal_coordinates`), six depth
    images (:func:`depth_images`), their low Fourier magnitudes made invariant to the
    principal axes' signs: each image's to flips of its axes, each pair of opposite
    views by the sum and the absolute difference of their features. Invariant to
    rotation, translation and scale up to the principal frame's stability; compare by L1.

    Parameters
    ----------
    shell : (s, 3) float
        Cell centres, model units.
    centroid : (3,) float
        Volume centroid, model units.
    cell : float
        Cell edge, model units, > 0.
    config : DepthConfig, optional

    Raises
    ------
    ValueError
        As :func:`principal_coordinates`.
    """
    cfg = config or DepthConfig()
    y, s = principal_coordinates(shell, centroid)
    imgs = depth_images(y, cell / 2.0 / s, cfg.resolution)
    out = []
    for axis in range(3):
        p = _flip_invariant(imgs[2 * axis], cfg.frequencies)
        m = _flip_invariant(imgs[2 * axis + 1], cfg.frequencies)
        out += [p + m, np.abs(p - m)]
    return np.concatenate(out)


@functools.lru_cache(maxsize=4)
def _harmonics_on_grid(bands: int, n_theta: int) -> tuple[FloatArray, NDArray[np.complex128]]:
    """Conjugate harmonics ``Y_lm`` (l < bands, 0 <= m <= l) at the centres of an angle grid.

    Returns the per-column weights (2 for m > 0, else 1) and (n_theta * 2 n_theta, columns).
    """
    from scipy.special import sph_harm_y

    n_phi = 2 * n_theta
    t = (np.arange(n_theta) + 0.5) * np.pi / n_theta
    p = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    tt, pp = (a.reshape(-1) for a in np.meshgrid(t, p, indexing="ij"))
    cols, weights = [], []
    for n in range(bands):
        for m in range(n + 1):
            cols.append(np.conj(sph_harm_y(n, m, tt, pp)))
            weights.append(2.0 if m else 1.0)
    return np.asarray(weights), np.stack(cols, axis=1)


def _spherical(
    shell: ArrayLike, centroid: ArrayLike, shells: int
) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Each shell cell's ring (of ``shells`` up to twice the mean distance to ``centroid``),
    polar angle in [0, pi] and azimuth in (-pi, pi].

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    x = np.asarray(shell, dtype=np.float64) - np.asarray(centroid, dtype=np.float64)
    dist = np.linalg.norm(x, axis=1)
    mean = float(dist.mean()) if len(x) else 0.0
    if not mean > 0:
        raise ValueError("degenerate shell: empty or every cell on the centroid")
    ring = np.minimum((dist / (2.0 * mean) * shells).astype(np.int64), shells - 1)
    theta = np.arccos(np.clip(x[:, 2] / np.maximum(dist, 1e-300), -1.0, 1.0))
    return ring, theta, np.arctan2(x[:, 1], x[:, 0])


def harmonic_descriptor_grid(
    shell: ArrayLike, centroid: ArrayLike, *, shells: int = 32, bands: int = 16, n_theta: int = 64
) -> FloatArray:
    """:func:`harmonic_descriptor` with each cell's direction snapped to an angle grid.

    The cells are counted per ring and per cell of an ``n_theta`` x ``2 n_theta`` grid in
    polar and azimuthal angle, and the harmonics, evaluated once per grid
    (:func:`_harmonics_on_grid`, cached), summed by a matrix product: the same energies
    up to the snapping, at a fraction of the cost. (shells * bands,) float64.

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    ring, theta, phi = _spherical(shell, centroid, shells)
    phi = phi % (2 * np.pi)
    n_phi = 2 * n_theta
    it = np.minimum((theta / np.pi * n_theta).astype(np.int64), n_theta - 1)
    ip = np.minimum((phi / (2 * np.pi) * n_phi).astype(np.int64), n_phi - 1)
    g = n_theta * n_phi
    counts = np.bincount(ring * g + it * n_phi + ip, minlength=shells * g).reshape(shells, g)
    weights, table = _harmonics_on_grid(bands, n_theta)
    power = weights * np.abs(counts @ table) ** 2  # (shells, columns)
    degree = np.repeat(np.arange(bands), np.arange(1, bands + 1))
    out = np.stack([power[:, degree == n].sum(axis=1) for n in range(bands)], axis=1)
    return (np.sqrt(out) / len(ring)).reshape(-1)


def harmonic_descriptor(
    shell: ArrayLike, centroid: ArrayLike, *, shells: int = 32, bands: int = 16
) -> FloatArray:
    """Spherical-harmonic energies of the shell cells on concentric spheres: (shells * bands,).

    Kazhdan's SHD over the cells (each a point mass): about the volume centroid, radii
    scaled by twice their mean and cut into ``shells`` rings; per ring and degree
    ``l < bands``, the norm of the degree's coefficients, divided by the number of
    cells. Rotation, translation and scale invariant up to the grid (a face tilted to
    the grid has more shell cells per area); compare by L1 or L2.

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    from scipy.special import sph_harm_y

    ring, theta, phi = _spherical(shell, centroid, shells)
    out = np.zeros((shells, bands))
    for n in range(bands):
        power = np.zeros(shells)
        for m in range(n + 1):
            y = sph_harm_y(n, m, theta, phi)
            a = np.bincount(ring, weights=y.real, minlength=shells) + 1j * np.bincount(
                ring, weights=y.imag, minlength=shells
            )
            power += (2.0 if m else 1.0) * np.abs(a) ** 2
        out[:, n] = np.sqrt(power) / len(ring)
    return out.reshape(-1)


# --------------------------------------------------------------------------------------
# The study
# --------------------------------------------------------------------------------------

#: Descriptors of the study: name -> (function of a cached shell, distance).
DESCRIPTORS: dict[str, tuple[Any, str]] = {
    "DBD 64 px, k 8": (
        lambda z: depth_buffer_descriptor(z["shell"], z["centroid"], float(z["cell"])),
        "cityblock",
    ),
    "DBD 32 px, k 6": (
        lambda z: depth_buffer_descriptor(
            z["shell"], z["centroid"], float(z["cell"]), DepthConfig(resolution=32, frequencies=6)
        ),
        "cityblock",
    ),
    "SHD 32 x 16": (lambda z: harmonic_descriptor(z["shell"], z["centroid"]), "cityblock"),
    "SHD 32 x 16, grid": (
        lambda z: harmonic_descriptor_grid(z["shell"], z["centroid"]),
        "cityblock",
    ),
    "SHD 32 x 16, L2": (lambda z: harmonic_descriptor(z["shell"], z["centroid"]), "euclidean"),
}
#: Descriptors run unless named (the L2 SHD, measured once on web validation, is not).
DEFAULT = ("DBD 64 px, k 8", "DBD 32 px, k 6", "SHD 32 x 16")
#: Three-way fusions: the field light fields + weight x DBD 64 px + weight x SHD (L1).
TRIPLES = ((0.25, 0.25), (0.25, 0.5), (0.5, 0.25), (0.5, 0.5))
#: Weights of the second distance tried in a fusion (chosen on validation).
WEIGHTS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0)


def descriptor_matrix(
    name: str, shells_: Sequence[dict[str, Any]], keys: Sequence[str]
) -> tuple[FloatArray, float]:
    """(n, n) distances of descriptor ``name`` between the shells; median CPU s per model."""
    import hashlib

    from scipy.spatial.distance import cdist

    fn, metric = DESCRIPTORS[name]
    text = Path(__file__).read_text()
    code = text[text.index("# Descriptors of a shell") : text.index("# The study")].encode()
    key = hashlib.sha256(code + name.encode() + "\n".join(keys).encode()).hexdigest()[:16]
    path = FOLDER / "matrices" / f"{key}.npz"
    if path.exists():
        with np.load(path) as z:
            return np.asarray(z["d"]), float(z["cpu"])
    rows, cpu = [], []
    for z in shells_:
        c0 = time.process_time()
        rows.append(fn(z))
        cpu.append(time.process_time() - c0)
    d = cdist(np.stack(rows), np.stack(rows), metric=metric)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, d=d, cpu=np.float64(np.median(cpu)))
    return d, float(np.median(cpu))


def _normalised(d: FloatArray) -> FloatArray:
    off = d[~np.eye(len(d), dtype=bool)]
    med = float(np.median(off))
    return d / med if med > 0 else d


def fuse(first: FloatArray, second: FloatArray, weight: float) -> FloatArray:
    """``first / median + weight * second / median`` (medians of the off-diagonal distances)."""
    return _normalised(first) + weight * _normalised(second)


def run(
    split: str,
    datasets: Sequence[str],
    only: Sequence[str] | None,
    weights: dict[str, float] | None = None,
    triple: tuple[float, float] | None = None,
) -> dict[str, Any]:
    """Scores per set: mesh LFD, field light fields, each descriptor alone and fused."""
    from bench.lightfield_source import matrices
    from shapedb.config import Config

    lf = dataclasses.replace(Config().light_field, source="field", resolution=128)
    table: dict[str, dict[str, dict[str, float]]] = {}
    sizes: dict[str, int] = {}
    cpu: dict[str, dict[str, float]] = {}
    names = list(DEFAULT) if not only else [n for n in DESCRIPTORS if n in only]
    dbd, shd = "DBD 64 px, k 8", "SHD 32 x 16"
    for name in datasets:
        t0 = time.perf_counter()
        ds, mats = matrices(name, split, {"field LF (3 x 128 px)": lf})
        labels = np.asarray(ds.labels)
        sizes[name] = len(ds)
        got = shells(ds)
        keys = [m.name + m.source for m in ds.models]
        cpu[name] = {"field": float(np.median([float(z["field_cpu"]) for z in got]))}
        base = mats["field LF (3 x 128 px)"]
        for label, d in mats.items():
            table.setdefault(label, {})[name] = retrieval_scores(-d, labels)
        got_d: dict[str, FloatArray] = {}
        for dn in names:
            d, c = descriptor_matrix(dn, got, keys)
            got_d[dn] = d
            cpu[name][dn] = c
            table.setdefault(dn, {})[name] = retrieval_scores(-d, labels)
            ws = [weights[dn]] if weights and dn in weights else list(WEIGHTS)
            for w in ws:
                table.setdefault(f"field LF + {w:g} x {dn}", {})[name] = retrieval_scores(
                    -fuse(base, d, w), labels
                )
        for sh in (shd, "SHD 32 x 16, grid"):
            if dbd not in got_d or sh not in got_d:
                continue
            tag = "SHD" if sh == shd else "SHD (grid)"
            for wd, ws_ in [triple] if triple else TRIPLES:
                fused = fuse(base, got_d[dbd], wd) + ws_ * _normalised(got_d[sh])
                table.setdefault(f"field LF + {wd:g} x DBD + {ws_:g} x {tag}", {})[name] = (
                    retrieval_scores(-fused, labels)
                )
        print(f"  {name}: {len(ds)} models ({time.perf_counter() - t0:.0f} s)", flush=True)
    rows = [[label, *(f"{v[n]['nn']:.3f} / {v[n]['first_tier']:.3f} / {v[n]['dcg']:.3f}"
                      if n in v else "" for n in datasets)] for label, v in table.items()]  # fmt: skip
    print(format_table(f"depth buffers and harmonics of the field, {split} (NN / 1-T / DCG)",
                       ("descriptor", *(f"{n} ({sizes[n]})" for n in datasets)), rows))  # fmt: skip
    print(f"median CPU s per model: {cpu}")
    return {"split": split, "sizes": sizes, "table": table, "cpu": cpu}


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the exit status."""
    ap = argparse.ArgumentParser(prog="python -m bench.studies.field_depth",
                                 description=__doc__.split("\n")[0])  # fmt: skip
    ap.add_argument("--split", default="validation", choices=["validation", "test"])
    ap.add_argument("--datasets", nargs="+", default=["web"], choices=CHOICES)
    ap.add_argument("--only", nargs="*", default=None, choices=list(DESCRIPTORS))
    ap.add_argument("--weight", type=float, default=None,
                    help="the one fusion weight (default: every weight of WEIGHTS)")  # fmt: skip
    ap.add_argument("--triple", type=float, nargs=2, default=None,
                    help="the one three-way fusion: weights of the DBD and the SHD")  # fmt: skip
    ap.add_argument("--fill", action="store_true", help="only compute the shells")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.fill:
        for name in args.datasets:
            ds, _ = load(name, args.split)
            fill(ds)
        return 0
    weights = None
    if args.weight is not None:
        weights = {n: args.weight for n in (args.only or DESCRIPTORS)}
    triple = tuple(args.triple) if args.triple else None
    got = run(args.split, args.datasets, args.only, weights, triple)
    out = args.out or RESULTS / f"field_depth_{args.split}_{'_'.join(args.datasets)}.json"
    write_json(out, got)
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
