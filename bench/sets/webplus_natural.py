"""Builders of the ``webplus`` set's natural kinds (see :mod:`bench.sets.webplus_shapes`).

Category-level classes in many poses, as a held-out web benchmark has them: a biped
dinosaur, a kangaroo and an ape (standing, walking, hopping, knuckle-walking, sitting,
grazing), an elephant, a rhinoceros and a giraffe (walking, grazing, drinking, a leg or
the trunk raised), an ostrich (neck up, forward or grazing, wings folded or spread), a spider and an insect
(legs splayed or raised), a snake (coiled, S-curved, head raised), a penguin (standing,
leaning or on its belly), a whale (bent while swimming, diving or breaching), and three
plants (palm tree, cactus, potted plant). Built as web models are: ellipsoids and rods
that interpenetrate, ears, fins, wings and leaves as zero-thickness sheets. Within a
kind the proportions, the pose and optional parts vary with the seed.
"""

from __future__ import annotations

import numpy as np

from bench.sets.mesh_parts import Part, Rng, ellipsoid, revolve, rod, rotation, sheet
from bench.sets.web_furniture import vary
from bench.sets.webplus_made import tube

__all__ = ["limb", "BUILDERS"]


def _dir(yaw: float, pitch: float) -> np.ndarray:
    """Unit vector at azimuth ``yaw`` from +x and elevation ``pitch`` (radians)."""
    return np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])


def limb(start: np.ndarray, dirs: list[np.ndarray], lengths: list[float], r: float) -> list[Part]:
    """Rods from ``start`` along the unit directions ``dirs`` with ``lengths``, tapering."""
    pts = [np.asarray(start, dtype=float)]
    for d, length in zip(dirs, lengths, strict=True):
        pts.append(pts[-1] + length * np.asarray(d, dtype=float))
    radii = r * np.linspace(1.0, 0.7, len(dirs))
    return tube(np.asarray(pts), radii)


def _leg_to_ground(rng: Rng, hip: np.ndarray, length: float, r: float, swing: float,
                   lift: float = 0.0) -> list[Part]:  # fmt: skip
    """A two-segment leg from ``hip`` towards the ground, swung by ``swing`` along x."""
    foot = np.array([hip[0] + swing * length, hip[1], max(lift * length, 0.0)])
    knee = 0.5 * (hip + foot) + np.array([rng.uniform(-0.1, 0.15) * length, 0, 0])
    return tube(np.array([hip, knee, foot]), np.array([r, 0.8 * r]))


# --------------------------------------------------------------------------------------
# Bipeds and quadrupeds
# --------------------------------------------------------------------------------------


def dinosaur(rng: Rng) -> list[Part]:
    s = vary(rng, 4.0, 0.4)
    hip_h, body = s * vary(rng, 0.45, 0.2), s * vary(rng, 0.28, 0.2)
    pitch = rng.uniform(-0.35, 0.6)  # head down (hunting) to upright
    hip = np.array([0, 0, hip_h])
    fwd = _dir(0, pitch)
    parts = [ellipsoid(hip + 0.4 * body * fwd, (body, 0.45 * body, 0.5 * body))]
    parts[0] = ((parts[0][0] - hip) @ rotation(1, -pitch).T + hip, parts[0][1])
    chest = hip + 1.2 * body * fwd
    neck_a = pitch + rng.uniform(-0.2, 0.8)
    head = chest + 0.5 * body * _dir(0, neck_a)
    parts += tube(np.array([chest, head]), 0.18 * body)
    hl = body * vary(rng, 0.6, 0.3)
    parts.append(ellipsoid(head + [0.4 * hl, 0, 0], (hl / 2, 0.2 * hl, 0.25 * hl)))
    if rng.random() < 0.5:  # open jaw
        parts.append(
            sheet((head, head + [hl, 0.1 * hl, -0.3 * hl], head + [hl, -0.1 * hl, -0.3 * hl]))
        )
    yaw, pts = np.pi, [hip.copy()]
    tp = -pitch + rng.uniform(-0.3, 0.3)
    for _ in range(5):  # tail
        yaw += rng.normal(0, 0.25)
        tp += rng.normal(0, 0.15)
        pts.append(pts[-1] + 0.35 * body * _dir(yaw, tp))
    parts += tube(np.asarray(pts), 0.22 * body * np.linspace(1, 0.2, 5))
    for sy in (-1, 1):
        leg_hip = hip + [0, sy * 0.3 * body, 0]
        parts += _leg_to_ground(rng, leg_hip, hip_h, 0.12 * body, rng.uniform(-0.5, 0.5),
                                lift=rng.uniform(0, 0.3) if rng.random() < 0.3 else 0.0)  # fmt: skip
        arm = chest + [0, sy * 0.3 * body, -0.2 * body]
        parts += limb(arm, [_dir(rng.uniform(-0.5, 0.5), rng.uniform(-1.2, 0.3))] * 2,
                      [0.25 * body, 0.2 * body], 0.05 * body)  # fmt: skip
    return parts


