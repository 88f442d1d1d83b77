"""The stock's top surface as a height map, from the tops of the z dexels.

Each z ray of a :class:`~cnctwin.geometry.DexelStock` (see docs/dexel.md) keeps its material
as intervals along z; the upper end of its last interval is the stock's top surface over the
ray's (x, y). :func:`height_map` decimates the ray grid to at most ``max_cells`` cells a side:
each cell stands for ``step x step`` rays and holds the *lowest* top among them, so a cut
narrower than a cell still shows at its full depth. A ray without material has no top (NaN); a
cell has none only when all its rays are empty. The 3D stock views (the live dashboard, the
simulate report) draw it.

:func:`material_heights` resamples the other way, for the STL surface
(:func:`cnctwin.geometry.mesh.stock_mesh`): each cell holds the *mean* length of material of its
rays (an empty ray counts 0), so that cell area x mean height sums to the z rays' volume exactly.

Units: mm throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.geometry.dexel import DexelStock

__all__ = ["HeightMap", "MaterialHeights", "height_map", "material_heights"]

#: Largest number of map cells a side.
MAX_CELLS_LIMIT = 2000


@dataclass(frozen=True, slots=True)
class HeightMap:
    """The stock's top surface on a (decimated) grid.

    Attributes
    ----------
    x_mm, y_mm
        Centres of the map's cells along x ``(nx,)`` and y ``(ny,)``, mm (machine coordinates).
    z_mm
        ``(ny, nx)`` top of the material over each cell, mm; NaN where there is none.
    floor_mm
        Bottom of the stock's grid, mm.
    step
        Rays per map cell along x and y (1: every ray).
    """

    x_mm: NDArray[np.float64]
    y_mm: NDArray[np.float64]
    z_mm: NDArray[np.float64]
    floor_mm: float
    step: int


def _tops(stock: DexelStock) -> NDArray[np.float64]:
    """``(ny, nx)`` upper end of every z ray's last interval, mm; NaN for an empty ray."""
    count, start, _block, rows, _heap_top = stock.family_arrays("z")
    nx, ny, _ = stock.grid.shape
    tops = np.full(count.shape[0], np.nan)
    full = count > 0
    last = start[full].astype(np.int64) + count[full] - 1
    tops[full] = rows[last, 1].astype(np.float64) + stock.grid.origin_mm[2]
    return tops.reshape(ny, nx)


def height_map(stock: DexelStock, max_cells: int = 160) -> HeightMap:
    """The stock's top surface, decimated to at most ``max_cells`` cells along x and y.

    Parameters
    ----------
    stock
        The tri-dexel stock (only its z rays are read).
    max_cells
        Most map cells a side, 2..2000; the step is ``ceil(max(nx, ny) / max_cells)`` rays.

    Raises
    ------
    InputError
        For ``max_cells`` out of range.
    """
    if isinstance(max_cells, bool) or not 2 <= max_cells <= MAX_CELLS_LIMIT:
        raise InputError(f"max_cells={max_cells!r}; give 2 <= max_cells <= {MAX_CELLS_LIMIT}")
    grid = stock.grid
    nx, ny, _ = grid.shape
    step = max(1, math.ceil(max(nx, ny) / max_cells))
    tops = _tops(stock)
    if step > 1:
        mx, my = -(-nx // step), -(-ny // step)
        padded = np.full((my * step, mx * step), np.nan)
        padded[:ny, :nx] = tops
        blocks = padded.reshape(my, step, mx, step)
        empty = np.isnan(blocks).all(axis=(1, 3))
        tops = np.where(empty, np.nan, np.fmin.reduce(np.fmin.reduce(blocks, axis=3), axis=1))
    cells_x, cells_y = tops.shape[1], tops.shape[0]
    # A cell's centre: the middle of the rays it covers (the last cell may cover fewer).
    x = _centres(grid.origin_mm[0], grid.pitch_mm[0], nx, step, cells_x)
    y = _centres(grid.origin_mm[1], grid.pitch_mm[1], ny, step, cells_y)
    return HeightMap(x, y, tops, float(grid.origin_mm[2]), step)


def _centres(origin: float, pitch: float, n: int, step: int, cells: int) -> NDArray[np.float64]:
    first = np.arange(cells) * step
    last = np.minimum(first + step, n) - 1
    centres: NDArray[np.float64] = origin + (0.5 * (first + last) + 0.5) * pitch
    return centres


@dataclass(frozen=True, slots=True)
class MaterialHeights:
    """Material per cell of a coarsened z-ray grid, for a height-field surface.

    Attributes
    ----------
    x_edges_mm, y_edges_mm
        Cell boundaries along x ``(nx + 1,)`` and y ``(ny + 1,)``, mm (machine coordinates); the
        last cell is narrower where the rays do not divide evenly.
    height_mm
        ``(ny, nx)`` mean length of material of the cell's rays (empty rays count 0), mm.
    floor_mm
        Bottom of the stock's grid, mm: the heights stand on it.
    step
        Rays per cell along x and y.
    """

    x_edges_mm: NDArray[np.float64]
    y_edges_mm: NDArray[np.float64]
    height_mm: NDArray[np.float64]
    floor_mm: float
    step: int


def material_heights(stock: DexelStock, step: int) -> MaterialHeights:
    """Mean material length of the z rays over cells of ``step x step`` rays (>= 1), mm.

    The cells' volume, ``sum(area x height)``, equals ``stock.volume_mm3("z")`` (up to float
    rounding): the heights keep the material, not its shape within a cell. A ray's material is
    the summed length of its intervals, which is the height of its top above the floor for a
    stock milled from above (one interval a ray, resting on the floor).

    Raises
    ------
    InputError
        For ``step`` < 1.
    """
    if isinstance(step, bool) or step < 1:
        raise InputError(f"step={step!r}; give a whole number of rays per cell >= 1")
    count, start, _block, rows, _heap_top = stock.family_arrays("z")
    nx, ny, _ = stock.grid.shape
    length = np.zeros(count.shape[0])
    first = start.astype(np.int64)
    for k in range(int(count.max(initial=0))):
        has = count > k
        row = rows[first[has] + k].astype(np.float64)
        length[has] += row[:, 1] - row[:, 0]
    per_ray = length.reshape(ny, nx)
    mx, my = -(-nx // step), -(-ny // step)
    sums = np.add.reduceat(
        np.add.reduceat(per_ray, np.arange(0, ny, step), axis=0), np.arange(0, nx, step), axis=1
    )
    wx = np.minimum(np.arange(mx) * step + step, nx) - np.arange(mx) * step
    wy = np.minimum(np.arange(my) * step + step, ny) - np.arange(my) * step
    px, py, _ = stock.grid.pitch_mm
    ox, oy, oz = stock.grid.origin_mm
    x_edges = ox + np.minimum(np.arange(mx + 1) * step, nx) * px
    y_edges = oy + np.minimum(np.arange(my + 1) * step, ny) * py
    return MaterialHeights(x_edges, y_edges, sums / np.outer(wy, wx), float(oz), step)
