"""Cutter-workpiece engagement of one cut, from the dexels it actually removed.

Units: mm (names end in ``_mm``), mm^3, mm^3/s, mm/min for the feed (as the NC layer), s, rad.

Angle frame
-----------
Angles follow the mechanistic milling convention (Altintas, *Manufacturing Automation*, 2nd ed.,
2012, Sec. 2.2): with ``f`` the unit feed direction in the xy plane and ``n = (-f_y, f_x)`` its
left normal, a point of the tool's periphery at angle ``phi`` sits at ``r (sin(phi) f +
cos(phi) n)`` from the axis, so ``phi`` runs clockwise seen from above (+z), the sense of an M3
spindle: ``phi = 0`` on the left of the feed, ``pi/2`` ahead, ``pi`` on the right. The uncut chip
thickness is ``h = f_z sin(phi) sin(kappa)`` (``kappa`` from
:meth:`~cnctwin.geometry.cutter.Cutter.sin_kappa_at`, 1 on a cylinder). A full slot engages
``[0, pi]``; up milling (material on the left) ``[0, phi_e]`` and down milling (material on the
right) ``[pi - phi_e, pi]``, with ``phi_e = arccos(1 - 2 a_e / D)``.

Intervals
---------
The contact of a cut (see :mod:`cnctwin.geometry.removal`) is sampled where the grid's rays
cross the envelope, at most ``sqrt(2) p / r`` apart (pitch ``p``, slice radius ``r``), and
comes as arcs. Per slice, arcs closer than ``1.5 sqrt(2) p / r`` join one interval and each
interval is widened by ``p / (2 r)`` on both sides (half a sample spacing: the unbiased estimate
of where contact ends between two samples). Intervals are half-open ``[start, end)`` with
``0 <= start < end <= 2 pi``, sorted, disjoint; a contact region across ``phi = 0`` is split
into ``[0, e)`` and ``[s, 2 pi)``. Slices are the grid's z levels inside the fluted length;
slice ``k`` samples the envelope at its level ``z_k`` and stands for ``[z_k - p_z/2, z_k +
p_z/2]`` (the lowest one down to the tip).

Discrete positions (Heide 2025, Sec. 2.2) let contact reach ``s / (2 r)`` past a wall the tool
has just left (step ``s``), and a ball or bull nose leaves cusps ``s^2 / (8 R)`` high between
positions, which the next position removes behind its axis in the lowest slices: contact in
``(pi, 2 pi)``, where the chip thickness is 0.

Widths
------
``ae`` is the extent of the removed material along the feed normal ``n`` and ``ap`` its extent
along z: the removed dexels' ends (along z exact to float32 for z rays; x and y rays stand for
their level's slab, clipped to the tip and the fluted length).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from cnctwin.errors import ConfigError
from cnctwin.geometry.cutter import Cutter
from cnctwin.geometry.dexel import DexelStock
from cnctwin.geometry.removal import (
    A_ARCS,
    I_K0,
    I_NSLICES,
    P_GAP,
    P_L,
    P_PZ,
    P_R,
    P_RC,
    P_TZ,
    _cut,
    grow_for,
    kernel,
    prepare,
    workspace,
    xyz_mm,
)

__all__ = ["Engagement", "cut"]

TWO_PI = 2.0 * math.pi
_WIDEN_PITCHES = 0.5  # widen intervals by this many pitches (over r) on each side
_MIN_FEED_MOVE_MM = 1e-9  # a horizontal displacement below this leaves the feed direction +x


class Engagement(NamedTuple):
    """Engagement of one cut (one sampled tool position).

    Attributes
    ----------
    contact
        Whether the tool removed material.
    removed_volume_mm3
        Volume removed by this cut, mm^3 (mean of the three dexel families), >= 0.
    mrr_mm3_s
        Material removal rate ``removed_volume_mm3 / cycle_s``, mm^3/s.
    ae_mm
        Radial depth (width) of cut: extent of the removed material along the feed normal, mm,
        in [0, D].
    ap_mm
        Axial depth of cut: extent of the removed material along z, mm, in [0, flute length].
    feed_mm_min
        Feed velocity reconstructed from the tip's displacement since the previous position,
        ``|p - p_prev| / cycle_s``, mm/min (Heide 2025, Sec. 2.3); NaN without a previous
        position.
    feed_dir
        Unit feed direction (x, y) of the angle frame: the horizontal displacement, or (1, 0)
        when the tip did not move horizontally.
    h_mean_mm
        Mean uncut chip thickness over the engaged tool surface, ``integral of
        f_z max(sin phi, 0) sin kappa dphi dz / integral of dphi dz``, mm (for a flat end mill
        ``f_z (cos phi_st - cos phi_ex) / (phi_ex - phi_st)``, Martellotti); 0 without contact.
    h_max_mm
        Largest uncut chip thickness ``f_z sin(phi) sin(kappa)`` over the engagement, mm.
    slice_height_mm
        (m,) heights above the tip (mm) where the slices with contact sample the envelope.
    slice_dz_mm
        (m,) height of tool each slice stands for, mm.
    slice_radius_mm
        (m,) envelope radius at each slice's height, mm.
    interval_slice
        (q,) index into the slice arrays of each contact interval.
    interval_start_rad, interval_end_rad
        (q,) contact intervals ``[start, end)`` in rad, ``0 <= start < end <= 2 pi``, sorted
        and disjoint within a slice (see the module notes).
    bottom_contact
        The flat bottom face of a flat or bull-nose end mill cut material while moving down (a
        plunge or ramp; the first cut of a stock counts as moving down). Bottom-face contacts
        are not part of the intervals.
    above_flutes
        Material at the top of the fluted length inside the footprint: the shank would hit it.
    """

    contact: bool
    removed_volume_mm3: float
    mrr_mm3_s: float
    ae_mm: float
    ap_mm: float
    feed_mm_min: float
    feed_dir: tuple[float, float]
    h_mean_mm: float
    h_max_mm: float
    slice_height_mm: np.ndarray
    slice_dz_mm: np.ndarray
    slice_radius_mm: np.ndarray
    interval_slice: np.ndarray
    interval_start_rad: np.ndarray
    interval_end_rad: np.ndarray
    bottom_contact: bool
    above_flutes: bool

    def slice_intervals(self, index: int) -> list[tuple[float, float]]:
        """The contact intervals ``(start, end)`` in rad of slice ``index``."""
        sel = self.interval_slice == index
        return list(
            zip(
                self.interval_start_rad[sel].tolist(),
                self.interval_end_rad[sel].tolist(),
                strict=True,
            )
        )


def cut(
    stock: DexelStock,
    cutter: Cutter,
    position_mm: np.ndarray | tuple[float, float, float],
    previous_position_mm: np.ndarray | tuple[float, float, float] | None,
    feed_per_tooth_mm: float,
    cycle_s: float,
) -> Engagement:
    """One simulation step: cut the stock at a tool position and return the engagement.

    Parameters
    ----------
    stock
        The stock, changed in place.
    cutter
        The cutter (axis +z).
    position_mm
        Tool tip (x, y, z) in machine coordinates, mm (``SampleChunk.tcp_mm``).
    previous_position_mm
        Tool tip at the previous step, mm; ``None`` for the first step.
    feed_per_tooth_mm
        Feed per tooth ``f_z`` in mm for the chip thickness, finite and >= 0.
    cycle_s
        Time between the two positions in s, > 0.

    Returns
    -------
    Engagement
        ae, ap, contact intervals, chip thickness, MRR and the reconstructed feed.

    Raises
    ------
    ConfigError
        On a position that is not three finite numbers, a negative or non-finite feed per
        tooth, or a cycle time that is not finite and > 0.

    Notes
    -----
    Discrete-position material removal (Heide 2025, Sec. 2.2;
    :func:`cnctwin.geometry.removal.remove`) followed by the engagement of the removed dexels
    (Heide 2025, Fig. 5, steps 2-3), in one compiled call. A simulation loop::

        stock = DexelStock.box((0, 0, -30), (100, 100, 0), density_per_mm=10)
        previous = None
        for position in chunk.tcp_mm:
            engagement = cut(stock, cutter, position, previous, 0.05, 0.0125)
            previous = position
    """
    if not (math.isfinite(feed_per_tooth_mm) and feed_per_tooth_mm >= 0.0):
        raise ConfigError(
            f"feed_per_tooth_mm={feed_per_tooth_mm!r}; give a finite feed per tooth >= 0 mm"
        )
    if not (math.isfinite(cycle_s) and cycle_s > 0.0):
        raise ConfigError(f"cycle_s={cycle_s!r}; give a finite cycle time > 0 s")
    tip = xyz_mm(position_mm, "position_mm")
    feed_mm_min = math.nan
    feed_dir = (1.0, 0.0)
    if previous_position_mm is not None:
        px, py, pz = xyz_mm(previous_position_mm, "previous_position_mm")
        dx, dy, dz = tip[0] - px, tip[1] - py, tip[2] - pz
        feed_mm_min = math.sqrt(dx * dx + dy * dy + dz * dz) / cycle_s * 60.0
        horizontal = math.hypot(dx, dy)
        if horizontal > _MIN_FEED_MOVE_MM:
            feed_dir = (dx / horizontal, dy / horizontal)
    ws = workspace(stock)
    step = prepare(stock, ws, cutter, tip, feed_dir)
    widen_mm = _WIDEN_PITCHES * max(ws.grid[3], ws.grid[4])
    if not step.reaches:
        ws.stats[:] = 0.0
    while step.reaches:
        status = _step(
            step.prm,
            step.ints,
            *ws.cut_arrays(stock),
            step.acc,
            widen_mm,
            ws.first,
            ws.order,
            ws.ra,
            ws.rb,
            ws.pa,
            ws.pb,
            ws.slices,
            ws.iv_slice,
            ws.iv_angles,
            ws.stats,
        )
        if status == 0:
            break
        grow_for(status, stock, ws)
    len_z, len_x, len_y, nmin, nmax, zmin, zmax, bottom, above, _ = step.acc.tolist()
    integral, area, peak, used_f, count_f = ws.stats.tolist()
    px, py, pz = ws.grid[3:6]
    removed = max((len_z * px * py + len_x * py * pz + len_y * px * pz) / 3.0, 0.0)
    has_contact = removed > 0.0
    ae = ap = 0.0
    if has_contact:
        ae = min(max(nmax - nmin, 0.0), cutter.diameter_mm)
        ap = min(max(zmax - zmin, 0.0), cutter.flute_length_mm)
    used = int(used_f)
    count = int(count_f)
    slices = ws.slices[:, :used].copy()
    angles = ws.iv_angles[:, :count].copy()
    return Engagement(
        contact=has_contact,
        removed_volume_mm3=removed,
        mrr_mm3_s=removed / cycle_s,
        ae_mm=ae,
        ap_mm=ap,
        feed_mm_min=feed_mm_min,
        feed_dir=feed_dir,
        h_mean_mm=feed_per_tooth_mm * integral / area if area > 0.0 else 0.0,
        h_max_mm=feed_per_tooth_mm * peak,
        slice_height_mm=slices[0],
        slice_dz_mm=slices[1],
        slice_radius_mm=slices[2],
        interval_slice=ws.iv_slice[:count].copy(),
        interval_start_rad=angles[0],
        interval_end_rad=angles[1],
        bottom_contact=bottom > 0.0,
        above_flutes=above > 0.0,
    )


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
def _engage(
    prm,
    ints,
    arc_slice,
    arc_lo,
    arc_hi,
    n_arcs,
    widen_mm,
    first,
    order,
    ra,
    rb,
    pa,
    pb,
    slices,
    out_slice,
    out_angles,
    stats,
):
    """Contact arcs to intervals per slice (module notes), lengths in mm, angles in rad.

    Writes the used slices' (height above the tip, dz, radius) into ``slices`` columns, the
    intervals (index of their slice among the used ones, start, end) into ``out_slice`` and
    ``out_angles``, and ``stats`` = (integral of max(sin phi, 0) sin kappa over phi and z,
    engaged area in rad mm, max of sin phi sin kappa, slices used, intervals).
    """
    first_level = ints[I_K0]
    n_slices = ints[I_NSLICES]
    tip_z, pz = prm[P_TZ], prm[P_PZ]
    for q in range(5):
        stats[q] = 0.0
    big, rc, length = prm[P_R], prm[P_RC], prm[P_L]
    gap_mm = prm[P_GAP]
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
        if r <= 0.0:
            continue
        low = tip_z if s == 0 else max(level_z - 0.5 * pz, tip_z)
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
        widen = widen_mm / r
        for q in range(m):
            ra[q] = arc_lo[order[first[s] + q]]
            rb[q] = arc_hi[order[first[s] + q]]
        _sort_pairs(ra, rb, m)
        # Join arcs closer than the gap (angles unwrapped: hi may exceed 2 pi).
        nrun = 0
        for q in range(m):
            if nrun > 0 and ra[q] - rb[nrun - 1] <= gap:
                rb[nrun - 1] = max(rb[nrun - 1], rb[q])
            else:
                ra[nrun] = ra[q]
                rb[nrun] = rb[q]
                nrun += 1
        lo_run = 0
        if nrun > 1 and ra[0] + TWO_PI - rb[nrun - 1] <= gap:
            # The first run continues the last one across phi = 0.
            rb[nrun - 1] = max(rb[nrun - 1], rb[0] + TWO_PI)
            lo_run = 1
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
def _step(
    prm,
    ints,
    z_count,
    z_start,
    z_block,
    z_rows,
    z_heap_top,
    x_count,
    x_start,
    x_block,
    x_rows,
    x_heap_top,
    y_count,
    y_start,
    y_block,
    y_rows,
    y_heap_top,
    arc_slice,
    arc_lo,
    arc_hi,
    table,
    acc,
    widen_mm,
    first,
    order,
    ra,
    rb,
    pa,
    pb,
    slices,
    out_slice,
    out_angles,
    stats,
):
    """Removal (:func:`cnctwin.geometry.removal._cut`) then engagement (:func:`_engage`) in one
    call; returns the removal's status (0 done, else grow a buffer and call again)."""
    status = _cut(
        prm, ints, z_count, z_start, z_block, z_rows, z_heap_top, x_count, x_start, x_block,
        x_rows, x_heap_top, y_count, y_start, y_block, y_rows, y_heap_top, arc_slice, arc_lo,
        arc_hi, table, acc,
    )  # fmt: skip
    if status != 0:
        return status
    _engage(
        prm, ints, arc_slice, arc_lo, arc_hi, int(acc[A_ARCS]), widen_mm, first, order, ra, rb,
        pa, pb, slices, out_slice, out_angles, stats,
    )  # fmt: skip
    return 0
