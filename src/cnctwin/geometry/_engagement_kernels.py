"""Numba kernels of the engagement (private; see :mod:`cnctwin.geometry.engagement`).

Units: mm, rad, s; positions in grid coordinates (mm from the grid origin).

:func:`path` cuts (:func:`cnctwin.geometry._removal_kernels.cut`) and computes the engagement of
consecutive positions in one call. The one definition of what it shares with the Python side:
the engagement's work arrays (:class:`EngageWork`), its outputs (:class:`PathOutputs`, one row of
``O_*`` columns a position) and its status ``OUT_FULL``. The method is described in
:mod:`cnctwin.geometry.engagement`.

Changing a kernel: numba caches :func:`path` by this file's content alone, with the removal
kernels it calls compiled in, so delete ``geometry/__pycache__/*.nbi`` and ``*.nbc`` after
editing :mod:`cnctwin.geometry._removal_kernels` or :mod:`cnctwin.geometry._dexel_kernels`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from cnctwin.geometry._removal_kernels import (
    A_ABOVE,
    A_ARCS,
    A_BOTTOM,
    A_LEN_X,
    A_LEN_Y,
    A_LEN_Z,
    A_NMAX,
    A_NMIN,
    A_ZMAX,
    A_ZMIN,
    I_K0,
    I_NSLICES,
    P_FX,
    P_FY,
    P_GAP,
    P_INNER,
    P_L,
    P_PX,
    P_PY,
    P_PZ,
    P_R,
    P_RC,
    P_SLOPE,
    P_TZ,
    cut,
    cut_arrays,
    kernel,
    place,
    reset_accumulators,
    slice_low,
)

__all__ = [
    "N_OUT",
    "O_ABOVE",
    "O_AE",
    "O_AP",
    "O_BOTTOM",
    "O_CONTACT",
    "O_FDX",
    "O_FDY",
    "O_FEED",
    "O_HMAX",
    "O_HMEAN",
    "O_MRR",
    "O_REMOVED",
    "OUT_FULL",
    "EngageWork",
    "PathOutputs",
    "path",
]

TWO_PI = 2.0 * math.pi
_MIN_FEED_MOVE_MM = 1e-9  # a horizontal displacement below this leaves the feed direction +x
#: Across the 45-degree boundary between the x and the y rays' contact points, arcs of one
#: contact region may lie one more sample spacing (sqrt(2) pitches) apart than within a family:
#: up to sqrt(2) p before the boundary in one family and sqrt(2) p after it in the other.
_ACROSS_PITCHES = math.sqrt(2.0)
# Columns of the per-position output of path (PathOutputs.out).
O_CONTACT, O_REMOVED, O_MRR, O_AE, O_AP, O_FEED, O_FDX, O_FDY = range(8)
O_HMEAN, O_HMAX, O_BOTTOM, O_ABOVE = range(8, 12)
N_OUT = 12
OUT_FULL = 3  # kernel status: the output buffers of slices or intervals are full


class EngageWork(NamedTuple):
    """The work arrays of the engagement of one position (``arcs`` the arc capacity, ``nz`` the
    grid's z levels)."""

    #: int64 (nz + 2,): first arc of each slice (a counting sort by slice).
    first: np.ndarray
    #: int64 (arcs,): the arcs in slice order.
    order: np.ndarray
    #: float64 (arcs + 1,) each: one slice's arcs, then its runs (rad).
    ra: np.ndarray
    rb: np.ndarray
    #: float64 (2 arcs + 4,) each: one slice's widened pieces within [0, 2 pi] (rad).
    pa: np.ndarray
    pb: np.ndarray
    #: float64 (3, nz + 1): (height above the tip, dz, radius) of the used slices, mm.
    slices: np.ndarray
    #: int64 (2 arcs + 1,): slice of each interval among the used ones.
    interval_slice: np.ndarray
    #: float64 (2, 2 arcs + 1): (start, end) of each interval, rad.
    intervals: np.ndarray
    #: float64 (5,): integral of max(sin phi, 0) sin kappa over phi and z (rad mm), engaged
    #: area (rad mm), max of sin phi sin kappa, slices used, intervals.
    stats: np.ndarray


class PathOutputs(NamedTuple):
    """The outputs of :func:`path` for n positions."""

    #: float64 (n, N_OUT): a row of O_* columns a position.
    out: np.ndarray
    #: int64 (n + 1,): each position's first slice in ``slices``.
    slice_offsets: np.ndarray
    #: float64 (3, room): (height above the tip, dz, radius) of the slices, mm.
    slices: np.ndarray
    #: int64 (n + 1,): each position's first interval.
    interval_offsets: np.ndarray
    #: int64 (room,): slice of each interval among its position's slices.
    interval_slice: np.ndarray
    #: float64 (2, room): (start, end) of each interval, rad.
    intervals: np.ndarray


@njit(cache=True)
def _emit(a, b, pa, pb, npieces):
    """Append [a, b] (rad, may cross 0 or 2 pi) as pieces within [0, 2 pi]."""
    if b - a >= TWO_PI:
        pa[npieces] = 0.0
        pb[npieces] = TWO_PI
        return npieces + 1
    if a < 0.0:
        pa[npieces] = 0.0
        pb[npieces] = b
        pa[npieces + 1] = a + TWO_PI
        pb[npieces + 1] = TWO_PI
        return npieces + 2
    if b > TWO_PI:
        pa[npieces] = a
        pb[npieces] = TWO_PI
        pa[npieces + 1] = 0.0
        pb[npieces + 1] = b - TWO_PI
        return npieces + 2
    pa[npieces] = a
    pb[npieces] = b
    return npieces + 1


@njit(cache=True)
def _positive_sine(a, b):
    """(integral, maximum) of max(sin(phi), 0) over [a, b] within [0, 2 pi]."""
    if a >= math.pi:
        return 0.0, 0.0
    bb = min(b, math.pi)
    peak = 1.0 if a <= 0.5 * math.pi <= bb else max(math.sin(a), math.sin(bb))
    return math.cos(a) - math.cos(bb), peak


@njit(cache=True, inline="always")
def _joins(end, start, gap, gap_across, boundary):
    """Whether an arc ending at ``end`` and one starting at ``start`` (rad, ``start`` after
    ``end`` unwrapped) belong to one contact region: closer than ``gap``, or than
    ``gap_across`` where the gap spans a family boundary (``boundary`` modulo pi/2)."""
    space = start - end
    if space <= gap:
        return True
    if space > gap_across:
        return False
    quarter = 0.5 * math.pi
    return math.floor((start - boundary) / quarter) != math.floor((end - boundary) / quarter)


@njit(cache=True)
def _sort_pairs(a, b, m):
    """Sort the first m entries of a (and b alongside) by a: insertion sort, few entries."""
    for q in range(1, m):
        ka = a[q]
        kb = b[q]
        w = q - 1
        while w >= 0 and a[w] > ka:
            a[w + 1] = a[w]
            b[w + 1] = b[w]
            w -= 1
        a[w + 1] = ka
        b[w + 1] = kb


@kernel
def _engage(prm, ints, arcs, n_arcs, widen_mm, work):
    """Contact arcs (the first ``n_arcs`` of the :class:`Arcs`) to intervals per slice
    (:mod:`cnctwin.geometry.engagement`), lengths in mm, angles in rad.

    Writes into the :class:`EngageWork` the used slices' (height above the tip, dz, radius)
    as ``slices`` columns, the intervals (index of their slice among the used ones, start, end)
    into ``interval_slice`` and ``intervals``, and ``stats`` = (integral of max(sin phi, 0)
    sin kappa over phi and z, engaged area in rad mm, max of sin phi sin kappa, slices used,
    intervals).
    """
    arc_slice, arc_lo, arc_hi = arcs.slice, arcs.lo, arcs.hi
    first, order, ra, rb, pa, pb = work.first, work.order, work.ra, work.rb, work.pa, work.pb
    slices, out_slice, out_angles, stats = (
        work.slices,
        work.interval_slice,
        work.intervals,
        work.stats,
    )
    first_level = ints[I_K0]
    n_slices = ints[I_NSLICES]
    tip_z, pz = prm[P_TZ], prm[P_PZ]
    for q in range(5):
        stats[q] = 0.0
    big, rc, length = prm[P_R], prm[P_RC], prm[P_L]
    inner, slope = prm[P_INNER], prm[P_SLOPE]
    # On a cone sin(kappa) = cos(theta / 2) (Cutter.sin_kappa_at).
    cone_sin_kappa = 1.0 / math.sqrt(1.0 + slope * slope)
    gap_mm = prm[P_GAP]
    pitch = max(prm[P_PX], prm[P_PY])
    # The row families' contact points meet at 45 degrees to the grid axes, at these angles
    # modulo pi/2 in the feed frame (the point at phi lies at alpha + pi/2 - phi, alpha the
    # feed direction's angle).
    boundary = math.atan2(prm[P_FY], prm[P_FX]) + 0.25 * math.pi
    for s in range(n_slices + 1):
        first[s] = 0
    for q in range(n_arcs):
        first[arc_slice[q] + 1] += 1
    for s in range(n_slices):
        first[s + 1] += first[s]
    for q in range(n_arcs):
        # Counting sort by slice; `first` is restored below.
        s = arc_slice[q]
        order[first[s]] = q
        first[s] += 1
    for s in range(n_slices - 1, 0, -1):
        first[s] = first[s - 1]
    if n_slices > 0:
        first[0] = 0
    count = 0
    used = 0
    # The previous slice with contact: index, radius, first interval, sums per mm of height.
    prev_s = -1
    prev_r = -1.0
    prev_first = 0
    prev_integral = prev_area = 0.0
    for s in range(n_slices):
        m = first[s + 1] - first[s]
        if m == 0:
            continue
        level_z = (first_level + s + 0.5) * pz
        height = level_z - tip_z
        r = big
        sin_kappa = 1.0
        if height < rc:
            w = math.sqrt(max(rc * rc - (rc - max(height, 0.0)) ** 2, 0.0))
            r = big - rc + w
            sin_kappa = w / rc
        elif slope > 0.0 and inner + height * slope < big:
            r = inner + max(height, 0.0) * slope
            sin_kappa = cone_sin_kappa
        if r <= 0.0:
            continue
        low = slice_low(level_z, tip_z, pz)
        dz = max(min(level_z + 0.5 * pz, tip_z + length) - low, 0.0)
        slices[0, used] = height
        slices[1, used] = dz
        slices[2, used] = r
        if r == prev_r and m == first[prev_s + 1] - first[prev_s]:
            # The same arcs as the previous slice (the cylinder of a 2.5D cut): same intervals.
            same = True
            for q in range(m):
                a = order[first[s] + q]
                b = order[first[prev_s] + q]
                if arc_lo[a] != arc_lo[b] or arc_hi[a] != arc_hi[b]:
                    same = False
                    break
            if same:
                n_prev = count - prev_first
                for q in range(n_prev):
                    out_slice[count] = used
                    out_angles[0, count] = out_angles[0, prev_first + q]
                    out_angles[1, count] = out_angles[1, prev_first + q]
                    count += 1
                prev_first = count - n_prev
                prev_s = s
                stats[0] += prev_integral * dz
                stats[1] += prev_area * dz
                used += 1
                continue
        prev_s = s
        prev_r = r
        prev_first = count
        prev_integral = prev_area = 0.0
        gap = gap_mm / r
        gap_across = gap + _ACROSS_PITCHES * pitch / r
        widen = widen_mm / r
        for q in range(m):
            ra[q] = arc_lo[order[first[s] + q]]
            rb[q] = arc_hi[order[first[s] + q]]
        _sort_pairs(ra, rb, m)
        # Join arcs closer than the gap (angles unwrapped: hi may exceed 2 pi).
        nrun = 0
        for q in range(m):
            if nrun > 0 and _joins(rb[nrun - 1], ra[q], gap, gap_across, boundary):
                rb[nrun - 1] = max(rb[nrun - 1], rb[q])
            else:
                ra[nrun] = ra[q]
                rb[nrun] = rb[q]
                nrun += 1
        lo_run = 0
        while lo_run < nrun - 1 and _joins(
            rb[nrun - 1], ra[lo_run] + TWO_PI, gap, gap_across, boundary
        ):
            # The first runs continue the last one across phi = 0 (it may reach past several).
            rb[nrun - 1] = max(rb[nrun - 1], rb[lo_run] + TWO_PI)
            lo_run += 1
        npieces = 0
        for q in range(lo_run, nrun):
            a = ra[q] - widen
            b = rb[q] + widen
            if b - a + gap >= TWO_PI:
                a = 0.0
                b = TWO_PI
            npieces = _emit(a, b, pa, pb, npieces)
        _sort_pairs(pa, pb, npieces)
        merged = 0
        for q in range(npieces):
            if merged > 0 and pa[q] <= pb[merged - 1]:
                pb[merged - 1] = max(pb[merged - 1], pb[q])
            else:
                pa[merged] = pa[q]
                pb[merged] = pb[q]
                merged += 1
        for q in range(merged):
            a = pa[q]
            b = pb[q]
            out_slice[count] = used
            out_angles[0, count] = a
            out_angles[1, count] = b
            count += 1
            integral, peak = _positive_sine(a, b)
            prev_integral += integral * sin_kappa
            prev_area += b - a
            stats[2] = max(stats[2], peak * sin_kappa)
        stats[0] += prev_integral * dz
        stats[1] += prev_area * dz
        used += 1
    stats[3] = used
    stats[4] = count


@kernel
def path(
    prm, ints, tips, fz, cycle_s, state, prev_tip, old_tip, arrays, acc, widen_mm, work, outputs
):
    """Removal (:func:`cnctwin.geometry._removal_kernels.cut` of ``arrays``,
    ``plain(CutArrays)``) then engagement (:func:`_engage`, into ``work``,
    ``plain(EngageWork)``) at every tip (``tips``, (n, 3), grid coordinates, mm) from
    ``state[0]`` on, with feeds per tooth ``fz`` (n,) mm and the cycle ``cycle_s`` s.

    ``state``: next position, whether its removal is partly done (a resumed call keeps its
    accumulators ``acc``), whether ``prev_tip`` is the position before the first, whether
    ``old_tip`` is the stock's last cut with this cutter. Writes a row of ``outputs.out``
    (``plain(PathOutputs)``) per position and its slices and intervals at the offsets; widens
    the intervals by ``widen_mm`` over the slice radius. Returns 0 when all are done, else the
    status of a full heap or arc buffer or ``OUT_FULL``, with ``state`` set to resume (the
    caller grows the buffer and calls again).
    """
    arcs = cut_arrays(arrays).arcs
    work = EngageWork(*work)
    slices, iv_slice, iv_angles, stats = (
        work.slices,
        work.interval_slice,
        work.intervals,
        work.stats,
    )
    named = PathOutputs(*outputs)
    out, slice_offsets, out_slices = named.out, named.slice_offsets, named.slices
    interval_offsets, out_interval_slice = named.interval_offsets, named.interval_slice
    out_intervals = named.intervals
    n = tips.shape[0]
    px, py, pz = prm[P_PX], prm[P_PY], prm[P_PZ]
    diameter, length = 2.0 * prm[P_R], prm[P_L]
    i = state[0]
    while i < n:
        tx, ty, tz = tips[i, 0], tips[i, 1], tips[i, 2]
        has_prev = i > 0 or state[2] != 0
        if i > 0:
            qx, qy, qz = tips[i - 1, 0], tips[i - 1, 1], tips[i - 1, 2]
        else:
            qx, qy, qz = prev_tip[0], prev_tip[1], prev_tip[2]
        fx, fy = 1.0, 0.0
        feed = math.nan
        if has_prev:
            dx, dy, dz = tx - qx, ty - qy, tz - qz
            feed = math.sqrt(dx * dx + dy * dy + dz * dz) / cycle_s * 60.0
            horizontal = math.sqrt(dx * dx + dy * dy)
            if horizontal > _MIN_FEED_MOVE_MM:
                fx, fy = dx / horizontal, dy / horizontal
        if i > 0:
            reaches = place(prm, ints, tx, ty, tz, qx, qy, qz, True, fx, fy)
        else:
            reaches = place(
                prm, ints, tx, ty, tz, old_tip[0], old_tip[1], old_tip[2], state[3] != 0, fx, fy
            )
        if state[1] == 0:
            reset_accumulators(acc)
        if reaches:
            status = cut(prm, ints, arrays, acc)
            if status != 0:
                state[0] = i
                state[1] = 1
                return status
            _engage(prm, ints, arcs, int(acc[A_ARCS]), widen_mm, work)
        else:
            for q in range(5):
                stats[q] = 0.0
        used = int(stats[3])
        count = int(stats[4])
        s0 = slice_offsets[i]
        c0 = interval_offsets[i]
        if s0 + used > out_slices.shape[1] or c0 + count > out_intervals.shape[1]:
            state[0] = i
            state[1] = 1
            return OUT_FULL
        for q in range(used):
            out_slices[0, s0 + q] = slices[0, q]
            out_slices[1, s0 + q] = slices[1, q]
            out_slices[2, s0 + q] = slices[2, q]
        for q in range(count):
            out_interval_slice[c0 + q] = iv_slice[q]
            out_intervals[0, c0 + q] = iv_angles[0, q]
            out_intervals[1, c0 + q] = iv_angles[1, q]
        slice_offsets[i + 1] = s0 + used
        interval_offsets[i + 1] = c0 + count
        removed = (acc[A_LEN_Z] * px * py + acc[A_LEN_X] * py * pz + acc[A_LEN_Y] * px * pz) / 3.0
        removed = max(removed, 0.0)
        integral, area, peak = stats[0], stats[1], stats[2]
        out[i, O_CONTACT] = 1.0 if removed > 0.0 else 0.0
        out[i, O_REMOVED] = removed
        out[i, O_MRR] = removed / cycle_s
        out[i, O_AE] = min(max(acc[A_NMAX] - acc[A_NMIN], 0.0), diameter) if removed > 0 else 0.0
        out[i, O_AP] = min(max(acc[A_ZMAX] - acc[A_ZMIN], 0.0), length) if removed > 0 else 0.0
        out[i, O_FEED] = feed
        out[i, O_FDX] = fx
        out[i, O_FDY] = fy
        out[i, O_HMEAN] = fz[i] * integral / area if area > 0.0 else 0.0
        out[i, O_HMAX] = fz[i] * peak
        out[i, O_BOTTOM] = acc[A_BOTTOM]
        out[i, O_ABOVE] = acc[A_ABOVE]
        state[1] = 0
        i += 1
    state[0] = n
    return 0
