"""The light field descriptor of shapedb.signature.lightfield on analytic ball sets."""

from __future__ import annotations

import numpy as np
import pytest

from shapedb.config.core import LightFieldConfig
from shapedb.errors import ConfigError
from shapedb.signature.lightfield import (
    ball_light_field,
    dodecahedron_rotations,
    dodecahedron_views,
    field_directions,
    light_field_dim,
    light_field_distance,
    render_discs,
    view_permutations,
    zernike_magnitudes,
)

SMALL = LightFieldConfig(n_fields=3, resolution=48)


def _turn(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _shapes() -> list[tuple[np.ndarray, np.ndarray]]:
    """A dumbbell, an L of three balls, a flat ring of eight: (centres, radii)."""
    dumbbell = (np.array([[0, 0, 0], [3.0, 0, 0], [1.5, 0, 0]]), np.array([1.0, 1.0, 0.4]))
    ell = (np.array([[0, 0, 0], [2.0, 0, 0], [0, 2.0, 0]]), np.array([1.0, 0.8, 0.8]))
    t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    ring = (np.stack([3 * np.cos(t), 3 * np.sin(t), 0 * t], axis=1), np.full(8, 1.0))
    return [dumbbell, ell, ring]


def test_the_sixty_rotations_map_the_dodecahedron_onto_itself() -> None:
    rots = dodecahedron_rotations()
    assert rots.shape == (60, 3, 3) and np.allclose(rots[0], np.eye(3))
    assert np.allclose(np.einsum("kji,kjl->kil", rots, rots), np.eye(3))
    assert np.allclose(np.linalg.det(rots), 1.0)
    assert len({tuple(np.round(r, 6).ravel()) for r in rots}) == 60
    views = dodecahedron_views()
    for r, perm in zip(rots, view_permutations(), strict=True):
        assert sorted(perm) == list(range(10))
        # view v goes to view perm[v] or to its opposite
        assert np.allclose(np.abs(np.sum((views @ r.T) * views[perm], axis=1)), 1.0)


def test_a_single_ball_is_a_centred_disc_from_every_side() -> None:
    dirs = field_directions(2, 0)
    sil, depth = render_discs([[5.0, -2.0, 1.0]], [3.0], dirs, 64, depth=True)
    assert sil.shape == (20, 64, 64) and depth is not None and depth.shape == (20, 2, 64, 64)
    # the unit disc (plus half a pixel of slack), the same image from every direction
    c = (np.arange(64) + 0.5) / 32 - 1.0
    disc = np.hypot(*np.meshgrid(c, c)) <= 1.0 + 1.0 / 64
    assert all(np.array_equal(s, disc) for s in sil)
    # depth: the hemisphere's height, 1 at the centre, 1/2 at the rim, front = back
    assert np.allclose(depth[:, 0], depth[:, 1])
    assert depth[0, 0, 31:33, 31:33].min() > 0.99 and depth[0, 0][~disc].max() == 0.0
    z = zernike_magnitudes(sil, 10)
    # only the rotation-symmetric moments (m = 0) of a centred disc are non-zero
    orders = [(n, m) for n in range(11) for m in range(n % 2, n + 1, 2)]
    m = np.array([m for _, m in orders])
    assert np.all(z[:, 0] > 0.98)
    assert np.all(z[:, m % 4 != 0] < 1e-9)  # exact: the pixel grid has the square's symmetry
    assert np.all(z[:, (m > 0) & (m % 4 == 0)] < 0.03)  # the square grid's aliasing only
    f = ball_light_field([[5.0, -2.0, 1.0]], [3.0], SMALL)
    assert f.shape == (3, 10, light_field_dim(SMALL))
    assert np.allclose(f[..., -SMALL.fourier :], 0.0, atol=0.02)  # a circle's contour is flat


@pytest.mark.parametrize("depth_weight", [0.0, 1.0])
def test_a_moved_turned_scaled_copy_is_at_distance_about_zero(depth_weight: float) -> None:
    cfg = LightFieldConfig(n_fields=10, resolution=64, depth_weight=depth_weight)
    shapes = _shapes()
    lf = [ball_light_field(c, r, cfg) for c, r in shapes]
    moved = []
    for k, (c, r) in enumerate(shapes):
        turn = dodecahedron_rotations()[7 + k]  # a symmetry of the views: exact up to pixels
        moved.append(ball_light_field(2.5 * c @ turn.T + [1.0, -4.0, 2.0], 2.5 * r, cfg))
    d = light_field_distance(np.stack(lf + moved))
    assert np.allclose(d, d.T) and np.allclose(np.diag(d), 0.0)
    between = d[:3, :3][~np.eye(3, dtype=bool)].min()
    for k in range(3):
        assert d[k, 3 + k] < 0.15 * between
        assert np.argmin(d[3 + k, :3]) == k
    # an arbitrary turn: the ten light fields bound the error
    c, r = shapes[1]
    other = ball_light_field(c @ _turn(3).T, r, cfg)
    far = light_field_distance(np.stack(lf), other[None])[:, 0]
    assert np.argmin(far) == 1 and far[1] < 0.5 * far[[0, 2]].min()


def test_the_distance_is_symmetric_between_query_and_candidates() -> None:
    rng = np.random.default_rng(0)
    a = rng.random((4, 3, 10, 46))
    b = rng.random((5, 2, 10, 46))
    ab = light_field_distance(a, b)
    assert ab.shape == (4, 5)
    assert np.allclose(ab, light_field_distance(b, a).T)
    full = light_field_distance(a)
    assert np.allclose(full, light_field_distance(a, a)) and np.allclose(full, full.T)
    # a rotation of the views (a permutation of the 10 images) costs nothing
    turned = a[:, :, view_permutations()[11]]
    assert np.allclose(np.diag(light_field_distance(a, turned)), 0.0)


def test_the_distance_is_the_least_rotated_sum_of_view_distances() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.random((2, 2, 10, 7)), rng.random((3, 3, 10, 7))
    perm = view_permutations()
    expected = np.array([
        [
            min(
                np.abs(a[i, p] - b[j, q][perm[r]]).sum()
                for p in range(2) for q in range(3) for r in range(60)
            )
            for j in range(3)
        ]
        for i in range(2)
    ])  # fmt: skip
    assert np.allclose(light_field_distance(a, b), expected, rtol=1e-12)


def test_errors_name_the_reason() -> None:
    with pytest.raises(ValueError, match="do not match"):
        light_field_distance(np.zeros((2, 1, 10, 46)), np.zeros((2, 1, 10, 45)))
    with pytest.raises(ValueError, match="no ball"):
        ball_light_field(np.zeros((2, 3)), np.zeros(2))
    with pytest.raises(ConfigError, match="lf_n_fields"):
        LightFieldConfig(n_fields=0)
    with pytest.raises(ConfigError, match="fourier"):
        LightFieldConfig(fourier=40, angles=64)


def _pixel_centres(res: int) -> np.ndarray:
    return (np.arange(res) + 0.5) / res * 2.0 - 1.0


def test_a_contact_edge_fills_the_waist_between_two_touching_balls() -> None:
    # two unit balls touching at the origin, seen from the side: two discs meeting in a point
    c, r = np.array([[-1.0, 0, 0], [1.0, 0, 0]]), np.array([1.0, 1.0])
    view = np.array([[0.0, 0.0, 1.0]])  # image rows along -x, columns along +y
    res = 64
    plain, _ = render_discs(c, r, view, res)
    filled, _ = render_discs(c, r, view, res, edges=[[0, 1]])
    # the frame: centred on the origin, the far sides at radius 1 (balls of radius 1/2)
    x = -_pixel_centres(res)  # each row's x
    y = _pixel_centres(res)
    waist = np.argmin(np.abs(x))
    # every pixel on the segment between the centres is covered in both
    on_axis = np.argmin(np.abs(y))
    assert plain[0, np.abs(x) <= 0.5, on_axis].all() and filled[0, np.abs(x) <= 0.5, on_axis].all()
    # with the edge the waist is as wide as the balls (the hull: a 1 x 1 square between
    # the centres); without it the two discs meet in a point (widened by the half pixel
    # of slack: a third of the balls' width at the row nearest the contact)
    assert filled[0, waist, np.abs(y) <= 0.5].all()
    assert plain[0, waist].sum() < 0.4 * filled[0, waist].sum()
    inside = (np.abs(x)[:, None] <= 0.5) & (np.abs(y)[None, :] <= 0.5)
    assert filled[0][inside].all() and not plain[0][inside].all()
    # nothing beyond the hull (of the discs widened by the half pixel of slack)
    reach = 0.5 + 1.0 / res
    square = (np.abs(x)[:, None] <= 0.5) & (np.abs(y)[None, :] <= reach)
    hull = square | (np.hypot(np.abs(x)[:, None] - 0.5, y[None, :]) <= reach)
    assert not (filled[0] & ~hull).any()


def test_filled_unions_of_moved_turned_scaled_copies_are_at_distance_about_zero() -> None:
    cfg = LightFieldConfig(n_fields=10, resolution=96, edges=True, close_px=1)
    shapes = _shapes()
    edges = [np.array([[0, 2], [1, 2]]), np.array([[0, 1], [0, 2]]),
             np.stack([np.arange(8), (np.arange(8) + 1) % 8], axis=1)]  # fmt: skip
    lf = [ball_light_field(c, r, cfg, edges=e) for (c, r), e in zip(shapes, edges, strict=True)]
    moved = []
    for k, ((c, r), e) in enumerate(zip(shapes, edges, strict=True)):
        turn = dodecahedron_rotations()[7 + k]
        moved.append(ball_light_field(2.5 * c @ turn.T + [1.0, -4.0, 2.0], 2.5 * r, cfg, edges=e))
    d = light_field_distance(np.stack(lf + moved))
    assert np.allclose(np.diag(d), 0.0)
    between = d[:3, :3][~np.eye(3, dtype=bool)].min()
    for k in range(3):
        assert d[k, 3 + k] < 0.15 * between and np.argmin(d[3 + k, :3]) == k


def test_the_edge_fill_closes_a_string_of_beads() -> None:
    # a bent rod of beads with gaps between them (contacts given): filled, a rod
    t = np.linspace(0.0, 1.0, 12)
    c = np.stack([6 * t, 2 * np.sin(3 * t), 0 * t], axis=1)
    gap = np.linalg.norm(np.diff(c, axis=0), axis=1)
    r = np.full(12, 0.3 * gap.max())
    edges = np.stack([np.arange(11), np.arange(1, 12)], axis=1)
    cfg = LightFieldConfig(n_fields=10, resolution=64, edges=True)
    plain = ball_light_field(c, r, LightFieldConfig(n_fields=10, resolution=64))
    filled = ball_light_field(c, r, cfg, edges=edges)
    turn = dodecahedron_rotations()[9]
    moved = ball_light_field(3.0 * c @ turn.T + [4.0, 1.0, -2.0], 3.0 * r, cfg, edges=edges)
    d = light_field_distance(np.stack([plain, filled, moved]))
    # a thin rod's pixels move with the pose: its copy is far nearer than the beads are
    assert d[1, 2] < 0.25 * d[0, 1]
    sil, _ = render_discs(c, r, field_directions(1, 0), 64, edges=edges)
    beads, _ = render_discs(c, r, field_directions(1, 0), 64)
    assert sil.sum() > 1.2 * beads.sum() and (sil >= beads).all()
    with pytest.raises(ValueError, match="contact edges"):
        ball_light_field(c, r, cfg)
    with pytest.raises(ValueError, match="outside"):
        ball_light_field(c, r, cfg, edges=[[0, 12]])


def test_balls_of_zero_radius_are_left_out_with_their_edges() -> None:
    c = np.array([[0.0, 0, 0], [5.0, 0, 0], [1.0, 0, 0]])
    r = np.array([0.5, 0.0, 0.5])
    view = np.array([[0.0, 0.0, 1.0]])
    got, _ = render_discs(c, r, view, 32, edges=[[0, 1], [0, 2], [1, 2]])
    want, _ = render_discs(c[[0, 2]], r[[0, 2]], view, 32, edges=[[0, 1]])
    assert np.array_equal(got, want)


def test_dilation_and_closing_only_add_pixels() -> None:
    c, r = _shapes()[2]
    dirs = field_directions(1, 0)
    plain, _ = render_discs(c, r, dirs, 48)
    for kw in ({"dilate_px": 1.0}, {"close_px": 2}):
        grown, _ = render_discs(c, r, dirs, 48, **kw)  # type: ignore[arg-type]
        assert (grown >= plain).all() and grown.sum() > plain.sum()
    with pytest.raises(ConfigError, match="lf_dilate_px"):
        LightFieldConfig(dilate_px=-1.0)
    with pytest.raises(ConfigError, match="lf_edges"):
        LightFieldConfig(edges=1)  # type: ignore[arg-type]


def test_the_light_fields_of_a_longer_packing_are_those_of_the_balls_and_the_tail() -> None:
    from shapedb.geometry.implicit import Box, Capsule
    from shapedb.mdbd.decomposition import decompose
    from shapedb.signature.lightfield import decomposition_light_field, record_light_field

    g = Box([0, 0, 0], [2.0, 2.0, 2.0]) | Capsule([0.9, 0, 0], [2.8, 0, 0], 0.1)
    today = decompose(g, resolution=48, n_balls=16)
    longer = decompose(g, resolution=48, n_balls=16, tail_balls=300)
    plain = decomposition_light_field(today, SMALL)
    assert np.array_equal(plain, record_light_field(today.centers, today.radii, SMALL))
    got = decomposition_light_field(longer, SMALL)
    assert np.array_equal(got, record_light_field(*longer.longer_packing(), SMALL))
    # the tail adds the rod the 16 balls miss: nearer to a dense packing of the solid
    dense = decompose(g, resolution=48, n_balls=1500)
    ref = record_light_field(dense.centers, dense.radii, SMALL)
    d = light_field_distance(np.stack([ref, got, plain]))
    assert d[0, 1] < 0.5 * d[0, 2]
    # filled silhouettes of a tail use the contacts of all the balls
    filled = LightFieldConfig(n_fields=3, resolution=48, edges=True)
    assert decomposition_light_field(longer, filled).shape == got.shape


def test_the_packing_length_is_checked() -> None:
    with pytest.raises(ConfigError, match="lf_n_balls"):
        LightFieldConfig(n_balls=-1)
    assert LightFieldConfig(n_balls=1024).n_balls == 1024


def test_a_view_framed_silhouette_is_centred_and_its_light_field_fills_the_disc() -> None:
    # two balls of unequal size, far from the 3-D centre's frame: each view's covered
    # pixels have their centroid at the image's centre, and the widest view of each light
    # field reaches the unit disc's rim
    dirs = field_directions(2, 0)
    c, r = np.array([[0.0, 0, 0], [2.5, 0.7, 0]]), np.array([1.0, 0.35])
    sil, _ = render_discs(c, r, dirs, 96, framing="view")
    px = (np.arange(96) + 0.5) / 48 - 1.0
    reach = []
    for img in sil:
        rows, cols = np.nonzero(img)
        assert abs(px[cols].mean()) <= 1.5 / 48 and abs(px[rows].mean()) <= 1.5 / 48
        reach.append(np.hypot(px[cols], px[rows]).max())
    for field in np.reshape(reach, (2, 10)):
        assert 1.0 - 2.0 / 48 <= field.max() <= 1.0 + 1.0 / 48


def test_view_framing_ignores_where_the_frame_is_centred() -> None:
    c, r = _shapes()[1]
    dirs = field_directions(1, 0)
    # the same silhouettes up to the first pass's pixels (the centroid's), where the
    # sphere's frame moves and shrinks them
    a, _ = render_discs(c, r, dirs, 64, framing="view", frame=(c.mean(axis=0), 4.0))
    b, _ = render_discs(c, r, dirs, 64, framing="view", frame=(c[0] + 0.7, 9.0))
    assert (a ^ b).sum() < 0.05 * a.sum()
    s1, _ = render_discs(c, r, dirs, 64, frame=(c.mean(axis=0), 4.0))
    s2, _ = render_discs(c, r, dirs, 64, frame=(c[0] + 0.7, 9.0))
    assert (s1 ^ s2).sum() > 0.5 * s1.sum()


def test_a_bad_framing_names_the_option() -> None:
    with pytest.raises(ConfigError, match="lf_framing"):
        LightFieldConfig(framing="box")


# --------------------------------------------------------------------------------------
# A point cloud's own light fields
# --------------------------------------------------------------------------------------


def _box_surface(n: int, extents: tuple[float, float, float], seed: int = 0) -> np.ndarray:
    """n points uniform by area over the surface of a box of ``extents`` at the origin."""
    rng = np.random.default_rng(seed)
    e = np.asarray(extents, float) / 2
    areas = np.array([e[1] * e[2], e[0] * e[2], e[0] * e[1]] * 2)
    face = rng.choice(6, n, p=areas / areas.sum())
    p = rng.uniform(-1.0, 1.0, (n, 3)) * e
    p[np.arange(n), face % 3] = np.where(face < 3, 1.0, -1.0) * e[face % 3]
    return p


def _box_cells(extents: tuple[float, float, float], cell: float = 0.05) -> np.ndarray:
    """Centres of the grid cells filling a box of ``extents`` at the origin."""
    axes = [np.arange(-e / 2 + cell / 2, e / 2, cell) for e in extents]
    return np.stack([m.ravel() for m in np.meshgrid(*axes, indexing="ij")], axis=1)


def test_a_clouds_light_fields_are_its_solids() -> None:
    # samples of a box's surface draw the silhouettes of the solid box (its cells, each a
    # ball of half a cell, as a store draws a field's inside): far nearer to them than
    # the samples of boxes a fifth to a half thinner along one side
    from shapedb.signature.lightfield import cloud_light_field

    cfg = LightFieldConfig(n_fields=2, resolution=48)
    cells = _box_cells((2.0, 1.0, 0.5))
    solid = ball_light_field(cells, np.full(len(cells), 0.025), cfg)[None]
    others = [(2.0, 1.0, 0.1), (2.0, 0.6, 0.5), (1.5, 1.0, 0.5)]
    near = light_field_distance(
        cloud_light_field(_box_surface(3000, (2.0, 1.0, 0.5)), cfg)[None], solid
    )
    far = [
        light_field_distance(cloud_light_field(_box_surface(3000, e), cfg)[None], solid)
        for e in others
    ]
    # evened out (CLOUD_EVEN_QUANTILE) its discs are wider than the samples' median
    # spacing, which widens the silhouettes: 0.27 of the nearest thinner box (0.08 unevened)
    assert near[0, 0] < 0.3 * min(float(f[0, 0]) for f in far)


def test_a_clouds_light_fields_ignore_order_pose_and_duplicates() -> None:
    from shapedb.signature.lightfield import cloud_light_field

    cfg = LightFieldConfig(n_fields=2, resolution=48)
    p = _box_surface(2000, (2.0, 1.0, 0.5))
    a = cloud_light_field(p, cfg)
    assert a.shape == (2, 10, light_field_dim(cfg)) and a.dtype == np.float32
    shuffled = np.random.default_rng(1).permutation(p)
    np.testing.assert_array_equal(cloud_light_field(np.vstack([shuffled, p[:50]]), cfg), a)
    moved = 3.0 * p + [5.0, -2.0, 1.0]
    np.testing.assert_allclose(cloud_light_field(moved, cfg), a, atol=1e-3)


def test_a_large_cloud_is_drawn_from_a_seeded_subset(monkeypatch: pytest.MonkeyPatch) -> None:
    import shapedb.signature.lightfield as lf

    cfg = LightFieldConfig(n_fields=1, resolution=32)
    p = _box_surface(3000, (2.0, 1.0, 0.5))
    monkeypatch.setattr(lf, "CLOUD_POINTS", 1000)
    a = lf.cloud_light_field(p, cfg)
    np.testing.assert_array_equal(lf.cloud_light_field(p, cfg), a)
    assert light_field_distance(a[None], lf.cloud_light_field(p[:1000], cfg)[None])[0, 0] > 0


@pytest.mark.parametrize(
    ("points", "reason"),
    [(np.zeros((5, 3)), "3 or more distinct"), (np.full((5, 3), np.nan), "finite")],
)
def test_a_cloud_without_a_surface_has_no_light_fields(points: np.ndarray, reason: str) -> None:
    from shapedb.signature.lightfield import cloud_light_field

    with pytest.raises(ValueError, match=reason):
        cloud_light_field(points)


def test_a_clouds_light_fields_hardly_depend_on_how_its_points_are_spread(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a scanner's fall-off: a box's samples 20 times denser at one end than at the other;
    # evened out, their light fields lie nearer to an even sample's than they do unevened
    import shapedb.signature.lightfield as lf

    cfg = LightFieldConfig(n_fields=2, resolution=48)
    extents = (2.0, 1.0, 0.5)
    pool = _box_surface(40000, extents, seed=1)
    weight = np.exp(-1.5 * (pool[:, 0] + 1.0))
    keep = np.random.default_rng(2).choice(len(pool), 3000, replace=False, p=weight / weight.sum())
    even, falloff = _box_surface(3000, extents), pool[keep]

    def apart() -> float:
        a = lf.cloud_light_field(even, cfg)[None]
        return float(light_field_distance(a, lf.cloud_light_field(falloff, cfg)[None])[0, 0])

    evened = apart()
    monkeypatch.setattr(lf, "CLOUD_EVEN_QUANTILE", 0.0)
    assert evened < 0.6 * apart()  # 3.2 against 6.7
