"""Generated example solids: deterministic, valid, and meshable."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb import examples
from shapedb.errors import ConfigError
from shapedb.geometry import Grid
from shapedb.implicit import Implicit
from shapedb.mdbd import decompose


def test_figures_are_deterministic_and_distinct() -> None:
    pts = np.random.default_rng(0).uniform(-1, 1, (500, 3))
    a = examples.figure(1, 2)
    np.testing.assert_array_equal(
        a.signed_distance(pts), examples.figure(1, 2).signed_distance(pts)
    )
    assert not np.allclose(a.signed_distance(pts), examples.figure(2, 2).signed_distance(pts))
    assert not np.allclose(a.signed_distance(pts), examples.figure(1, 3).signed_distance(pts))
    assert a.name == "figure-s1-p2"
    with pytest.raises(ConfigError):
        examples.figure(-1, 0)


def test_parts_and_catalogue() -> None:
    cat = examples.catalogue()
    assert len(cat) == 20
    assert len({name for name, _, _ in cat}) == 20
    assert {label for _, label, _ in cat} == {
        "figure-s0",
        "figure-s1",
        "plate",
        "bracket",
        "flange",
    }
    for name, _, g in cat:
        assert isinstance(g, Implicit), name
        grid = Grid.fit(g.bounds, resolution=24, padding=1)
        F = g.grid_sdf(grid)
        assert F.max() > 0, f"{name} has no inside"
        # the padding layer is outside: bounds contain the solid
        for face in (F[0], F[-1], F[:, 0], F[:, -1], F[:, :, 0], F[:, :, -1]):
            assert face.max() < 0, name
    with pytest.raises(ConfigError, match="unknown part kind"):
        examples.part("gear")


def test_examples_decompose() -> None:
    for g in (examples.figure(0, 1), examples.part("bracket", 2)):
        d = decompose(g, resolution=48, n_balls=64)
        assert d.n_balls > 30
        assert np.all(g.signed_distance(d.centers) >= d.radii - 1e-9)


def test_to_mesh_is_a_closed_outward_surface() -> None:
    pytest.importorskip("skimage")
    g = examples.part("flange", 0)
    mesh = examples.to_mesh(g, resolution=48)
    assert mesh.is_watertight and mesh.volume > 0
    d = g.signed_distance(mesh.vertices)
    h = float((g.bounds[1] - g.bounds[0]).max()) / 44
    assert np.abs(d).max() < h


def test_public_api_is_pinned_and_resolves() -> None:
    """``shapedb.__all__`` is the public API; every name resolves (lazily or not)."""
    import shapedb

    expected = {
        "Config", "MDBDConfig", "KernelConfig", "PartConfig", "Geometry", "Grid", "Implicit", "Sphere", "Box",
        "Capsule", "Cylinder", "Torus", "Union", "Intersection", "Difference", "TriangleMesh",
        "PointCloud", "VoxelGrid", "decompose", "Decomposition", "ContactGraph", "contact_edges",
        "features", "features_batch", "weights", "distance", "kernel", "connect", "Database",
        "examples", "__version__",
    }  # fmt: skip
    assert expected <= set(shapedb.__all__)
    assert all(n.endswith("Error") for n in set(shapedb.__all__) - expected)
    for name in shapedb.__all__:
        assert getattr(shapedb, name) is not None, name
    assert callable(shapedb.kernel.kernel)  # shapedb.kernel is the module (Eq. 1-3)
