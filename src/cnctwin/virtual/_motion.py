"""Live path following: an interpreted NC program executed tick by tick with live overrides.

:class:`~cnctwin.nc.sampler.TrajectorySampler` samples a program whose overrides are known in
advance; a machine learns its overrides while it runs. :class:`PathFollower` therefore executes
the interpreter's segments one tick at a time, with the feed override, feed hold and stop read
at every tick, under the same motion model as the sampler (see :mod:`cnctwin.nc.sampler`):

* the controlled point moves along the segment by arc length; arcs and helices are
  interpolated exactly (angle, radius and travel along the normal linear in the arc length);
* the path speed approaches its target (``feed x override`` for feed moves, the rapid rate for
  rapids, 0 in a hold) with the segment's path acceleration ``min_i a_i / |u_i|`` (half of the
  in-plane axes' acceleration on arcs, whose speed is also capped by the centripetal
  acceleration ``v^2 / r <= sqrt(3)/2 a``); axis velocity limits cap it the same way;
* junctions: grbl's junction deviation (``v^2 = a delta sin(theta/2) / (1 - sin(theta/2))``),
  tangent junctions keep their speed; a one-segment lookahead assumes a stop at the end of the
  next segment, so the speed at a junction is also at most ``sqrt(2 a L_next)``; the program
  stops at every dwell and at its end.

Within a tick the motion is integrated exactly, phase by phase (accelerate, cruise, brake), so
the time to run a segment does not depend on the tick. Units: mm, mm/s, mm/s^2, s.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

from cnctwin.nc import PLANE_AXES, MotionKind, Plane, Segment, arc_sweep_rad

__all__ = ["Move", "PathFollower"]

_EPS_MM = 1e-9
_MAX_PHASES = 100_000  # per tick: a safeguard against a zero-time loop


@dataclass(slots=True)
class Move:
    """One segment, prepared for following.

    Attributes
    ----------
    segment
        The interpreter's segment.
    length_mm
        Path length, mm.
    feed_mm_s
        Programmed feed, mm/s (0 for rapids and dwells).
    accel_mm_s2
        Path acceleration limit, mm/s^2.
    vmax_mm_s
        Path speed limit from the axes (velocity, centripetal acceleration), mm/s.
    u_start, u_end
        Unit tangents at the start and the end.
    arc
        For arcs: (first axis, second axis, normal axis, centre first, centre second, start
        radius, end radius, start angle, sweep, normal start, normal end).
    """

    segment: Segment
    length_mm: float
    feed_mm_s: float
    accel_mm_s2: float
    vmax_mm_s: float
    u_start: tuple[float, float, float]
    u_end: tuple[float, float, float]
    arc: tuple[int, int, int, float, float, float, float, float, float, float, float] | None

    def point(self, s_mm: float) -> tuple[float, float, float]:
        """Controlled point (machine coordinates, mm) at arc length ``s_mm`` from the start."""
        seg = self.segment
        if self.arc is None or self.length_mm <= 0.0:
            if self.length_mm <= 0.0:
                return seg.end_mm
            f = min(s_mm / self.length_mm, 1.0)
            a, b = seg.start_mm, seg.end_mm
            return (a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f)
        i0, i1, n, c0, c1, r0, r1, a0, sweep, n0, n1 = self.arc
        f = min(s_mm / self.length_mm, 1.0)
        angle = a0 + sweep * f
        r = r0 + (r1 - r0) * f
        p = [0.0, 0.0, 0.0]
        p[i0] = c0 + r * math.cos(angle)
        p[i1] = c1 + r * math.sin(angle)
        p[n] = n0 + (n1 - n0) * f
        return (p[0], p[1], p[2])

    def tangent(self, s_mm: float) -> tuple[float, float, float]:
        """Unit tangent of the path (direction of travel) at arc length ``s_mm``, mm/mm."""
        if self.arc is None or self.length_mm <= 0.0:
            return self.u_start
        i0, i1, n, _c0, _c1, r0, r1, a0, sweep, n0, n1 = self.arc
        f = min(max(s_mm / self.length_mm, 0.0), 1.0)
        angle = a0 + sweep * f
        r = r0 + (r1 - r0) * f
        t = [0.0, 0.0, 0.0]
        t[i0] = (r1 - r0) * math.cos(angle) - r * sweep * math.sin(angle)
        t[i1] = (r1 - r0) * math.sin(angle) + r * sweep * math.cos(angle)
        t[n] = n1 - n0
        return _unit((t[0], t[1], t[2]))


def _unit(v: tuple[float, float, float]) -> tuple[float, float, float]:
    norm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if norm <= 0.0:
        return (0.0, 0.0, 0.0)
    return (v[0] / norm, v[1] / norm, v[2] / norm)


def _prepare(
    seg: Segment,
    rapid_mm_s: float,
    accel_mm_s2: tuple[float, float, float],
    velocity_mm_s: tuple[float, float, float],
) -> Move:
    """A :class:`Move` of a segment, with its limits (mm, mm/s, mm/s^2)."""
    kind = seg.kind
    feed = seg.feed_mm_min / 60.0 if kind in (MotionKind.LINEAR, MotionKind.ARC) else 0.0
    if kind == MotionKind.DWELL:
        zero = (0.0, 0.0, 0.0)
        return Move(seg, 0.0, 0.0, math.inf, 0.0, zero, zero, None)
    if kind == MotionKind.ARC and seg.center_mm is not None:
        plane = Plane(seg.state.plane)
        i0, i1, n = PLANE_AXES[plane]
        s, e, c = seg.start_mm, seg.end_mm, seg.center_mm
        r0, a0, sweep = arc_sweep_rad(s, e, c, seg.turns, plane)
        r1 = math.hypot(e[i0] - c[i0], e[i1] - c[i1])
        dn = e[n] - s[n]
        length = math.hypot(0.5 * (r0 + r1) * sweep, dn)
        arc = (i0, i1, n, c[i0], c[i1], r0, r1, a0, sweep, s[n], e[n])
        tangents = []
        for angle, r in ((a0, r0), (a0 + sweep, r1)):
            t = [0.0, 0.0, 0.0]
            dr = r1 - r0
            t[i0] = dr * math.cos(angle) - r * sweep * math.sin(angle)
            t[i1] = dr * math.sin(angle) + r * sweep * math.cos(angle)
            t[n] = dn
            tangents.append(_unit((t[0], t[1], t[2])))
        a_plane = min(accel_mm_s2[i0], accel_mm_s2[i1])
        helix = abs(dn) / length if length > 0.0 else 0.0
        accel = 0.5 * a_plane
        if helix > 0.0:
            accel = min(accel, accel_mm_s2[n] / helix)
        radius = max(min(r0, r1), _EPS_MM)
        vmax = min(
            min(velocity_mm_s[i0], velocity_mm_s[i1]),
            math.sqrt(math.sqrt(3.0) / 2.0 * a_plane * radius),
        )
        if helix > 0.0:
            vmax = min(vmax, velocity_mm_s[n] / helix)
        return Move(seg, length, feed, accel, vmax, tangents[0], tangents[1], arc)
    s, e = seg.start_mm, seg.end_mm
    d = (e[0] - s[0], e[1] - s[1], e[2] - s[2])
    length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    u = _unit(d)
    accel = math.inf
    vmax = math.inf
    for axis in range(3):
        if abs(u[axis]) > 1e-12:
            accel = min(accel, accel_mm_s2[axis] / abs(u[axis]))
            vmax = min(vmax, velocity_mm_s[axis] / abs(u[axis]))
    if kind == MotionKind.RAPID:
        vmax = min(vmax, rapid_mm_s)
    return Move(seg, length, feed, accel, vmax, u, u, None)


class PathFollower:
    """Executes segments tick by tick with a live feed override and hold.

    Parameters
    ----------
    segments
        The interpreted program (consumed lazily, one segment ahead).
    rapid_mm_min
        Rapid rate, mm/min.
    accel_mm_s2, velocity_mm_s
        Axis acceleration (mm/s^2) and velocity (mm/s) limits of X, Y, Z.
    junction_deviation_mm
        grbl's junction deviation, mm (0: exact stop at every corner).
    start_mm
        Controlled point before the program, machine coordinates, mm.
    """

    def __init__(
        self,
        segments: Iterator[Segment],
        *,
        rapid_mm_min: float,
        accel_mm_s2: tuple[float, float, float],
        velocity_mm_s: tuple[float, float, float],
        junction_deviation_mm: float,
        start_mm: tuple[float, float, float],
    ) -> None:
        self._segments = segments
        self._rapid_mm_s = rapid_mm_min / 60.0
        self._accel = accel_mm_s2
        self._velocity = velocity_mm_s
        self._deviation = junction_deviation_mm
        self._move: Move | None = None
        self._next: Move | None = None
        self._s = 0.0
        self._dwell_left = 0.0
        #: Path speed, mm/s.
        self.speed_mm_s = 0.0
        #: Controlled point, machine coordinates, mm.
        self.position_mm = start_mm
        #: Path length travelled during the last :meth:`advance`, mm.
        self.travelled_mm = 0.0
        self._exhausted = False
        self._move = self._fetch()
        self._next = self._fetch()
        self._enter()

    @property
    def move(self) -> Move | None:
        """The move being executed (``None`` once the program is done)."""
        return self._move

    @property
    def tangent(self) -> tuple[float, float, float]:
        """Unit tangent of the path at the controlled point (zero in a dwell or at the end)."""
        m = self._move
        if m is None or m.segment.kind == MotionKind.DWELL:
            return (0.0, 0.0, 0.0)
        return m.tangent(self._s)

    @property
    def finished(self) -> bool:
        """Whether every segment has been executed."""
        return self._move is None

    def _fetch(self) -> Move | None:
        if self._exhausted:
            return None
        seg = next(self._segments, None)
        if seg is None:
            self._exhausted = True
            return None
        return _prepare(seg, self._rapid_mm_s, self._accel, self._velocity)

    def _enter(self) -> None:
        """Skip empty moves; start the current one."""
        while self._move is not None:
            m = self._move
            if m.segment.kind == MotionKind.DWELL:
                self._dwell_left = m.segment.dwell_s
                if self._dwell_left > 0.0:
                    return
            elif m.length_mm > _EPS_MM:
                self._s = 0.0
                return
            self.position_mm = m.segment.end_mm
            self._move, self._next = self._next, self._fetch()

    def _target(self, m: Move, feed_factor: float) -> float:
        """Target path speed of a move, mm/s."""
        if m.segment.kind == MotionKind.RAPID:
            return m.vmax_mm_s
        return min(m.feed_mm_s * feed_factor, m.vmax_mm_s)

    def _junction(self, m: Move, feed_factor: float) -> float:
        """Highest speed (mm/s) at the end of move m into the next."""
        n = self._next
        if n is None or n.segment.kind == MotionKind.DWELL or n.length_mm <= _EPS_MM:
            return 0.0
        v = min(self._target(m, feed_factor), self._target(n, feed_factor))
        v = min(v, math.sqrt(2.0 * n.accel_mm_s2 * n.length_mm))
        cos_theta = -(
            m.u_end[0] * n.u_start[0] + m.u_end[1] * n.u_start[1] + m.u_end[2] * n.u_start[2]
        )
        if cos_theta > -0.999999:  # not tangent: junction deviation (grbl)
            sin_half = math.sqrt(max(0.5 * (1.0 - cos_theta), 0.0))
            if sin_half >= 1.0:
                return v
            a = min(m.accel_mm_s2, n.accel_mm_s2)
            v = min(v, math.sqrt(a * self._deviation * sin_half / (1.0 - sin_half)))
        return v

    def advance(self, dt_s: float, feed_factor: float, hold: bool) -> None:
        """Run the program for ``dt_s`` seconds.

        Parameters
        ----------
        dt_s
            Time, s (> 0).
        feed_factor
            Feed override, 1.0 = 100 % (feed moves only; rapids run at the rapid rate).
        hold
            Decelerate to a standstill and stay there (feed hold, stop); dwells pause too.
        """
        left = dt_s
        travelled = 0.0
        phases = 0
        while left > 0.0 and self._move is not None and phases < _MAX_PHASES:
            phases += 1
            m = self._move
            if m.segment.kind == MotionKind.DWELL:
                if hold:
                    break
                take = min(left, self._dwell_left)
                self._dwell_left -= take
                left -= take
                if self._dwell_left <= 0.0:
                    self._move, self._next = self._next, self._fetch()
                    self._enter()
                continue
            a = m.accel_mm_s2
            target = 0.0 if hold else self._target(m, feed_factor)
            v_end = 0.0 if hold else self._junction(m, feed_factor)
            v = self.speed_mm_s
            d_left = m.length_mm - self._s
            room = v_end * v_end + 2.0 * a * d_left  # v^2 the brake curve allows here
            if v > 0.0 and v * v >= room * (1.0 - 1e-9):
                # On (or over) the brake curve: brake to v_end at the end of the move.
                decel = (v * v - v_end * v_end) / (2.0 * d_left) if d_left > _EPS_MM else math.inf
                decel = max(decel, a)
                t_end = (v - v_end) / decel if v > v_end else d_left / max(v, _EPS_MM)
                if t_end <= left:
                    travelled += d_left
                    left -= t_end
                    self.speed_mm_s = v_end
                    self._finish_move()
                    continue
                v_new = v - decel * left
                step = 0.5 * (v + v_new) * left
                self._s += step
                travelled += step
                self.speed_mm_s = v_new
                left = 0.0
                break
            if v < target - 1e-12:
                t_acc = (target - v) / a
                t_curve = (-v + math.sqrt(0.5 * (v * v + room))) / a
                t = min(t_acc, t_curve, left)
                step = v * t + 0.5 * a * t * t
                v = v + a * t
            elif v > target + 1e-12:
                t = min((v - target) / a, left)
                step = v * t - 0.5 * a * t * t
                v = v - a * t
            else:
                v = target
                if v <= 0.0:
                    break  # held, at rest
                t_cruise = (d_left - (v * v - v_end * v_end) / (2.0 * a)) / v
                if t_cruise <= 0.0:
                    # At the brake point (to rounding): put the point on the brake curve.
                    self.speed_mm_s = v
                    self._s = min(self._s, m.length_mm - (v * v - v_end * v_end) / (2.0 * a))
                    self._s = max(self._s, 0.0)
                    continue
                t = min(t_cruise, left)
                step = v * t
            step = min(step, d_left)
            self._s += step
            travelled += step
            self.speed_mm_s = v
            left -= t
            if self._s >= m.length_mm - _EPS_MM:
                self._finish_move()
        if self._move is not None and self._move.segment.kind != MotionKind.DWELL:
            self.position_mm = self._move.point(self._s)
        self.travelled_mm = travelled

    def _finish_move(self) -> None:
        m = self._move
        assert m is not None  # only called while a move runs
        self.position_mm = m.segment.end_mm
        self._move, self._next = self._next, self._fetch()
        self._s = 0.0
        self._enter()
        if self._move is None or self._move.segment.kind == MotionKind.DWELL:
            self.speed_mm_s = 0.0
