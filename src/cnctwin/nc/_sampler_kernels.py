"""Numba kernels of the trajectory sampler (private; see :mod:`cnctwin.nc.sampler`).

Units: lengths in mm, speeds in mm/s, accelerations in mm/s^2, times in s, angles in rad.

Three kernels share the column layouts below:

* :func:`build_geometry` turns raw segment rows (as read from :class:`~cnctwin.nc.segments.Segment`
  objects) into per-segment geometry and kinematic limits, dropping segments that take no time;
* :func:`plan_backward` is the lookahead's backward pass (exit speed limits, stop assumed at the
  end of the buffer);
* :func:`run` walks the segments in motion phases of constant path acceleration and writes the
  samples at ``t_k = k * dt`` into the output arrays. It is resumable: all its state lives in two
  small arrays, so it can stop when the output is full and go on at the next call.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Raw input rows, one per Segment, built by the sampler (float64).
R_KIND = 0
R_LINE = 1
R_START = 2  # 3 columns, machine coordinates of the controlled point, mm
R_END = 5  # 3 columns
R_FEED = 8  # mm/min
R_RPM = 9
R_CENTER = 10  # 3 columns, NaN when the segment has no centre
R_TURNS = 13
R_DWELL = 14  # s
N_RAW = 15

# State table rows (float64): tool offset x, y, z (mm), plane index (0 XY, 1 ZX, 2 YZ), tool.
S_OFFSET = 0
S_PLANE = 3
S_TOOL = 4

# Geometry rows (float64), tool-tip (TCP) frame.
G_KIND = 0
G_LINE = 1
G_P0 = 2  # 3 columns: TCP at the start, mm
G_DIR = 5  # 3 columns: lines: unit direction; arcs: centre (first, second) and normal start, mm
G_LEN = 8  # path length, mm
G_R0 = 9  # arcs: radius at the start, mm
G_DR = 10  # arcs: end radius minus start radius, mm
G_TH0 = 11  # arcs: start angle, rad
G_SWEEP = 12  # arcs: signed sweep, rad
G_H = 13  # arcs: travel along the plane normal, mm
G_PLANE = 14  # plane index
G_SPEED = 15  # programmed path speed at 100 % override, mm/s (rapid rate for rapids)
G_DWELL = 16  # s
G_RPM = 17
G_TOOL = 18
G_VCAP = 19  # path speed limit from axis velocity and centripetal limits, mm/s
G_ACC = 20  # admissible path acceleration, mm/s^2
G_JUNC = 21  # entry junction speed limit, mm/s
G_TIN = 22  # 3 columns: unit tangent at the start
G_TOUT = 25  # 3 columns: unit tangent at the end
N_GEO = 28

KIND_RAPID = 0
KIND_LINEAR = 1
KIND_ARC = 2
KIND_DWELL = 3

# Carry between geometry batches: has previous, previous was a dwell, its vcap, its end tangent.
P_HAS = 0
P_DWELL = 1
P_VCAP = 2
P_TOUT = 3
N_PREV = 6

# Error codes of build_geometry.
ERR_NONE = 0
ERR_FEED = 1
ERR_NO_CENTER = 2
ERR_DWELL = 3
ERR_NOT_FINITE = 4

# Float state of run().
F_T = 0  # time at the current state, s
F_S = 1  # distance along the current segment, mm
F_V = 2  # path speed, mm/s
F_T0 = 3  # phase start time, s
F_T1 = 4  # phase end time, s
F_S0 = 5  # phase start distance, mm
F_V0 = 6  # phase start speed, mm/s
F_A = 7  # phase path acceleration, mm/s^2
F_S1 = 8  # phase end distance, mm
F_V1 = 9  # phase end speed, mm/s
N_FSTATE = 10

# Integer state of run().
I_J = 0  # current segment (row of the geometry buffer)
I_K = 1  # next sample index
I_HAVE = 2  # a phase is pending
I_ENDS = 3  # the pending phase ends its segment
I_FEED_IDX = 4  # feed-override cursor
I_RAPID_IDX = 5  # rapid-override cursor
I_PLANNED = 6  # the backward pass is valid for the buffer
I_PLAN_FEED = 7  # feed-override index the plan used
I_PLAN_RAPID = 8  # rapid-override index the plan used
N_ISTATE = 9

# Segment-end samples of run(): none; all but the tangent junctions of two feed moves; every
# segment.
ENDS_NONE = 0
ENDS_KIND = 1
ENDS_ALL = 2
#: ENDS_KIND samples the junction of two feed moves whose direction turns by more than this
#: (rad): a step spanning such a corner cuts the chord, not the corner (see _end_sampled).
CORNER_RAD = 1e-3
CORNER_COS = math.cos(CORNER_RAD)
#: A segment end this close to a sample time (in cycles) falls on it (segment-end samples).
END_TOLERANCE = 1e-9
#: Segments shorter than this (mm) and without dwell take no time.
MIN_LENGTH_MM = 1e-9
#: Share of an in-plane axis' acceleration left to the tangential acceleration on arcs; the
#: centripetal acceleration gets sqrt(1 - share^2), so their vector sum stays within the limit.
ARC_TANGENTIAL_SHARE = 0.5
ARC_NORMAL_SHARE = math.sqrt(1.0 - ARC_TANGENTIAL_SHARE**2)
#: Junctions whose direction change is below about 3e-6 rad count as tangent.
TANGENT_SIN_HALF = 1.0 - 1e-12

TWO_PI = 2.0 * math.pi


@njit(cache=True)
def plane_axes(plane: int) -> tuple[int, int, int]:
    """(first, second, normal) axis indices of plane index 0 (XY), 1 (ZX) or 2 (YZ)."""
    if plane == 0:
        return 0, 1, 2
    if plane == 1:
        return 2, 0, 1
    return 1, 2, 0


@njit(cache=True)
def _axis_limited(value: float, u: np.ndarray, limit: np.ndarray) -> float:
    """min(value, limit_i / |u_i|) over the axes with a component."""
    for i in range(3):
        c = abs(u[i])
        if c > 0.0:
            value = min(value, limit[i] / c)
    return value


@njit(cache=True)
def build_geometry(
    raw: np.ndarray,
    state_index: np.ndarray,
    states: np.ndarray,
    rapid_mm_s: float,
    acc_mm_s2: np.ndarray,
    vmax_mm_s: np.ndarray,
    junction_deviation_mm: float,
    limited: bool,
    prev: np.ndarray,
    geo: np.ndarray,
) -> tuple[int, int, int]:
    """Geometry and limits of a batch of raw segment rows.

    Writes one row of ``geo`` per segment that takes time, in order, and updates ``prev``.
    Returns (rows written, error code, raw row of the error).
    """
    m = 0
    p0 = np.empty(3)
    p1 = np.empty(3)
    cen = np.empty(3)
    tin = np.empty(3)
    tout = np.empty(3)
    for i in range(raw.shape[0]):
        kind = int(raw[i, R_KIND])
        st = state_index[i]
        for a in range(3):
            off = states[st, S_OFFSET + a]
            p0[a] = raw[i, R_START + a] - off
            p1[a] = raw[i, R_END + a] - off
            cen[a] = raw[i, R_CENTER + a] - off
        row = geo[m]
        row[G_KIND] = kind
        row[G_LINE] = raw[i, R_LINE]
        row[G_RPM] = raw[i, R_RPM]
        row[G_TOOL] = states[st, S_TOOL]
        row[G_P0 : G_P0 + 3] = p0
        if kind == KIND_DWELL:
            dwell = raw[i, R_DWELL]
            if not (dwell >= 0.0 and math.isfinite(dwell)):
                return m, ERR_DWELL, i
            if not (math.isfinite(p0[0]) and math.isfinite(p0[1]) and math.isfinite(p0[2])):
                return m, ERR_NOT_FINITE, i
            if dwell == 0.0:
                continue
            row[G_DWELL] = dwell
            row[G_LEN] = 0.0
            row[G_SPEED] = 0.0
            row[G_VCAP] = 0.0
            row[G_ACC] = math.inf
            row[G_JUNC] = 0.0
            prev[P_HAS] = 1.0
            prev[P_DWELL] = 1.0
            m += 1
            continue
        row[G_DWELL] = 0.0
        plane = int(states[st, S_PLANE])
        if kind == KIND_ARC:
            if math.isnan(cen[0]) or math.isnan(cen[1]) or math.isnan(cen[2]):
                return m, ERR_NO_CENTER, i
            i0, i1, i2 = plane_axes(plane)
            u0 = p0[i0] - cen[i0]
            v0 = p0[i1] - cen[i1]
            u1 = p1[i0] - cen[i0]
            v1 = p1[i1] - cen[i1]
            a0 = math.atan2(v0, u0)
            a1 = math.atan2(v1, u1)
            r0 = math.hypot(u0, v0)
            r1 = math.hypot(u1, v1)
            # Same sweep rule as cnctwin.nc.segments.arc_sweep_rad (checked by a test).
            turns = raw[i, R_TURNS]
            extra = (abs(turns) - 1.0) * TWO_PI if turns != 0.0 else 0.0
            sweep = a1 - a0
            if turns >= 0.0:
                if sweep <= 1e-12:
                    sweep += TWO_PI
                sweep += extra
            else:
                if sweep >= -1e-12:
                    sweep -= TWO_PI
                sweep -= extra
            h = p1[i2] - p0[i2]
            dr = r1 - r0
            # Radius linear in the angle: the planar length is the mean radius times the sweep.
            length = math.hypot(0.5 * (r0 + r1) * sweep, h)
            row[G_DIR + 0] = cen[i0]
            row[G_DIR + 1] = cen[i1]
            row[G_DIR + 2] = p0[i2]
            row[G_R0] = r0
            row[G_DR] = dr
            row[G_TH0] = a0
            row[G_SWEEP] = sweep
            row[G_H] = h
            if length > 0.0:
                _arc_tangent(tin, plane, a0, r0, dr, sweep, h)
                _arc_tangent(tout, plane, a0 + sweep, r1, dr, sweep, h)
        else:
            length = math.sqrt((p1[0] - p0[0]) ** 2 + (p1[1] - p0[1]) ** 2 + (p1[2] - p0[2]) ** 2)
            if length > 0.0:
                for a in range(3):
                    tin[a] = (p1[a] - p0[a]) / length
                    tout[a] = tin[a]
                row[G_DIR : G_DIR + 3] = tin
        if not math.isfinite(length):
            return m, ERR_NOT_FINITE, i
        if length <= MIN_LENGTH_MM:
            continue
        row[G_LEN] = length
        row[G_PLANE] = plane
        if kind == KIND_RAPID:
            row[G_SPEED] = rapid_mm_s
        else:
            feed = raw[i, R_FEED]
            if not (feed > 0.0 and math.isfinite(feed)):
                return m, ERR_FEED, i
            row[G_SPEED] = feed / 60.0
        row[G_TIN : G_TIN + 3] = tin
        row[G_TOUT : G_TOUT + 3] = tout
        if limited:
            if kind == KIND_ARC:
                vcap, acc = _arc_limits(row, acc_mm_s2, vmax_mm_s)
            else:
                vcap = _axis_limited(math.inf, tin, vmax_mm_s)
                acc = _axis_limited(math.inf, tin, acc_mm_s2)
            junc = 0.0
            if prev[P_HAS] != 0.0 and prev[P_DWELL] == 0.0:
                junc = _junction_speed(
                    prev[P_TOUT : P_TOUT + 3], tin, acc_mm_s2, junction_deviation_mm
                )
                junc = min(junc, vcap, prev[P_VCAP])
        else:
            vcap = math.inf
            acc = math.inf
            junc = math.inf
        row[G_VCAP] = vcap
        row[G_ACC] = acc
        row[G_JUNC] = junc
        prev[P_HAS] = 1.0
        prev[P_DWELL] = 0.0
        prev[P_VCAP] = vcap
        prev[P_TOUT : P_TOUT + 3] = tout
        m += 1
    return m, ERR_NONE, -1


@njit(cache=True)
def _arc_tangent(
    out: np.ndarray, plane: int, phi: float, r: float, dr: float, sweep: float, h: float
) -> None:
    """Unit tangent of an arc at angle phi (rad) where the radius is r (mm)."""
    i0, i1, i2 = plane_axes(plane)
    c = math.cos(phi)
    sn = math.sin(phi)
    out[i0] = dr * c - r * sweep * sn
    out[i1] = dr * sn + r * sweep * c
    out[i2] = h
    nrm = math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2)
    for a in range(3):
        out[a] /= nrm


@njit(cache=True)
def _arc_limits(
    row: np.ndarray, acc_mm_s2: np.ndarray, vmax_mm_s: np.ndarray
) -> tuple[float, float]:
    """(speed limit mm/s, path acceleration limit mm/s^2) of an arc, worst case over a full turn.

    The tangent makes the angle alpha with the plane; an in-plane axis sees at most
    cos(alpha) of the path velocity and acceleration, the normal axis sin(alpha). In the plane
    the tangential share is ARC_TANGENTIAL_SHARE of the axis limit and the centripetal
    acceleration (v cos(alpha))^2 / r_min at most ARC_NORMAL_SHARE of it.
    """
    i0, i1, i2 = plane_axes(int(row[G_PLANE]))
    r0 = row[G_R0]
    r1 = r0 + row[G_DR]
    length = row[G_LEN]
    cos_a = 0.5 * (r0 + r1) * abs(row[G_SWEEP]) / length
    sin_a = abs(row[G_H]) / length
    vcap = math.inf
    acc = math.inf
    if cos_a > 0.0:
        a_plane = min(acc_mm_s2[i0], acc_mm_s2[i1])
        vcap = min(vmax_mm_s[i0], vmax_mm_s[i1]) / cos_a
        acc = ARC_TANGENTIAL_SHARE * a_plane / cos_a
        r_min = min(r0, r1)
        vcap = min(vcap, math.sqrt(ARC_NORMAL_SHARE * a_plane * r_min) / cos_a)
    if sin_a > 0.0:
        vcap = min(vcap, vmax_mm_s[i2] / sin_a)
        acc = min(acc, acc_mm_s2[i2] / sin_a)
    return vcap, acc


@njit(cache=True)
def _junction_speed(
    t_prev: np.ndarray, t_next: np.ndarray, acc_mm_s2: np.ndarray, deviation_mm: float
) -> float:
    """Junction speed limit in mm/s after the junction-deviation model (as grbl).

    The corner is replaced, for the speed limit only, by a circle tangent to both directions
    whose distance to the corner is ``deviation_mm``; the centripetal acceleration on it is
    limited by the axis accelerations along the corner's bisector (direction t_next - t_prev).
    """
    cos_theta = -(t_prev[0] * t_next[0] + t_prev[1] * t_next[1] + t_prev[2] * t_next[2])
    sin_half = math.sqrt(max(0.0, 0.5 * (1.0 - cos_theta)))
    if sin_half >= TANGENT_SIN_HALF:
        return math.inf
    d = np.empty(3)
    for a in range(3):
        d[a] = t_next[a] - t_prev[a]
    nrm = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    for a in range(3):
        d[a] /= nrm
    acc = _axis_limited(math.inf, d, acc_mm_s2)
    return math.sqrt(acc * deviation_mm * sin_half / (1.0 - sin_half))


@njit(cache=True)
def _target(geo: np.ndarray, j: int, feed_ov: float, rapid_ov: float) -> float:
    """Target path speed of segment j in mm/s under the given overrides."""
    ov = rapid_ov if int(geo[j, G_KIND]) == KIND_RAPID else feed_ov
    speed: float = min(geo[j, G_SPEED] * ov, geo[j, G_VCAP])
    return speed


@njit(cache=True)
def plan_backward(
    geo: np.ndarray, j0: int, n_buf: int, vexit: np.ndarray, feed_ov: float, rapid_ov: float
) -> None:
    """Exit speed limits of segments j0..n_buf-1, assuming a stop at the end of the buffer."""
    nxt = 0.0
    for i in range(n_buf - 1, j0 - 1, -1):
        vexit[i] = nxt
        if int(geo[i, G_KIND]) == KIND_DWELL:
            nxt = 0.0
            continue
        reach = math.sqrt(nxt * nxt + 2.0 * geo[i, G_ACC] * geo[i, G_LEN])
        entry = min(geo[i, G_JUNC], _target(geo, i, feed_ov, rapid_ov), reach)
        if i > j0:
            entry = min(entry, _target(geo, i - 1, feed_ov, rapid_ov))
        nxt = entry


@njit(cache=True)
def _cursor(times: np.ndarray, t: float, idx: int) -> int:
    """Advance an override cursor: the last index with times[idx] <= t (0 before the first)."""
    n = times.shape[0]
    while idx + 1 < n and times[idx + 1] <= t:
        idx += 1
    return idx


@njit(cache=True)
def _next_break(times: np.ndarray, idx: int) -> float:
    return times[idx + 1] if idx + 1 < times.shape[0] else math.inf


@njit(cache=True)
def _next_phase(
    geo: np.ndarray,
    vexit: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    feed_ov: float,
    rapid_ov: float,
    t_break: float,
    limited: bool,
) -> None:
    """Plan the next motion phase of segment ist[I_J] from the state (t, s, v) in fs."""
    j = ist[I_J]
    t = fs[F_T]
    s = fs[F_S]
    v = fs[F_V]
    kind = int(geo[j, G_KIND])
    if kind == KIND_DWELL:
        fs[F_T0] = t
        fs[F_T1] = t + geo[j, G_DWELL]
        fs[F_S0] = 0.0
        fs[F_V0] = 0.0
        fs[F_A] = 0.0
        fs[F_S1] = 0.0
        fs[F_V1] = 0.0
        ist[I_ENDS] = 1
        ist[I_HAVE] = 1
        return
    length = geo[j, G_LEN]
    c = _target(geo, j, feed_ov, rapid_ov)
    rem = length - s
    acc = 0.0
    ends = 0
    hold = False
    if not limited:
        v = c
        if c <= 0.0:
            hold = True
            s_end = s
        else:
            s_end = length
            ends = 1
        v_end = c
    else:
        a = geo[j, G_ACC]
        ve = vexit[j]
        vb = math.sqrt(ve * ve + 2.0 * a * rem)
        tol = 1e-9 * max(1.0, v)
        if v > c + tol:
            # Slow down to a lowered target (override or feed change).
            acc = -a
            v_l2 = v * v - 2.0 * a * rem
            if v_l2 <= c * c:
                s_end = min(s + (v * v - c * c) / (2.0 * a), length)
                v_end = c
            else:
                s_end = length
                v_end = math.sqrt(v_l2)
                ends = 1
        elif v >= vb - tol:
            # On (or, after an override drop, above) the braking curve: decelerate to the end.
            acc = -a
            s_end = length
            v_end = ve if v <= vb + tol else math.sqrt(v * v - 2.0 * a * rem)
            ends = 1
        elif v < c - tol:
            acc = a
            s_c = s + (c * c - v * v) / (2.0 * a)
            s_x = s + (ve * ve - v * v + 2.0 * a * rem) / (4.0 * a)
            if s_c <= s_x and s_c < length:
                s_end = s_c
                v_end = c
            elif s_x < length:
                s_end = s_x
                v_end = math.sqrt(v * v + 2.0 * a * (s_x - s))
            else:
                s_end = length
                v_end = math.sqrt(v * v + 2.0 * a * rem)
                ends = 1
        else:
            v = c
            v_end = c
            if c <= 0.0:
                hold = True
                s_end = s
            elif c <= ve:
                s_end = length
                ends = 1
            else:
                s_end = max(s, length - (c * c - ve * ve) / (2.0 * a))
    if hold:
        duration = t_break - t
    elif v + v_end > 0.0:
        duration = 2.0 * (s_end - s) / (v + v_end)
    else:
        duration = 0.0
    t_end = t + duration
    if t_end > t_break:
        tau = t_break - t
        s_end = min(s + v * tau + 0.5 * acc * tau * tau, length)
        v_end = max(v + acc * tau, 0.0)
        t_end = t_break
        ends = 0
    fs[F_T0] = t
    fs[F_T1] = t_end
    fs[F_S0] = s
    fs[F_V0] = v
    fs[F_A] = acc
    fs[F_S1] = s_end
    fs[F_V1] = v_end
    ist[I_ENDS] = ends
    ist[I_HAVE] = 1


@njit(cache=True)
def run(
    geo: np.ndarray,
    n_buf: int,
    n_exec: int,
    vexit: np.ndarray,
    feed_t: np.ndarray,
    feed_v: np.ndarray,
    rapid_t: np.ndarray,
    rapid_v: np.ndarray,
    limited: bool,
    dt: float,
    ends: int,
    fs: np.ndarray,
    ist: np.ndarray,
    out_t: np.ndarray,
    out_p: np.ndarray,
    out_v: np.ndarray,
    out_speed: np.ndarray,
    out_line: np.ndarray,
    out_kind: np.ndarray,
    out_tool: np.ndarray,
    out_rpm: np.ndarray,
    n_out: int,
) -> int:
    """Sample segments up to n_exec (exclusive) or until the output is full; returns n_out.

    With ``ends`` (``ENDS_ALL``: every segment; ``ENDS_KIND``: all but a feed move followed
    tangentially by a feed move of the same tool, see :func:`_end_sampled`) a segment also
    gives a sample at its end time, labelled with it: the grid sample there when the end falls
    on the grid (within ``END_TOLERANCE * dt``), else an extra one; none when a grid sample of
    the segment already lies that close before its end.
    """
    cap = out_t.shape[0]
    while True:
        if ist[I_HAVE] == 0:
            j = ist[I_J]
            if j >= n_exec:
                return n_out
            t = fs[F_T]
            fi = _cursor(feed_t, t, ist[I_FEED_IDX])
            ri = _cursor(rapid_t, t, ist[I_RAPID_IDX])
            ist[I_FEED_IDX] = fi
            ist[I_RAPID_IDX] = ri
            if limited and (
                ist[I_PLANNED] == 0 or ist[I_PLAN_FEED] != fi or ist[I_PLAN_RAPID] != ri
            ):
                plan_backward(geo, j, n_buf, vexit, feed_v[fi], rapid_v[ri])
                ist[I_PLANNED] = 1
                ist[I_PLAN_FEED] = fi
                ist[I_PLAN_RAPID] = ri
            t_break = min(_next_break(feed_t, fi), _next_break(rapid_t, ri))
            _next_phase(geo, vexit, fs, ist, feed_v[fi], rapid_v[ri], t_break, limited)
        j = ist[I_J]
        t0 = fs[F_T0]
        t1 = fs[F_T1]
        s0 = fs[F_S0]
        v0 = fs[F_V0]
        acc = fs[F_A]
        k = ist[I_K]
        row = geo[j]
        kind = int(row[G_KIND])
        length = row[G_LEN]
        while k * dt < t1:
            if n_out >= cap:
                ist[I_K] = k
                return n_out
            tk = k * dt
            tau = tk - t0
            s = min(max(s0 + v0 * tau + 0.5 * acc * tau * tau, 0.0), length)
            v = max(v0 + acc * tau, 0.0)
            _emit(row, kind, s, v, out_p, out_v, n_out)
            out_t[n_out] = tk
            out_speed[n_out] = 60.0 * v
            out_line[n_out] = int(row[G_LINE])
            out_kind[n_out] = kind
            out_tool[n_out] = int(row[G_TOOL])
            out_rpm[n_out] = row[G_RPM]
            n_out += 1
            k += 1
        if (
            ist[I_ENDS] != 0
            and _end_sampled(geo, j, n_buf, ends)
            and not (k > 0 and (k - 1) * dt > t1 - END_TOLERANCE * dt)
        ):
            if n_out >= cap:
                ist[I_K] = k
                return n_out
            tk = t1
            if k * dt - t1 <= END_TOLERANCE * dt:
                tk = k * dt  # the end is on the grid: the grid sample is the end sample
                k += 1
            _emit(row, kind, length, fs[F_V1], out_p, out_v, n_out)
            out_t[n_out] = tk
            out_speed[n_out] = 60.0 * fs[F_V1]
            out_line[n_out] = int(row[G_LINE])
            out_kind[n_out] = kind
            out_tool[n_out] = int(row[G_TOOL])
            out_rpm[n_out] = row[G_RPM]
            n_out += 1
        ist[I_K] = k
        fs[F_T] = t1
        fs[F_S] = fs[F_S1]
        fs[F_V] = fs[F_V1]
        if ist[I_ENDS] != 0:
            ist[I_J] = j + 1
            fs[F_S] = 0.0
        ist[I_HAVE] = 0


@njit(cache=True)
def _end_sampled(geo: np.ndarray, j: int, n_buf: int, ends: int) -> bool:
    """Whether segment j's end gets a sample of its own in mode ``ends`` (ENDS_*): with
    ENDS_KIND, unless it and the next segment are both feed moves (linear or arc) of the same
    tool that meet at a tangent (direction change at most ``CORNER_RAD``; the buffer holds the
    next one unless the program ends with j).

    A step spanning a corner moves the tool along the chord between its two positions: the tool
    never stands at the corner, and leaves a sliver of the material the corner's position
    removes (up to ``s sin(theta) / 4`` thick for a step ``s`` turning by ``theta``). A later
    pass along the same wall (the next layer) would remove that sliver as if it were a chip of
    the full feed per tooth, over the whole height of the wall: a force spike that is no cut.
    """
    if ends == ENDS_NONE:
        return False
    if ends == ENDS_ALL or j + 1 >= n_buf:
        return True
    here = int(geo[j, G_KIND])
    there = int(geo[j + 1, G_KIND])
    feeds = here in (KIND_LINEAR, KIND_ARC) and there in (KIND_LINEAR, KIND_ARC)
    if not feeds or geo[j, G_TOOL] != geo[j + 1, G_TOOL]:
        return True
    turn = 0.0
    for a in range(3):
        turn += geo[j, G_TOUT + a] * geo[j + 1, G_TIN + a]
    return turn < CORNER_COS


@njit(cache=True)
def _emit(
    row: np.ndarray, kind: int, s: float, v: float, out_p: np.ndarray, out_v: np.ndarray, n: int
) -> None:
    """TCP position (mm) and velocity (mm/s) at distance s (mm) and path speed v (mm/s)."""
    if kind == KIND_DWELL:
        for a in range(3):
            out_p[n, a] = row[G_P0 + a]
            out_v[n, a] = 0.0
        return
    if kind != KIND_ARC:
        for a in range(3):
            u = row[G_DIR + a]
            out_p[n, a] = row[G_P0 + a] + u * s
            out_v[n, a] = u * v
        return
    i0, i1, i2 = plane_axes(int(row[G_PLANE]))
    length = row[G_LEN]
    f = s / length
    sweep = row[G_SWEEP]
    dr = row[G_DR]
    h = row[G_H]
    phi = row[G_TH0] + sweep * f
    r = row[G_R0] + dr * f
    c = math.cos(phi)
    sn = math.sin(phi)
    out_p[n, i0] = row[G_DIR + 0] + r * c
    out_p[n, i1] = row[G_DIR + 1] + r * sn
    out_p[n, i2] = row[G_DIR + 2] + h * f
    k = v / length
    out_v[n, i0] = (dr * c - r * sweep * sn) * k
    out_v[n, i1] = (dr * sn + r * sweep * c) * k
    out_v[n, i2] = h * k
