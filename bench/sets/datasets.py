"""Labelled data sets for the retrieval benchmarks, and their point-cloud versions.

Three sets, each a :class:`Dataset` of :class:`Model` entries with a fixed, seeded
validation/test split by model (stratified by class: a third of each class goes to
validation, the rest to test; parameter studies see only the validation split):

``capod``
    The 180 real meshes of ../shared/data/capod (15 classes x 12), labels from
    ``labels.csv``. Cite: P. Papadakis, "The Canonically Posed 3D Objects Dataset",
    3DOR 2014.
``articulated``
    Jointed figures from :func:`shapedb.examples.figure`: several subjects with
    different limb proportions, each in many poses (the class is the subject),
    like SHREC'14's 15 subjects x 20 poses. Meshed with :func:`shapedb.examples.to_mesh`.
``people``
    Fine-grained people from :func:`bench.sets.people.person`: 12 subjects x 10 poses
    whose limb lengths and girths lie 3-10 % apart (the class is the subject),
    meshes of about 7,000 vertices, like registered scans of real people.
``parts``
    Machined parts from :func:`shapedb.examples.part` (the class is the kind,
    seeds vary the dimensions and features).
``generic``
    Web-like man-made and natural models from :mod:`bench.sets.generic_shapes` (boxes,
    zero-thickness sheets, open and interpenetrating parts; the class is the kind),
    used as the triangle soups they are generated as.
``web``
    A harder web-like set from :mod:`bench.sets.web_shapes`: 45 kinds in close families
    (seats, tables, buildings, vehicles, aircraft, ...), large variation within a
    kind, random yaw and some arbitrary rotations; sources carry
    :func:`bench.sets.web_shapes.web_version`, so caches key on the generator's code.
``webplus``
    A held-out web-like set from :mod:`bench.sets.webplus_shapes`: 39 kinds that neither
    ``web`` nor ``generic`` has (close man-made families, animals in many poses,
    plants), built and oriented as ``web``; every model is in the test split (nobody
    tunes on it). Sources carry :func:`bench.sets.webplus_shapes.webplus_version`.
``enclosures``
    Thin-walled, enclosing man-made kinds from :mod:`bench.sets.enclosures` (houses with
    open rooms, rail cars, desks, bookcases, sinks, housings, wheels, dishes, books,
    brackets, tents, boats): single-sided sheets with gaps for doors and vents, open
    boxes, inconsistent winding, repeated faces and stray vertices, y or z up.
    Sources carry :func:`bench.sets.enclosures.enclosure_version`.

Point-cloud versions follow the paper: a random 20 % of the mesh vertices, seeded by
the model name; meshes so coarse that this gives fewer than ``min_points`` points are
sampled uniformly on their surface instead (``min_points`` = 2000; the people keep
the paper's 20 % of their ~7,000 vertices: :func:`min_cloud_points`).
"""

from __future__ import annotations

import csv
import functools
import inspect
import os
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CAPOD_ROOT",
    "CACHE_DIR",
    "Model",
    "Dataset",
    "stable_seed",
    "split_by_model",
    "capod",
    "articulated",
    "people",
    "parts",
    "generic",
    "web",
    "webplus",
    "enclosures",
    "load_dataset",
    "build_sets",
    "mesh_arrays",
    "families",
    "point_cloud",
    "min_cloud_points",
    "people_version",
]

REPO = Path(__file__).resolve().parents[2]
#: The real data set (outside the repository; never copied into it): ``SHAPEDB_CAPOD``,
#: else ``../shared/data/capod`` beside the checkout or beside the worktrees' folder.
CAPOD_ROOT = Path(
    os.environ.get(
        "SHAPEDB_CAPOD",
        next(
            (
                p / "shared" / "data" / "capod"
                for p in (REPO.parent, REPO.parent.parent)
                if (p / "shared" / "data" / "capod").is_dir()
            ),
            REPO.parent / "shared" / "data" / "capod",
        ),
    )
)
#: Decompositions and generated meshes (git-ignored); ``SHAPEDB_BENCH_CACHE`` overrides it.
CACHE_DIR = Path(os.environ.get("SHAPEDB_BENCH_CACHE", REPO / "bench" / "results" / "cache"))

#: Marching-cubes resolution of the generated sets' meshes.
GENERATED_MESH_RESOLUTION = 96


