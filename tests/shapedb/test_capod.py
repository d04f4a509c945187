"""Checks on real models (CAPOD, ../shared/data): slow, run with ``-m slow``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

CAPOD = Path(__file__).resolve().parents[3] / "shared" / "data" / "capod"
# one model of several classes: human, dolphin, airplane, hand, horse, gun
MODELS = [
    "class1/m1.obj",
    "class2/m16.obj",
    "class4/m37.obj",
    "class8/m85.obj",
    "class13/m145.obj",
    "class14/m160.obj",
]
OPTIONS = {"resolution": 64, "n_balls": 128}

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not CAPOD.is_dir(), reason="needs ../shared/data/capod"),
]


def _mesh(name: str):  # type: ignore[no-untyped-def]
    import trimesh

    from shapedb.geometry.mesh import TriangleMesh

    tm = trimesh.load(CAPOD / name, force="mesh", process=False)
    return TriangleMesh(np.asarray(tm.vertices), np.asarray(tm.faces))


def _cloud(mesh, seed: int):  # type: ignore[no-untyped-def]
    """The paper's cloud: a random 20 % of the vertices, or 2,000 surface samples."""
    from shapedb.geometry.pointcloud import PointCloud

    rng = np.random.default_rng(seed)
    v = np.asarray(mesh.vertices)
    k = int(round(0.2 * len(v)))
    pts = v[rng.choice(len(v), k, replace=False)] if k >= 2000 else mesh.sample_surface(2000, seed)
    return PointCloud(pts)


@pytest.mark.parametrize("name", MODELS)
def test_balls_are_sorted_disjoint_and_inside(name: str) -> None:
    """Inside the solid the MDBD packs: the mesh, with its sheets thickened into slabs."""
    from shapedb.config.core import MDBDConfig
    from shapedb.mdbd.decomposition import decompose, prepare_field

    mesh = _mesh(name)
    d = decompose(mesh, **OPTIONS)
    packed = prepare_field(mesh, MDBDConfig(**OPTIONS))
    tol = 0.02 * d.spacing
    assert d.n_balls > 10
    assert np.all(np.diff(d.radii) <= 1e-12)
    gap = np.linalg.norm(d.centers[:, None] - d.centers[None], axis=-1)
    gap -= d.radii[:, None] + d.radii[None]
    np.fill_diagonal(gap, np.inf)
    assert gap.min() >= -tol
    rotation, centre = packed.frame[:3, :3], packed.frame[:3, 3]
    local = (d.centers - centre) @ rotation / packed.scale  # the packed solid's own frame
    assert np.all(packed.local.signed_distance(local) * packed.scale >= d.radii - tol)


def test_similarity_transform_keeps_the_kernel() -> None:
    """a rotated, moved and uniformly scaled copy has kernel >= 0.99.

    Meshes get their frame from their own (exact) moments and are queried through a
    copy rebuilt in that frame, so the copy's decomposition is the same up to
    rounding: measured 1.0 on every model and rotation (it was 0.66-0.85 with the
    sampled frame, which followed a rotation to 0.01-5 degrees only)."""
    from scipy.spatial.transform import Rotation

    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.kernel import features, kernel

    sims = []
    for name in MODELS:
        mesh = _mesh(name)
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        d0 = decompose(mesh, **OPTIONS)
        f0 = features(d0)
        for k, angles in enumerate([(0.3, 0.7, -0.4), (1.1, -0.5, 2.0)]):
            rot = Rotation.from_euler("xyz", angles).as_matrix()
            s, t = (1.0, np.zeros(3)) if k == 0 else (2.5, np.array([3.0, -1.0, 0.5]))
            d1 = decompose(TriangleMesh(s * v @ rot.T + t, f), **OPTIONS)
            sims.append(kernel(f0, features(d1)))
            np.testing.assert_allclose(d1.radii[:10], s * d0.radii[:10], rtol=1e-4)
    assert min(sims) >= 0.99, sims


@pytest.mark.xfail(
    strict=True,
    reason="open CAPOD meshes and their 20 % point clouds do not always bound the same "
    "solid, and several classes are one mesh in many poses: over all 180 models a cloud "
    "finds its own mesh first for 29 %, its own mesh or a re-posed copy of it for 56 % "
    "(bench/representations.py), and (ridge ties on their first cell) its own "
    "model first among 20,000-sample clouds of the same surfaces no more often than its "
    "own mesh (34 % against 32 %, --against dense)",
)
def test_point_cloud_finds_its_own_mesh_first() -> None:
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.kernel import distance, features

    meshes = [_mesh(n) for n in MODELS]
    fm = np.stack([features(decompose(m, **OPTIONS)) for m in meshes])
    fp = np.stack([features(decompose(_cloud(m, k), **OPTIONS)) for k, m in enumerate(meshes)])
    first = [int(np.argmin(distance(fp[i], fm))) == i for i in range(len(meshes))]
    assert np.mean(first) >= 0.95, first
