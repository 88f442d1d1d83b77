"""The stock as the 3D view draws it: the height map of the stock's top surface
(:func:`cnctwin.geometry.height_map`, from the tops of the z dexels) and the tool.

A cell without material is ``null`` in JSON (a hole in the surface).

Units: mm throughout.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from cnctwin.geometry import Cutter, DexelStock, height_map

if TYPE_CHECKING:
    from cnctwin.twin import CycleState, TwinPhysics

__all__ = ["MAX_CELLS", "stock_message", "stock_view"]

#: Default and largest number of map cells a side: 160 x 160 values are ~0.3 MB of JSON,
#: sent a few times a second.
MAX_CELLS = 160
#: Heights are sent rounded to 1 um.
_DECIMALS = 3


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
        See :func:`cnctwin.geometry.height_map`.

    Returns
    -------
    dict
        ``x_mm``, ``y_mm`` (cell centres), ``z_mm`` (rows along y of heights, ``null`` for
        no material, rounded to 1 um), ``floor_mm``, ``box_mm`` (the grid's
        ``[[xmin, ymin, zmin], [xmax, ymax, zmax]]``), ``z_range_mm`` (the lowest and the
        highest top, ``[lo, hi]``, or None without material: the colour scale spans it, so a
        cut shows however shallow it is against the block), ``step`` and ``tool``:
        ``{"x_mm", "y_mm", "z_mm", "radius_mm", "length_mm"}`` or None.
    """
    hmap = height_map(stock, max_cells)
    grid = stock.grid
    low = [float(v) for v in grid.origin_mm]
    high = [o + s for o, s in zip(low, grid.size_mm, strict=True)]
    z = np.round(hmap.z_mm, _DECIMALS)
    material = z[np.isfinite(z)]
    z_range = [float(material.min()), float(material.max())] if material.size else None
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
        "z_range_mm": z_range,
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