def ape(rng: Rng) -> list[Part]:
    h = vary(rng, 1.6, 0.25)
    pose = int(rng.choice(3, p=[0.4, 0.35, 0.25]))  # upright, knuckle-walking, sitting
    hip_h = 0.12 * h if pose == 2 else 0.38 * h
    lean = {0: rng.uniform(-0.1, 0.3), 1: rng.uniform(0.8, 1.2), 2: rng.uniform(-0.2, 0.3)}[pose]
    hip = np.array([0, 0, hip_h])
    up = np.array([np.sin(lean), 0, np.cos(lean)])
    tl = 0.35 * h
    chest = hip + tl * up
    parts = [ellipsoid(hip + 0.5 * tl * up, (0.55 * tl, 0.6 * tl * vary(rng, 1.0, 0.2), 0.6 * tl))]
    head = chest + 0.18 * h * up + [0.05 * h, 0, 0]
    parts.append(ellipsoid(head, (0.09 * h, 0.08 * h, 0.1 * h)))
    parts.append(
        ellipsoid(head + [0.07 * h, 0, -0.03 * h], (0.05 * h, 0.06 * h, 0.04 * h))
    )  # muzzle
    arm_l, leg_l = 0.5 * h * vary(rng, 1.0, 0.15), 0.36 * h
    for sy in (-1, 1):
        sh = chest + [0, sy * 0.28 * tl * 1.2, 0]
        if pose == 1:  # knuckles on the ground
            hand = np.array([sh[0] + rng.uniform(-0.1, 0.2) * h, sh[1] * 1.3, 0.0])
            elbow = 0.5 * (sh + hand) + [0, sy * 0.05 * h, 0]
            parts += tube(np.array([sh, elbow, hand]), np.array([0.045 * h, 0.04 * h]))
        else:
            a, b = rng.uniform(-0.6, 2.8), rng.uniform(-0.6, 0.8)
            d1 = np.array([np.sin(b) * np.cos(a) * 0 + np.sin(b), sy * np.sin(a) * 0.7, -np.cos(a)])
            parts += limb(sh, [d1 / np.linalg.norm(d1), _dir(rng.uniform(-1, 1), rng.uniform(-1.4, 1.0))],
                          [arm_l / 2, arm_l / 2], 0.045 * h)  # fmt: skip
        hp = hip + [0, sy * 0.12 * h, 0]
        if pose == 2:  # legs forward on the ground, knees up
            knee = hp + [0.2 * h, sy * 0.08 * h, 0.15 * h]
            parts += tube(np.array([hp, knee, knee + [0.15 * h, 0, -0.15 * h]]), 0.05 * h)
        else:
            parts += _leg_to_ground(rng, hp, leg_l, 0.05 * h, rng.uniform(-0.35, 0.35))
    return parts


def _quadruped_legs(rng: Rng, xs: tuple[float, float], y: float, z: float, leg: float, r: float,
                    pose: int) -> list[Part]:  # fmt: skip
    """Four legs under a body at height ``z``; pose 1 raises one, pose 2 splays the front pair."""
    raised = int(rng.integers(4)) if pose == 1 else -1
    parts: list[Part] = []
    k = 0
    for x in xs:
        for sy in (-1, 1):
            hip = np.array([x, sy * y, z])
            if k == raised:
                knee = hip + [0.35 * leg, 0, -0.35 * leg]
                parts += tube(np.array([hip, knee, knee + [0.1 * leg, 0, -0.35 * leg]]), r)
            elif pose == 2 and x == max(xs):  # drinking: front legs spread wide
                foot = np.array([x + 0.3 * leg, sy * (y + 0.5 * leg), 0])
                parts += tube(np.array([hip, foot]), r)
            else:
                parts += _leg_to_ground(rng, hip, z, r, rng.uniform(-0.25, 0.25))
            k += 1
    return parts


