"""The inside of a decomposition's field and its light fields (shapedb.geometry.inside)."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.config.core import LightFieldConfig
from shapedb.errors import ConfigError
from shapedb.geometry.base import Grid
from shapedb.geometry.implicit import Box, Sphere
from shapedb.geometry.inside import field_inside
from shapedb.mdbd.decomposition import decompose
from shapedb.signature.lightfield import (
    decomposition_light_field,
    image_axes,
    inside_light_field,
    record_light_field,
    render_discs,
)

RES = 64


def _sphere_field(radius: float, cells: int) -> tuple[np.ndarray, Grid]:
    grid = Grid.fit(np.array([[-radius] * 3, [radius] * 3]), resolution=cells, padding=2)
    p = grid.points()
    return (radius - np.linalg.norm(p, axis=1)).reshape(grid.shape).astype(np.float32), grid


def _extent(inside) -> float:  # type: ignore[no-untyped-def]
    return float(np.max(np.linalg.norm(inside.shell - inside.centroid, axis=1))) + 0.5 * inside.cell


def test_the_shell_is_the_inside_cells_with_a_neighbour_outside() -> None:
    F, grid = _sphere_field(1.0, 24)
    inside = field_inside(F, grid)
    cells = grid.to_point(np.argwhere(F >= 0))
    assert inside.count == len(cells)
    assert 0 < len(inside.shell) < inside.count
    assert np.allclose(inside.centroid, cells.mean(axis=0))
    # every inside cell farther than a cell from the boundary is not in the shell
    depth = 1.0 - np.linalg.norm(inside.shell, axis=1)
    assert depth.max() < 2.0 * grid.spacing and depth.min() >= 0.0


def test_the_inside_shell_of_a_sphere_renders_a_disc_of_the_right_radius() -> None:
    F, grid = _sphere_field(1.0, 40)
    inside = field_inside(F, grid)
    ext = _extent(inside)
    dirs = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, 0.0, 0.8]])
    shell, _ = render_discs(
        inside.shell, np.full(len(inside.shell), 0.5 * inside.cell), dirs, RES,
        frame=(inside.centroid, ext),
    )  # fmt: skip
    cells = grid.to_point(np.argwhere(F >= 0))
    full, _ = render_discs(cells, np.full(len(cells), 0.5 * inside.cell), dirs, RES)
    assert np.array_equal(shell, full)  # the shell sees what every inside cell sees
    c = (np.arange(RES) + 0.5) / RES * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    for img in shell:
        radius_px = np.sqrt(img.sum() / np.pi)  # the disc's radius, pixels
        # the sphere's radius 1 is 1 / ext image units; cells reach half a cell past it at
        # most, discs half a pixel
        want = RES / 2 * (1.0 + 0.5 * inside.cell) / ext
        assert abs(radius_px - want) <= 1.0
        assert abs((x * img).sum() / img.sum()) < 0.5 * 2 / RES
        assert abs((y * img).sum() / img.sum()) < 0.5 * 2 / RES


def test_the_centroid_is_the_solid_s_not_the_shell_s() -> None:
    big, small = Sphere((0, 0, 0), 1.0), Sphere((3, 0, 0), 0.5)
    d = decompose(big | small, resolution=64, n_balls=8, keep_inside=True)
    assert d.inside is not None
    want = 3.0 * 0.5**3 / (1.0 + 0.5**3)  # volume-weighted
    assert abs(d.inside.centroid[0] - want) < d.spacing
    assert abs(d.inside.shell.mean(axis=0)[0] - want) > 3 * d.spacing


def test_a_thin_fin_is_in_the_field_s_silhouette_and_not_in_the_balls() -> None:
    solid = Box((0, 0, 0), (2, 2, 2)) | Box((2, 0, 0), (2.2, 1.6, 0.25))
    d = decompose(solid, resolution=48, n_balls=16, keep_inside=True)
    assert d.inside is not None
    assert d.radii.min() > 0.125  # every ball is thicker than the fin
    view = np.array([[0.0, 0.0, 1.0]])
    u, w = image_axes(view)
    tip = np.array([2.8, 0.0, 0.0])  # on the fin, far from the box

    def pixel(o: np.ndarray, ext: float) -> tuple[int, int]:
        q = (tip - o) / ext
        return int((q @ w[0] + 1) * RES / 2), int((q @ u[0] + 1) * RES / 2)

    ext = _extent(d.inside)
    field, _ = render_discs(
        d.inside.shell, np.full(len(d.inside.shell), 0.5 * d.inside.cell), view, RES,
        frame=(d.inside.centroid, ext),
    )  # fmt: skip
    # the balls in the same frame
    balls, _ = render_discs(d.centers, d.radii, view, RES, frame=(d.inside.centroid, ext))
    row, col = pixel(d.inside.centroid, ext)
    assert 0 <= row < RES and 0 <= col < RES
    assert field[0][row, col] and not balls[0][row, col]
    assert field[0].sum() > balls[0].sum() + 100  # the fin's pixels
    cfg = LightFieldConfig(source="field")
    got = decomposition_light_field(d, cfg)
    assert np.array_equal(got, inside_light_field(d.inside, cfg))
    assert not np.array_equal(got, decomposition_light_field(d, LightFieldConfig()))


def test_the_surface_centre_is_the_shell_mean_and_moves_the_silhouette() -> None:
    # a bulky cube with a wide thin sheet: the sheet pulls the shell's mean far more than
    # the volume centroid
    solid = Box((0, 0, 0), (1, 1, 1)) | Box((2.5, 0, 0), (4, 1, 0.2))
    d = decompose(solid, resolution=64, n_balls=8, keep_inside=True)
    assert d.inside is not None
    surface = d.inside.shell.mean(axis=0)
    assert surface[0] > d.inside.centroid[0] + 0.3
    cfg = LightFieldConfig(source="field", n_fields=1, centre="surface")
    ext = float(np.max(np.linalg.norm(d.inside.shell - surface, axis=1))) + 0.5 * d.inside.cell
    want = record_light_field(
        d.inside.shell, np.full(len(d.inside.shell), 0.5 * d.inside.cell), cfg,
        frame=(surface, ext),
    )  # fmt: skip
    got = inside_light_field(d.inside, cfg)
    assert np.array_equal(got, want)
    assert np.array_equal(got, decomposition_light_field(d, cfg))
    volume = inside_light_field(d.inside, LightFieldConfig(source="field", n_fields=1))
    assert not np.allclose(got, volume)
    # seen about the shell's mean, the top view (the sheet's area) sits nearer the image
    # centre: its image centroid
    view = np.array([[0.0, 0.0, 1.0]])
    r = np.full(len(d.inside.shell), 0.5 * d.inside.cell)
    c = (np.arange(RES) + 0.5) / RES * 2.0 - 1.0
    offsets = []
    for o in (d.inside.centroid, surface):
        e = float(np.max(np.linalg.norm(d.inside.shell - o, axis=1))) + 0.5 * d.inside.cell
        img, _ = render_discs(d.inside.shell, r, view, RES, frame=(o, e))
        ys, xs = np.nonzero(img[0])
        offsets.append(np.hypot(c[xs].mean(), c[ys].mean()))
    assert offsets[1] < offsets[0] - 0.05
    # translating the solid moves neither
    moved = decompose(solid.translate((5.0, -2.0, 1.0)), resolution=64, n_balls=8,
                      keep_inside=True)  # fmt: skip
    assert moved.inside is not None
    assert np.allclose(inside_light_field(moved.inside, cfg), got, atol=1e-4)


def test_a_light_field_centre_must_be_known() -> None:
    with pytest.raises(ConfigError, match="lf_centre"):
        LightFieldConfig(centre="bbox")


def test_field_light_fields_need_the_inside() -> None:
    d = decompose(Sphere((0, 0, 0), 1.0), resolution=24, n_balls=4)
    assert d.inside is None
    with pytest.raises(ConfigError, match="keep_inside=True"):
        decomposition_light_field(d, LightFieldConfig(source="field"))
    with pytest.raises(ConfigError, match="keep_inside"):
        decompose(Sphere((0, 0, 0), 1.0), resolution=24, keep_inside=1)  # type: ignore[arg-type]


def test_keeping_the_inside_leaves_the_balls_unchanged() -> None:
    g = Box((0, 0, 0), (2, 1, 0.5)) | Sphere((1, 0, 0), 0.6)
    a = decompose(g, resolution=40, n_balls=32)
    b = decompose(g, resolution=40, n_balls=32, keep_inside=True)
    assert np.array_equal(a.centers, b.centers) and np.array_equal(a.radii, b.radii)
    assert np.array_equal(a.edges, b.edges)


def test_an_empty_field_has_no_light_field() -> None:
    grid = Grid(origin=np.zeros(3), spacing=1.0, shape=(4, 4, 4))
    inside = field_inside(np.full((4, 4, 4), -1.0, np.float32), grid)
    assert inside.count == 0 and inside.shell.shape == (0, 3)
    with pytest.raises(ValueError, match="no inside cell"):
        inside_light_field(inside)
    with pytest.raises(ValueError, match="does not match"):
        field_inside(np.zeros((3, 4, 4), np.float32), grid)