@dataclass(frozen=True)
class Model:
    """One labelled model of a benchmark set.

    Attributes
    ----------
    name : str
        Unique id inside the set, e.g. ``"class1/m3"`` or ``"s04_p11"``.
    label : str
        Class used for retrieval scoring.
    source : str
        A file path (``capod``) or a generator spec ``"figure:subject:pose"`` /
        ``"part:kind:seed"``.
    split : str
        ``"validation"`` or ``"test"``.
    """

    name: str
    label: str
    source: str
    split: str = "test"


@dataclass(frozen=True)
class Dataset:
    """A named, labelled collection of models.

    Attributes
    ----------
    name : str
        ``"capod"``, ``"articulated"`` or ``"parts"``.
    models : tuple of Model
        In a fixed order.
    """

    name: str
    models: tuple[Model, ...]

    def __len__(self) -> int:
        return len(self.models)

    @property
    def labels(self) -> NDArray[np.str_]:
        """(n,) str: class of each model."""
        return np.asarray([m.label for m in self.models])

    def split(self, which: str) -> Dataset:
        """The models of one split (``"validation"``, ``"test"`` or ``"all"``)."""
        if which == "all":
            return self
        if which not in ("validation", "test"):
            raise ValueError(f"unknown split {which!r}: use validation, test or all")
        return Dataset(self.name, tuple(m for m in self.models if m.split == which))

    def head(self, per_class: int | None = None, classes: int | None = None) -> Dataset:
        """A deterministic subset: the first ``per_class`` models of the first ``classes``."""
        order: list[str] = []
        for m in self.models:
            if m.label not in order:
                order.append(m.label)
        keep = set(order[:classes] if classes else order)
        count: dict[str, int] = {}
        out = []
        for m in self.models:
            if m.label in keep and count.get(m.label, 0) < (per_class or 10**9):
                count[m.label] = count.get(m.label, 0) + 1
                out.append(m)
        return Dataset(self.name, tuple(out))


def stable_seed(*parts: object) -> int:
    """A seed that depends only on ``parts`` (not on PYTHONHASHSEED)."""
    return zlib.crc32("/".join(map(str, parts)).encode())


def split_by_model(
    models: Sequence[Model], *, validation: float = 1 / 3, seed: int = 2024
) -> tuple[Model, ...]:
    """Assign each model to ``validation`` or ``test``, stratified by class, seeded.

    Parameters
    ----------
    models : sequence of Model
        Models of one set.
    validation : float
        Fraction of each class that goes to validation (at least one model, at
        most all but one).
    seed : int
        Seed of the shuffle; the split is fixed for a given seed and model list.
    """
    by_class: dict[str, list[int]] = {}
    for i, m in enumerate(models):
        by_class.setdefault(m.label, []).append(i)
    chosen: set[int] = set()
    for label, idx in sorted(by_class.items()):
        rng = np.random.default_rng(stable_seed(seed, label))
        k = min(max(int(round(validation * len(idx))), 1), max(len(idx) - 1, 1))
        chosen.update(np.asarray(idx)[rng.permutation(len(idx))[:k]].tolist())
    return tuple(
        replace(m, split="validation" if i in chosen else "test") for i, m in enumerate(models)
    )


# --------------------------------------------------------------------------------------
# The three sets
# --------------------------------------------------------------------------------------


def capod(root: Path | str = CAPOD_ROOT) -> Dataset:
    """The CAPOD meshes with their labels (``labels.csv``), split by model."""
    root = Path(root)
    with open(root / "labels.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    models = [
        Model(name=r["path"].removesuffix(".obj"), label=r["label"], source=str(root / r["path"]))
        for r in rows
    ]
    return Dataset("capod", split_by_model(models))


def articulated(subjects: int = 15, poses: int = 20) -> Dataset:
    """Jointed figures: ``subjects`` classes x ``poses`` models (SHREC'14-like)."""
    models = [
        Model(name=f"s{s:02d}_p{p:02d}", label=f"subject{s:02d}", source=f"figure:{s}:{p}")
        for s in range(subjects)
        for p in range(poses)
    ]
    return Dataset("articulated", split_by_model(models))


#: Subjects the people set adds to its validation split only (``people(extra_validation=...)``).
PEOPLE_EXTRA_VALIDATION = 12
#: Poses of each extra validation subject (seeded among the ``poses`` of the set).
PEOPLE_EXTRA_POSES = 3


