"""Builders of the ``web`` set's natural kinds (see :mod:`bench.sets.web_shapes`).

Animals, people and trees as web models make them: ellipsoids and rods that
interpenetrate, fins and wings as zero-thickness sheets. Close families: two
quadrupeds (dog, horse), a bird, a fish, a standing person, a head, a tree. Within
a kind the proportions, the pose and optional parts vary with the seed.
"""

from __future__ import annotations

import numpy as np

from bench.sets.mesh_parts import Part, Rng, box, ellipsoid, revolve, rod, sheet
from bench.sets.web_furniture import vary

__all__ = ["BUILDERS"]


def _quadruped(rng: Rng, length: float, hgt: float, body_r: float, neck: float,
               head: float, leg_r: float) -> list[Part]:  # fmt: skip
    """Body, four legs, neck, head, tail, ears; standing (60 %), sitting or lying down."""
    pose = int(rng.choice(3, p=[0.6, 0.2, 0.2]))
    pitch = rng.uniform(0.5, 0.8) if pose == 1 else 0.0  # sitting: the body rises to the front
    if pose == 2:  # lying: the body rests on the ground
        hgt = 0.1 * hgt
    z = hgt + body_r * 0.5
    v, f = ellipsoid((0, 0, 0), (length / 2, body_r, body_r * rng.uniform(0.9, 1.2)))
    rot = np.array(
        [[np.cos(pitch), 0, -np.sin(pitch)], [0, 1, 0], [np.sin(pitch), 0, np.cos(pitch)]]
    )
    hip = np.array([-length / 2, 0, 0])
    centre = np.array([0, 0, z]) + (hip - rot @ hip if pitch else 0.0)
    parts: list[Part] = [(v @ rot.T + centre, f)]

    def on_body(x: float) -> np.ndarray:
        return np.asarray(rot @ np.array([x, 0, 0]) + centre)

    for sx in (-1, 1):
        for sy in (-1, 1):
            top = on_body(sx * (length / 2 - 0.7 * body_r)) + [0, sy * body_r * 0.6, 0]
            if pose == 2:  # legs tucked under or stretched forward
                foot = top + [sx * 0.4 * length * (sx > 0), 0, -top[2] + leg_r]
                parts.append(rod(top, foot, leg_r, n=6))
                continue
            if pose == 1 and sx < 0:  # haunches
                parts.append(rod(top, top + [0.35 * length, 0, -top[2] + leg_r], leg_r, n=6))
                continue
            swing = rng.normal(0, 0.25) * hgt
            knee = np.array([top[0] + 0.5 * swing, top[1], 0.5 * top[2]])
            parts.append(rod(top, knee, leg_r, n=6))
            parts.append(rod(knee, (top[0] + swing, top[1], 0.0), 0.8 * leg_r, n=6))
    a = rng.uniform(-0.3, 1.2) + pitch  # neck angle from horizontal (grazing to raised)
    base = on_body(length / 2 - 0.3 * body_r) + [0, 0, 0.3 * body_r]
    top = base + neck * np.array([np.cos(a), 0, np.sin(a)])
    parts.append(rod(base, top, 0.45 * body_r, n=8))
    parts.append(ellipsoid(top + [0.5 * head, 0, 0], (head, 0.45 * head, 0.5 * head)))
    if rng.random() < 0.7:  # ears
        for sy in (-1, 1):
            e = top + [0.1 * head, sy * 0.25 * head, 0.4 * head]
            parts.append(sheet((e, e + [0.1 * head, 0, 0], e + [0.05 * head, 0, 0.4 * head])))
    t = rng.uniform(-0.8, 0.8)
    tail0 = on_body(-length / 2) + [0, 0, 0.3 * body_r]
    parts.append(rod(tail0, tail0 + vary(rng, 0.5, 0.4) * length * np.array([-np.cos(t), 0, np.sin(t)]),
                     0.25 * leg_r + 0.005, n=6))  # fmt: skip
    return parts


def dog(rng: Rng) -> list[Part]:
    length = vary(rng, 0.8, 0.35)
    return _quadruped(rng, length, hgt=vary(rng, 0.45, 0.4) * length, body_r=vary(rng, 0.16, 0.3) * length,
                      neck=vary(rng, 0.25, 0.4) * length, head=vary(rng, 0.16, 0.3) * length,
                      leg_r=0.045 * length)  # fmt: skip