def elephant(rng: Rng) -> list[Part]:
    length = vary(rng, 5.0, 0.3)
    z, br = length * vary(rng, 0.45, 0.2), length * vary(rng, 0.25, 0.15)
    pose = int(rng.choice(3, p=[0.5, 0.3, 0.2]))
    parts = [ellipsoid((0, 0, z + 0.6 * br), (0.5 * length, br, 1.1 * br))]
    parts += _quadruped_legs(rng, (-0.3 * length, 0.3 * length), 0.5 * br, z + 0.3 * br, z + 0.3 * br,
                             0.1 * length, 0 if pose == 2 else pose)  # fmt: skip
    head = np.array([0.55 * length, 0, z + 1.2 * br])
    parts.append(ellipsoid(head, (0.5 * br, 0.55 * br, 0.6 * br)))
    for sy in (-1, 1):  # ears
        e = head + [-0.1 * br, sy * 0.5 * br, 0]
        flap = rng.uniform(0.1, 1.2)
        out = np.array([-np.cos(flap) * 0.7, sy * np.sin(flap) * 0.9, 0]) * br
        parts.append(sheet((e + [0, 0, 0.5 * br], e + out + [0, 0, 0.4 * br], e + out - [0, 0, 0.6 * br],
                            e - [0, 0, 0.5 * br])))  # fmt: skip
    pitch, pts = (
        -1.2 + (rng.uniform(1.0, 2.8) if rng.random() < 0.4 else rng.uniform(-0.3, 0.4)),
        [],
    )
    pts.append(head + [0.45 * br, 0, -0.2 * br])
    for _ in range(5):  # trunk
        pts.append(pts[-1] + 0.22 * br * _dir(rng.normal(0, 0.2), pitch))
        pitch += rng.normal(0.1, 0.25)
    parts += tube(np.asarray(pts), 0.12 * br * np.linspace(1, 0.5, 5))
    if rng.random() < 0.6:  # tusks
        for sy in (-1, 1):
            t0 = head + [0.35 * br, sy * 0.2 * br, -0.4 * br]
            parts.append(rod(t0, t0 + [0.6 * br, 0, 0.15 * br], 0.04 * br, n=5))
    parts.append(
        rod((-0.5 * length, 0, z + br), (-0.55 * length, 0, z + 0.2 * br), 0.02 * length, n=4)
    )
    return parts


def giraffe(rng: Rng) -> list[Part]:
    length = vary(rng, 2.2, 0.25)
    leg = length * vary(rng, 0.9, 0.2)
    pose = int(rng.choice(3, p=[0.5, 0.25, 0.25]))  # walking, a leg raised, drinking
    z = leg if pose != 2 else 0.75 * leg
    br = 0.2 * length
    parts = [ellipsoid((0, 0, z + 0.5 * br), (0.5 * length, br, 1.1 * br))]
    parts += _quadruped_legs(rng, (-0.35 * length, 0.35 * length), 0.5 * br, z + 0.2 * br, z, 0.035 * length,
                             pose)  # fmt: skip
    a = rng.uniform(-1.1, -0.6) if pose == 2 else rng.uniform(0.7, 1.4)
    base = np.array([0.45 * length, 0, z + br])
    neck = length * vary(rng, 1.0, 0.2)
    top = base + neck * np.array([np.cos(a), 0, np.sin(a)])
    parts += tube(np.array([base, 0.5 * (base + top) + [0, rng.normal(0, 0.05) * neck, 0], top]),
                  np.array([0.09, 0.06]) * length)  # fmt: skip
    hd = _dir(rng.normal(0, 0.4), -0.5 if pose == 2 else rng.uniform(-0.6, 0.2))
    parts.append(ellipsoid(top + 0.15 * length * hd, (0.18 * length, 0.06 * length, 0.07 * length)))
    for sy in (-1, 1):  # ossicones and ears
        parts.append(rod(top + [0, sy * 0.03 * length, 0], top + [-0.02, sy * 0.04 * length, 0.12 * length],
                         0.012 * length, n=4))  # fmt: skip
        parts.append(sheet((top + [0, sy * 0.05 * length, 0.02], top + [-0.1 * length, sy * 0.12 * length, 0.05],
                            top + [-0.02, sy * 0.06 * length, 0.06 * length])))  # fmt: skip
    t = rng.uniform(-1.4, -0.3)
    parts.append(rod((-0.5 * length, 0, z + br), (-0.5 * length + 0.4 * length * np.cos(t) * -1, 0,
                     z + br + 0.4 * length * np.sin(t)), 0.012 * length, n=4))  # fmt: skip
    return parts


