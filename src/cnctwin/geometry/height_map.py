"""The stock's top surface as a height map, from the tops of the z dexels.

Each z ray of a :class:`~cnctwin.geometry.DexelStock` (see docs/dexel.md) keeps its material
as intervals along z; the upper end of its last interval is the stock's top surface over the
ray's (x, y). :func:`height_map` decimates the ray grid to at most ``max_cells`` cells a side:
each cell stands for ``step x step`` rays and holds the *lowest* top among them, so a cut
narrower than a cell still shows at its full depth. A ray without material has no top (NaN); a
cell has none only when all its rays are empty. The 3D stock views (the live dashboard, the
simulate report) draw it.

Units: mm throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.geometry.dexel import DexelStock

__all__ = ["HeightMap", "height_map"]

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
