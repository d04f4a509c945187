"""Shared pieces of the bench scripts: tables, JSON, retrieval scores, cached decompositions.

Decompositions are cached in ``bench/results/cache/dec/`` as npz files keyed by the
model's source (path, size and content digest, or generator spec), the
representation variant and the parameters the balls depend on, so that reruns only
compute what changed. The contact tolerance is not part of the key: the balls do not
depend on it, and the contact graph is rebuilt at the requested tolerance on loading.
They are computed by a pool of worker processes (2 by default).
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import hashlib
import json
import logging
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bench.sets.datasets import (
    CACHE_DIR,
    Model,
    mesh_arrays,
    min_cloud_points,
    people_version,
    point_cloud,
    stable_seed,
)
from shapedb.config.core import CloudConfig, MDBDConfig

__all__ = [
    "code_digest",
    "format_table",
    "write_json",
    "log_margin",
    "retrieval_scores",
    "class_nn",
    "per_query",
    "Balls",
    "VARIANTS",
    "RECON_BASE_DEPTH",
    "recon_variant",
    "decompose_all",
    "mdbd_config",
]

logger = logging.getLogger(__name__)

#: Measures reported in every table, in order.
MEASURES = ("nn", "first_tier", "second_tier", "e_measure", "dcg")


# --------------------------------------------------------------------------------------
# Tables and JSON
# --------------------------------------------------------------------------------------


def format_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A plain-text table: floats with 3 decimals, columns aligned.

    Parameters
    ----------
    title : str
        Printed above the table.
    columns : sequence of str
        Header.
    rows : sequence of sequences
        Cells; floats are formatted ``.3f``, ``None`` as ``-``.
    """

    def cell(x: Any) -> str:
        if x is None:
            return "-"
        if isinstance(x, float | np.floating):
            return f"{x:.3f}"
        return str(x)

    text = [[cell(c) for c in columns]] + [[cell(c) for c in r] for r in rows]
    widths = [max(len(r[k]) for r in text) for k in range(len(columns))]
    lines = [title, "-" * len(title)]
    for n, r in enumerate(text):
        lines.append(
            "  ".join(
                c.ljust(w) if k == 0 else c.rjust(w)
                for k, (c, w) in enumerate(zip(r, widths, strict=True))
            )
        )
        if n == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _plain(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating | float):
        return None if not np.isfinite(obj) else round(float(obj), 5)
    return obj


