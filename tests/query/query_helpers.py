"""Helpers of the query tests (not fixtures): synthetic features and example records."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np

from shapedb.config.core import Config
from shapedb.geometry.implicit import Box, Capsule, Cylinder, Sphere, Torus, Union
from shapedb.mdbd.decomposition import decompose
from shapedb.signature.kernel import features
from shapedb.store.schema import ShapeRecord

CONFIG = Config().with_options(resolution=32, n_balls=64)
#: The light field stage of the small analytic stores (``StageTuning`` options): K 5 and
#: K2 2, the gate open, the shared-neighbour term at k 2 with beta 0.8; the field vectors
#: at the research's weights 0.5 and 0.5 of its scales 20.67, 6.045, 2.168 (``alpha = a *
#: m_l / m_b``, ``gamma = c * m_l / m_h``, ``scale = (1 + a + c) * m_l``).
SMALL_STAGE: dict[str, Any] = {
    "candidates": 5, "field_depth_weight": 0.5 * 20.67 / 6.045,
    "field_harmonic_weight": 0.5 * 20.67 / 2.168, "scale": 2.0 * 20.67,
    "field_candidates": 2, "ceiling": 0.0, "contrast_floor": 0.0, "shared_neighbours": 2,
    "shared_weight": 0.8,
}  # fmt: skip


def synthetic_features(n: int, n_r: int = 32, seed: int = 0) -> np.ndarray:
    """Vectors shaped like Eq. 1 features: (n, 2 n_r) float32.

    Sorted, decreasing radius ratios in (0, 1] (the first is 1), then walk averages
    of about 0.6 times a neighbourhood mean of them.
    """
    rng = np.random.default_rng(seed)
    i = np.arange(n_r)
    alpha = rng.uniform(0.01, 0.3, (n, 1))
    beta = rng.uniform(0.5, 1.5, (n, 1))
    r = np.exp(-alpha * i**beta) * (1 + 0.05 * rng.standard_normal((n, n_r)))
    r = -np.sort(-np.clip(r, 1e-3, None), axis=1)
    r /= r[:, :1]
    nb = rng.integers(0, n_r, (n, n_r, 3))
    mean_nb = np.take_along_axis(np.repeat(r[:, :, None], 3, 2), nb, 1).mean(2)
    walk = rng.uniform(0.5, 0.7, (n, 1)) * (0.5 * r + 0.5 * mean_nb)
    return np.concatenate([r, walk], 1).astype(np.float32)


def _shapes() -> list[tuple[str, str, Any]]:
    out: list[tuple[str, str, Any]] = []
    for k, (x, y, z) in enumerate([(2, 1, 1), (3, 1, 1), (2, 2, 1), (4, 1, 0.5)]):
        out.append((f"box{k}", "box", Box([0, 0, 0], [x, y, z])))
    for k, length in enumerate([1.5, 2.0, 3.0, 4.0]):
        out.append((f"capsule{k}", "capsule", Capsule([0, 0, 0], [length, 0, 0], 0.4)))
    for k, (h, r) in enumerate([(2.0, 0.5), (3.0, 0.5), (1.0, 0.8)]):
        out.append((f"cylinder{k}", "cylinder", Cylinder([0, 0, 0], [0, 0, h], r)))
    for k, (big, small) in enumerate([(1.0, 0.3), (1.2, 0.3), (1.0, 0.2)]):
        out.append((f"torus{k}", "torus", Torus([0, 0, 0], big, small)))
    return out


def shape_pairs() -> dict[str, Any]:
    """Seven analytic shapes by name: two boxes, two rods, two rings (a kind's pair shares
    the name's prefix, its label) and a ball."""
    return {
        "box_a": Box((0, 0, 0), (2.0, 1.0, 1.0)),
        "box_b": Box((0, 0, 0), (2.4, 1.0, 0.9)),
        "rod_a": Capsule((0, 0, 0), (3.0, 0, 0), 0.4),
        "rod_b": Cylinder((0, 0, 0), (3.2, 0, 0), 0.45),
        "ring_a": Torus((0, 0, 0), 1.0, 0.3),
        "ring_b": Torus((0, 0, 0), 1.1, 0.35),
        "ball": Sphere((0, 0, 0), 1.0),
    }


def solids() -> dict[str, Any]:
    """Six analytic solids by name, one of a kind: sphere, box, capsule, cylinder, snowman
    (two balls) and dumbbell (two balls on a bar)."""
    return {
        "sphere": Sphere([0, 0, 0], 1.0),
        "box": Box([0, 0, 0], [2.4, 1.2, 0.8]),
        "capsule": Capsule([-1.2, 0, 0], [1.2, 0, 0], 0.4),
        "cylinder": Cylinder([0, 0, -1], [0, 0, 1], 0.6),
        "snowman": Union(Sphere([0, 0, 0], 0.8), Sphere([0, 0, 1.1], 0.5)),
        "dumbbell": Union(
            Sphere([-1.2, 0, 0], 0.5),
            Sphere([1.2, 0, 0], 0.5),
            Cylinder([-1.2, 0, 0], [1.2, 0, 0], 0.2),
        ),
    }


def names_by_id(db: Any) -> dict[int, str]:
    """Every stored shape's name by its id."""
    t = db.sql("select id, name from shapes")
    return dict(zip(t.column("id").to_pylist(), t.column("name").to_pylist(), strict=True))


def make_record(
    name: str, label: str | None, geometry: Any, config: Config = CONFIG
) -> ShapeRecord:
    """A ShapeRecord of an implicit shape, as ingest would build it."""
    dec = decompose(geometry, config=config.mdbd)
    feat = features(dec, config.kernel).astype(np.float32)
    return ShapeRecord(
        name=name,
        decomposition=dec,
        feature=feat,
        config=config,
        content_hash=hashlib.sha256(name.encode() + feat.tobytes()).hexdigest(),
        representation="implicit",
        label=label,
        metadata={"family": label or "none", "size": str(len(name))},
    )