def rhinoceros(rng: Rng) -> list[Part]:
    length = vary(rng, 3.5, 0.3)
    z, br = length * vary(rng, 0.28, 0.25), length * vary(rng, 0.2, 0.2)
    pose = int(rng.choice(2, p=[0.7, 0.3]))
    parts = [ellipsoid((0, 0, z + 0.8 * br), (0.5 * length, br, 1.05 * br))]
    parts += _quadruped_legs(rng, (-0.3 * length, 0.3 * length), 0.55 * br, z + 0.4 * br,
                             z + 0.4 * br, 0.07 * length, pose)  # fmt: skip
    dip = rng.uniform(-0.7, 0.2)  # head lowered (grazing) to raised
    neck = np.array([0.45 * length, 0, z + 1.0 * br])
    head = neck + 0.5 * br * _dir(0, dip)
    hl = 0.35 * length * vary(rng, 1.0, 0.2)
    e = ellipsoid((0, 0, 0), (hl / 2, 0.45 * br, 0.5 * br))
    parts.append((e[0] @ rotation(1, -dip).T + head, e[1]))
    snout = head + 0.45 * hl * _dir(0, dip)
    for k in range(int(rng.integers(1, 3))):  # horns
        base = snout - 0.25 * k * hl * _dir(0, dip) + [0, 0, 0.35 * br]
        parts.append(revolve(np.array([0, vary(rng, 0.35, 0.4) * br * (1 - 0.4 * k)]),
                             np.array([0.12 * br, 0.01]), n=8, c=(0, 0)))  # fmt: skip
        parts[-1] = (parts[-1][0] + base, parts[-1][1])
    for sy in (-1, 1):  # ears
        ear = head - 0.3 * hl * _dir(0, dip) + [0, sy * 0.3 * br, 0.45 * br]
        parts.append(
            sheet((ear, ear + [-0.1 * br, sy * 0.1 * br, 0.35 * br], ear + [0.1 * br, 0, 0]))
        )
    parts.append(
        rod((-0.5 * length, 0, z + br), (-0.55 * length, 0, z + 0.3 * br), 0.015 * length, n=4)
    )
    return parts


def kangaroo(rng: Rng) -> list[Part]:
    h = vary(rng, 1.5, 0.3)
    pose = int(rng.choice(3, p=[0.45, 0.35, 0.2]))  # upright, hopping, grazing
    lean = {0: rng.uniform(0.0, 0.4), 1: rng.uniform(0.9, 1.3), 2: rng.uniform(1.2, 1.5)}[pose]
    hip = np.array([0, 0, (0.3 if pose != 1 else 0.45) * h])
    up = np.array([np.sin(lean), 0, np.cos(lean)])
    tl = 0.4 * h
    parts = [ellipsoid(hip + 0.45 * tl * up, (0.3 * tl, 0.25 * tl, 0.55 * tl))]
    parts[0] = ((parts[0][0] - hip - 0.45 * tl * up) @ rotation(1, lean).T + hip + 0.45 * tl * up,
                parts[0][1])  # fmt: skip
    chest = hip + tl * up
    head = chest + 0.12 * h * _dir(0, np.pi / 2 - lean + rng.uniform(-0.4, 0.4)) + [0.04 * h, 0, 0]
    parts.append(ellipsoid(head + [0.04 * h, 0, 0], (0.09 * h, 0.045 * h, 0.05 * h)))
    tail = [hip, hip + [-0.3 * h, 0, -0.15 * h if pose != 1 else 0.0]]
    tail.append(tail[-1] + [-0.35 * h, 0, rng.uniform(-0.3, 0.1) * h])
    tail[-1][2] = max(tail[-1][2], 0.02)
    parts += tube(np.asarray(tail), np.array([0.06, 0.035]) * h)
    for sy in (-1, 1):
        parts.append(sheet((head + [0, sy * 0.02 * h, 0.03 * h], head + [-0.02 * h, sy * 0.04 * h, 0.15 * h],
                            head + [-0.05 * h, sy * 0.02 * h, 0.03 * h])))  # ears  # fmt: skip
        hp = hip + [0, sy * 0.08 * h, 0]
        if pose == 1:  # legs stretched back in a hop
            knee = hp + [0.15 * h, 0, -0.25 * h]
            parts += tube(
                np.array([hp, knee, knee + [-0.35 * h, 0, -0.15 * h]]), np.array([0.06, 0.03]) * h
            )
        else:  # folded, long feet flat on the ground
            knee = hp + [0.2 * h, 0, -0.12 * h]
            heel = np.array([hp[0] - 0.1 * h, hp[1], 0.03 * h])
            parts += tube(np.array([hp, knee, heel, heel + [0.3 * h, 0, -0.02 * h]]), 0.045 * h)
        sh = chest + [0.02 * h, sy * 0.07 * h, -0.05 * h]
        reach = 0.25 * h if pose != 2 else None
        if reach is None:  # grazing: forepaws on the ground
            parts += tube(np.array([sh, [sh[0] + 0.05 * h, sh[1], 0.0]]), 0.02 * h)
        else:
            parts += limb(sh, [_dir(0, rng.uniform(-1.4, 0.3)), _dir(0, rng.uniform(-1.4, 0.6))],
                          [reach / 2, reach / 2], 0.02 * h)  # fmt: skip
    return parts