def horse(rng: Rng) -> list[Part]:
    length = vary(rng, 1.6, 0.25)
    return _quadruped(rng, length, hgt=vary(rng, 0.6, 0.2) * length, body_r=vary(rng, 0.19, 0.2) * length,
                      neck=vary(rng, 0.55, 0.25) * length, head=vary(rng, 0.2, 0.2) * length,
                      leg_r=0.03 * length)  # fmt: skip


def bird(rng: Rng) -> list[Part]:
    length = vary(rng, 0.4, 0.35)
    z = vary(rng, 0.15, 0.4)
    parts = [ellipsoid((0, 0, z), (length / 2, 0.2 * length, 0.22 * length))]
    head = np.array([0.45 * length, 0, z + 0.25 * length])
    parts.append(ellipsoid(head, (0.12 * length, 0.1 * length, 0.1 * length)))
    parts.append(rod(head + [0.08 * length, 0, 0], head + [vary(rng, 0.25, 0.5) * length, 0, -0.02],
                     0.02 * length, n=4))  # beak  # fmt: skip
    span = vary(rng, 1.5, 0.4) * length
    lift = rng.uniform(-0.3, 1.0)  # folded (< 0) to raised
    for sy in (-1, 1):
        root = np.array([0.1 * length, sy * 0.15 * length, z + 0.1 * length])
        tip = root + [-0.25 * length, sy * span / 2 * np.cos(lift), span / 2 * np.sin(lift)]
        if lift < 0:
            tip = root + [-0.45 * length, sy * 0.05 * length, -0.05 * length]
        parts.append(sheet((root + [0.12 * length, 0, 0], root - [0.15 * length, 0, 0], tip)))
    parts.append(sheet(((-0.4 * length, 0, z), (-0.8 * length, -0.12 * length, z + 0.05),
                        (-0.8 * length, 0.12 * length, z + 0.05))))  # tail  # fmt: skip
    for sy in (-1, 1):
        parts.append(
            rod(
                (0, sy * 0.06 * length, z - 0.15 * length),
                (0.02, sy * 0.06 * length, 0),
                0.01 * length + 0.002,
                n=4,
            )
        )
    return parts


def fish(rng: Rng) -> list[Part]:
    length = vary(rng, 1.0, 0.3)
    hgt, wd = length * vary(rng, 0.22, 0.45), length * vary(rng, 0.1, 0.35)
    parts = [ellipsoid((0, 0, 0), (length / 2, wd, hgt))]
    tx, ts = -length / 2, vary(rng, 0.22, 0.4) * length
    fork = rng.uniform(0, 0.6)
    parts.append(
        sheet(
            ((tx + 0.05, 0, 0), (tx - ts, 0, ts), (tx - ts * (1 - fork), 0, 0), (tx - ts, 0, -ts))
        )
    )
    dl = vary(rng, 0.3, 0.4) * length
    parts.append(sheet(((0.1 * length, 0, hgt * 0.85), (0.1 * length - dl, 0, hgt * 0.85),
                        (-dl * 0.8, 0, hgt + vary(rng, 0.12, 0.5) * length))))  # dorsal  # fmt: skip
    for s in (-1, 1):
        parts.append(sheet(((0.15 * length, s * wd, -0.3 * hgt), (0.05 * length, s * wd, -0.3 * hgt),
                            (0.0, s * (wd + 0.12 * length), -0.5 * hgt))))  # fmt: skip
    if rng.random() < 0.5:  # anal fin
        parts.append(sheet(((-0.2 * length, 0, -0.8 * hgt), (-0.35 * length, 0, -0.7 * hgt),
                            (-0.32 * length, 0, -hgt - 0.08 * length))))  # fmt: skip
    return parts


