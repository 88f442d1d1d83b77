"""Material removal: subtract the cutter's envelope at one tool position from a tri-dexel stock.

Units: mm (names end in ``_mm``), mm^3, rad.

Method
------
The discrete-position method of Heide 2025 (Sec. 2.2, after Pape): at every sampled tool-tip
position the cutting envelope (:class:`~cnctwin.geometry.cutter.Cutter`, a solid of revolution
about +z) is subtracted from every ray it crosses; the swept volume between positions is *not*
modelled, so a step longer than the dexel pitch leaves the scallops of Heide 2025's Fig. 7a.

Per ray the envelope is one interval, in closed form: along a ``z`` ray at horizontal distance
``d`` from the axis it is ``[tip + zmin(d), tip + L]``; along an ``x`` (or ``y``) ray at height
``z`` it is the chord ``c +- sqrt(r(z - tip)^2 - dv^2)`` of the local disc. The removed volume of
a family is the sum of the removed lengths times the ray's cell area, computed from the stored
float32 values, so the sum of removed volumes equals the stock's loss to rounding of the sum.

When the stock's previous cut was made with the same cutter, its envelope is already empty, so
only the part of the new envelope outside the previous one is subtracted (at most two pieces per
ray): the result is the same, the cost proportional to the new material instead of the tool's
footprint.

Contact record
--------------
Every end of a removed piece that is a point of the *new* envelope's surface lying strictly
inside material is a contact point of the cutting edges with the workpiece. Along ``x`` and
``y`` rays these points lie on the slice's circle. Each row family records the points within 45
degrees of its rays' direction, where consecutive rows' crossings are at most ``sqrt(2)``
pitches apart (the other family covers the rest as densely); contact points of neighbouring
rows join into one arc (up to ``GAP_PITCHES`` pitches apart), so that an angle is computed only
where an arc starts or ends. Corner contacts of ball and bull-nose tools, seen by the ``z``
rays, are point arcs. Arcs are recorded per axial slice (one per ``z`` level of the grid) as
angles ``phi`` in the feed frame of :mod:`cnctwin.geometry.engagement`, which merges them into
intervals. Contacts of the flat bottom face of a flat or bull-nose end mill are flagged instead
when the tool moves down, and so is material at the top of the fluted length.

Thin material
-------------
Discrete positions a step ``s`` apart leave cusps ``s^2 / (8 r)`` high on every wall a slice of
radius ``r`` cuts (two circles ``s`` apart meet that far inside their radius). A later pass
along such a wall (the next layer of a pocket, a spring pass) removes those cusp tips, which
are artefacts of the sampling, not chips: as contacts they would add arcs at ``phi = 0`` and
``pi`` on every slice up to the wall's top, and ``ap`` would jump to the wall's height. So a
removed piece is a *cut* only if it reaches at least ``THIN_CUSPS s^2 / (8 r)`` inside the new
envelope (``s`` the horizontal step from the previous cut with the same cutter), and at least a
few float32 spacings of the grid: along ``x`` and ``y`` rays the depth inside the slice's circle
of the piece's point nearest the axis; along ``z`` rays both the piece's length and the depth of
the ray inside the envelope's radius at the piece's top. Only cuts give the extents (``ae``,
``ap``), the shank flag and the ``z`` rays' corner contacts; a run of neighbouring rows' contact
points is a contact arc if any of its pieces is a cut. Material thin all along a wall thus makes
no contact, while the thin edge of a real contact (the sides of a slot, where the new material
is ``s sin(phi)`` thick; the wedge where the tool leaves the material) keeps it. With
``THIN_CUSPS = 2`` a wall left with steps up to ``sqrt(2) s`` is retraced without contact;
coarser earlier steps leave cusps that still count. The removed volume counts every piece.

Performance
-----------
Rays of consecutive levels whose new and previous disc radii agree (the cylinder of the tool)
share one table of operations (ray row, piece, and what the contact bookkeeping needs of the
row), so the per-ray work is the subtraction itself, through
:func:`~cnctwin.geometry.dexel.trim_interval` (the common case, a trimmed end, first). The
kernels run without numba's reference counting (see :data:`kernel`) and cut the row families
before the z rays, whose crescent is new to the cache at every step. A step costs about one
operation per ray whose material changes: along x and y one or two per row the tool's
silhouette crosses at every level, ``rho^2`` per mm^2 of silhouette (Boess et al., cited by
Heide 2025, Eq. 1), about 7 ns each; along z the rays of the new crescent only.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from typing import NamedTuple, cast

import numpy as np
from numba import njit

from cnctwin.errors import ConfigError
from cnctwin.geometry.cutter import Cutter
from cnctwin.geometry.dexel import AXES, DexelStock, subtract_interval, trim_interval

__all__ = ["GAP_PITCHES", "THIN_CUSPS", "ContactRecord", "Removal", "remove"]

TWO_PI = 2.0 * math.pi
#: The decorator of the kernels that allocate nothing: they run without numba's reference
#: counting (``_nrt=False``). With it, every inlined call taking the stock's arrays costs atomic
#: reference-count updates: measured 15x slower per ray.
kernel = njit(cache=True, _nrt=False)  # type: ignore[call-overload]
#: Contact points closer than this many grid pitches belong to one contact arc (the largest
#: spacing of the ray crossings of a circle is sqrt(2) pitches; 1.5 of it leaves a margin).
GAP_PITCHES = 1.5 * math.sqrt(2.0)
#: Removed material is a cut only where it reaches at least ``THIN_CUSPS`` times the cusp height
#: ``s^2 / (8 r)`` inside the envelope (mm; horizontal step ``s``, slice radius ``r``): see the
#: module notes.
THIN_CUSPS = 2.0
#: ... and at least this many float32 spacings of the grid's largest coordinate.
_THIN_ULPS = 4.0

# Kernel parameters (float64 array).
P_CX, P_CY, P_TZ = 0, 1, 2  # tool tip, grid coordinates, mm
P_OCX, P_OCY, P_OTZ = 3, 4, 5  # tip of the previous cut with the same cutter, mm
P_USE_OLD = 6  # 1.0 when the previous envelope is known to be empty
P_R, P_RC, P_L = 7, 8, 9  # radius, corner radius, fluted length, mm
P_FX, P_FY = 10, 11  # unit feed direction in the xy plane
P_PX, P_PY, P_PZ = 12, 13, 14  # grid pitch, mm
P_GAP = 15  # largest distance between contact points of one arc, mm
P_THIN = 16  # THIN_CUSPS s^2 / 8 (horizontal step s), mm^2: over a radius, the thinnest cut
P_THIN0 = 17  # the thinnest cut on any radius (float32 resolution of the grid), mm
P_INNER = 18  # radius of the flat bottom face (Cutter.flat_radius_mm), mm
P_SLOPE = 19  # tan(theta / 2) of a conical or snub tool's cone, 0 for the others
P_SX, P_SY, P_SZ = 20, 21, 22  # size of the grid, mm
_N_PRM = 23

# Integer parameters (int64 array).
I_NX, I_NY, I_NZ, I_K0, I_NSLICES = range(5)

# Accumulators (float64 array), kept across a rerun after a buffer grew.
A_LEN_Z, A_LEN_X, A_LEN_Y = 0, 1, 2  # removed length per family, mm
A_NMIN, A_NMAX = 3, 4  # extent of removed material along the feed normal, mm from the axis
A_ZMIN, A_ZMAX = 5, 6  # extent of removed material along z, grid coordinates, mm
A_BOTTOM = 7  # 1.0: the flat bottom face cut material moving down
A_ABOVE = 8  # 1.0: material at the top of the fluted length
A_ARCS = 9  # contact arcs written

N_ACC = 10  # accumulators (their start values: reset_accumulators)

# Kernel status.
_DONE = 0
_HEAP_FULL = 1  # plus 10 x the family index (z 0, x 1, y 2)
_ARCS_FULL = 2
_INITIAL_ARCS = 4096

# Atan on [0, 1] as an odd polynomial (least squares on Chebyshev nodes, max error 2.7e-7 rad,
# checked in tests/geometry/test_removal.py).
_ATAN_C0 = 0.99999663
_ATAN_C1 = -0.33318301
_ATAN_C2 = 0.198132
_ATAN_C3 = -0.13247467
_ATAN_C4 = 0.07981017
_ATAN_C5 = -0.03372501
_ATAN_C6 = 0.00684231


@njit(cache=True, inline="always")
def fast_atan2(y: float, x: float) -> float:
    """``atan2(y, x)`` in rad within 3e-7 rad (0 for the origin)."""
    ax = abs(x)
    ay = abs(y)
    big = max(ax, ay)
    if big == 0.0:
        return 0.0
    t = min(ax, ay) / big
    t2 = t * t
    p = t * (
        _ATAN_C0
        + t2
        * (
            _ATAN_C1
            + t2 * (_ATAN_C2 + t2 * (_ATAN_C3 + t2 * (_ATAN_C4 + t2 * (_ATAN_C5 + t2 * _ATAN_C6))))
        )
    )
    if ay > ax:
        p = 0.5 * math.pi - p
    if x < 0.0:
        p = math.pi - p
    if y < 0.0:
        p = -p
    return p


@njit(cache=True, inline="always")
def _zmin(d2: float, inner: float, inner2: float, rc: float, slope: float) -> float:
    """Height (mm) of the envelope's lower surface above the tip at squared distance d2 (mm^2)
    from the axis: 0 on the flat bottom (radius ``inner``), then the corner of radius ``rc``
    or the cone of ``slope = tan(theta / 2)``."""
    if d2 <= inner2:
        return 0.0
    if rc > 0.0:
        u = math.sqrt(d2) - inner
        w = rc * rc - u * u
        return rc - math.sqrt(w) if w > 0.0 else rc
    return (math.sqrt(d2) - inner) / slope


@njit(cache=True, inline="always")
def _cell_floor(x: float, n: int) -> int:
    """``floor(x)`` as a cell index clamped to [-1, n] (x in cells).

    Safe for any float: converting a float beyond the int64 range (a fluted length or a
    position of 1e300 mm over a pitch) gives an undefined integer whose differences wrap
    around, which would index far outside the grid's buffers.
    """
    if not x > -1.0:  # also NaN
        return -1
    if x >= n:
        return n
    return int(math.floor(x))


@njit(cache=True, inline="always")
def _cell_ceil(x: float, n: int) -> int:
    """``ceil(x)`` as a cell index clamped to [-1, n] (x in cells; as :func:`_cell_floor`)."""
    if not x > -1.0:
        return -1
    if x >= n:
        return n
    return int(math.ceil(x))


@njit(cache=True, inline="always")
def _radius(h: float, big: float, rc: float, inner: float, slope: float, length: float) -> float:
    """Envelope radius (mm) at height h (mm) above the tip; -1 outside the envelope (profile as
    for :func:`_zmin`)."""
    if h < 0.0 or h > length:
        return -1.0
    if rc > 0.0:
        if h >= rc:
            return big
        w = rc * rc - (rc - h) * (rc - h)
        return big - rc + (math.sqrt(w) if w > 0.0 else 0.0)
    if slope > 0.0:
        return min(inner + h * slope, big)
    return big


@njit(cache=True, inline="always")
def _emit_arc(s, a0, v0, a1, v1, f_al, f_row, n_al, n_row, arc_slice, arc_lo, arc_hi, n):
    """Append the contact arc of slice s from point (a0, v0) to (a1, v1) (mm from the axis,
    along the ray and across it) as (slice, lo, hi): lo in [0, 2 pi), hi - lo in [0, pi]."""
    phi0 = fast_atan2(a0 * f_al + v0 * f_row, a0 * n_al + v0 * n_row)
    phi1 = phi0
    if a1 != a0 or v1 != v0:
        phi1 = fast_atan2(a1 * f_al + v1 * f_row, a1 * n_al + v1 * n_row)
    span = phi1 - phi0
    if span > math.pi:
        span -= TWO_PI
    elif span < -math.pi:
        span += TWO_PI
    lo = phi0
    if span < 0.0:
        lo = phi1
        span = -span
    if lo < 0.0:
        lo += TWO_PI
    arc_slice[n] = s
    arc_lo[n] = lo
    arc_hi[n] = lo + span
    return n + 1


@kernel
def _cut_z(prm, ints, count, start, block, rows, heap_top, arc_slice, arc_lo, arc_hi, acc):
    """Subtract the envelope from the z rays.

    Returns 0, or a status (heap or arcs full) with the rays done so far left done.
    """
    nx, ny = ints[I_NX], ints[I_NY]
    k0, nslices = ints[I_K0], ints[I_NSLICES]
    cx, cy, tz = prm[P_CX], prm[P_CY], prm[P_TZ]
    ocx, ocy, otz = prm[P_OCX], prm[P_OCY], prm[P_OTZ]
    use_old = prm[P_USE_OLD] > 0.0
    big, rc, length = prm[P_R], prm[P_RC], prm[P_L]
    inner, slope = prm[P_INNER], prm[P_SLOPE]
    fx, fy = prm[P_FX], prm[P_FY]
    px, py, pz = prm[P_PX], prm[P_PY], prm[P_PZ]
    big2 = big * big
    inner2 = inner * inner
    top = tz + length
    otop = otz + length
    removed_total = 0.0
    nmin, nmax = acc[A_NMIN], acc[A_NMAX]
    zmin, zmax = acc[A_ZMIN], acc[A_ZMAX]
    bottom = acc[A_BOTTOM] > 0.0
    above = acc[A_ABOVE] > 0.0
    n_arcs = int(acc[A_ARCS])
    thin = min(max(prm[P_THIN] / big, prm[P_THIN0]), 0.5 * big)
    status = _DONE
    plunging = not use_old or tz < otz
    # Inside both flat bottoms at the same height, the new interval equals the old one.
    skip_inner = use_old and otz == tz and inner > 0.0
    j0 = max(0, _cell_ceil((cy - big) / py - 0.5, ny))
    j1 = min(ny - 1, _cell_floor((cy + big) / py - 0.5, ny))
    for j in range(j0, j1 + 1):
        y = (j + 0.5) * py
        dy = y - cy
        dy2 = dy * dy
        if dy2 > big2:
            continue
        half = math.sqrt(big2 - dy2)
        i0 = max(0, _cell_ceil((cx - half) / px - 0.5, nx))
        i1 = min(nx - 1, _cell_floor((cx + half) / px - 0.5, nx))
        if n_arcs + (i1 - i0 + 1) > arc_slice.shape[0]:
            status = _ARCS_FULL
            break
        s0 = i1 + 1
        s1 = i1
        ody = y - ocy
        if skip_inner and dy2 < inner2 and ody * ody < inner2:
            h1 = math.sqrt(inner2 - dy2)
            h2 = math.sqrt(inner2 - ody * ody)
            lo = max(cx - h1, ocx - h2) + 1e-9
            hi = min(cx + h1, ocx + h2) - 1e-9
            if hi > lo:
                s0 = max(i0, _cell_ceil(lo / px - 0.5, nx))
                s1 = min(i1, _cell_floor(hi / px - 0.5, nx))
        i = i0
        while i <= i1:
            if i == s0 and s1 >= s0:
                i = s1 + 1
                continue
            x = (i + 0.5) * px
            dx = x - cx
            d2 = dx * dx + dy2
            i += 1
            if d2 > big2:
                continue
            bot = tz + _zmin(d2, inner, inner2, rc, slope)
            # Pieces of [bot, top] outside the old envelope's interval on this ray: the first
            # ends at the old bottom, the second starts at the old top (not tool surfaces).
            b1 = top
            a2 = top
            if use_old:
                odx = x - ocx
                od2 = odx * odx + ody * ody
                if od2 <= big2:
                    obot = otz + _zmin(od2, inner, inner2, rc, slope)
                    if obot < top and otop > bot:
                        b1 = obot
                        a2 = otop
            r = j * nx + (i - 1)
            pn = dx * (-fy) + dy * fx
            # The level of a corner contact of the first piece, emitted after the loop over
            # the pieces (inside it, the compiler would compute the contact's angle for every
            # ray, in case it is needed).
            contact_level = -1
            for piece in range(2):
                if piece == 0:
                    a, b = bot, b1
                else:
                    a, b = a2, top
                if not b > a:
                    continue
                st, removed, lo_in, hi_in, clo, chi, _ = subtract_interval(
                    r, np.float32(a), np.float32(b), 0, count, start, block, rows, heap_top
                )
                if st != 0:
                    status = _HEAP_FULL
                    break
                if removed > 0.0:
                    removed_total += removed
                    if lo_in and piece == 0 and inner > 0.0 and d2 <= inner2:
                        # The flat bottom face inside material: a cut only when it moves
                        # down (a plunge or ramp); moving sideways it just bounds the floor.
                        bottom = bottom or plunging
                    # A cut when the removed piece is at least `thin` along the ray and
                    # across it, inside the envelope's radius at its top.
                    deep = _radius(chi - tz, big, rc, inner, slope, length) - thin
                    if chi - clo < thin or deep <= 0.0 or d2 >= deep * deep:
                        continue
                    nmin = min(nmin, pn)
                    nmax = max(nmax, pn)
                    zmin = min(zmin, clo)
                    zmax = max(zmax, chi)
                    if lo_in and piece == 0 and d2 > inner2 and nslices > 0:
                        contact_level = _cell_floor(a / pz, ints[I_NZ])
                    if hi_in and (piece == 1 or b1 == top):
                        above = True
            if contact_level >= 0:
                s = min(max(contact_level - k0, 0), nslices - 1)
                n_arcs = _emit_arc(
                    s, dx, dy, dx, dy, fx, fy, -fy, fx, arc_slice, arc_lo, arc_hi, n_arcs
                )
            if status != _DONE:
                break
        if status != _DONE:
            break
    acc[A_LEN_Z] += removed_total
    acc[A_NMIN], acc[A_NMAX], acc[A_ZMIN], acc[A_ZMAX] = nmin, nmax, zmin, zmax
    acc[A_BOTTOM] = 1.0 if bottom else 0.0
    acc[A_ABOVE] = 1.0 if above else 0.0
    acc[A_ARCS] = n_arcs
    return status


# Rows of the chord table of one level group (see _chords): per row q = j - j0 the half chord
# and the row's offset from the axis; then the operations: ray row, piece start and end
# (float32 values), flags, the part of the row a removed piece must reach to be a cut, and the
# row's offset times the feed normal's component across the rows (the operation carries what
# its row's removal needs, so the kernel reads one column of the table per operation).
T_HALF, T_DV, T_OP_ROW, T_OP_FA, T_OP_FB, T_OP_FLAGS = 0, 1, 2, 3, 4, 5
T_OP_CUT_LO, T_OP_CUT_HI, T_OP_DV_N = 6, 7, 8
N_TABLE = 9
# Bits of T_OP_FLAGS.
F_LO = 1  # record a contact at the piece's start if it lies inside material
F_HI = 2  # record a contact at the piece's end if it lies inside material
F_LINKED = 4  # the row's contact points continue the previous row's (closer than the gap)
F_SECOND = 8  # the second piece of its row


@njit(cache=True, inline="always")
def _chords(table, r, orad, c_al, c_row, oc_al, oc_row, p_row, n_row, j0, j1, gap2, deep2):
    """Fill the chord table of rows j0..j1 for a disc of radius r (and the previous one of
    radius orad, -1 for none); returns the number of operations (``n_row``: the feed normal's
    component across the rows).

    Per row the half chord (-1 outside the disc) and its offset from the axis; per non-empty
    piece of the new chord outside the previous one (the first from the new chord's start to
    the previous chord's start, the second from the previous chord's end to the new chord's
    end) an operation. Contacts are recorded where the rays cross the circle at most 45
    degrees from their own direction (|dv| <= half): there consecutive rows' crossings lie at
    most sqrt(2) pitches apart, and the other row family samples the rest as densely.
    """
    r2 = r * r
    or2 = orad * orad
    prev_half = -1.0
    prev_dv = 0.0
    n_ops = 0
    for j in range(j0, j1 + 1):
        q = j - j0
        v = (j + 0.5) * p_row
        dv = v - c_row
        w = r2 - dv * dv
        table[T_DV, q] = dv
        # Points of the row closer than sqrt(deep2) to the axis: a removed piece reaching
        # into (cut_lo, cut_hi) is a cut (module notes, "Thin material").
        cut_w = deep2 - dv * dv
        cut_lo = math.inf
        cut_hi = -math.inf
        if cut_w > 0.0:
            cut_w = math.sqrt(cut_w)
            cut_lo = c_al - cut_w
            cut_hi = c_al + cut_w
        if w < 0.0:
            table[T_HALF, q] = -1.0
            prev_half = -1.0
            continue
        half = math.sqrt(w)
        table[T_HALF, q] = half
        b1 = c_al + half
        a2 = b1
        whole = True
        if orad > 0.0:
            odv = v - oc_row
            ow = or2 - odv * odv
            if ow >= 0.0:
                ohalf = math.sqrt(ow)
                oa = oc_al - ohalf
                ob = oc_al + ohalf
                if oa < b1 and ob > c_al - half:
                    b1 = oa
                    a2 = ob
                    whole = False
        flags = 0
        if half >= abs(dv):
            flags = F_LO | F_HI
            if prev_half >= 0.0 and (half - prev_half) ** 2 + (dv - prev_dv) ** 2 <= gap2:
                flags |= F_LINKED
            prev_half = half
            prev_dv = dv
        else:
            prev_half = -1.0
        fa0 = np.float32(c_al - half)
        fb0 = np.float32(b1)
        if fb0 > fa0:
            _op(
                table,
                n_ops,
                j,
                fa0,
                fb0,
                flags if whole else flags & ~F_HI,
                cut_lo,
                cut_hi,
                dv * n_row,
            )
            n_ops += 1
        fa1 = np.float32(a2)
        fb1 = np.float32(c_al + half)
        if fb1 > fa1:
            _op(table, n_ops, j, fa1, fb1, (flags & ~F_LO) | F_SECOND, cut_lo, cut_hi, dv * n_row)
            n_ops += 1
    return n_ops


@njit(cache=True, inline="always")
def _op(table, o, j, fa, fb, flags, cut_lo, cut_hi, dv_n):
    """Write operation o of the chord table (see N_TABLE)."""
    table[T_OP_ROW, o] = j
    table[T_OP_FA, o] = fa
    table[T_OP_FB, o] = fb
    table[T_OP_FLAGS, o] = flags
    table[T_OP_CUT_LO, o] = cut_lo
    table[T_OP_CUT_HI, o] = cut_hi
    table[T_OP_DV_N, o] = dv_n


@kernel
def _cut_rows(
    prm, ints, count, start, block, rows, heap_top, arc_slice, arc_lo, arc_hi, table, acc, along
):
    """Subtract the envelope from the x rays (``along == 0``) or the y rays (``along == 1``).

    Consecutive levels whose new and previous disc radii agree (the cylinder of the tool)
    share one chord table. Returns 0, or a status (heap or arcs full) with the levels done so
    far left done.
    """
    nz = ints[I_NZ]
    k0 = ints[I_K0]
    big, rc, length = prm[P_R], prm[P_RC], prm[P_L]
    inner, slope = prm[P_INNER], prm[P_SLOPE]
    tz, otz = prm[P_TZ], prm[P_OTZ]
    use_old = prm[P_USE_OLD] > 0.0
    pz = prm[P_PZ]
    gap2 = prm[P_GAP] * prm[P_GAP]
    fx, fy = prm[P_FX], prm[P_FY]
    if along == 0:
        c_al, c_row, oc_al, oc_row = prm[P_CX], prm[P_CY], prm[P_OCX], prm[P_OCY]
        f_al, f_row, n_al, n_row = fx, fy, -fy, fx
        p_row = prm[P_PY]
        n_rows = ints[I_NY]
    else:
        c_al, c_row, oc_al, oc_row = prm[P_CY], prm[P_CX], prm[P_OCY], prm[P_OCX]
        f_al, f_row, n_al, n_row = fy, fx, fx, -fy
        p_row = prm[P_PX]
        n_rows = ints[I_NX]
    removed_total = 0.0
    nmin, nmax = acc[A_NMIN], acc[A_NMAX]
    zmin, zmax = acc[A_ZMIN], acc[A_ZMAX]
    n_arcs = int(acc[A_ARCS])
    status = _DONE
    table_r = -2.0
    table_orad = -2.0
    n_ops = 0
    k1 = min(nz - 1, _cell_floor((tz + length) / pz - 0.5, nz))
    for k in range(max(k0, 0), k1 + 1):
        zk = (k + 0.5) * pz
        r = _radius(zk - tz, big, rc, inner, slope, length)
        if r <= 0.0:
            continue
        orad = _radius(zk - otz, big, rc, inner, slope, length) if use_old else -1.0
        s = k - k0
        j0 = max(0, _cell_ceil((c_row - r) / p_row - 0.5, n_rows))
        j1 = min(n_rows - 1, _cell_floor((c_row + r) / p_row - 0.5, n_rows))
        if n_arcs + 2 * (j1 - j0 + 2) > arc_slice.shape[0]:
            status = _ARCS_FULL
            break
        if r != table_r or orad != table_orad:
            # A removed piece is a cut when its point nearest the axis lies at least `thin`
            # inside the circle: closer than r - thin to the axis.
            thin = min(max(prm[P_THIN] / r, prm[P_THIN0]), 0.5 * r)
            deep2 = (r - thin) * (r - thin) if r > thin else -1.0
            n_ops = _chords(
                table, r, orad, c_al, c_row, oc_al, oc_row, p_row, n_row, j0, j1, gap2, deep2
            )
            table_r = r
            table_orad = orad
        level_cut = False
        # Open contact runs at the low (L) and high (H) chord ends: first and last row, and
        # whether a piece of the run is a cut (only then is the run a contact).
        first_l = last_l = first_h = last_h = -2
        cut_l = cut_h = False
        base_ray = k * n_rows
        hint0 = hint1 = 0
        for o in range(n_ops):
            j = int(table[T_OP_ROW, o])
            flags = int(table[T_OP_FLAGS, o])
            second = flags & F_SECOND
            st, removed, lo_in, hi_in, clo, chi, found = trim_interval(
                base_ray + j,
                np.float32(table[T_OP_FA, o]),
                np.float32(table[T_OP_FB, o]),
                hint1 if second else hint0,
                count,
                start,
                block,
                rows,
                heap_top,
            )
            if st != 0:
                status = _HEAP_FULL
                break
            if second:
                hint1 = found
            else:
                hint0 = found
            if removed <= 0.0:
                continue
            removed_total += removed
            is_cut = clo < table[T_OP_CUT_HI, o] and chi > table[T_OP_CUT_LO, o]
            if is_cut:
                dv_n = table[T_OP_DV_N, o]
                level_cut = True
                p_lo = (clo - c_al) * n_al + dv_n
                p_hi = (chi - c_al) * n_al + dv_n
                nmin = min(nmin, min(p_lo, p_hi))
                nmax = max(nmax, max(p_lo, p_hi))
            if lo_in and flags & F_LO:
                if last_l == j - 1 and flags & F_LINKED:
                    last_l = j
                    cut_l = cut_l or is_cut
                else:
                    if cut_l:
                        n_arcs = _emit_run(
                            s, first_l, last_l, -1.0, j0, table, f_al, f_row, n_al, n_row,
                            arc_slice, arc_lo, arc_hi, n_arcs,
                        )  # fmt: skip
                    first_l = last_l = j
                    cut_l = is_cut
            if hi_in and flags & F_HI:
                if last_h == j - 1 and flags & F_LINKED:
                    last_h = j
                    cut_h = cut_h or is_cut
                else:
                    if cut_h:
                        n_arcs = _emit_run(
                            s, first_h, last_h, 1.0, j0, table, f_al, f_row, n_al, n_row,
                            arc_slice, arc_lo, arc_hi, n_arcs,
                        )  # fmt: skip
                    first_h = last_h = j
                    cut_h = is_cut
        if cut_l:
            n_arcs = _emit_run(
                s, first_l, last_l, -1.0, j0, table, f_al, f_row, n_al, n_row, arc_slice,
                arc_lo, arc_hi, n_arcs,
            )  # fmt: skip
        if cut_h:
            n_arcs = _emit_run(
                s, first_h, last_h, 1.0, j0, table, f_al, f_row, n_al, n_row, arc_slice,
                arc_lo, arc_hi, n_arcs,
            )  # fmt: skip
        if level_cut:
            zmin = min(zmin, tz if s == 0 else max(tz, zk - 0.5 * pz))
            zmax = max(zmax, min(tz + length, zk + 0.5 * pz))
        if status != _DONE:
            break
    acc[A_LEN_X if along == 0 else A_LEN_Y] += removed_total
    acc[A_NMIN], acc[A_NMAX], acc[A_ZMIN], acc[A_ZMAX] = nmin, nmax, zmin, zmax
    acc[A_ARCS] = n_arcs
    return status


@kernel
def _emit_run(
    s, first, last, side, j0, table, f_al, f_row, n_al, n_row, arc_slice, arc_lo, arc_hi, n
):
    """Emit a run of contacts at one chord end (side -1 low, +1 high) from row `first` to row
    `last` of slice s as an arc (out of line: runs end rarely)."""
    qa = first - j0
    qb = last - j0
    return _emit_arc(
        s, side * table[T_HALF, qa], table[T_DV, qa], side * table[T_HALF, qb], table[T_DV, qb],
        f_al, f_row, n_al, n_row, arc_slice, arc_lo, arc_hi, n,
    )  # fmt: skip


@kernel
def _cut(
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
):
    """All three families. Returns 0; ``1 + 10 f`` when family f's (z 0, x 1, y 2) heap is
    full; 2 when the arc buffer is full.

    The families' arrays come one by one (a tuple argument would cost the dispatcher ~0.4 ms).
    """
    # The row families first: their rays stay in the cache from step to step, while the z
    # rays of the crescent are new to it every step (z last measured 4% faster a step).
    st = _cut_rows(
        prm, ints, x_count, x_start, x_block, x_rows, x_heap_top, arc_slice, arc_lo, arc_hi,
        table, acc, 0,
    )  # fmt: skip
    if st != _DONE:
        return st if st == _ARCS_FULL else st + 10
    st = _cut_rows(
        prm, ints, y_count, y_start, y_block, y_rows, y_heap_top, arc_slice, arc_lo, arc_hi,
        table, acc, 1,
    )  # fmt: skip
    if st != _DONE:
        return st if st == _ARCS_FULL else st + 20
    st = _cut_z(
        prm, ints, z_count, z_start, z_block, z_rows, z_heap_top, arc_slice, arc_lo, arc_hi, acc
    )
    if st != _DONE:
        return st
    return _DONE


class Workspace:
    """Work arrays of one stock (private to the geometry package).

    The growable contact-arc buffer (slice, lowest and highest angle in rad), the chord table
    of one level (:func:`_chords`), and the engagement's work and output arrays, sized by the
    arc capacity and the grid's z levels (see :mod:`cnctwin.geometry.engagement`).
    """

    __slots__ = (
        "_cut_arrays",
        "_version",
        "acc",
        "first",
        "grid",
        "hi",
        "iv_angles",
        "iv_slice",
        "lo",
        "order",
        "outputs",
        "pa",
        "parameters",
        "pb",
        "ra",
        "rb",
        "slice",
        "slices",
        "stats",
        "table",
        "thin0",
    )

    def __init__(self, stock: DexelStock, arcs: int = _INITIAL_ARCS) -> None:
        grid = stock.grid
        nz = grid.shape[2]
        px, py, pz = grid.pitch_mm
        #: (origin x, y, z, pitch x, y, z, cells x, y, z, size x, y, z, arc gap), mm.
        self.grid = (
            *grid.origin_mm,
            px,
            py,
            pz,
            *grid.shape,
            *grid.size_mm,
            GAP_PITCHES * max(px, py),
        )
        #: The thinnest cut, mm: a few float32 spacings at the grid's far end.
        self.thin0 = _THIN_ULPS * float(np.spacing(np.float32(max(grid.size_mm))))
        self.table = np.zeros((N_TABLE, 2 * max(stock.grid.shape[0], stock.grid.shape[1]) + 4))
        self.first = np.zeros(nz + 2, dtype=np.int64)
        self.slices = np.zeros((3, nz + 1))
        self.stats = np.zeros(5)
        #: The accumulators of the cut in progress (kept while buffers grow).
        self.acc = np.zeros(N_ACC)
        #: The kernel parameters of each cutter used on this stock (see :func:`parameters`).
        self.parameters: dict[Cutter, tuple[np.ndarray, np.ndarray]] = {}
        #: Output buffers of one position (kept by :func:`cnctwin.geometry.engagement.cut`).
        self.outputs: object = None
        self._size(arcs)
        self._version = -1
        self._cut_arrays: tuple[np.ndarray, ...] = ()

    slice: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    order: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    pa: np.ndarray
    pb: np.ndarray
    iv_slice: np.ndarray
    iv_angles: np.ndarray

    def _size(self, arcs: int) -> None:
        self.slice = np.zeros(arcs, dtype=np.int32)
        self.lo = np.zeros(arcs)
        self.hi = np.zeros(arcs)
        self.order = np.zeros(arcs, dtype=np.int64)
        self.ra = np.zeros(arcs + 1)
        self.rb = np.zeros(arcs + 1)
        self.pa = np.zeros(2 * arcs + 4)
        self.pb = np.zeros(2 * arcs + 4)
        self.iv_slice = np.zeros(2 * arcs + 1, dtype=np.int64)
        self.iv_angles = np.zeros((2, 2 * arcs + 1))

    def grow_arcs(self) -> None:
        """Double the arc capacity, keeping the arcs written so far."""
        old = (self.slice, self.lo, self.hi)
        self._size(2 * self.slice.shape[0])
        for new, kept in zip((self.slice, self.lo, self.hi), old, strict=True):
            new[: kept.shape[0]] = kept
        self._version = -1

    def cut_arrays(self, stock: DexelStock) -> tuple[np.ndarray, ...]:
        """The arrays :func:`_cut` takes between its parameters and its accumulators: the
        stock's families (z, x, y), the arcs and the chord table (cached until either
        changes)."""
        if self._version != stock.version:
            self._cut_arrays = (
                *stock.family_arrays("z"),
                *stock.family_arrays("x"),
                *stock.family_arrays("y"),
                self.slice,
                self.lo,
                self.hi,
                self.table,
            )
            self._version = stock.version
        return self._cut_arrays


_WORKSPACES: weakref.WeakKeyDictionary[DexelStock, Workspace] = weakref.WeakKeyDictionary()


def workspace(stock: DexelStock) -> Workspace:
    """The stock's :class:`Workspace` (private to the geometry package)."""
    ws = _WORKSPACES.get(stock)
    if ws is None:
        ws = _WORKSPACES[stock] = Workspace(stock)
    return ws