def people(subjects: int = 12, poses: int = 10, *, extra_validation: int = 0) -> Dataset:
    """Fine-grained people: ``subjects`` classes x ``poses`` models (a registered-scan set).

    ``extra_validation`` more subjects (numbered from ``subjects`` on) join the
    validation split only, each in :data:`PEOPLE_EXTRA_POSES` seeded poses, so that
    choices made on validation rest on more queries; the test split is the same
    whatever ``extra_validation`` is.
    """
    models = [
        Model(name=f"h{s:02d}_p{p:02d}", label=f"person{s:02d}", source=f"person:{s}:{p}")
        for s in range(subjects)
        for p in range(poses)
    ]
    extra = []
    for s in range(subjects, subjects + extra_validation):
        rng = np.random.default_rng(stable_seed("people-extra", s))
        for p in sorted(rng.permutation(poses)[: min(PEOPLE_EXTRA_POSES, poses)].tolist()):
            extra.append(
                Model(
                    name=f"h{s:02d}_p{p:02d}",
                    label=f"person{s:02d}",
                    source=f"person:{s}:{p}",
                    split="validation",
                )
            )
    return Dataset("people", split_by_model(models) + tuple(extra))


def part_kinds() -> tuple[str, ...]:
    """The machined-part kinds that :func:`shapedb.examples.part` offers."""
    from shapedb import examples

    for attr in ("PART_KINDS", "PARTS", "KINDS"):
        kinds = getattr(examples, attr, None)
        if kinds:
            return tuple(kinds)
    raise RuntimeError("shapedb.examples exposes no list of part kinds (PART_KINDS)")


def parts(per_kind: int = 12, kinds: Sequence[str] | None = None) -> Dataset:
    """Generated engineering parts: one class per kind, ``per_kind`` seeds each."""
    kinds = tuple(kinds) if kinds else part_kinds()
    models = [
        Model(name=f"{k}_{i:02d}", label=k, source=f"part:{k}:{i}")
        for k in kinds
        for i in range(per_kind)
    ]
    return Dataset("parts", split_by_model(models))


def generic(per_kind: int = 20, kinds: Sequence[str] | None = None) -> Dataset:
    """Generated web-like models: one class per kind of :mod:`bench.sets.generic_shapes`."""
    from bench.sets.generic_shapes import KINDS

    kinds = tuple(kinds) if kinds else KINDS
    models = [
        Model(name=f"{k}_{i:02d}", label=k, source=f"generic:{k}:{i}")
        for k in kinds
        for i in range(per_kind)
    ]
    return Dataset("generic", split_by_model(models))


def _kind_models(prefix: str, kinds: Sequence[str], per_kind: int, version: str) -> list[Model]:
    """``per_kind`` models of each kind (test split), sources ``"<prefix>:<kind>:<seed>:<version>"``."""
    return [
        Model(name=f"{k}_{i:02d}", label=k, source=f"{prefix}:{k}:{i}:{version}")
        for k in kinds
        for i in range(per_kind)
    ]


def web(per_kind: int = 20, kinds: Sequence[str] | None = None) -> Dataset:
    """The hard web-like set: one class per kind of :mod:`bench.sets.web_shapes`.

    Sources are ``"web:<kind>:<seed>:<web_version>"``: a change of the generator's
    code changes every source, so no cache serves stale models.
    """
    from bench.sets.web_shapes import KINDS, web_version

    models = _kind_models("web", tuple(kinds) if kinds else KINDS, per_kind, web_version())
    return Dataset("web", split_by_model(models))


def webplus(per_kind: int = 16, kinds: Sequence[str] | None = None) -> Dataset:
    """The held-out web-like set: one class per kind of :mod:`bench.sets.webplus_shapes`.

    Every model is in the ``"test"`` split (the validation split is empty: the set
    checks settings chosen on the other sets and is never tuned on). Sources are
    ``"webplus:<kind>:<seed>:<webplus_version>"``, so no cache serves stale models.
    """
    from bench.sets.webplus_shapes import KINDS, webplus_version

    models = _kind_models("webplus", tuple(kinds) if kinds else KINDS, per_kind, webplus_version())
    return Dataset("webplus", tuple(models))