def write_json(path: Path | str, data: Any) -> None:
    """Write ``data`` (numpy values allowed) as indented JSON, atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(_plain(data), indent=1, sort_keys=False) + "\n")
    tmp.replace(path)


# --------------------------------------------------------------------------------------
# Retrieval scores (Princeton Shape Benchmark measures)
# --------------------------------------------------------------------------------------


def _psb_scores(similarity: NDArray[np.float64], labels: NDArray[Any]) -> dict[str, float]:
    """NN, 1-T, 2-T, E (top 32) and normalised DCG, each query excluding itself."""
    n = len(labels)
    sums = dict.fromkeys(MEASURES, 0.0)
    counted = 0
    _, inverse, counts = np.unique(labels, return_inverse=True, return_counts=True)
    for i in range(n):
        c = int(counts[inverse[i]])
        if c < 2:
            continue
        others = np.delete(np.arange(n), i)
        order = others[np.argsort(-similarity[i, others], kind="stable")]
        rel = (inverse[order] == inverse[i]).astype(np.float64)
        k = c - 1
        sums["nn"] += rel[0]
        sums["first_tier"] += rel[:k].sum() / k
        sums["second_tier"] += rel[: 2 * k].sum() / k
        hits = rel[:32].sum()
        p, r = hits / 32, hits / k
        sums["e_measure"] += 0.0 if hits == 0 else 2 * p * r / (p + r)
        disc = np.ones(len(rel))
        disc[1:] = 1.0 / np.log2(np.arange(2, len(rel) + 1))
        sums["dcg"] += (rel * disc).sum() / disc[:k].sum()
        counted += 1
    return {m: sums[m] / max(counted, 1) for m in MEASURES}


def class_nn(d: NDArray[np.float64], labels: NDArray[np.str_]) -> dict[str, float]:
    """Per class, the fraction of its queries whose nearest other model shares its class.

    ``d``: (n, n) distances (the diagonal is ignored); ``labels``: (n,) classes.
    Ties go to the lower index, as :func:`numpy.argmin` breaks them.
    """
    d = np.array(d, dtype=np.float64)
    np.fill_diagonal(d, np.inf)
    hit = labels[np.argmin(d, axis=1)] == labels
    return {str(k): float(hit[labels == k].mean()) for k in dict.fromkeys(labels.tolist())}


def per_query(
    d: NDArray[np.float64], labels: Sequence[str]
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """Per query of an (n, n) distance matrix: nearest neighbour right, first-tier share.

    The query itself is left out; a class of one model gets first tier 0.
    """
    d = np.array(d, np.float64)
    np.fill_diagonal(d, np.inf)
    lab = np.asarray(labels)
    nn = lab[np.argmin(d, axis=1)] == lab
    tier = np.zeros(len(lab))
    for i in range(len(lab)):
        k = int((lab == lab[i]).sum()) - 1
        if k:
            tier[i] = (lab[np.argsort(d[i], kind="stable")[:k]] == lab[i]).sum() / k
    return nn, tier


def log_margin(d: NDArray[np.float64], labels: NDArray[Any]) -> float:
    """Mean over queries (rows) of log(d(nearest same class) / d(nearest other class)).

    The diagonal (a query against itself, or against its own model in another
    representation) is left out; lower is better, and far less noisy than NN.
    """
    same = labels[:, None] == labels[None, :]
    off = ~np.eye(len(labels), dtype=bool)
    near = np.where(same & off, d, np.inf).min(1) / np.where(~same, d, np.inf).min(1)
    ok = np.isfinite(near) & (near > 0)
    return float(np.mean(np.log(near[ok])))


def retrieval_scores(similarity: ArrayLike, labels: ArrayLike) -> dict[str, float]:
    """PSB measures of an (n, n) similarity matrix; larger is more similar.

    Uses ``query.evaluate.retrieval_scores`` when that module exists, so the bench
    and ``db.evaluate`` agree; otherwise the same definitions implemented here.
    """
    s = np.asarray(similarity, dtype=np.float64)
    lab = np.asarray(labels)
    try:
        from query.evaluate import retrieval_scores as library_scores
    except ImportError:
        return _psb_scores(s, lab)
    res = library_scores(s, lab)
    out = {}
    for m in MEASURES:
        v = getattr(res, m, None)
        if v is None and isinstance(res, dict):
            v = res.get(m)
        out[m] = float(v) if v is not None else float("nan")
    if not all(np.isfinite(list(out.values()))):  # an interface we do not know: ours
        return _psb_scores(s, lab)
    return out


# --------------------------------------------------------------------------------------
# Cached decompositions
# --------------------------------------------------------------------------------------

#: Representation variants a model can be decomposed in.
VARIANTS = (
    "mesh",
    "pointcloud",
    "mesh_shift",
    "mesh_rotate",
    "mesh_decimate",
    "pointcloud_b",
    "pointcloud_sphere",
    "pointcloud_noisy",
    "pointcloud_partial",
    "pointcloud_recon",
    "pointcloud_noisy_recon",
    "pointcloud_partial_recon",
    "pointcloud_recon_d6",
    "pointcloud_recon_d7",
    "pointcloud_turn_0",
    "pointcloud_turn_1",
    "pointcloud_turn_2",
    "pointcloud_dense",
    "mesh_subdivide",
    "mesh_turn_0.01",
    "mesh_turn_0.5",
    "mesh_turn_2",
    "pointcloud_scan",
    "pointcloud_scan_recon",
    "mesh_cropped",
)

#: The :mod:`bench.sets.scans` variants and the query kind whose seed they share with
#: ``python -m bench.quality --queries`` (:mod:`bench.support.scan_queries`).
SCAN_VARIANTS = {"pointcloud_scan": "one-sided", "mesh_cropped": "cropped"}

#: Axis (unit) of the ``mesh_turn_*`` variants' rotations about the vertex centroid.
TURN_AXIS = np.array([0.6, 0.64, 0.48])

#: Turn of the ``pointcloud_turn_<axis>`` variants about their frame's axis, degrees.
CLOUD_TURN_DEGREES = 1.0

#: Surface samples of the ``pointcloud_dense`` variant.
DENSE_SAMPLES = 20_000

#: Poisson octree depth of the unsuffixed ``*_recon`` variants (``*_recon_d<depth>``:
#: another depth). Fixed, not the store default, so that cached files keep their meaning.
RECON_BASE_DEPTH = 8


def recon_variant(base: str = "pointcloud", depth: int | None = None) -> str:
    """The variant of ``base``'s reconstructions at Poisson ``depth``.

    ``depth`` None: a default store's (``CloudConfig.reconstruct_depth``).
    """
    d = CloudConfig().reconstruct_depth if depth is None else depth
    return f"{base}_recon" if d == RECON_BASE_DEPTH else f"{base}_recon_d{d}"


@dataclass(frozen=True, eq=False)
class Balls:
    """A cached decomposition: the arrays the descriptors need, and the timing.

    Attributes
    ----------
    centers : (n, 3) float64
    radii : (n,) float64
        Non-increasing.
    edges : (m, 2) int64
    spacing : float
        Grid cell size, model units.
    seconds : float
        Wall-clock time of geometry construction plus decomposition.
    timings : dict
        The decomposition's own per-stage timings.
    sampling : float
        The source's surface sample spacing, model units (0.0 for exact surfaces).
    """

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    edges: NDArray[np.int64]
    spacing: float
    seconds: float
    timings: dict[str, float] = field(default_factory=dict)
    sampling: float = 0.0

    def truncate(self, n: int) -> Balls:
        """The first ``n`` balls and the contacts among them (greedy MDBD prefix)."""
        if n >= len(self.radii):
            return self
        e = self.edges[(self.edges < n).all(axis=1)]
        return Balls(
            self.centers[:n], self.radii[:n], e, self.spacing, self.seconds, self.timings,
            self.sampling,
        )  # fmt: skip

    def with_contact_tol(self, tol_cells: float) -> Balls:
        """The same balls with their contacts found again at ``tol_cells`` grid cells."""
        from shapedb.mdbd.graph import contact_edges

        edges = contact_edges(self.centers, self.radii, tol_cells * self.spacing)
        return replace(self, edges=edges.astype(np.int64).reshape(-1, 2))

    def decomposition(self) -> Any:
        """A :class:`shapedb.mdbd.decomposition.Decomposition` with these balls."""
        from shapedb.mdbd.decomposition import Decomposition

        lo = (self.centers - self.radii[:, None]).min(axis=0)
        hi = (self.centers + self.radii[:, None]).max(axis=0)
        return Decomposition(
            centers=self.centers,
            radii=self.radii,
            edges=self.edges.astype(np.int32),
            spacing=self.spacing,
            bounds=np.stack([lo, hi]),
            sampling=self.sampling,
        )


@functools.lru_cache(maxsize=65536)
def _file_digest(path: str, size: int, mtime_ns: int) -> str:
    """sha256 (16 hex) of a file's content; cached per path, size and mtime."""
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()[:16]