def ostrich(rng: Rng) -> list[Part]:
    h = vary(rng, 2.2, 0.2)
    leg = 0.45 * h * vary(rng, 1.0, 0.15)
    body = np.array([0, 0, leg + 0.1 * h])
    tilt = rng.uniform(-0.2, 0.3)
    e = ellipsoid((0, 0, 0), (0.2 * h, 0.13 * h, 0.12 * h))
    parts = [(e[0] @ rotation(1, -tilt).T + body, e[1])]
    neck_a = rng.choice([rng.uniform(1.2, 1.5), rng.uniform(0.3, 0.8), rng.uniform(-1.3, -0.9)])
    base = body + [0.15 * h, 0, 0.05 * h]
    top = base + 0.4 * h * _dir(rng.normal(0, 0.2), neck_a)
    top[2] = max(top[2], 0.04 * h)
    parts += tube(np.array([base, 0.5 * (base + top) + [0, 0, 0.03 * h], top]), 0.02 * h)
    parts.append(ellipsoid(top + [0.03 * h, 0, 0], (0.04 * h, 0.025 * h, 0.025 * h)))
    parts.append(rod(top + [0.05 * h, 0, 0], top + [0.1 * h, 0, -0.01 * h], 0.008 * h, n=4))
    for sy in (-1, 1):
        hp = body + [0, sy * 0.06 * h, -0.05 * h]
        parts += _leg_to_ground(rng, hp, leg + 0.05 * h, 0.025 * h, rng.uniform(-0.4, 0.4),
                                lift=rng.uniform(0, 0.4) if rng.random() < 0.3 else 0.0)  # fmt: skip
        spread = rng.uniform(0.0, 1.3)  # folded to spread wings
        root = body + [0.05 * h, sy * 0.12 * h, 0.04 * h]
        tip = root + 0.3 * h * np.array(
            [-np.cos(spread), sy * np.sin(spread), 0.3 * np.sin(spread)]
        )
        parts.append(sheet((root + [0.08 * h, 0, 0], tip, root - [0.12 * h, 0, 0.02 * h])))
    parts.append(sheet((body - [0.18 * h, 0, 0], body + [-0.32 * h, -0.06 * h, 0.08 * h],
                        body + [-0.32 * h, 0.06 * h, 0.08 * h])))  # tail plumes  # fmt: skip
    return parts


# --------------------------------------------------------------------------------------
# Many legs, no legs
# --------------------------------------------------------------------------------------