class ContactRecord(NamedTuple):
    """Where the envelope met material in one cut.

    Attributes
    ----------
    tip_grid_mm
        Tool tip in grid coordinates (relative to the grid origin), mm.
    feed_dir
        Unit feed direction (x, y) of the angle frame.
    first_level
        Grid z level of slice 0 (the lowest level at or above the tip).
    n_slices
        Slices: grid z levels inside the fluted length and the grid.
    arc_slice, arc_lo_rad, arc_hi_rad
        (q,) contact arcs: slice, and angles ``lo`` in [0, 2 pi), ``hi`` in ``[lo, lo + pi]``
        (rad; ``hi`` may exceed 2 pi when the arc crosses phi = 0), in no particular order.
    n_extent_mm
        (lowest, highest) coordinate of removed material along the feed normal ``n`` (mm,
        from the tool axis); (inf, -inf) when nothing was removed.
    z_extent_mm
        (lowest, highest) z of removed material, grid coordinates (mm).
    bottom_contact
        The flat bottom face of a flat or bull-nose tool cut material while moving down (a
        plunge or a ramp; the first cut of a stock counts as moving down).
    above_flutes
        Material at the top of the fluted length inside the tool's footprint: the shank or
        holder would hit it.
    """

    tip_grid_mm: tuple[float, float, float]
    feed_dir: tuple[float, float]
    first_level: int
    n_slices: int
    arc_slice: np.ndarray
    arc_lo_rad: np.ndarray
    arc_hi_rad: np.ndarray
    n_extent_mm: tuple[float, float]
    z_extent_mm: tuple[float, float]
    bottom_contact: bool
    above_flutes: bool


