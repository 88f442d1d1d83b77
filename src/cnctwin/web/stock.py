"""The stock as the 3D view draws it: a height map from the tops of the z dexels, and the tool.

Each z ray of a :class:`~cnctwin.geometry.DexelStock` (see docs/dexel.md) keeps its material
as intervals along z; the upper end of its last interval is the stock's top surface over the
ray's (x, y). The view decimates the ray grid to at most ``max_cells`` cells a side: each cell
of the map stands for ``step x step`` rays and shows the *lowest* top among them, so a cut
narrower than a cell still shows at its full depth. A ray without material has no top (NaN,
``null`` in JSON, a hole in the surface); a cell shows a hole only when all its rays are empty.

Units: mm throughout.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter, DexelStock

if TYPE_CHECKING:
    from cnctwin.twin import CycleState, TwinPhysics

__all__ = ["MAX_CELLS", "HeightMap", "height_map", "stock_message", "stock_view"]

#: Default and largest number of map cells a side: 160 x 160 values are ~0.3 MB of JSON,
#: sent a few times a second.
MAX_CELLS = 160
_LIMIT_CELLS = 2000
#: Heights are sent rounded to 1 um.
_DECIMALS = 3


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


def height_map(stock: DexelStock, max_cells: int = MAX_CELLS) -> HeightMap:
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
    if isinstance(max_cells, bool) or not 2 <= max_cells <= _LIMIT_CELLS:
        raise InputError(f"max_cells={max_cells!r}; give 2 <= max_cells <= {_LIMIT_CELLS}")
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
    return origin + (0.5 * (first + last) + 0.5) * pitch


def stock_view(
    stock: DexelStock,
    tool_position_mm: Sequence[float] | None = None,
    cutter: Cutter | None = None,
    max_cells: int = MAX_CELLS,
) -> dict[str, Any]:
    """The JSON object static/stock.js draws: the height map and the tool at its position.

    Parameters
    ----------
    stock
        The stock.
    tool_position_mm
        Tool tip (x, y, z) in machine coordinates, mm; None draws no tool.
    cutter
        The tool in the spindle (its radius and flute length are drawn); None with a
        position draws a marker only.
    max_cells
        See :func:`height_map`.

    Returns
    -------
    dict
        ``x_mm``, ``y_mm`` (cell centres), ``z_mm`` (rows along y of heights, ``null`` for
        no material, rounded to 1 um), ``floor_mm``, ``box_mm`` (the grid's
        ``[[xmin, ymin, zmin], [xmax, ymax, zmax]]``), ``step`` and ``tool``:
        ``{"x_mm", "y_mm", "z_mm", "radius_mm", "length_mm"}`` or None.
    """
    hmap = height_map(stock, max_cells)
    grid = stock.grid
    low = [float(v) for v in grid.origin_mm]
    high = [o + s for o, s in zip(low, grid.size_mm, strict=True)]
    z = np.round(hmap.z_mm, _DECIMALS)
    tool = None
    if tool_position_mm is not None:
        x, y, zt = (float(v) for v in tool_position_mm)
        if all(math.isfinite(v) for v in (x, y, zt)):
            tool = {
                "x_mm": x,
                "y_mm": y,
                "z_mm": zt,
                "radius_mm": cutter.radius_mm if cutter is not None else 0.0,
                "length_mm": cutter.flute_length_mm if cutter is not None else 0.0,
            }
    return {
        "x_mm": np.round(hmap.x_mm, _DECIMALS).tolist(),
        "y_mm": np.round(hmap.y_mm, _DECIMALS).tolist(),
        "z_mm": [[None if math.isnan(v) else v for v in row] for row in z.tolist()],
        "floor_mm": hmap.floor_mm,
        "box_mm": [low, high],
        "step": hmap.step,
        "tool": tool,
    }


def stock_message(physics: TwinPhysics, state: CycleState | None) -> dict[str, Any]:
    """The live 3D view: the twin's stock and the tool in the spindle at its latest position.

    Parameters
    ----------
    physics
        The twin's physics (its :attr:`~cnctwin.twin.physics.TwinPhysics.stock` and cutters).
    state
        The latest cycle (tool number, tool tip in mm); None before the first.

    Returns
    -------
    dict
        :func:`stock_view`'s object. The stock is read while the twin may cut it: a cell
        can show the surface of the cycle before.
    """
    position = None if state is None else state.position_mm
    cutter = None if state is None else physics.cutters.get(state.tool)
    return stock_view(physics.stock, position, cutter)