def _source_key(model: Model) -> str:
    """The model's source: path, size and content digest of a file, else its spec.

    The content, not the modification time, so that data copied afresh (same bytes,
    new mtime) keeps its cached decompositions.
    """
    if os.path.exists(model.source):
        st = os.stat(model.source)
        digest = _file_digest(model.source, st.st_size, st.st_mtime_ns)
        return f"{model.source}:{st.st_size}:{digest}"
    if model.source.startswith("person:"):
        return f"{model.source}:{people_version()}"
    return model.source


#: Core modules whose source decides what a decomposition is: the cache key includes
#: their content, so an engine change never reuses stale decompositions.
_ENGINE_MODULES = (
    "geometry", "mesh", "pointcloud", "voxels", "implicit", "complement", "_meshing",
    "frame", "refine", "packing", "mdbd", "graph", "sheet", "surface_fit",
)  # fmt: skip
#: Where each engine module lives under shapedb/ today (the keys are the flat names it had
#: before the subpackages, which older commits' files are read by).
_ENGINE_PATHS = {
    "geometry": "geometry/base", "mdbd": "mdbd/decomposition", "frame": "mdbd/frame",
    "refine": "mdbd/refine", "packing": "mdbd/packing", "graph": "mdbd/graph",
    "reconstruct": "mdbd/reconstruct", "config": "config/core",
}  # fmt: skip


