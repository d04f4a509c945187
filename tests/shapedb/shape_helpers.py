"""Helpers shared by the core tests (not fixtures)."""

from __future__ import annotations

import numpy as np


def rotation(angles: tuple[float, float, float]) -> np.ndarray:
    """Rotation matrix (3, 3) from x-y-z Euler angles in radians."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("xyz", angles).as_matrix()
