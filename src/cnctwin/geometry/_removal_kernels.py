"""Numba kernels of material removal (private; see :mod:`cnctwin.geometry.removal`).

Units: mm, rad; positions in grid coordinates (mm from the grid origin).

The one definition of what the removal kernels share with their callers (the removal's and the
engagement's Python side, :mod:`cnctwin.geometry._engagement_kernels`): the layouts of the
parameter arrays (``P_*`` float64, ``I_*`` int64, filled by :func:`place`), of the accumulators
(``A_*``, started by :func:`reset_accumulators`) and of the chord table (``T_*``); the kernel
statuses; and the arrays :func:`cut` takes, :class:`CutArrays`. The method is described in
:mod:`cnctwin.geometry.removal`.

Changing a kernel here: numba caches a kernel that calls these by its own module's content alone
(:mod:`cnctwin.geometry._engagement_kernels` compiles :func:`cut` into its path kernel), so
delete ``geometry/__pycache__/*.nbi`` and ``*.nbc`` after editing this file or
:mod:`cnctwin.geometry._dexel_kernels`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from cnctwin.geometry._dexel_kernels import Family, subtract_interval, trim_interval

__all__ = [
    "A_ABOVE",
    "A_ARCS",
    "A_BOTTOM",
    "A_LEN_X",
    "A_LEN_Y",
    "A_LEN_Z",
    "A_NMAX",
    "A_NMIN",
    "A_ZMAX",
    "A_ZMIN",
    "ARCS_FULL",
    "DONE",
    "GAP_PITCHES",
    "I_K0",
    "I_NSLICES",
    "I_NX",
    "I_NY",
    "I_NZ",
    "SLICE_TIP_PITCHES",
    "N_ACC",
    "N_INTS",
    "N_PRM",
    "N_TABLE",
    "P_CX",
    "P_CY",
    "P_FX",
    "P_FY",
    "P_GAP",
    "P_INNER",
    "P_L",
    "P_PX",
    "P_PY",
    "P_PZ",
    "P_R",
    "P_RC",
    "P_SLOPE",
    "P_SX",
    "P_SY",
    "P_SZ",
    "P_THIN0",
    "P_TZ",
    "THIN_CUSPS",
    "THIN_ULPS",
    "Arcs",
    "CutArrays",
    "cut",
    "cut_arrays",
    "fast_atan2",
    "kernel",
    "place",
    "plain",
    "reset_accumulators",
    "slice_low",
]

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
THIN_ULPS = 4.0

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
N_PRM = 23

# Integer parameters (int64 array).
I_NX, I_NY, I_NZ, I_K0, I_NSLICES = range(5)

#: A slice reaches down to the tip when its level is less than this many z pitches above it
#: (:func:`slice_low`).
SLICE_TIP_PITCHES = 1.0 - 1e-9
N_INTS = 5

# Accumulators (float64 array), kept across a rerun after a buffer grew.
A_LEN_Z, A_LEN_X, A_LEN_Y = 0, 1, 2  # removed length per family, mm
A_NMIN, A_NMAX = 3, 4  # extent of removed material along the feed normal, mm from the axis
A_ZMIN, A_ZMAX = 5, 6  # extent of removed material along z, grid coordinates, mm
A_BOTTOM = 7  # 1.0: the flat bottom face cut material moving down
A_ABOVE = 8  # 1.0: material at the top of the fluted length
A_ARCS = 9  # contact arcs written

N_ACC = 10  # accumulators (their start values: reset_accumulators)

# Kernel status.
DONE = 0
HEAP_FULL = 1  # plus 10 x the family index (z 0, x 1, y 2)
ARCS_FULL = 2

# Atan on [0, 1] as an odd polynomial (least squares on Chebyshev nodes, max error 2.7e-7 rad,
# checked in tests/geometry/test_removal.py).
_ATAN_C0 = 0.99999663
_ATAN_C1 = -0.33318301
_ATAN_C2 = 0.198132
_ATAN_C3 = -0.13247467
_ATAN_C4 = 0.07981017
_ATAN_C5 = -0.03372501
_ATAN_C6 = 0.00684231


class Arcs(NamedTuple):
    """The contact-arc buffer (see :class:`cnctwin.geometry.removal.ContactRecord`)."""

    #: int32 (capacity,): slice of each arc.
    slice: np.ndarray
    #: float64 (capacity,): lowest angle, rad, in [0, 2 pi).
    lo: np.ndarray
    #: float64 (capacity,): highest angle, rad, in [lo, lo + pi].
    hi: np.ndarray


class CutArrays(NamedTuple):
    """The arrays :func:`cut` takes besides its parameters and accumulators."""

    z: Family
    x: Family
    y: Family
    arcs: Arcs
    #: float64 (N_TABLE, 2 max(nx, ny) + 4): the chord table of one level group (T_* rows).
    table: np.ndarray


def plain(bundle: tuple[object, ...]) -> tuple[object, ...]:
    """``bundle`` (a NamedTuple of arrays and NamedTuples) as nested plain tuples: numba's
    dispatcher types those in about 0.3 us, NamedTuples in about 3 us a call."""
    return tuple(plain(v) if isinstance(v, tuple) else v for v in bundle)


@njit(cache=True, inline="always")
def cut_arrays(arrays):
    """The :class:`CutArrays` of ``plain(CutArrays)``."""
    return CutArrays(
        Family(*arrays[0]), Family(*arrays[1]), Family(*arrays[2]), Arcs(*arrays[3]), arrays[4]
    )


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
def _emit_arc(s, a0, v0, a1, v1, f_al, f_row, n_al, n_row, arcs, n):
    """Append the contact arc of slice s from point (a0, v0) to (a1, v1) (mm from the axis,
    along the ray and across it) to the :class:`Arcs`: lo in [0, 2 pi), hi - lo in [0, pi]."""
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
    arcs.slice[n] = s
    arcs.lo[n] = lo
    arcs.hi[n] = lo + span
    return n + 1


@kernel
def _cut_z(prm, ints, family, arcs, acc):
    """Subtract the envelope from the z rays (``family``, a :class:`Family`).

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
    status = DONE
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
        if n_arcs + (i1 - i0 + 1) > arcs.slice.shape[0]:
            status = ARCS_FULL
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
                    r, np.float32(a), np.float32(b), 0, family
                )
                if st != 0:
                    status = HEAP_FULL
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
                n_arcs = _emit_arc(s, dx, dy, dx, dy, fx, fy, -fy, fx, arcs, n_arcs)
            if status != DONE:
                break
        if status != DONE:
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
def _cut_rows(prm, ints, family, arcs, table, acc, along):
    """Subtract the envelope from the x rays (``along == 0``) or the y rays (``along == 1``),
    ``family`` (a :class:`Family`).

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
    status = DONE
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
        if n_arcs + 2 * (j1 - j0 + 2) > arcs.slice.shape[0]:
            status = ARCS_FULL
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
                family,
            )
            if st != 0:
                status = HEAP_FULL
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
                            arcs, n_arcs,
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
                            arcs, n_arcs,
                        )  # fmt: skip
                    first_h = last_h = j
                    cut_h = is_cut
        if cut_l:
            n_arcs = _emit_run(
                s, first_l, last_l, -1.0, j0, table, f_al, f_row, n_al, n_row, arcs, n_arcs,
            )  # fmt: skip
        if cut_h:
            n_arcs = _emit_run(
                s, first_h, last_h, 1.0, j0, table, f_al, f_row, n_al, n_row, arcs, n_arcs,
            )  # fmt: skip
        if level_cut:
            zmin = min(zmin, slice_low(zk, tz, pz))
            zmax = max(zmax, min(tz + length, zk + 0.5 * pz))
        if status != DONE:
            break
    acc[A_LEN_X if along == 0 else A_LEN_Y] += removed_total
    acc[A_NMIN], acc[A_NMAX], acc[A_ZMIN], acc[A_ZMAX] = nmin, nmax, zmin, zmax
    acc[A_ARCS] = n_arcs
    return status


@kernel
def _emit_run(s, first, last, side, j0, table, f_al, f_row, n_al, n_row, arcs, n):
    """Emit a run of contacts at one chord end (side -1 low, +1 high) from row `first` to row
    `last` of slice s as an arc (out of line: runs end rarely)."""
    qa = first - j0
    qb = last - j0
    return _emit_arc(
        s, side * table[T_HALF, qa], table[T_DV, qa], side * table[T_HALF, qb], table[T_DV, qb],
        f_al, f_row, n_al, n_row, arcs, n,
    )  # fmt: skip


@kernel
def cut(prm, ints, arrays, acc):
    """Subtract the envelope (parameters ``prm``, ``ints`` as set by :func:`place`) from the
    three families of ``arrays`` (``plain(CutArrays)``: the dispatcher's fast path), adding to
    the accumulators ``acc``. Returns DONE; ``HEAP_FULL + 10 f`` when family f's (z 0, x 1,
    y 2) heap is full; ARCS_FULL when the arc buffer is full (grow it and call again: the rays
    done so far stay done).
    """
    named = cut_arrays(arrays)
    # The row families first: their rays stay in the cache from step to step, while the z
    # rays of the crescent are new to it every step (z last measured 4% faster a step).
    st = _cut_rows(prm, ints, named.x, named.arcs, named.table, acc, 0)
    if st != DONE:
        return st if st == ARCS_FULL else st + 10
    st = _cut_rows(prm, ints, named.y, named.arcs, named.table, acc, 1)
    if st != DONE:
        return st if st == ARCS_FULL else st + 20
    st = _cut_z(prm, ints, named.z, named.arcs, acc)
    if st != DONE:
        return st
    return DONE


@njit(cache=True, inline="always")
def slice_low(level_z, tip_z, pz):
    """Lowest height (grid z, mm) of the tool that the slice at level ``level_z`` stands for,
    with the tip at ``tip_z`` and the grid's z pitch ``pz`` (mm): the tip when the level lies
    less than a pitch above it (the lowest slice reaches down to the tip; ``SLICE_TIP_PITCHES``
    keeps the next level, a pitch up to float rounding, out), else half a pitch below the
    level. A tip further down is below the grid's lowest level, where there is no material:
    the slice must not stand for the tool down there (an ``ap`` past the stock's bottom, and
    overlapping slices for the force model). :func:`cnctwin.geometry.engagement.slice_low_mm`
    is the same rule on heights above the tip."""
    return tip_z if level_z - tip_z < SLICE_TIP_PITCHES * pz else level_z - 0.5 * pz


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