class Removal(NamedTuple):
    """The result of subtracting one envelope.

    Attributes
    ----------
    removed_volume_mm3
        Removed volume in mm^3, the mean of the three families (as
        :meth:`DexelStock.volume_mm3`), >= 0.
    family_removed_mm3
        Removed volume of the z, x and y families in mm^3.
    contact
        Where the envelope met material.
    """

    removed_volume_mm3: float
    family_removed_mm3: tuple[float, float, float]
    contact: ContactRecord


class Step(NamedTuple):
    """The kernel inputs of one cut (private to the geometry package; see :func:`prepare`)."""

    prm: np.ndarray
    ints: np.ndarray
    acc: np.ndarray
    reaches: bool


def xyz_mm(value: object, name: str) -> tuple[float, float, float]:
    """Three finite floats (x, y, z) from a sequence or array.

    Raises
    ------
    ConfigError
        When ``value`` is not three finite numbers; the message names ``name``.
    """
    try:
        # An array's values as Python numbers (faster to unpack than numpy scalars).
        u, v, w = (
            value.tolist() if isinstance(value, np.ndarray) else cast("Sequence[float]", value)
        )
        x, y, z = float(u), float(v), float(w)
    except (TypeError, ValueError):
        raise ConfigError(f"{name}={value!r}; give three finite numbers (x, y, z) mm") from None
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ConfigError(f"{name}={value!r}; give three finite numbers (x, y, z) mm")
    return x, y, z