def _engine_path(name: str) -> str:
    return _ENGINE_PATHS.get(name, f"geometry/{name}")


def _code_only(source: str) -> str:
    """``source``'s syntax tree without docstrings (comments are not in it)."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (
            isinstance(body, list)
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)
        ):
            body[0] = ast.Pass()
    return ast.dump(tree)


@functools.lru_cache(maxsize=256)
def _source_at(commit: str, module: str) -> str | None:
    """``shapedb/<module>.py`` at ``commit``, else the module at its place in the subpackages
    (:data:`_ENGINE_PATHS`); None if it did not exist then."""
    import subprocess

    root = Path(__file__).resolve().parents[1]
    for where in dict.fromkeys((module, _engine_path(module))):
        done = subprocess.run(
            ["git", "show", f"{commit}:shapedb/{where}.py"],
            cwd=root, capture_output=True, text=True, check=False,
        )  # fmt: skip
        if done.returncode == 0:
            return done.stdout
    return None


@functools.lru_cache(maxsize=256)
def _module_code(path: str, size: int, mtime_ns: int) -> str:
    """:func:`_code_only` of the file at ``path``; cached per path, size and mtime."""
    return _code_only(Path(path).read_text())


@functools.lru_cache(maxsize=256)
def _code_at(commit: str, module: str) -> str | None:
    """:func:`_code_only` of ``shapedb/<module>.py`` at ``commit`` (None if absent)."""
    source = _source_at(commit, module)
    return None if source is None else _code_only(source)


def code_digest(paths: Sequence[Path]) -> str:
    """A digest (16 hex) of the code of the Python files ``paths`` (docstrings and comments
    left out, so documentation edits keep what is keyed by it), in sorted order."""
    digest = hashlib.sha256()
    for path in sorted(Path(p) for p in paths):
        st = path.stat()
        digest.update(_module_code(str(path), st.st_size, st.st_mtime_ns).encode())
    return digest.hexdigest()[:16]


def engine_version(variant: str | None = None, *, commit: str | None = None) -> str:
    """A digest (16 hex) of the decomposition engine's code.

    ``commit``: of the engine as it was at that git commit of this repository (the
    modules it did not have yet left out), to read decompositions cached then.

    Docstrings and comments do not count, so documentation edits keep the cache.
    Mesh variants leave ``pointcloud.py`` and ``surface_fit.py`` out of it, so that
    work on the point-cloud distance does not recompute every mesh decomposition; ``view_*`` variants (sparse
    views, decomposed as point clouds) add ``view.py``.
    """
    import shapedb

    root = Path(shapedb.__file__).parent
    digest = hashlib.sha256()
    clouds = variant is None or variant.startswith(("pointcloud", "view_"))
    skip = () if clouds else ("pointcloud", "surface_fit")
    modules = (
        (*_ENGINE_MODULES, "view") if variant and variant.startswith("view_") else _ENGINE_MODULES
    )
    if variant and variant.startswith("pointcloud") and "_recon" in variant:
        modules = (*modules, "reconstruct")
    for name in modules:
        if name in skip:
            continue
        if commit is None:
            path = root / f"{_engine_path(name)}.py"
            st = path.stat()
            code: str | None = _module_code(str(path), st.st_size, st.st_mtime_ns)
        else:
            code = _code_at(commit, name)
        if code is not None:
            digest.update(code.encode())
    return digest.hexdigest()[:16]


def mdbd_config(
    base: MDBDConfig | None = None,
    *,
    resolution: int | None = None,
    n_balls: int | None = None,
    no_refine: bool = False,
) -> MDBDConfig:
    """``base`` (default ``MDBDConfig()``) with the bench scripts' command-line overrides."""
    cfg = base or MDBDConfig()
    if resolution:
        cfg = replace(cfg, resolution=resolution)
    if n_balls:
        cfg = replace(cfg, n_balls=n_balls)
    return replace(cfg, refine=False) if no_refine else cfg


