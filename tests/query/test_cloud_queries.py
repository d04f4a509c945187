"""Sparse point-cloud queries against a store of meshes only (``query.search.engine``).

A mesh that is not closed, with holes wider than a grid cell, packs its enclosed solid: a
shell two cells thick (:mod:`shapedb.geometry.enclosed`), while an even cloud of the same
surface packs the solid its samples enclose, so the two features disagree. In a store of
meshes only, a sparse cloud is therefore ranked as any query, by the re-ranking stage (its
light fields are silhouettes, alike for a shell and its filled solid), its list holding each
mesh at the nearer of its own feature's and its Poisson reconstruction's distance.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh

import shapedb
from query.search.tuning import PRODUCT
from shapedb.config.core import Config
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud
from shapedb.geometry.view import is_sparse
from shapedb.mdbd.decomposition import decompose
from shapedb.mdbd.reconstruct import reconstructed
from shapedb.signature.kernel import features

CONFIG = Config().with_options(resolution=40, n_balls=96)


def _holed_box(extents: tuple[float, float, float], hole: float = 0.5) -> trimesh.Trimesh:
    """A box whose six faces each miss their middle (``hole`` of each side): not closed."""
    box = trimesh.creation.box(extents=extents)
    v, f = box.vertices, box.faces
    for _ in range(3):
        v, f = trimesh.remesh.subdivide(v, f)
    centres, half = v[f].mean(axis=1), np.asarray(extents) / 2
    keep = np.ones(len(f), dtype=bool)
    for axis in range(3):
        on = np.isclose(np.abs(centres[:, axis]), half[axis])
        rest = [a for a in range(3) if a != axis]
        keep &= ~(on & np.all(np.abs(centres[:, rest]) < hole * half[rest], axis=1))
    return trimesh.Trimesh(v, f[keep])


def _meshes() -> dict[str, TriangleMesh]:
    c = trimesh.creation
    shapes = {
        "holed-box": _holed_box((2.0, 1.2, 1.0)),
        "sphere": c.icosphere(subdivisions=3, radius=1.0),
        "torus": c.torus(major_radius=1.0, minor_radius=0.35),
        "cylinder": c.cylinder(radius=0.6, height=2.0, sections=48),
        "capsule": c.capsule(height=1.6, radius=0.4, count=[24, 24]),
    }
    return {n: TriangleMesh.from_trimesh(m, name=n) for n, m in shapes.items()}


def _cloud(mesh: TriangleMesh) -> PointCloud:
    """600 points spread evenly over the surface: a sample every 3-4 grid cells here."""
    return PointCloud(mesh.sample_surface(600, seed=7), name="query")


@pytest.fixture(scope="module")
def mesh_db(
    tmp_path_factory: pytest.TempPathFactory, forget: Callable[[Any], None]
) -> Iterator[Any]:
    meshes = _meshes()
    db = shapedb.connect(Path(tmp_path_factory.mktemp("clouds")) / "store", config=CONFIG)
    report = db.ingest(list(meshes.values()), names=list(meshes), workers=1)
    assert len(report.failed) == 0, report.failed
    yield db
    forget(db)


def test_the_holed_box_packs_a_shell_and_its_cloud_a_solid() -> None:
    """The disagreement the search works around (ball volume ``sum r^3``)."""
    mesh = _meshes()["holed-box"]
    assert not mesh.closed
    shell = decompose(mesh, config=CONFIG.mdbd)
    cloud = decompose(_cloud(mesh), config=CONFIG.mdbd)
    assert is_sparse(cloud.sampling, cloud.spacing)
    assert np.sum(cloud.radii**3) > 5 * np.sum(shell.radii**3)


@pytest.mark.parametrize("name", ["torus", "cylinder"])
def test_an_even_cloud_finds_its_mesh_first(mesh_db: Any, name: str) -> None:
    hits = mesh_db.search(_cloud(_meshes()[name]), k=len(mesh_db))
    assert hits[0].name == name
    assert {h.path for h in hits} == {"whole"}


def test_the_stage_lifts_the_holed_box_above_its_stored_distance(mesh_db: Any) -> None:
    """By the stored distance the holed box's cloud is 4th; the stage moves it up."""
    hits = mesh_db.search(_cloud(_meshes()["holed-box"]), k=len(mesh_db))
    names = [h.name for h in hits]
    by_distance = [h.name for h in sorted(hits, key=lambda h: (h.distance, h.id))]
    assert by_distance.index("holed-box") == 3
    assert names.index("holed-box") <= 1


