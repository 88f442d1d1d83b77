"""Numba kernels of the tri-dexel stock's packed layout (private; see :mod:`.dexel`).

Units: mm along the rays (float32 values relative to the grid origin, as stored).

:class:`Family` is the one definition of a ray family's packed arrays (the layout is described in
:mod:`cnctwin.geometry.dexel`, "Layout"). Numba's dispatcher types a plain tuple of arrays in
about 0.3 us a call and a NamedTuple in about 3 us (it has no fast path for them), so the kernels
that Python calls take a family as the plain tuple ``tuple(family)`` and name its fields again
with ``Family(*arrays)``; kernels called from kernels take the :class:`Family`.

Changing a kernel here: numba caches a kernel that inlines or calls these by its own module's
content alone, so delete ``geometry/__pycache__/*.nbi`` and ``*.nbc`` (or touch the callers)
after editing this file.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["Family", "fill", "subtract_interval", "total_length", "trim_interval"]


class Family(NamedTuple):
    """The packed arrays of one ray family (see :mod:`cnctwin.geometry.dexel`, "Layout")."""

    #: int32 (n_rays,): number of intervals of each ray.
    # The field shadows tuple.count (a method); the kernels and dexel.py read it by this name.
    count: np.ndarray  # type: ignore[assignment]
    #: int32 (n_rays,): the ray's first row.
    start: np.ndarray
    #: int32 (n_rays,): the capacity of the ray's block, rows.
    block: np.ndarray
    #: float32 (inline rows + heap rows, 2): interval rows (lo, hi), mm along the ray.
    rows: np.ndarray
    #: int64 (1,): the first free row of the heap.
    heap_top: np.ndarray


@njit(cache=True)
def fill(counts, local, capacity, arrays):
    """Write the intervals ``local`` ((sum(counts), 2), ray after ray) into an empty family
    (``arrays``: ``tuple(Family)``), rays with more than ``capacity`` intervals in heap blocks."""
    family = Family(*arrays)
    count, start, block, rows, heap_top = (
        family.count, family.start, family.block, family.rows, family.heap_top
    )  # fmt: skip
    src = 0
    for r in range(counts.shape[0]):
        n = counts[r]
        count[r] = n
        if n > capacity:
            cap = 2 * capacity
            while cap < n:
                cap *= 2
            start[r] = heap_top[0]
            block[r] = cap
            heap_top[0] += cap
        base = start[r]
        for q in range(n):
            rows[base + q, 0] = local[src + q, 0]
            rows[base + q, 1] = local[src + q, 1]
        src += n


@njit(cache=True)
def total_length(arrays):
    """Total length (mm, float64 sum of the float32 rows) of a family's intervals (``arrays``:
    ``tuple(Family)``)."""
    family = Family(*arrays)
    count, start, rows = family.count, family.start, family.rows
    total = 0.0
    for r in range(count.shape[0]):
        base = start[r]
        for q in range(count[r]):
            total += np.float64(rows[base + q, 1]) - np.float64(rows[base + q, 0])
    return total


@njit(cache=True, inline="always")
def subtract_interval(r, fa, fb, hint, family):
    """Remove ``[fa, fb]`` (float32, ray coordinates) from ray ``r`` of a :class:`Family`.

    ``hint`` is a guess of the index of the first interval ending after ``fa`` (0 if none;
    the caller passes the index found on a similar ray, which makes rays through many features
    cheap). Returns ``(status, removed, lo_inside, hi_inside, cut_lo, cut_hi, index)``: status
    0 done, 1 the heap is full (the ray is untouched; grow the heap and call again); the
    removed length (mm, float64 from the stored float32 values); whether ``fa`` and ``fb`` lay
    strictly inside material (there the boundary of the removed piece is the cutting tool's
    surface); the lowest and highest removed coordinate (``inf``/``-inf`` when nothing was
    removed); the index of the first interval ending after ``fa``.

    Array indices are unsigned (``_u``), which spares numba's wrap-around of negative indices
    on every access (a sixth of the time of a row kernel).
    """
    count, start, block, rows = family.count, family.start, family.block, family.rows
    u = _u(r)
    n = count[u]
    base = start[u]
    if (
        hint < n
        and rows[_u(base + hint), 1] > fa
        and (hint == 0 or rows[_u(base + hint - 1), 1] <= fa)
    ):
        i = hint
    elif n <= 8:
        i = 0
        while i < n and rows[_u(base + i), 1] <= fa:
            i += 1
    else:
        i = 0
        top = n
        while i < top:
            mid = (i + top) >> 1
            if rows[_u(base + mid), 1] <= fa:
                i = mid + 1
            else:
                top = mid
    if i == n or rows[_u(base + i), 0] >= fb or not fa < fb:
        return (0, 0.0, False, False, np.inf, -np.inf, i)
    at = _u(base + i)
    lo = rows[at, 0]
    hi = rows[at, 1]
    keep_left = lo < fa
    if hi >= fb or i == n - 1 or rows[_u(base + i + 1), 0] >= fb:
        # One interval overlaps (the common case): trim it, empty it or split it.
        keep_right = hi > fb
        cut_lo = max(lo, fa)
        cut_hi = min(hi, fb)
        removed = np.float64(cut_hi) - np.float64(cut_lo)
        if keep_left and keep_right:
            if n + 1 > block[u]:
                if not _move_to_heap(r, n, base, family):
                    return (1, 0.0, False, False, np.inf, -np.inf, i)
                base = start[u]
                at = _u(base + i)
            for q in range(n - 1, i, -1):
                rows[_u(base + q + 1), 0] = rows[_u(base + q), 0]
                rows[_u(base + q + 1), 1] = rows[_u(base + q), 1]
            rows[at, 1] = fa
            rows[_u(base + i + 1), 0] = fb
            rows[_u(base + i + 1), 1] = hi
            count[u] = n + 1
        elif keep_left:
            rows[at, 1] = fa
        elif keep_right:
            rows[at, 0] = fb
        else:
            for q in range(i + 1, n):
                rows[_u(base + q - 1), 0] = rows[_u(base + q), 0]
                rows[_u(base + q - 1), 1] = rows[_u(base + q), 1]
            count[u] = n - 1
        return (0, removed, keep_left, keep_right, np.float64(cut_lo), np.float64(cut_hi), i)
    # Several intervals overlap: keep the left part of the first and the right part of the
    # last one (never more intervals than before).
    j = i + 1
    while j + 1 < n and rows[_u(base + j + 1), 0] < fb:
        j += 1
    right_hi = rows[_u(base + j), 1]
    keep_right = right_hi > fb
    removed = np.float64(0.0)
    for q in range(i, j + 1):
        removed += np.float64(min(rows[_u(base + q), 1], fb)) - np.float64(
            max(rows[_u(base + q), 0], fa)
        )
    cut_lo = np.float64(max(lo, fa))
    cut_hi = np.float64(min(right_hi, fb))
    w = i
    if keep_left:
        rows[_u(base + w), 1] = fa
        w += 1
    if keep_right:
        rows[_u(base + w), 0] = fb
        rows[_u(base + w), 1] = right_hi
        w += 1
    for q in range(j + 1, n):
        rows[_u(base + w), 0] = rows[_u(base + q), 0]
        rows[_u(base + w), 1] = rows[_u(base + q), 1]
        w += 1
    count[u] = w
    return (0, removed, keep_left, keep_right, cut_lo, cut_hi, i)


@njit(cache=True, inline="always")
def trim_interval(r, fa, fb, hint, family):
    """:func:`subtract_interval` (same arguments and results) with the common case of a cut
    first: ``[fa, fb]`` overlaps only the interval at ``hint`` and trims one of its ends. The
    branch returns whether each end lay inside material as constants, which lets the compiler
    simplify the caller's contact bookkeeping after it (measured 10% faster a row kernel).
    """
    count, start, rows = family.count, family.start, family.rows
    u = _u(r)
    n = count[u]
    base = start[u]
    if hint < n and fa < fb:
        at = _u(base + hint)
        lo = rows[at, 0]
        hi = rows[at, 1]
        if (
            hi > fa
            and lo < fb
            and (hint == 0 or rows[_u(base + hint - 1), 1] <= fa)
            and (hi >= fb or hint == n - 1 or rows[_u(base + hint + 1), 0] >= fb)
        ):
            if lo < fa and hi <= fb:  # the interval's upper end is cut away
                rows[at, 1] = fa
                return (0, np.float64(hi) - np.float64(fa), True, False, np.float64(fa),
                        np.float64(hi), hint)  # fmt: skip
            if lo >= fa and hi > fb:  # its lower end
                rows[at, 0] = fb
                return (0, np.float64(fb) - np.float64(lo), False, True, np.float64(lo),
                        np.float64(fb), hint)  # fmt: skip
    return subtract_interval(r, fa, fb, hint, family)


@njit(cache=True, inline="always")
def _u(index):
    """``index`` (>= 0) as an unsigned array index: numba then omits the wrap-around of
    negative indices (a compare and an add on every access)."""
    return np.uintp(index)


@njit(cache=True, inline="always")
def _move_to_heap(r, n, base, family):
    """Move ray r's n intervals to a new heap block of twice its capacity; False if the heap is
    full (nothing changed)."""
    start, block, rows, heap_top = family.start, family.block, family.rows, family.heap_top
    new_block = 2 * block[r]
    top = heap_top[0]
    if top + new_block > rows.shape[0]:
        return False
    for q in range(n):
        rows[top + q, 0] = rows[base + q, 0]
        rows[top + q, 1] = rows[base + q, 1]
    heap_top[0] = top + new_block
    start[r] = top
    block[r] = new_block
    return True