def cache_path(
    model: Model, variant: str, config: MDBDConfig, *, engine_commit: str | None = None
) -> Path:
    """Where the decomposition of ``model`` in ``variant`` with ``config`` is cached.

    The key holds the model's source, the variant, the config (without
    ``contact_tol_cells``, which only the contact graph depends on) and
    :func:`engine_version` of the variant. ``engine_commit``: the key an older engine
    used (its code at that commit; ``sheet_cells`` left out of the config if it had
    no ``sheet.py``, ``sheet_rule`` if its configuration had none), to read what it
    cached where the changes since cannot matter.
    """
    params = asdict(config)
    del params["contact_tol_cells"]
    if engine_commit is not None and _source_at(engine_commit, "sheet") is None:
        del params["sheet_cells"]
    if engine_commit is not None and "sheet_rule" not in (
        _source_at(engine_commit, "config") or ""
    ):
        del params["sheet_rule"]
    version = engine_version(variant, commit=engine_commit)
    key = [_source_key(model), variant, params, version]
    if variant.startswith(("pointcloud_noisy", "pointcloud_partial")):
        key.append(people_version("scans"))  # bench.sets.people makes these clouds
    if variant.startswith(tuple(SCAN_VARIANTS)):
        key.append(_scans_version())
    text = json.dumps(key, sort_keys=True)
    digest = hashlib.sha256(text.encode()).hexdigest()[:20]
    return CACHE_DIR / "dec" / f"{digest}.npz"


@functools.lru_cache(maxsize=1)
def _scans_version() -> str:
    """sha256 (8 hex) of :mod:`bench.sets.scans`, which makes the scan variants."""
    from bench.sets import scans

    return hashlib.sha256(Path(scans.__file__).read_bytes()).hexdigest()[:8]


def existing_cache_path(
    model: Model, variant: str, config: MDBDConfig, commits: Sequence[str] = ()
) -> Path:
    """Today's cache path of ``model`` in ``variant`` if it exists, else an older engine's.

    ``commits``: engines (git commits of this repository) whose keys are tried in
    order (:func:`cache_path` with ``engine_commit``); today's path when none exists.
    Only for variants whose decomposition the changes since those commits leave alone.
    """
    path = cache_path(model, variant, config)
    if path.exists():
        return path
    for commit in commits:
        old = cache_path(model, variant, config, engine_commit=commit)
        if old.exists():
            return old
    return path


