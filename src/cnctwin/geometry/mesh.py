"""A closed triangle mesh of the stock, for STL export and viewing.

The mesh is built from the stock's z dexels as columns: each z interval is a prism over its
dexel cell, and faces are emitted where material meets air: the top and bottom of every
interval, and on each side of a cell the heights where the cell has material and its
neighbour (or the outside) has none. The surface is closed and its enclosed volume equals the
z family's volume exactly; where columns of different heights meet, edges end on other edges
(T-junctions), which viewers and slicers accept but a strict manifold check does not. Its
resolution is the dexel pitch (a voxel-like surface, as dexel viewers show before smoothing).

Units: mm.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from cnctwin.geometry.dexel import DexelStock

__all__ = ["stock_mesh", "mesh_volume_mm3"]


@njit(cache=True)
def _intervals(
    count: np.ndarray, start: np.ndarray, rows: np.ndarray, ray: int, out: np.ndarray
) -> int:  # pragma: no cover - numba
    n: int = count[ray]
    first = start[ray]
    for k in range(n):
        out[k, 0] = rows[first + k, 0]
        out[k, 1] = rows[first + k, 1]
    return n


@njit(cache=True)
def _difference(
    a: np.ndarray, na: int, b: np.ndarray, nb: int, out: np.ndarray
) -> int:  # pragma: no cover - numba
    """Parts of the sorted intervals a[:na] not covered by b[:nb]; returns how many."""
    m = 0
    j = 0
    for i in range(na):
        lo = a[i, 0]
        hi = a[i, 1]
        while j < nb and b[j, 1] <= lo:
            j += 1
        k = j
        cur = lo
        while k < nb and b[k, 0] < hi:
            if b[k, 0] > cur:
                out[m, 0] = cur
                out[m, 1] = b[k, 0]
                m += 1
            if b[k, 1] > cur:
                cur = b[k, 1]
            if cur >= hi:
                break
            k += 1
        if cur < hi:
            out[m, 0] = cur
            out[m, 1] = hi
            m += 1
    return m


@njit(cache=True)
def _quad(
    tris: np.ndarray, t: int, p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray
) -> int:  # pragma: no cover - numba
    """Two triangles (p0, p1, p2) and (p0, p2, p3); counter-clockwise seen from outside."""
    for c in range(3):
        tris[t, 0, c] = p0[c]
        tris[t, 1, c] = p1[c]
        tris[t, 2, c] = p2[c]
        tris[t + 1, 0, c] = p0[c]
        tris[t + 1, 1, c] = p2[c]
        tris[t + 1, 2, c] = p3[c]
    return t + 2


@njit(cache=True)
def _build(
    count: np.ndarray,
    start: np.ndarray,
    rows: np.ndarray,
    nx: int,
    ny: int,
    px: float,
    py: float,
    ox: float,
    oy: float,
    oz: float,
    tris: np.ndarray,
    emit: bool,
) -> int:  # pragma: no cover
    """Emit the mesh's triangles into ``tris`` (or only count them when ``emit`` is False)."""
    maxn = 1
    for r in range(count.size):
        if count[r] > maxn:
            maxn = count[r]
    a = np.empty((maxn, 2), np.float32)
    b = np.empty((maxn, 2), np.float32)
    d = np.empty((maxn + maxn, 2), np.float32)
    p0 = np.empty(3)
    p1 = np.empty(3)
    p2 = np.empty(3)
    p3 = np.empty(3)
    t = 0
    for j in range(ny):
        for i in range(nx):
            na = _intervals(count, start, rows, j * nx + i, a)
            if na == 0:
                continue
            x0 = ox + i * px
            x1 = x0 + px
            y0 = oy + j * py
            y1 = y0 + py
            for k in range(na):
                zl = oz + a[k, 0]
                zh = oz + a[k, 1]
                if emit:
                    p0[0], p0[1], p0[2] = x0, y0, zh
                    p1[0], p1[1], p1[2] = x1, y0, zh
                    p2[0], p2[1], p2[2] = x1, y1, zh
                    p3[0], p3[1], p3[2] = x0, y1, zh
                    _quad(tris, t, p0, p1, p2, p3)
                    p0[0], p0[1], p0[2] = x0, y0, zl
                    p1[0], p1[1], p1[2] = x0, y1, zl
                    p2[0], p2[1], p2[2] = x1, y1, zl
                    p3[0], p3[1], p3[2] = x1, y0, zl
                    _quad(tris, t + 2, p0, p1, p2, p3)
                t += 4
            # Four sides: -x, +x, -y, +y.
            for side in range(4):
                if side == 0:
                    ni, nj = i - 1, j
                elif side == 1:
                    ni, nj = i + 1, j
                elif side == 2:
                    ni, nj = i, j - 1
                else:
                    ni, nj = i, j + 1
                nb = 0
                if 0 <= ni < nx and 0 <= nj < ny:
                    nb = _intervals(count, start, rows, nj * nx + ni, b)
                m = _difference(a, na, b, nb, d)
                for k in range(m):
                    zl = oz + d[k, 0]
                    zh = oz + d[k, 1]
                    if emit:
                        if side == 0:
                            p0[0], p0[1], p0[2] = x0, y0, zl
                            p1[0], p1[1], p1[2] = x0, y0, zh
                            p2[0], p2[1], p2[2] = x0, y1, zh
                            p3[0], p3[1], p3[2] = x0, y1, zl
                        elif side == 1:
                            p0[0], p0[1], p0[2] = x1, y0, zl
                            p1[0], p1[1], p1[2] = x1, y1, zl
                            p2[0], p2[1], p2[2] = x1, y1, zh
                            p3[0], p3[1], p3[2] = x1, y0, zh
                        elif side == 2:
                            p0[0], p0[1], p0[2] = x0, y0, zl
                            p1[0], p1[1], p1[2] = x1, y0, zl
                            p2[0], p2[1], p2[2] = x1, y0, zh
                            p3[0], p3[1], p3[2] = x0, y0, zh
                        else:
                            p0[0], p0[1], p0[2] = x0, y1, zl
                            p1[0], p1[1], p1[2] = x0, y1, zh
                            p2[0], p2[1], p2[2] = x1, y1, zh
                            p3[0], p3[1], p3[2] = x1, y1, zl
                        _quad(tris, t, p0, p1, p2, p3)
                    t += 2
    return t


def stock_mesh(stock: DexelStock) -> NDArray[np.float32]:
    """Triangles of the stock's surface, ``(n, 3, 3)`` vertices in machine coordinates, mm.

    Triangles wind counter-clockwise seen from outside (normals point out of the material).
    """
    z = stock.family_arrays("z")
    grid = stock.grid
    nx, ny, _ = grid.shape
    px, py, _ = grid.pitch_mm
    ox, oy, oz = grid.origin_mm
    dummy = np.empty((0, 3, 3), np.float32)
    n = _build(z.count, z.start, z.rows, nx, ny, px, py, ox, oy, oz, dummy, False)
    tris = np.empty((n, 3, 3), np.float32)
    _build(z.count, z.start, z.rows, nx, ny, px, py, ox, oy, oz, tris, True)
    return tris


def mesh_volume_mm3(triangles: NDArray[np.floating]) -> float:
    """Volume enclosed by a closed, outward-wound triangle mesh (divergence theorem), mm^3."""
    t = np.asarray(triangles, dtype=np.float64)
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)