def spider(rng: Rng) -> list[Part]:
    s = vary(rng, 0.1, 0.5)
    z = s * vary(rng, 0.5, 0.4)
    parts = [ellipsoid((0.3 * s, 0, z), (0.35 * s, 0.3 * s, 0.2 * s))]
    ab = vary(rng, 0.55, 0.3) * s
    tilt = rng.uniform(-0.3, 0.6)
    parts.append(
        ellipsoid(
            (-0.1 * s - ab * np.cos(tilt), 0, z + ab * np.sin(tilt)), (ab, 0.8 * ab, 0.75 * ab)
        )
    )
    span = vary(rng, 1.3, 0.3) * s
    threat = rng.random() < 0.3
    for sy in (-1, 1):
        for k in range(4):
            a = sy * (0.35 + 0.7 * k + rng.normal(0, 0.15))
            root = np.array([0.3 * s, 0, z]) + 0.2 * s * _dir(a, 0)
            if threat and k == 0:
                parts += limb(root, [_dir(a * 0.5, 0.9), _dir(a * 0.5, 0.3)], [0.6 * span, 0.5 * span],
                              0.04 * s)  # fmt: skip
                continue
            up = rng.uniform(0.5, 1.2)
            knee = root + 0.5 * span * _dir(a, up)
            foot = np.array([*(root[:2] + span * _dir(a, 0)[:2] * rng.uniform(0.8, 1.2)), 0.0])
            parts += tube(np.array([root, knee, foot]), np.array([0.05, 0.035]) * s)
    return parts


def insect(rng: Rng) -> list[Part]:
    s = vary(rng, 0.02, 0.5)
    z = s * vary(rng, 0.35, 0.3)
    head, thorax, ab = s * vary(rng, 0.18, 0.3), s * vary(rng, 0.25, 0.3), s * vary(rng, 0.45, 0.4)
    pitch = rng.uniform(-0.3, 0.5)
    parts = [ellipsoid((thorax + head, 0, z + 0.05 * s), (head, 0.8 * head, 0.8 * head)),
             ellipsoid((0, 0, z), (thorax, 0.5 * thorax, 0.5 * thorax))]  # fmt: skip
    c = np.array([-thorax - ab * np.cos(pitch), 0, z + ab * np.sin(pitch)])
    parts.append(ellipsoid(c, (ab, 0.6 * ab * vary(rng, 1.0, 0.3), 0.55 * ab)))
    for sy in (-1, 1):
        for k in range(3):
            root = np.array([(0.5 - 0.5 * k) * thorax, sy * 0.3 * thorax, z])
            a = sy * (0.6 + 0.9 * k + rng.normal(0, 0.2))
            knee = root + 0.35 * s * _dir(a, rng.uniform(0.2, 0.9))
            foot = np.array([*(root[:2] + 0.6 * s * _dir(a, 0)[:2]), 0.0])
            parts += tube(np.array([root, knee, foot]), 0.02 * s)
        ant = np.array([thorax + 1.7 * head, sy * 0.3 * head, z + 0.5 * head])
        parts += limb(ant, [_dir(sy * rng.uniform(0.1, 0.7), rng.uniform(0.2, 1.0)),
                            _dir(sy * rng.uniform(0.3, 0.9), rng.uniform(-0.5, 0.3))],
                      [0.25 * s, 0.25 * s], 0.01 * s)  # fmt: skip
    if rng.random() < 0.35:  # wings, folded or spread
        spread = rng.uniform(0.1, 1.4)
        for sy in (-1, 1):
            root = np.array([0, sy * 0.3 * thorax, z + 0.4 * thorax])
            tip = root + 0.9 * s * np.array([-np.cos(spread), sy * np.sin(spread), 0.05])
            parts.append(sheet((root + [0.1 * s, 0, 0], tip, root - [0.1 * s, 0, 0])))
    return parts


def snake(rng: Rng) -> list[Part]:
    length, r = vary(rng, 2.0, 0.4), vary(rng, 0.035, 0.3)
    style = int(rng.integers(3))  # coiled, S-curve, head raised
    n = 16
    t = np.linspace(0, 1, n)
    if style == 0:
        turns = rng.uniform(1.2, 2.5)
        rad = length / (2 * np.pi * turns) * (1.3 - 0.6 * t)
        ang = 2 * np.pi * turns * t
        pts = np.column_stack([rad * np.cos(ang), rad * np.sin(ang), 2.2 * r * t * turns])
    else:
        waves, amp = rng.uniform(1.0, 2.5), length * rng.uniform(0.05, 0.15)
        pts = np.column_stack(
            [length * t, amp * np.sin(2 * np.pi * waves * t + rng.uniform(0, 6)), np.full(n, r)]
        )
    if style == 2:  # the front third rises
        rise = np.clip((t - 0.66) / 0.34, 0, 1)
        pts[:, 2] += 0.3 * length * rise**1.5
    parts = tube(pts, r * np.clip(1.2 - np.abs(t[:-1] - 0.4), 0.3, 1.0))
    d = pts[-1] - pts[-2]
    parts.append(ellipsoid(pts[-1] + 1.5 * r * d / np.linalg.norm(d), (2.2 * r, 1.5 * r, r)))
    return parts