def test_a_proxied_cloud_is_as_far_as_its_own_feature_and_is_not_reconstructed(
    mesh_db: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ranked as its proxy, a cloud needs no Poisson surface: each hit at its distance to
    the cloud's own feature."""
    import shapedb.mdbd.reconstruct as rec

    calls: list[int] = []
    real = rec.reconstructed

    def spy(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(rec, "reconstructed", spy)
    query = _cloud(_meshes()["torus"])
    hits = mesh_db.search(query, k=len(mesh_db))
    ids, own = mesh_db.store.features()
    dec = decompose(query, config=CONFIG.mdbd)
    want = np.abs(own - features(dec, CONFIG.kernel)).sum(axis=1)
    assert {h.id: round(h.distance, 4) for h in hits} == {
        int(i): round(float(w), 4) for i, w in zip(ids, want, strict=True)
    }
    assert calls == []


def test_a_cloud_is_as_far_as_the_nearer_of_its_feature_and_reconstruction(mesh_db: Any) -> None:
    """Without the proxy (studies) the stage's stored distances put each mesh at the
    nearer of the two comparisons."""
    from dataclasses import replace

    from query.search.tuning import tuned

    query = _cloud(_meshes()["torus"])
    with tuned(replace(PRODUCT, proxy=False)):
        hits = mesh_db.search(query, k=len(mesh_db))
    ids, own = mesh_db.store.features()
    dec = decompose(query, config=CONFIG.mdbd)
    recon = reconstructed(query, dec, CONFIG.mdbd, depth=CONFIG.cloud.reconstruct_depth)
    assert recon is not None
    by_own = np.abs(own - features(dec, CONFIG.kernel)).sum(axis=1)
    by_recon = np.abs(own - features(recon, CONFIG.kernel)).sum(axis=1)
    want = np.minimum(by_own, by_recon)
    assert {h.id: round(h.distance, 4) for h in hits} == {
        int(i): round(float(w), 4) for i, w in zip(ids, want, strict=True)
    }


def test_a_clouds_light_fields_are_drawn_from_its_points(
    mesh_db: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Its decomposed inside would draw them too, less faithfully: the stage reads the
    points' own (and a mesh query keeps its decomposition's)."""
    import shapedb.signature.lightfield as lf

    drawn: list[int] = []
    real = lf.cloud_light_field

    def spy(points: Any, config: Any = None) -> Any:
        drawn.append(len(points))
        return real(points, config)

    monkeypatch.setattr(lf, "cloud_light_field", spy)
    hits = mesh_db.search(_cloud(_meshes()["torus"]), k=3)
    assert drawn == [600] and hits[0].name == "torus"
    mesh_db.search(_meshes()["torus"], k=3)
    assert drawn == [600]


def test_a_cloud_ranks_as_its_proxy(mesh_db: Any) -> None:
    """The stored shape its light fields find nearest comes first, the rest as a search
    for that shape ranks them; each hit at its distance to the cloud."""
    from query.search.cloud_proxy import proxies
    from query.search.rerank_lightfield import stored_arrays
    from shapedb.signature.lightfield import cloud_light_field

    for name in ("torus", "holed-box"):
        cloud = _cloud(_meshes()[name])
        hits = mesh_db.search(cloud, k=len(mesh_db))
        ids = np.array([h.id for h in hits], np.int64)
        lf = cloud_light_field(cloud.points, mesh_db.config.light_field)
        proxy = proxies(lf[None].astype(np.float64), ids[None], stored_arrays(mesh_db))[0]
        assert hits[0].id == proxy and hits[0].name == name
        assert [h.id for h in mesh_db.search(int(proxy), k=len(mesh_db))] == ids.tolist()


def test_without_the_proxy_a_cloud_keeps_its_own_row(mesh_db: Any) -> None:
    """``StageTuning.proxy`` off (studies): the cloud's own stage row orders its hits."""
    from dataclasses import replace

    from query.search.tuning import tuned

    cloud = _cloud(_meshes()["holed-box"])
    with_proxy = [h.name for h in mesh_db.search(cloud, k=len(mesh_db))]
    with tuned(replace(PRODUCT, proxy=False)):
        own_row = [h.name for h in mesh_db.search(cloud, k=len(mesh_db))]
    as_proxy = [h.name for h in mesh_db.search(with_proxy[0], k=len(mesh_db))]
    assert with_proxy == as_proxy
    assert own_row != as_proxy