def enclosures(per_kind: int = 20, kinds: Sequence[str] | None = None) -> Dataset:
    """The thin-walled set: one class per kind of :mod:`bench.sets.enclosures`.

    Sources are ``"enclosure:<kind>:<seed>:<enclosure_version>"``: a change of the
    generator's code changes every source, so no cache serves stale models.
    """
    from bench.sets.enclosures import KINDS, enclosure_version

    kinds = tuple(kinds) if kinds else KINDS
    models = _kind_models("enclosure", kinds, per_kind, enclosure_version())
    return Dataset("enclosures", split_by_model(models))


def load_dataset(name: str) -> Dataset:
    """A set by name, at its default size.

    One of ``capod``, ``articulated``, ``people``, ``parts``, ``generic``, ``web``,
    ``webplus``, ``enclosures``; ValueError for another name.
    """
    makers = {
        "capod": capod,
        "articulated": articulated,
        "people": people,
        "parts": parts,
        "generic": generic,
        "web": web,
        "webplus": webplus,
        "enclosures": enclosures,
    }
    if name not in makers:
        raise ValueError(f"unknown data set {name!r}: choose from {sorted(makers)}")
    return makers[name]()


def build_sets(
    names: Sequence[str], quick: bool, subjects: int = 15, poses: int = 20, per_kind: int = 12
) -> list[Dataset]:
    """The requested data sets by name, subsets when ``quick`` (the benches' ``--datasets``).

    Raises
    ------
    SystemExit
        For an unknown name (the benches' command lines).
    """
    out = []
    for name in names:
        if name == "capod":
            ds = capod()
            out.append(ds.head(per_class=6, classes=8) if quick else ds)
        elif name == "articulated":
            out.append(articulated(6, 6) if quick else articulated(subjects, poses))
        elif name == "parts":
            try:
                out.append(parts(4) if quick else parts(per_kind))
            except (ImportError, AttributeError, RuntimeError) as exc:
                print(f"parts set unavailable: {exc}")
        elif name in ("generic", "web", "webplus", "enclosures"):
            ds = load_dataset(name)
            out.append(ds.head(per_class=6) if quick else ds)
        else:
            raise SystemExit(f"unknown data set {name!r}")
    return out


# --------------------------------------------------------------------------------------
# Geometry of a model
# --------------------------------------------------------------------------------------


def _generated(source: str) -> object:
    from shapedb import examples

    kind, a, b = source.split(":")
    if kind == "figure":
        return examples.figure(int(a), int(b))
    if kind == "part":
        return examples.part(a, seed=int(b))
    raise ValueError(f"unknown generator spec {source!r}")


def _to_mesh(geometry: object, resolution: int) -> object:
    from shapedb import examples

    params = inspect.signature(examples.to_mesh).parameters
    if "resolution" in params:
        return examples.to_mesh(geometry, resolution=resolution)
    return examples.to_mesh(geometry, resolution)


