"""A closed triangle mesh of the stock, for STL export and viewing.

The stock is resampled to cells of ``step x step`` z dexels (the output resolution), each
holding its rays' mean material length (:func:`cnctwin.geometry.height_map.material_heights`),
and meshed as a height field over a flat bottom:

- the top surface passes through a node at every cell centre at the cell's height, plus nodes
  on the stock's outline that repeat the height of the cell next to them; each square of four
  nodes is split into two triangles along its diagonal of smaller height difference;
- four vertical walls close the outline down to the floor, and a fan of triangles around the
  outline's centroid closes the bottom.

Every edge is shared by exactly two triangles, walked in opposite directions (a closed,
consistently outward-wound 2-manifold; no T-junctions), so slicers and CAD take the file as a
solid. The height field assumes the material of each z ray rests on the floor, which is what
milling from above leaves; a ray cut through keeps a skin of :data:`MIN_THICKNESS_MM` so that
the top never touches the bottom.

Volume: the trapezoid rule through cell centres keeps the cells' volume where the heights vary
linearly; it differs only in the cells beside a step (a wall of the part) and by the skin, so
``|V_mesh - V_dexel| <= (length x height of the part's walls) x resolution`` plus the skin's
``area x MIN_THICKNESS_MM`` (docs/simulate.md). Units: mm.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.geometry.dexel import DexelStock
from cnctwin.geometry.height_map import material_heights

__all__ = ["MIN_THICKNESS_MM", "mesh_step", "mesh_volume_mm3", "stock_mesh"]

#: Material kept over a ray cut through, mm, so that the top surface stays above the bottom.
MIN_THICKNESS_MM = 1e-3


def mesh_step(stock: DexelStock, resolution_mm: float | None) -> int:
    """Rays per mesh cell for an output resolution (mm; ``None``: every ray, the dexel pitch).

    The cells are the largest whole number of rays not wider than ``resolution_mm`` (at least
    one: a resolution finer than the dexel pitch gives the pitch).

    Raises
    ------
    InputError
        For a resolution that is not finite and > 0.
    """
    if resolution_mm is None:
        return 1
    if not (math.isfinite(resolution_mm) and resolution_mm > 0.0):
        raise InputError(
            f"STL resolution {resolution_mm!r} mm; give a finite resolution > 0 mm "
            "(at most the stock's size)"
        )
    px, py, _ = stock.grid.pitch_mm
    return max(1, math.floor(resolution_mm / max(px, py) * (1.0 + 1e-9)))


def _nodes(edges: NDArray[np.float64]) -> NDArray[np.float64]:
    """The outline's two ends with the cell centres between them."""
    return np.concatenate([edges[:1], 0.5 * (edges[:-1] + edges[1:]), edges[-1:]])


def stock_mesh(stock: DexelStock, resolution_mm: float | None = None) -> NDArray[np.float32]:
    """Triangles of the stock's surface, ``(n, 3, 3)`` vertices in machine coordinates, mm.

    ``resolution_mm`` is the size of the resampled cells (see :func:`mesh_step`; ``None``: the
    dexel pitch). Triangles wind counter-clockwise seen from outside (normals point out of the
    material). A stock of ``nx x ny`` cells gives ``2 (nx + 1)(ny + 1) + 6 (nx + ny + 2)``
    triangles.
    """
    cells = material_heights(stock, mesh_step(stock, resolution_mm))
    xs, ys = _nodes(cells.x_edges_mm), _nodes(cells.y_edges_mm)
    nx, ny = xs.size, ys.size
    h = np.maximum(np.pad(cells.height_mm, 1, mode="edge"), MIN_THICKNESS_MM)
    floor = cells.floor_mm
    gx, gy = np.meshgrid(xs, ys)
    top = np.column_stack([gx.ravel(), gy.ravel(), floor + h.ravel()])
    # Top: the squares (a, b, c, d) counter-clockwise from above, split along a-c or b-d.
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    z = h.ravel()
    ac = np.abs(z[a] - z[c]) <= np.abs(z[b] - z[d])
    faces = [
        np.where(ac[:, None], np.column_stack([a, b, c]), np.column_stack([a, b, d])),
        np.where(ac[:, None], np.column_stack([a, c, d]), np.column_stack([b, c, d])),
    ]
    # The outline, counter-clockwise from above: bottom row, right column, top row, left column.
    loop = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])
    p, q = loop, np.roll(loop, -1)
    base = nx * ny
    pb = base + np.arange(loop.size)  # the outline's nodes again, on the floor
    qb = np.roll(pb, -1)
    faces += [np.column_stack([pb, qb, q]), np.column_stack([pb, q, p])]
    centre = base + loop.size
    faces.append(np.column_stack([np.full(loop.size, centre), qb, pb]))
    bottom = top[loop].copy()
    bottom[:, 2] = floor
    middle = [0.5 * (xs[0] + xs[-1]), 0.5 * (ys[0] + ys[-1]), floor]
    vertices = np.vstack([top, bottom, middle])
    triangles: NDArray[np.float32] = vertices[np.concatenate(faces)].astype(np.float32)
    return triangles


def mesh_volume_mm3(triangles: NDArray[np.floating]) -> float:
    """Volume enclosed by a closed, outward-wound triangle mesh (divergence theorem), mm^3."""
    t = np.asarray(triangles, dtype=np.float64)
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)