def parameters(ws: Workspace, cutter: Cutter) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' parameter arrays (float64, int64) for ``cutter`` on the workspace's grid
    (kept in the workspace); :func:`place` fills in a position."""
    cached = ws.parameters.get(cutter)
    if cached is not None:
        return cached
    ox0, oy0, oz0, px, py, pz, nx, ny, nz, sx, sy, sz, gap = ws.grid
    prm = np.zeros(_N_PRM)
    prm[P_R] = 0.5 * cutter.diameter_mm
    prm[P_RC] = cutter.corner_radius_mm
    prm[P_L] = cutter.flute_length_mm
    prm[P_PX], prm[P_PY], prm[P_PZ] = px, py, pz
    prm[P_GAP] = gap
    prm[P_THIN0] = ws.thin0
    prm[P_INNER] = cutter.flat_radius_mm
    prm[P_SLOPE] = math.tan(0.5 * cutter.tip_angle_rad)
    prm[P_SX], prm[P_SY], prm[P_SZ] = sx, sy, sz
    ints = np.array([nx, ny, nz, 0, 0], dtype=np.int64)
    ws.parameters[cutter] = (prm, ints)
    return prm, ints


@njit(cache=True, inline="always")
def place(prm, ints, tx, ty, tz, ox, oy, oz, use_old, fx, fy):
    """Set the tip (tx, ty, tz), the previous cut's tip (ox, oy, oz; grid coordinates, mm; used
    when ``use_old``) and the unit feed direction (fx, fy) in the parameters; returns whether
    the envelope can reach the grid."""
    prm[P_CX], prm[P_CY], prm[P_TZ] = tx, ty, tz
    prm[P_OCX], prm[P_OCY], prm[P_OTZ] = ox, oy, oz
    prm[P_USE_OLD] = 1.0 if use_old else 0.0
    prm[P_FX], prm[P_FY] = fx, fy
    step2 = (tx - ox) * (tx - ox) + (ty - oy) * (ty - oy) if use_old else 0.0
    prm[P_THIN] = THIN_CUSPS * step2 / 8.0
    big, length, pz = prm[P_R], prm[P_L], prm[P_PZ]
    k0 = max(0, _cell_ceil(tz / pz - 0.5, ints[I_NZ]))
    k1 = min(ints[I_NZ] - 1, _cell_floor((tz + length) / pz - 0.5, ints[I_NZ]))
    ints[I_K0] = k0
    ints[I_NSLICES] = max(0, k1 - k0 + 1)
    return -big < tx < prm[P_SX] + big and -big < ty < prm[P_SY] + big and -length < tz < prm[P_SZ]


@njit(cache=True, inline="always")
def reset_accumulators(acc):
    """Set the accumulators to their start values (nothing removed yet)."""
    for q in range(acc.shape[0]):
        acc[q] = 0.0
    acc[A_NMIN] = acc[A_ZMIN] = math.inf
    acc[A_NMAX] = acc[A_ZMAX] = -math.inf


def last_tip(stock: DexelStock, cutter: Cutter) -> tuple[float, float, float] | None:
    """Tip (grid coordinates, mm) of the stock's last cut if ``cutter`` made it, else None."""
    last = stock.last_cut
    if last is not None and (last[0] is cutter or last[0] == cutter):
        return last[1]
    return None