def _rotation(seed: int) -> NDArray[np.float64]:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def variant_geometry(model: Model, variant: str, config: MDBDConfig) -> Any:
    """The geometry of ``model`` in a representation variant.

    ``mesh`` the mesh; ``pointcloud`` the paper's point cloud (seeded by the name);
    ``pointcloud_b`` another draw of it; ``pointcloud_sphere`` the paper's cloud with
    the sphere-fit distance (``PointCloud(distance="sphere")``); ``pointcloud_noisy`` the paper's cloud with
    Gaussian noise (:func:`bench.sets.people.noisy_cloud`, sigma 0.3 % of the diagonal);
    ``pointcloud_partial`` the part of it one horizontal depth camera sees
    (:func:`bench.sets.people.partial_cloud`); ``pointcloud_dense`` DENSE_SAMPLES points
    sampled uniformly by area on the surface (no normals); ``mesh_shift`` the mesh translated by
    (0.37, 0.21, 0.43) grid cells; ``mesh_rotate`` randomly rotated (seeded);
    ``mesh_decimate`` decimated to 25 % of its faces (fast-simplification);
    ``pointcloud_recon`` the screened Poisson surface (depth :data:`RECON_BASE_DEPTH`)
    of the paper's point cloud (``pointcloud_noisy_recon``, ``pointcloud_partial_recon``:
    of those clouds)
    (:func:`shapedb.mdbd.reconstruct.reconstruct`, decomposed as a mesh; whether it is kept
    is decided against the cloud's own packing, :func:`shapedb.mdbd.reconstruct.volumes_agree`),
    ``pointcloud_recon_d<depth>`` the same at another octree depth;
    ``pointcloud_turn_<axis>`` the paper's point cloud in its canonical frame turned by
    :data:`CLOUD_TURN_DEGREES` about that frame axis (0-2) and decomposed without
    the canonical frame: another packing of the same cloud;
    ``pointcloud_scan`` what one depth camera sees (:func:`bench.sets.scans.one_sided_scan`),
    ``mesh_cropped`` half of the mesh (:func:`bench.sets.scans.cropped_mesh`), seeded as
    ``python -m bench.quality --queries one-sided cropped``;
    ``mesh_subdivide`` every triangle split in four at its edge midpoints (the same
    solid, other triangles); ``view_<cells>`` the mesh's sparse view
    (:func:`shapedb.geometry.view.view_geometry`, one sample per ``<cells>`` grid cells of its
    mesh decomposition); ``mesh_turn_<deg>`` rotated by ``<deg>`` degrees about
    :data:`TURN_AXIS` through the vertex centroid (decomposed without the canonical
    frame, this turns the grid against the solid by that angle).
    """
    from shapedb.geometry.mesh import TriangleMesh

    v, f = mesh_arrays(model)
    if variant.startswith("view_"):
        from shapedb.geometry.view import view_geometry

        spacing = _mesh_spacing(model, config)
        return view_geometry(TriangleMesh(v, f, name=model.name), spacing, float(variant[5:]))
    if "_recon" in variant and variant.startswith("pointcloud"):
        from shapedb.mdbd.reconstruct import reconstruct

        base, _, rest = variant.partition("_recon")
        depth = int(rest.removeprefix("_d")) if rest.startswith("_d") else RECON_BASE_DEPTH
        # in the cloud's frame, as shapedb.mdbd.reconstruct.reconstructed does
        surface = reconstruct(_framed_cloud(model, v, f, config, base), depth=depth)
        if surface is None:
            raise ValueError(f"{model.name}: no reconstruction")
        return surface
    if variant.startswith("pointcloud_turn_"):
        from scipy.spatial.transform import Rotation

        axis = np.eye(3)[int(variant.removeprefix("pointcloud_turn_"))]
        turn = Rotation.from_rotvec(np.deg2rad(CLOUD_TURN_DEGREES) * axis).as_matrix()
        return _framed_cloud(model, v, f, config).transformed(turn, np.zeros(3))
    if variant in ("pointcloud", "pointcloud_b", "pointcloud_sphere"):
        from shapedb.geometry.pointcloud import PointCloud

        seed = stable_seed(model.name, "pointcloud" if variant.endswith("sphere") else variant)
        points = point_cloud(v, f, seed=seed, min_points=min_cloud_points(model))
        if variant == "pointcloud_sphere":
            return PointCloud(points, distance="sphere")
        return PointCloud(points)
    if variant in ("pointcloud_noisy", "pointcloud_partial"):
        from bench.sets.people import noisy_cloud, partial_cloud
        from shapedb.geometry.pointcloud import PointCloud

        paper = point_cloud(
            v, f, seed=stable_seed(model.name, "pointcloud"), min_points=min_cloud_points(model)
        )
        seed = stable_seed(model.name, variant)
        if variant == "pointcloud_noisy":
            return PointCloud(noisy_cloud(paper, v, seed=seed))
        return PointCloud(partial_cloud(paper, v, f, seed=seed))
    if variant in SCAN_VARIANTS:
        from bench.sets import scans
        from shapedb.geometry.pointcloud import PointCloud

        seed = stable_seed(model.name, SCAN_VARIANTS[variant])
        if variant == "mesh_cropped":
            return TriangleMesh(*scans.cropped_mesh(v, f, seed=seed), name=model.name)
        return PointCloud(scans.one_sided_scan(v, f, seed=seed), name=model.name)
    if variant == "pointcloud_dense":
        from bench.support.baselines import sample_surface
        from shapedb.geometry.pointcloud import PointCloud

        rng = np.random.default_rng(stable_seed(model.name, variant))
        return PointCloud(sample_surface(v, f, DENSE_SAMPLES, rng=rng))
    if variant == "mesh_shift":
        extent = float((v.max(axis=0) - v.min(axis=0)).max())
        cell = extent / max(config.resolution - 2 * config.padding_cells, 1)
        v = v + cell * np.array([0.37, 0.21, 0.43])
    elif variant == "mesh_rotate":
        v = v @ _rotation(stable_seed(model.name, "rotate")).T
    elif variant == "mesh_decimate":
        import fast_simplification

        v, f = fast_simplification.simplify(
            v.astype(np.float32), f.astype(np.int32), target_reduction=0.75
        )
    elif variant == "mesh_subdivide":
        import trimesh

        v, f = trimesh.remesh.subdivide(v, f)
    elif variant.startswith("mesh_turn_") and variant in VARIANTS:
        from scipy.spatial.transform import Rotation

        angle = np.deg2rad(float(variant.removeprefix("mesh_turn_")))
        c = v.mean(axis=0)
        v = (v - c) @ Rotation.from_rotvec(angle * TURN_AXIS).as_matrix().T + c
    elif variant != "mesh":
        raise ValueError(f"unknown variant {variant!r}; known: {VARIANTS}")
    return TriangleMesh(v, f, name=model.name)