def _versioned(
    model: Model,
    generator: str,
    version: str,
    mesh: Callable[[str, int], tuple[NDArray[np.float64], NDArray[np.int64]]],
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """``mesh(kind, seed)`` of a ``"<set>:<kind>:<seed>:<version>"`` source.

    Raises
    ------
    ValueError
        When the source was made by another version of the generator's code.
    """
    _, kind, seed, made = model.source.split(":")
    if made != version:
        raise ValueError(
            f"{model.name}: made by {generator} generator {made}, this code is {version}"
        )
    return mesh(kind, int(seed))


def mesh_arrays(
    model: Model, *, cache: bool = True
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices (v, 3) and faces (f, 3) of a model's mesh.

    CAPOD meshes are read as they are (triangle soups included); generated shapes
    are meshed at :data:`GENERATED_MESH_RESOLUTION` and cached as npz.
    """
    if model.source.startswith("generic:"):
        from bench.sets.generic_shapes import generic_mesh

        _, kind, seed = model.source.split(":")
        return generic_mesh(kind, int(seed))
    if model.source.startswith("web:"):
        from bench.sets.web_shapes import web_mesh, web_version

        return _versioned(model, "web", web_version(), web_mesh)
    if model.source.startswith("webplus:"):
        from bench.sets.webplus_shapes import webplus_mesh, webplus_version

        return _versioned(model, "webplus", webplus_version(), webplus_mesh)
    if model.source.startswith("enclosure:"):
        from bench.sets.enclosures import enclosure_mesh, enclosure_version

        return _versioned(model, "enclosures", enclosure_version(), enclosure_mesh)
    if not model.source.startswith(("figure:", "part:", "person:")):
        import trimesh

        m = trimesh.load(model.source, force="mesh", process=False)
        return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)
    path = (
        CACHE_DIR / "meshes" / f"{model.source.replace(':', '_')}_{GENERATED_MESH_RESOLUTION}.npz"
    )
    if model.source.startswith("person:"):
        from bench.sets import people as people_module

        path = path.with_name(
            f"{model.source.replace(':', '_')}_{people_module.MESH_RESOLUTION}"
            f"_{people_module.MESH_VERTICES}_{people_version()}.npz"
        )
    if cache and path.exists():
        with np.load(path) as z:
            return z["vertices"], z["faces"]
    if model.source.startswith("person:"):
        _, s, p = model.source.split(":")
        v, f = people_module.person_mesh(int(s), int(p))
    else:
        mesh = _to_mesh(_generated(model.source), GENERATED_MESH_RESOLUTION)
        v = np.asarray(mesh.vertices, dtype=np.float64)  # type: ignore[attr-defined]
        f = np.asarray(mesh.faces, dtype=np.int64)  # type: ignore[attr-defined]
    if cache:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, vertices=v, faces=f)
        tmp.replace(path)
    return v, f


@functools.lru_cache(maxsize=2)
def people_version(part: str = "mesh") -> str:
    """sha256 (8 hex) of the people generator's code: part of the cache keys.

    ``part`` ``"mesh"``: what a person's mesh depends on; ``"scans"``: what the
    noisy and partial clouds of any mesh depend on.
    """
    import hashlib

    from bench.sets import people as p

    if part == "mesh":
        code = [p.proportions, p.angles, p._segments, p._cone, p.person, p.person_mesh]
        consts = [p._BASE, p._JOINTS, p._RANGES, p.MESH_RESOLUTION, p.MESH_VERTICES, p.BLEND]
    else:
        code, consts = [p.noisy_cloud, p.partial_cloud], [p.NOISE_SIGMA]
    text = "".join(inspect.getsource(f) for f in code) + repr(consts)
    return hashlib.sha256(text.encode()).hexdigest()[:8]


def min_cloud_points(model: Model) -> int:
    """``min_points`` of :func:`point_cloud` for ``model``: 0 for the people, else 2000."""
    return 0 if model.source.startswith("person:") else 2000


def families(models: Sequence[Model]) -> NDArray[np.str_]:
    """A key per model, equal for re-posed copies of one shape: (n,) str.

    CAPOD meshes with the same triangles (connectivity) but other vertex positions
    (most CAPOD classes are one mesh in 9-12 poses; a few models are exact
    duplicates), and the poses of one subject of the jointed figures; every other
    model is its own family.
    """
    import hashlib

    keys = []
    for m in models:
        if m.source.startswith(("figure:", "person:")):
            keys.append(m.source.rsplit(":", 1)[0])
        elif m.source.startswith(("part:", "generic:", "web:", "webplus:", "enclosure:")):
            keys.append(m.source)
        else:
            faces = np.ascontiguousarray(mesh_arrays(m)[1], dtype=np.int64)
            keys.append(m.label + ":" + hashlib.sha1(faces.tobytes()).hexdigest()[:12])
    return np.asarray(keys)


def point_cloud(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    seed: int,
    fraction: float = 0.2,
    min_points: int = 2000,
) -> NDArray[np.float64]:
    """The paper's point-cloud version of a mesh.

    Parameters
    ----------
    vertices : (v, 3) float
        Mesh vertices.
    faces : (f, 3) int
        Mesh faces (used only for coarse meshes).
    seed : int
        Seed of the selection.
    fraction : float
        Fraction of the vertices kept (the paper: about 20 %).
    min_points : int
        Meshes for which ``fraction`` of the vertices is fewer points than this are
        sampled uniformly by area on their surface instead, ``min_points`` points.

    Returns
    -------
    (k, 3) float64
        The points.
    """
    from bench.support.baselines import sample_surface

    rng = np.random.default_rng(seed)
    v = np.asarray(vertices, dtype=np.float64)
    # Only vertices that some face uses: unreferenced ones are not on the surface.
    v = v[np.unique(np.asarray(faces).ravel())]
    k = int(round(fraction * len(v)))
    if k >= min_points:
        return v[rng.choice(len(v), size=k, replace=False)]
    return sample_surface(vertices, faces, min_points, rng=rng)
