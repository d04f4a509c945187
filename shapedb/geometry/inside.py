"""The inside of the field a decomposition packs, and its light fields.

The MDBD packs the signed distance field of the solid on a grid
(:func:`shapedb.mdbd.decomposition.prepare_field`; a sheet thinner than the grid is thickened there
first). The cells where that field is >= 0 are the solid as the grid sees it, whatever
the representation it came from; unlike the disjoint balls, they keep the sheets and
slabs thinner than the smallest ball the packing reaches. An orthographic silhouette,
and a front or back depth image, of the inside cells is that of their *shell*: the
inside cells with a 6-neighbour outside (or on the grid's border), far fewer cells.

:class:`Inside` holds the shell's centres, the cell size and the centroid of all the
inside cells, in model units; :func:`shapedb.mdbd.decomposition.decompose` keeps it, with
``keep_inside=True``, in memory only (:attr:`shapedb.mdbd.decomposition.Decomposition.inside`; never
stored). :func:`shapedb.signature.lightfield.inside_light_field` renders each cell as a ball of
half a cell under the balls' normalisation rules: centred on the solid's volume
centroid (the inside cells' mean) and scaled so that the farthest cell's far side lies
on the unit sphere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from shapedb.geometry.base import Grid

__all__ = ["Inside", "field_inside"]


@dataclass(frozen=True, eq=False)
class Inside:
    """The inside cells of a decomposition's field, as their shell.

    Attributes
    ----------
    shell : (s, 3) float64
        Centres of the inside cells with a 6-neighbour outside the solid or the grid,
        model units, in C order of the grid's cells.
    cell : float
        Edge of a cell, model units.
    centroid : (3,) float64
        Mean of the centres of all the inside cells (the solid's volume centroid as the
        grid sees it), model units.
    count : int
        Number of inside cells.
    """

    shell: NDArray[np.float64]
    cell: float
    centroid: NDArray[np.float64]
    count: int


def field_inside(
    F: NDArray[np.float32],
    grid: Grid,
    frame: NDArray[np.float64] | None = None,
    scale: float = 1.0,
) -> Inside:
    """The inside (``F >= 0``) of a grid's signed field, as its shell in model units.

    Parameters
    ----------
    F : (nx, ny, nz) float
        Signed distance on ``grid``'s cells, positive inside.
    grid : Grid
        The grid, in the field's (local) frame.
    frame : (4, 4) float, optional
        Homogeneous map from the local frame, in units of ``scale``, to model
        coordinates (:attr:`shapedb.mdbd.decomposition.PreparedField.frame`); identity by default.
    scale : float
        Model units per local unit (:attr:`shapedb.mdbd.decomposition.PreparedField.scale`), > 0.

    Returns
    -------
    Inside
        With ``count`` 0 and an empty (0, 3) shell when no cell is inside.

    Raises
    ------
    ValueError
        If ``F``'s shape is not ``grid.shape``.
    """
    if tuple(F.shape) != tuple(grid.shape):
        raise ValueError(f"field of shape {F.shape} does not match grid {grid.shape}")
    m = np.asarray(F) >= 0
    count = int(m.sum())
    if count == 0:
        return Inside(np.zeros((0, 3)), float(scale * grid.spacing), np.zeros(3), 0)
    p = np.pad(m, 1)
    core = (
        p[:-2, 1:-1, 1:-1] & p[2:, 1:-1, 1:-1] & p[1:-1, :-2, 1:-1]
        & p[1:-1, 2:, 1:-1] & p[1:-1, 1:-1, :-2] & p[1:-1, 1:-1, 2:]
    )  # fmt: skip
    shell_idx = np.argwhere(m & ~core)
    mean_idx = np.array(
        [float(np.arange(m.shape[a]) @ m.sum(axis=tuple(b for b in range(3) if b != a)))
         for a in range(3)]
    ) / count  # fmt: skip
    fr = np.eye(4) if frame is None else np.asarray(frame, dtype=np.float64)
    rot, shift = fr[:3, :3], fr[:3, 3]
    shell = (scale * grid.to_point(shell_idx)) @ rot.T + shift
    centroid = (scale * grid.to_point(mean_idx[None])[0]) @ rot.T + shift
    return Inside(shell, float(scale * grid.spacing), centroid, count)