def _framed_cloud(
    model: Model,
    v: NDArray[np.float64],
    f: NDArray[np.int64],
    config: MDBDConfig,
    variant: str = "pointcloud",
) -> Any:
    """The cloud of ``model`` in a cloud ``variant``, moved into its canonical frame."""
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.mdbd.frame import canonical_frame

    if variant == "pointcloud":
        points = point_cloud(
            v, f, seed=stable_seed(model.name, "pointcloud"), min_points=min_cloud_points(model)
        )
        cloud = PointCloud(points)
    else:
        cloud = variant_geometry(model, variant, config)
    found = canonical_frame(cloud, config)
    return cloud if found is None else cloud.transformed(found[0].T, -found[0].T @ found[1])


def _mesh_spacing(model: Model, config: MDBDConfig) -> float:
    """Grid cell size of the model's mesh decomposition (cached, or decomposed now)."""
    path = cache_path(model, "mesh", config)
    if path.exists():
        return load_balls(path).spacing
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.mdbd.decomposition import decompose

    return float(decompose(TriangleMesh(*mesh_arrays(model)), config=config).spacing)


def _work(model: Model, variant: str, config: MDBDConfig, path: str) -> tuple[str, str | None]:
    """Worker: decompose one model variant and write its npz (or return the error)."""
    from shapedb.mdbd.decomposition import decompose

    try:
        t0 = time.perf_counter()
        geom = variant_geometry(model, variant, config)
        if variant.startswith("pointcloud_turn_"):  # the turn is against the canonical frame
            config = dataclasses.replace(config, canonical_frame=False)
        dec = decompose(geom, config=config)
        seconds = time.perf_counter() - t0
        tmp = path + f".{os.getpid()}.tmp.npz"
        np.savez_compressed(
            tmp,
            centers=np.asarray(dec.centers, dtype=np.float64),
            radii=np.asarray(dec.radii, dtype=np.float64),
            edges=np.asarray(dec.edges, dtype=np.int64).reshape(-1, 2),
            spacing=np.float64(dec.spacing),
            seconds=np.float64(seconds),
            timings=np.asarray(json.dumps(dict(dec.timings))),
            sampling=np.float64(dec.sampling),
            contact_tol_cells=np.float64(config.contact_tol_cells),
        )
        os.replace(tmp, path)
        return path, None
    except Exception as exc:  # noqa: BLE001 - reported per model, the run goes on
        return path, f"{type(exc).__name__}: {exc}"