def prepare(
    stock: DexelStock,
    ws: Workspace,
    cutter: Cutter,
    tip_mm: tuple[float, float, float],
    feed_dir: tuple[float, float],
) -> Step:
    """Kernel parameters for cutting ``stock`` with ``cutter``'s tip at ``tip_mm`` (machine
    coordinates, mm); records the cut as the stock's last."""
    origin = ws.grid[:3]
    tx, ty, tz = tip_mm[0] - origin[0], tip_mm[1] - origin[1], tip_mm[2] - origin[2]
    prm, ints = parameters(ws, cutter)
    old = last_tip(stock, cutter)
    ox, oy, oz = old if old is not None else (0.0, 0.0, 0.0)
    reaches = place(prm, ints, tx, ty, tz, ox, oy, oz, old is not None, feed_dir[0], feed_dir[1])
    acc = np.empty(N_ACC)
    reset_accumulators(acc)
    stock.last_cut = (cutter, (tx, ty, tz))
    return Step(prm, ints, acc, bool(reaches))


def grow_for(status: int, stock: DexelStock, ws: Workspace) -> None:
    """Make room after a kernel stopped with ``status`` (a full heap or arc buffer)."""
    if status == _ARCS_FULL:
        ws.grow_arcs()
    else:
        stock.grow_heap(AXES[status // 10])


def removed_volumes_mm3(stock: DexelStock, acc: np.ndarray) -> tuple[float, float, float]:
    """Removed volume of the z, x and y families (mm^3) from a kernel's accumulators."""
    px, py, pz = stock.grid.pitch_mm
    return (
        float(acc[A_LEN_Z]) * px * py,
        float(acc[A_LEN_X]) * py * pz,
        float(acc[A_LEN_Y]) * px * pz,
    )


def remove(
    stock: DexelStock,
    cutter: Cutter,
    position_mm: np.ndarray | tuple[float, float, float],
    feed_dir: tuple[float, float] = (1.0, 0.0),
) -> Removal:
    """Subtract ``cutter``'s envelope with its tip at ``position_mm`` from ``stock``.

    Parameters
    ----------
    stock
        The stock, changed in place.
    cutter
        The cutter; its axis is +z.
    position_mm
        Tool tip (x, y, z) in machine coordinates, mm (``SampleChunk.tcp_mm``).
    feed_dir
        Unit feed direction (x, y) defining the angle frame of the contact record.

    Returns
    -------
    Removal
        Removed volume (mm^3) and the contact record.

    Raises
    ------
    ConfigError
        On a position that is not three finite numbers.

    Notes
    -----
    Discrete-position method (Heide 2025, Sec. 2.2): the envelope at this position only, not the
    volume swept since the last one. :func:`cnctwin.geometry.cut` does this and computes the
    engagement in one call.
    """
    ws = workspace(stock)
    step = prepare(stock, ws, cutter, xyz_mm(position_mm, "position_mm"), feed_dir)
    while step.reaches:
        status = _cut(step.prm, step.ints, *ws.cut_arrays(stock), step.acc)
        if status == _DONE:
            break
        grow_for(status, stock, ws)
    acc = step.acc
    family = removed_volumes_mm3(stock, acc)
    n_arcs = int(acc[A_ARCS])
    record = ContactRecord(
        tip_grid_mm=(float(step.prm[P_CX]), float(step.prm[P_CY]), float(step.prm[P_TZ])),
        feed_dir=(float(feed_dir[0]), float(feed_dir[1])),
        first_level=int(step.ints[I_K0]),
        n_slices=int(step.ints[I_NSLICES]),
        arc_slice=ws.slice[:n_arcs].copy(),
        arc_lo_rad=ws.lo[:n_arcs].copy(),
        arc_hi_rad=ws.hi[:n_arcs].copy(),
        n_extent_mm=(float(acc[A_NMIN]), float(acc[A_NMAX])),
        z_extent_mm=(float(acc[A_ZMIN]), float(acc[A_ZMAX])),
        bottom_contact=bool(acc[A_BOTTOM]),
        above_flutes=bool(acc[A_ABOVE]),
    )
    return Removal((family[0] + family[1] + family[2]) / 3.0, family, record)
