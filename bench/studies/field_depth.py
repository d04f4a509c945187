"""Depth buffers and spherical harmonics of the field's inside, beside its light fields.

Usage (from the repository root)::

    export SHAPEDB_BENCH_CACHE=/work/bench_cache
    nice -n 5 python -m bench.studies.field_depth --fill --datasets web --split validation
    nice -n 5 python -m bench.studies.field_depth                     # web validation study
    nice -n 5 python -m bench.studies.field_depth --split test --datasets web webplus \
        --only "DBD 64 px, k 8" "SHD 32 x 16, grid" --triple 0.5 0.5   # the chosen fusion

For each model of a split (those :func:`bench.support.cached.load` has): the field of
:func:`shapedb.mdbd.decomposition.prepare_field` and its inside (:func:`shapedb.geometry.inside.field_inside`,
its shell cells), cached by :mod:`bench.support.field_shells`. From the shell (the
descriptors the product stores, :mod:`shapedb.signature.field_vector`):

- :func:`depth_buffer_descriptor` (Vranic's DBD): the cells in their principal frame,
  six orthographic depth images (+-x, +-y, +-z), low-frequency 2D Fourier magnitudes,
  made invariant to the frame's sign flips (mirror-symmetrised magnitudes; opposite views
  paired by sum and absolute difference).
- :func:`harmonic_descriptor` (Kazhdan's SHD): spherical-harmonic energies of the shell
  cells on concentric spheres about the volume centroid (rotation invariant);
  :func:`harmonic_descriptor_grid` the same with directions snapped to an angle grid and
  the harmonics evaluated once (a twentieth of the cost; the product's
  :func:`shapedb.signature.field_vector.harmonic_energies`).

Both are compared by L1 (indexable). Measured alone and fused with the cached field
light fields (:func:`bench.support.inside_fields.light_fields`, 3 x 128 px) and the mesh light
field descriptor (:func:`bench.support.lightfield.lfd_matrix`), in the same run: fusion is
the sum of distances each divided by its median off-diagonal distance, the second
weighted. Results go to bench/results/studies/field_depth_<split>.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bench.common import format_table, retrieval_scores, write_json
from bench.support.cached import CHOICES, load
from bench.support.field_shells import FOLDER, fill, shells
from shapedb.config.core import FieldVectorConfig
from shapedb.signature import field_vector
from shapedb.signature.field_vector import spherical_coordinates

FloatArray = NDArray[np.float64]
RESULTS = Path(__file__).resolve().parents[1] / "results" / "studies"


# --------------------------------------------------------------------------------------
# Descriptors of a shell
# --------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class DepthConfig:
    """Depth buffer descriptor settings (``FieldVectorConfig``'s depth fields).

    Attributes
    ----------
    resolution : int
        Pixels along each side of the six depth images, >= 8.
    frequencies : int
        Fourier coefficients kept: ``0 <= u, v`` with ``u + v <= frequencies``.
    """

    resolution: int = 64
    frequencies: int = 8


def depth_buffer_descriptor(
    shell: ArrayLike, centroid: ArrayLike, cell: float, config: DepthConfig | None = None
) -> FloatArray:
    """:func:`shapedb.signature.field_vector.depth_buffer_descriptor` at ``config``'s settings."""
    cfg = config or DepthConfig()
    fv = FieldVectorConfig(depth_resolution=cfg.resolution, depth_frequencies=cfg.frequencies)
    return field_vector.depth_buffer_descriptor(shell, centroid, cell, fv)


def harmonic_descriptor_grid(
    shell: ArrayLike, centroid: ArrayLike, *, shells: int = 32, bands: int = 16, n_theta: int = 64
) -> FloatArray:
    """:func:`shapedb.signature.field_vector.harmonic_energies` (the harmonics on an angle grid,
    the product's) at these settings: (shells * bands,) float64."""
    fv = FieldVectorConfig(harmonic_shells=shells, harmonic_bands=bands, harmonic_angles=n_theta)
    return field_vector.harmonic_energies(shell, centroid, fv)


def harmonic_descriptor(
    shell: ArrayLike, centroid: ArrayLike, *, shells: int = 32, bands: int = 16
) -> FloatArray:
    """Spherical-harmonic energies of the shell cells on concentric spheres: (shells * bands,).

    Kazhdan's SHD over the cells (each a point mass): about the volume centroid, radii
    scaled by twice their mean and cut into ``shells`` rings; per ring and degree
    ``l < bands``, the norm of the degree's coefficients, divided by the number of
    cells, with the harmonics evaluated at every cell's exact direction (the product's
    :func:`harmonic_descriptor_grid` snaps them to an angle grid). Rotation, translation
    and scale invariant up to the grid (a face tilted to the grid has more shell cells
    per area); compare by L1 or L2.

    Raises
    ------
    ValueError
        If the shell is empty or all its cells sit on the centroid.
    """
    from scipy.special import sph_harm_y

    ring, theta, phi = spherical_coordinates(shell, centroid, shells)
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
    code += inspect.getsource(field_vector).encode()
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
    from bench.studies.lightfield_source import matrices
    from shapedb.config.core import Config

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