#: The contact tolerance of cache files written before it was recorded in them.
_LEGACY_TOL_CELLS = 0.5


def load_balls(path: Path | str, contact_tol_cells: float | None = None) -> Balls:
    """Read a cached decomposition.

    With ``contact_tol_cells`` (grid cells), the contact graph is rebuilt at that
    tolerance when the file's was another.
    """
    with np.load(path) as z:
        b = Balls(
            centers=z["centers"],
            radii=z["radii"],
            edges=z["edges"],
            spacing=float(z["spacing"]),
            seconds=float(z["seconds"]),
            timings=json.loads(str(z["timings"])),
            sampling=float(z["sampling"]) if "sampling" in z else 0.0,
        )
        tol = float(z["contact_tol_cells"]) if "contact_tol_cells" in z else _LEGACY_TOL_CELLS
    if contact_tol_cells is None or contact_tol_cells == tol or len(b.radii) == 0:
        return b
    return b.with_contact_tol(contact_tol_cells)


def decompose_all(
    models: Sequence[Model],
    variant: str,
    config: MDBDConfig,
    *,
    workers: int = 2,
    progress: Callable[[str], None] | None = print,
) -> list[Balls | None]:
    """Decompositions of ``models`` in ``variant``, from the cache or computed in parallel.

    Returns
    -------
    list of Balls or None
        One entry per model; None where the decomposition failed (reported).
    """
    paths = [cache_path(m, variant, config) for m in models]
    todo = [i for i, p in enumerate(paths) if not p.exists()]
    errors: dict[int, str] = {}
    if todo:
        paths[0].parent.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        if workers <= 1:
            results = [_work(models[i], variant, config, str(paths[i])) for i in todo]
            for i, (_, err) in zip(todo, results, strict=True):
                if err:
                    errors[i] = err
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                futs = {
                    pool.submit(_work, models[i], variant, config, str(paths[i])): i for i in todo
                }
                for done, fut in enumerate(as_completed(futs), 1):
                    _, err = fut.result()
                    if err:
                        errors[futs[fut]] = err
                    if progress and (done % 10 == 0 or done == len(todo)):
                        progress(
                            f"  [{variant}] {done}/{len(todo)} decomposed "
                            f"({time.perf_counter() - t0:.0f} s)"
                        )
    for i, err in errors.items():
        msg = f"  decomposition failed: {models[i].name} [{variant}]: {err}"
        if progress:
            progress(msg)
        else:
            logger.warning(msg)
    tol = config.contact_tol_cells
    return [load_balls(p, tol) if p.exists() else None for p in paths]