def human(rng: Rng) -> list[Part]:
    h = vary(rng, 1.75, 0.15)
    leg, sh = vary(rng, 0.47, 0.1) * h, vary(rng, 0.12, 0.2) * h
    parts = [box_or_ellipsoid(rng, (0, 0, leg + 0.15 * h), (2 * sh, 0.1 * h, 0.3 * h))]
    parts.append(ellipsoid((0, 0, 0.92 * h), (0.06 * h, 0.07 * h, 0.08 * h)))
    parts.append(rod((0, 0, leg + 0.28 * h), (0, 0, 0.86 * h), 0.025 * h, n=6))  # neck
    for s in (-1, 1):
        sw = rng.uniform(-0.35, 0.35)
        knee = np.array([s * 0.07 * h, 0.5 * sw * leg, 0.5 * leg])
        parts.append(rod((s * 0.06 * h, 0, leg + 0.02), knee, 0.04 * h, n=6))
        parts.append(rod(knee, (s * 0.07 * h, sw * leg, 0), 0.03 * h, n=6))
        a, b = rng.uniform(0.05, 2.6), rng.uniform(-0.6, 0.6)  # shoulder abduction, swing
        elbow = np.array(
            [
                s * (sh + 0.18 * h * np.sin(a)),
                0.18 * h * np.sin(b),
                leg + 0.28 * h - 0.18 * h * np.cos(a),
            ]
        )
        bend = rng.uniform(0, 1.5)
        hand = elbow + 0.18 * h * np.array(
            [s * np.sin(a + bend * 0.3), np.sin(b + bend), -np.cos(a + bend)]
        )
        parts.append(rod((s * sh, 0, leg + 0.28 * h), elbow, 0.025 * h, n=6))
        parts.append(rod(elbow, hand, 0.02 * h, n=6))
    return parts


def box_or_ellipsoid(
    rng: Rng, c: tuple[float, float, float], size: tuple[float, float, float]
) -> Part:
    """A box of full sizes ``size`` or the ellipsoid inscribed in it, at random."""
    return box(c, size) if rng.random() < 0.5 else ellipsoid(c, np.asarray(size) / 2)


def head(rng: Rng) -> list[Part]:
    s = vary(rng, 0.22, 0.2)
    parts = [ellipsoid((0, 0, 0), (s * vary(rng, 0.75, 0.15), s * vary(rng, 0.65, 0.15), s))]
    parts.append(ellipsoid((0, 0, -0.6 * s), (0.55 * s, 0.5 * s, 0.35 * s)))  # jaw
    nl = vary(rng, 0.25, 0.4) * s
    parts.append(
        sheet(
            (
                (0.7 * s, -0.1 * s, -0.15 * s),
                (0.7 * s, 0.1 * s, -0.15 * s),
                (0.7 * s + nl, 0, -0.2 * s),
            )
        )
    )
    parts.append(
        sheet(((0.7 * s, 0, 0.1 * s), (0.7 * s, -0.1 * s, -0.15 * s), (0.7 * s + nl, 0, -0.2 * s)))
    )
    for sy in (-1, 1):
        parts.append(
            ellipsoid((0, sy * 0.68 * s, -0.05 * s), (0.12 * s, 0.05 * s, 0.2 * s))
        )  # ears
        parts.append(ellipsoid((0.6 * s, sy * 0.25 * s, 0.15 * s), (0.06 * s, 0.08 * s, 0.04 * s)))
    if rng.random() < 0.6:  # neck
        parts.append(revolve(np.array([-2.0 * s, -0.6 * s]), np.array([0.4 * s, 0.35 * s]), n=12,
                             c=(-0.15 * s, 0)))  # fmt: skip
    if rng.random() < 0.4:  # hair or hat
        parts.append(ellipsoid((-0.1 * s, 0, 0.3 * s), (0.8 * s, 0.7 * s, 0.8 * s)))
    return parts


def tree(rng: Rng) -> list[Part]:
    h = vary(rng, 1.5, 0.35)
    parts = [revolve(np.array([0, 0.5 * h]), np.array([0.05, 0.035]) * h, n=8, top=True)]
    if rng.random() < 0.45:  # conifer
        for k in range(int(rng.integers(2, 5))):
            z0 = 0.3 * h + 0.18 * h * k
            parts.append(revolve(np.array([z0, z0 + 0.4 * h]),
                                 np.array([0.32 * h * (1 - 0.2 * k), 0.01]), n=12))  # fmt: skip
    else:
        for _ in range(int(rng.integers(1, 6))):
            c = (rng.normal(0, 0.1 * h), rng.normal(0, 0.1 * h), h * rng.uniform(0.6, 0.85))
            parts.append(ellipsoid(c, h * rng.uniform(0.12, 0.3, size=3)))
        for _ in range(int(rng.integers(0, 4))):  # branches
            a = rng.uniform(0, 2 * np.pi)
            parts.append(
                rod(
                    (0, 0, 0.4 * h),
                    (0.3 * h * np.cos(a), 0.3 * h * np.sin(a), 0.7 * h),
                    0.015 * h,
                    n=5,
                )
            )
    return parts


#: Builders of this module by kind name.
BUILDERS = {
    "dog": dog, "horse": horse, "bird": bird, "fish": fish, "human": human, "head": head,
    "tree": tree,
}  # fmt: skip