# --------------------------------------------------------------------------------------
# Birds and whales
# --------------------------------------------------------------------------------------


def penguin(rng: Rng) -> list[Part]:
    h = vary(rng, 0.7, 0.4)
    belly = rng.random() < 0.2
    lean = rng.uniform(1.3, 1.5) if belly else rng.uniform(-0.15, 0.4)
    up = np.array([np.sin(lean), 0, np.cos(lean)])
    w = vary(rng, 0.22, 0.2) * h
    base = np.array([0, 0, w if belly else 0.08 * h])
    body = base + 0.35 * h * up
    parts = [ellipsoid((0, 0, 0), (w * 1.05, w, 0.38 * h))]
    parts[0] = (parts[0][0] @ rotation(1, lean).T + body, parts[0][1])
    head = base + 0.78 * h * up
    parts.append(ellipsoid(head, (0.13 * h, 0.12 * h, 0.13 * h)))
    fwd = np.array([np.cos(lean), 0, -np.sin(lean)])
    look = fwd + rng.normal(0, 0.3, 3)
    parts.append(rod(head + 0.1 * h * fwd, head + (0.1 + vary(rng, 0.12, 0.4)) * h * look / np.linalg.norm(look),
                     0.02 * h, n=4))  # fmt: skip
    for sy in (-1, 1):
        flap = rng.uniform(0.05, 1.3)
        root = body + 0.2 * h * up + [0, sy * w, 0]
        tip = root + 0.35 * h * (-np.cos(flap) * up + sy * np.sin(flap) * np.array([0, 1, 0]))
        parts.append(sheet((root - 0.05 * h * fwd, root + 0.06 * h * fwd, tip)))
        parts.append(sheet((base + [0.1 * h, sy * 0.06 * h, 0], base + [0.1 * h, sy * 0.14 * h, 0],
                            base + [-0.02, sy * 0.1 * h, 0])))  # feet  # fmt: skip
    return parts


def whale(rng: Rng) -> list[Part]:
    length = vary(rng, 12.0, 0.4)
    r = length * vary(rng, 0.1, 0.3)
    bend = rng.normal(0, 0.25)
    pitch = rng.uniform(-0.6, 0.9) if rng.random() < 0.4 else 0.0  # diving or breaching
    pts, ang = [np.zeros(3)], pitch
    for _ in range(4):
        pts.append(pts[-1] - 0.25 * length * _dir(0, ang))
        ang += bend
    parts = []
    for k in range(4):
        c = 0.5 * (pts[k] + pts[k + 1])
        rr = r * (1.0, 0.9, 0.6, 0.3)[k]
        e = ellipsoid((0, 0, 0), (0.16 * length, rr, rr * 0.9))
        a = pitch + bend * k
        parts.append((e[0] @ rotation(1, -a).T + c, e[1]))
    tail = pts[-1]
    fl = vary(rng, 0.14, 0.3) * length
    back = tail - pts[-2]
    back = back / np.linalg.norm(back)
    side = np.array([0, 1.0, 0])
    parts.append(sheet((tail - 0.05 * length * back, tail + fl * (back + side), tail + 0.5 * fl * back,
                        tail + fl * (back - side))))  # flukes  # fmt: skip
    for sy in (-1, 1):
        root = pts[0] - 0.15 * length * _dir(0, pitch) + [0, sy * r, -0.5 * r]
        fin = vary(rng, 0.15, 0.6) * length
        parts.append(
            sheet((root, root - [0.1 * length, 0, 0], root + [-0.1 * fin, sy * fin, -0.3 * fin]))
        )
    if rng.random() < 0.6:  # dorsal fin
        d0 = pts[2] + [0, 0, 0.5 * r]
        parts.append(sheet((d0, d0 - [0.08 * length, 0, 0], d0 + [-0.08 * length, 0, 0.3 * r])))
    return parts


# --------------------------------------------------------------------------------------
# Plants
# --------------------------------------------------------------------------------------


def palm_tree(rng: Rng) -> list[Part]:
    h = vary(rng, 8.0, 0.4)
    lean, bend = rng.uniform(0, 0.35), rng.uniform(-0.05, 0.08)
    pts, ang = [np.zeros(3)], np.pi / 2 - lean
    for _ in range(5):
        pts.append(pts[-1] + 0.2 * h * np.array([np.cos(ang), 0, np.sin(ang)]))
        ang -= bend
    parts = tube(np.asarray(pts), 0.03 * h * np.linspace(1.2, 0.8, 5))
    top = pts[-1]
    n, fl = int(rng.integers(5, 13)), vary(rng, 0.35, 0.3) * h
    for k in range(n):
        a = 2 * np.pi * k / n + rng.normal(0, 0.2)
        droop = rng.uniform(-0.2, 0.7)
        mid = top + 0.5 * fl * _dir(a, 0.3 - 0.3 * droop)
        tip = top + fl * _dir(a, -droop)
        side = 0.06 * h * _dir(a + np.pi / 2, 0)
        parts.append(sheet((top, mid + side, tip, mid - side)))
    for _ in range(int(rng.integers(0, 5))):  # coconuts
        parts.append(
            ellipsoid(top + rng.normal(0, 0.04 * h, 3) - [0, 0, 0.05 * h], (0.02 * h,) * 3)
        )
    return parts


def cactus(rng: Rng) -> list[Part]:
    h, r = vary(rng, 3.0, 0.4), vary(rng, 0.15, 0.35)
    z = np.array([0, 0.9 * h, 0.97 * h, h])
    parts = [revolve(z, np.array([r, r, 0.8 * r, 0.3 * r]), n=10, top=True)]
    for _ in range(int(rng.integers(0, 5))):  # arms: out, then up
        a, z0 = rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 0.7) * h
        out, up = vary(rng, 0.35, 0.4) * h, rng.uniform(0.1, 0.45) * h
        d = np.array([np.cos(a), np.sin(a), 0])
        p0 = np.array([0, 0, z0])
        p1 = p0 + out * d + [0, 0, 0.1 * out]
        parts += tube(np.array([p0, p1, p1 + [0, 0, up]]), 0.7 * r)
    if rng.random() < 0.3:  # in a pot
        parts.append(revolve(np.array([-0.4 * h, 0.02]), np.array([1.5 * r, 2.2 * r]), n=12))
    return parts


def potted_plant(rng: Rng) -> list[Part]:
    pr, ph = vary(rng, 0.15, 0.4), vary(rng, 0.2, 0.4)
    parts = [revolve(np.array([0, ph]), np.array([0.75 * pr, pr]), n=14)]
    parts.append(
        revolve(np.array([0.85 * ph, 0.85 * ph]), np.array([0.01, 0.95 * pr]), n=14)
    )  # soil
    stems, hgt = int(rng.integers(3, 12)), vary(rng, 0.5, 0.5)
    for _ in range(stems):
        a, tilt = rng.uniform(0, 2 * np.pi), rng.uniform(0.6, 1.5)
        p0 = np.array([0.3 * pr * np.cos(a), 0.3 * pr * np.sin(a), 0.85 * ph])
        p1 = p0 + hgt * rng.uniform(0.5, 1.0) * _dir(a, tilt)
        parts.append(rod(p0, p1, 0.006, n=4))
        ll, lw = vary(rng, 0.15, 0.4), vary(rng, 0.06, 0.4)
        droop = rng.uniform(-0.6, 0.5)
        tip = p1 + ll * _dir(a, droop)
        side = lw * _dir(a + np.pi / 2, 0)
        parts.append(sheet((p1, 0.5 * (p1 + tip) + side, tip, 0.5 * (p1 + tip) - side)))
    if rng.random() < 0.4:  # a saucer
        parts.append(
            revolve(np.array([0, 0.02]), np.array([1.2 * pr, 1.3 * pr]), n=14, bottom=True)
        )
    return parts


#: Builders of this module by kind name.
BUILDERS = {
    "dinosaur": dinosaur, "kangaroo": kangaroo, "ape": ape, "elephant": elephant,
    "rhinoceros": rhinoceros, "giraffe": giraffe, "ostrich": ostrich,
    "spider": spider, "insect": insect, "snake": snake, "penguin": penguin, "whale": whale,
    "palm_tree": palm_tree, "cactus": cactus, "potted_plant": potted_plant,
}  # fmt: skip
