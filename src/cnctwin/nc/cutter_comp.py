"""Cutter radius compensation (G41/G42, G41.1/G42.1) on lines and arcs, as LinuxCNC does it.

The interpreter hands :class:`CutterCompensator` the *programmed* moves one at a time
(machine coordinates of the controlled point, mm, uncompensated); the compensator holds
the latest move until it knows the next one, because the end of a compensated move
depends on the corner it makes with the following move. Semantics, each checked
against LinuxCNC's canonical-call traces (``gcode_golden/linuxcnc/ccomp/*``,
``interp/inside-corners``, ``interp/crazy-paths``, ``interp/cam-nisley``):

* The tool is kept at the compensation radius ``r`` to the left (G41) or right (G42)
  of the programmed path, seen from the positive plane normal (+Z in G17, +Y in G18,
  +X in G19) looking along the direction of motion.
* **Entry move** (the first move in the plane after compensation is turned on) starts
  at the current, uncompensated position. A straight entry ends at its programmed end
  offset by ``r`` perpendicular to *its own* direction (not to the next move's); an
  arc entry ends on the offset arc (radius ``R -/+ r``) and gets a new centre on the
  line from the programmed centre through that end, equidistant from the start and the
  end, so that it meets the offset arc tangentially. The entry's end then takes part
  in the corner with the next move like any other end.
* **Tangent junctions**: the offset end of one move is the offset start of the next
  (closer than 0.0025 mm: LinuxCNC leaves gaps of 0.0007 mm alone, and inserts arcs
  from 0.0136 mm on); nothing is inserted and the next move starts exactly where the
  previous one ended.
* **Convex (outside) corners**, where the path turns away from the tool: both moves keep
  their offset ends; an arc of radius ``r`` centred on the programmed corner joins them
  (clockwise for G41, counter-clockwise for G42). It lies at the height (normal-axis
  position) of the corner and takes the line number, feed and state of the *following*
  move, and is emitted with the move before it.
* **Concave (inside) corners**, where the path turns toward the tool: the two offset
  paths (lines, or circles about the programmed centres through the offset *ends*) are
  intersected; the held move ends and the next starts at the intersection nearest the
  programmed corner.
* **Reversals** (the path turns back within 0.05 rad of 180 degrees, e.g. at a cusp
  between two arcs): the direction of the turn says little, so the corner is concave
  when the offset paths cut each other within both moves, and convex otherwise
  (``interp/inside-corners`` and ``interp/crazy-paths`` have both kinds).
* Moves without motion in the plane (e.g. Z-only moves in G17, dwells) pass through at
  the held position: they are emitted after the held move, at its final in-plane end.
* Errors (:class:`~cnctwin.errors.NCError`, with the move's file and line): an arc on
  whose inside the tool does not fit (``R <= r``); a concave corner whose offset paths do
  not meet, or whose trimming would run a move backwards (gouging); an arc in a plane
  other than the compensation plane.

Lathe tools (tool-table orientation ``Q`` 1-8) control their imaginary tool tip, not the
centre of the nose radius: in the ZX plane the compensated path of the nose centre is
shifted by ``r`` along Z and/or X to the tip (``ccomp/lathe-comp``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Final

from cnctwin.errors import NCError
from cnctwin.nc.segments import (
    PLANE_AXES,
    CutterComp,
    MotionKind,
    Plane,
    Segment,
    Vec3,
    arc_sweep_rad,
)

__all__ = ["LATHE_TIP_SHIFT", "CutterCompensator"]

_Vec2 = tuple[float, float]

#: Position of the imaginary tool tip relative to the nose-radius centre for each lathe
#: tool orientation (tool-table ``Q``), in units of the nose radius, as (dZ, dX) — the
#: (first, second) axes of the ZX plane. Orientations 0 and 9 control the nose centre.
#: Orientations 2 and 7 are checked against ``ccomp/lathe-comp``; the others follow from
#: LinuxCNC's orientation chart (and agree with the front/back angles ``I``/``J`` of the
#: oracle's tool table: the tip points away from the tool body).
LATHE_TIP_SHIFT: Final[dict[int, _Vec2]] = {
    0: (0.0, 0.0),
    1: (1.0, -1.0),
    2: (-1.0, -1.0),
    3: (-1.0, 1.0),
    4: (1.0, 1.0),
    5: (1.0, 0.0),
    6: (0.0, -1.0),
    7: (-1.0, 0.0),
    8: (0.0, 1.0),
    9: (0.0, 0.0),
}

#: Offset end and offset start closer than this (mm) make a tangent junction: the next
#: move starts where the held one ends. LinuxCNC's traces show no corner arc and no
#: trimming up to a gap of 0.0007 mm (inside-corners), and corners from 0.0136 mm on.
_TANGENT_GAP_MM: Final = 0.0025
#: sin of the angle within which a turn counts as a reversal (cusp) of the path.
_CUSP_SIN: Final = math.sin(0.05)
#: In-plane displacement (mm) below which a straight move has no motion in the plane.
_NO_MOTION_MM: Final = 1e-9


def _sub(a: _Vec2, b: _Vec2) -> _Vec2:
    return (a[0] - b[0], a[1] - b[1])


def _add(a: _Vec2, b: _Vec2) -> _Vec2:
    return (a[0] + b[0], a[1] + b[1])


def _scale(a: _Vec2, k: float) -> _Vec2:
    return (a[0] * k, a[1] * k)


def _dot(a: _Vec2, b: _Vec2) -> float:
    return a[0] * b[0] + a[1] * b[1]


def _cross(a: _Vec2, b: _Vec2) -> float:
    return a[0] * b[1] - a[1] * b[0]


def _perp(a: _Vec2) -> _Vec2:
    """``a`` turned 90 degrees counter-clockwise (its left normal)."""
    return (-a[1], a[0])


def _norm(a: _Vec2) -> float:
    return math.hypot(a[0], a[1])


def _unit(a: _Vec2) -> _Vec2:
    n = _norm(a)
    return (a[0] / n, a[1] / n)


def _wrap(angle: float) -> float:
    """``angle`` (rad) wrapped into (-pi, pi]."""
    return angle - 2.0 * math.pi * math.ceil((angle - math.pi) / (2.0 * math.pi))


@dataclass(frozen=True, slots=True)
class _Path:
    """One programmed move seen in the plane (nose-centre space), mm.

    A line has a unit ``direction``; an arc has a ``centre`` and a ``sense`` (+1 CCW,
    -1 CW); the other fields are ``None``. Its offset path is the parallel line through
    ``comp_start`` (and ``comp_end``), or the circle about ``centre`` through them.
    """

    start: _Vec2
    end: _Vec2
    direction: _Vec2 | None
    centre: _Vec2 | None
    sense: int
    comp_start: _Vec2
    comp_end: _Vec2
    t_start: _Vec2  # unit tangent at the start
    t_end: _Vec2  # unit tangent at the end
    rho_end: float  # arcs: offset radius through ``comp_end``, mm; 0 for lines
    sweep: float  # arcs: programmed swept angle, rad (signed); 0 for lines
    length: float  # length of the offset path, mm


@dataclass(slots=True)
class _Held:
    """The move held back until the next move decides its end."""

    seg: Segment
    path: _Path
    start: Vec3  # compensated start, nose-centre space, mm (final)
    end: _Vec2  # compensated end in the plane: nominal, or trimmed at a concave corner
    entry: bool


class CutterCompensator:
    """Cutter radius compensation of a stream of programmed moves, LinuxCNC style.

    Parameters
    ----------
    side
        :attr:`CutterComp.LEFT` (G41) or :attr:`CutterComp.RIGHT` (G42).
    radius_mm
        Compensation radius in mm (half the tool-table diameter, or half the G41.1 ``D``
        word). A negative radius compensates on the other side (LinuxCNC's meaning of a
        negative diameter); zero leaves the path unchanged.
    plane
        Plane of compensation; arcs must lie in it.
    position_mm
        Current position of the controlled point in machine coordinates, mm (the actual
        position, where the entry move starts).
    orientation
        Lathe tool orientation (tool-table ``Q``, 0-9). In the ZX plane, orientations
        1-8 shift the compensated path from the nose centre to the imaginary tool tip
        (see :data:`LATHE_TIP_SHIFT`); other planes ignore it.

    Raises
    ------
    cnctwin.errors.NCError
        If ``side`` is not LEFT or RIGHT, the radius is not finite, or ``orientation``
        is not 0-9.

    Notes
    -----
    Feed :meth:`push` every programmed move after G41/G42 and call :meth:`finish` at G40
    or at the end of the program; emit what they return, in order. After
    :meth:`finish` the next :meth:`push` is an entry move again.
    """

    def __init__(
        self,
        side: CutterComp,
        radius_mm: float,
        plane: Plane,
        position_mm: Vec3,
        orientation: int = 0,
    ) -> None:
        if side not in (CutterComp.LEFT, CutterComp.RIGHT):
            raise NCError(
                f"cutter radius compensation side must be LEFT (G41) or RIGHT (G42); got {side!r}"
            )
        if not math.isfinite(radius_mm):
            raise NCError(f"cutter radius compensation radius must be finite; got {radius_mm!r} mm")
        if orientation not in LATHE_TIP_SHIFT:
            raise NCError(f"lathe tool orientation must be 0 to 9; got {orientation!r}")
        sign = 1 if side == CutterComp.LEFT else -1
        if radius_mm < 0.0:
            sign = -sign
        self._side = sign
        self._r = abs(radius_mm)
        self._plane = plane
        self._axes = PLANE_AXES[plane]
        if plane == Plane.ZX:
            dz, dx = LATHE_TIP_SHIFT[orientation]
            self._shift: _Vec2 = (dz * self._r, dx * self._r)
        else:
            self._shift = (0.0, 0.0)
        self._pos: Vec3 = self._to_nose(position_mm)
        self._held: _Held | None = None
        self._waiting: list[Segment] = []

    # ------------------------------------------------------------------ public

    @property
    def position_mm(self) -> Vec3:
        """End of the last emitted segment (where the tool is), machine coordinates, mm."""
        return self._to_tip(self._pos)

    def push(self, seg: Segment) -> list[Segment]:
        """Take the next programmed move and return the compensated segments now known.

        Parameters
        ----------
        seg
            A RAPID, LINEAR or ARC move (a DWELL passes through), machine coordinates in
            mm, uncompensated; ``start_mm`` is the previous programmed end.

        Returns
        -------
        list[Segment]
            Zero or more compensated segments, in order: usually the previous move
            ending at its corner point, then (at a convex corner) the inserted corner arc.

        Raises
        ------
        cnctwin.errors.NCError
            For an arc the tool does not fit inside, a gouging concave corner, or an arc
            outside the compensation plane (with the move's file and line).
        """
        i0, i1, _ = self._axes
        if seg.kind == MotionKind.ARC and seg.state.plane != self._plane:
            raise self._error(
                seg,
                f"arc in plane G{int(seg.state.plane)} while cutter radius compensation is on in "
                f"plane G{int(self._plane)}; turn compensation off (G40) before changing planes",
            )
        planar = (
            seg.kind == MotionKind.ARC
            or math.hypot(seg.end_mm[i0] - seg.start_mm[i0], seg.end_mm[i1] - seg.start_mm[i1])
            > _NO_MOTION_MM
        )
        if not planar:
            if self._held is None:
                return [self._emit_through(seg)]
            self._waiting.append(seg)
            return []
        if self._held is None:
            self._held = self._entry(seg)
            return []
        return self._corner(self._held, seg)

    def finish(self) -> list[Segment]:
        """Emit what is held (at G40 or program end): the held move ends at its offset end.

        Returns
        -------
        list[Segment]
            The held move and the moves without motion in the plane that followed it.
            The next move (the exit move) starts at :attr:`position_mm`.

        Raises
        ------
        cnctwin.errors.NCError
            If the held move cannot be completed (see :meth:`push`).
        """
        if self._held is None:
            return []
        out = self._release(self._held)
        self._held = None
        return out

    # ------------------------------------------------------------------ geometry

    def _p2(self, p: Vec3) -> _Vec2:
        return (p[self._axes[0]], p[self._axes[1]])

    def _p3(self, p2: _Vec2, normal: float) -> Vec3:
        out = [0.0, 0.0, 0.0]
        i0, i1, i2 = self._axes
        out[i0], out[i1], out[i2] = p2[0], p2[1], normal
        return (out[0], out[1], out[2])

    def _to_nose(self, p: Vec3) -> Vec3:
        return self._p3(_sub(self._p2(p), self._shift), p[self._axes[2]])

    def _to_tip(self, p: Vec3) -> Vec3:
        return self._p3(_add(self._p2(p), self._shift), p[self._axes[2]])

    def _offset_radius(self, seg: Segment, radius: float, sense: int, at: str) -> float:
        """Radius of the offset arc where the programmed arc has radius ``radius`` (mm).

        A tool as large as an arc it cuts on the inside is accepted, as LinuxCNC does: the
        offset arc shrinks to its centre (radius 0).
        """
        rho = radius - self._side * sense * self._r
        if rho < -_NO_MOTION_MM:
            raise self._error(
                seg,
                f"cutter radius compensation: tool radius {self._r:.6g} mm is larger than the arc "
                f"radius {radius:.6g} mm at the arc's {at}; the tool must be no larger than an "
                "arc it cuts on the inside",
            )
        return max(rho, 0.0)

    def _path(self, seg: Segment, start: _Vec2) -> _Path:
        """Geometry and nominal offset of a programmed move starting at ``start``."""
        end = self._p2(seg.end_mm)
        if seg.kind != MotionKind.ARC:
            d = _unit(_sub(end, start))
            n = _scale(_perp(d), self._side * self._r)
            return _Path(
                start,
                end,
                d,
                None,
                0,
                _add(start, n),
                _add(end, n),
                d,
                d,
                0.0,
                0.0,
                _norm(_sub(end, start)),
            )
        if seg.center_mm is None:
            raise self._error(seg, "arc segment without a centre")
        c = self._p2(seg.center_mm)
        sense = 1 if seg.turns >= 0 else -1
        u_start, u_end = _sub(start, c), _sub(end, c)
        r_start, r_end = _norm(u_start), _norm(u_end)
        if r_start == 0.0 or r_end == 0.0:
            raise self._error(seg, "arc of zero radius under cutter radius compensation")
        rho_start = self._offset_radius(seg, r_start, sense, "start")
        rho_end = self._offset_radius(seg, r_end, sense, "end")
        u_start, u_end = _scale(u_start, 1.0 / r_start), _scale(u_end, 1.0 / r_end)
        sweep = arc_sweep_rad(seg.start_mm, seg.end_mm, seg.center_mm, seg.turns, self._plane)[2]
        return _Path(
            start,
            end,
            None,
            c,
            sense,
            _add(c, _scale(u_start, rho_start)),
            _add(c, _scale(u_end, rho_end)),
            _scale(_perp(u_start), sense),
            _scale(_perp(u_end), sense),
            rho_end,
            sweep,
            abs(sweep) * rho_end,
        )

    def _entry(self, seg: Segment) -> _Held:
        """Hold the entry move: it starts at the actual (uncompensated) position.

        A straight entry is offset perpendicular to the line from the actual position to
        its end; an arc entry is offset like the programmed arc (its centre is replaced
        when it is emitted, see :meth:`_entry_centre`).
        """
        here = self._p2(self._to_tip(self._pos))  # the actual point, in program geometry
        if seg.kind == MotionKind.ARC:
            path = self._path(seg, self._p2(seg.start_mm))
        elif _norm(_sub(self._p2(seg.end_mm), here)) <= _NO_MOTION_MM:
            raise self._error(
                seg,
                "cutter radius compensation: the entry move ends where the tool already is; "
                "the first move after G41/G42 must move in the plane",
            )
        else:
            length = _norm(_sub(self._p2(seg.end_mm), here))
            if length < self._r - _NO_MOTION_MM:
                raise self._error(
                    seg,
                    f"cutter radius compensation: the entry move is {length:.6g} mm long, "
                    f"shorter than the tool radius {self._r:.6g} mm (LinuxCNC refuses it); "
                    "start the entry at least one tool radius away",
                )
            path = self._path(seg, here)
        return _Held(seg, path, self._pos, path.comp_end, entry=True)

    def _corner(self, held: _Held, seg: Segment) -> list[Segment]:
        """Resolve the corner between the held move and ``seg``; emit the held move."""
        b = self._path(seg, self._p2(seg.start_mm))
        start = b.comp_start
        arc_from: _Vec2 | None = None
        if _norm(_sub(held.end, start)) <= _TANGENT_GAP_MM:
            start = held.end
        else:
            point = self._concave_point(held, b, seg)
            if point is None:
                arc_from = held.end
            else:
                held.end = start = point
        out = self._release(held)
        if arc_from is not None:
            out.append(self._corner_arc(seg, b.start, arc_from, start))
        self._held = _Held(
            seg, b, self._p3(start, self._pos[self._axes[2]]), b.comp_end, entry=False
        )
        return out

    def _concave_point(self, held: _Held, b: _Path, seg: Segment) -> _Vec2 | None:
        """Where the held move must end at a concave corner; None at a convex one."""
        a = held.path
        cross = _cross(a.t_end, b.t_start)
        if _dot(a.t_end, b.t_start) < 0.0 and abs(cross) <= _CUSP_SIN:
            # Near a reversal the sign of the turn says little: the corner is concave when
            # the offset paths cut each other within both moves.
            cuts = [
                p
                for p in self._meet(held, b)
                if -a.length
                <= _along(a, held.end, p)
                < 0.0
                < _along(b, b.comp_start, p)
                <= b.length
            ]
            return _nearest(cuts, b.start)
        if self._side * cross <= 0.0:
            return None
        point = _nearest(self._meet(held, b), b.start)
        if point is None:
            raise self._gouge(seg)
        return point

    def _meet(self, held: _Held, b: _Path) -> list[_Vec2]:
        """Points where the held move's offset path meets the next one's (0, 1 or 2)."""
        a = held.path
        if a.centre is None and b.centre is None:
            da, db = _direction(a), _direction(b)
            den = _cross(da, db)
            if den == 0.0:
                return []
            s = _cross(_sub(b.comp_start, held.end), db) / den
            return [_add(held.end, _scale(da, s))]
        if a.centre is not None and b.centre is not None:
            return _circle_circle(a.centre, a.rho_end, b.centre, b.rho_end)
        if a.centre is not None:
            return _line_circle(b.comp_start, _direction(b), a.centre, a.rho_end)
        assert b.centre is not None
        return _line_circle(held.end, _direction(a), b.centre, b.rho_end)

    # ------------------------------------------------------------------ emission

    def _release(self, held: _Held) -> list[Segment]:
        """Emit the held move with its final end, then the moves waiting behind it."""
        seg, path = held.seg, held.path
        normal = self._axes[2]
        start = held.start
        end = self._p3(held.end, seg.end_mm[normal])
        if path.centre is not None:
            if held.entry:
                centre = self._entry_centre(held)
            else:
                centre = path.centre
                self._check_arc_trim(held, centre)
            emitted = replace(
                seg,
                start_mm=self._to_tip(start),
                end_mm=self._to_tip(end),
                center_mm=self._to_tip(self._p3(centre, start[normal])),
            )
        else:
            if _dot(_sub(held.end, self._p2(start)), _direction(path)) < 0.0:
                raise self._gouge(seg)
            emitted = replace(seg, start_mm=self._to_tip(start), end_mm=self._to_tip(end))
        out = [emitted]
        self._pos = end
        out.extend(self._emit_through(wait) for wait in self._waiting)
        self._waiting = []
        return out

    def _emit_through(self, seg: Segment) -> Segment:
        """A move without motion in the plane, at the current in-plane position."""
        normal = self._axes[2]
        here = self._p2(self._pos)
        start = self._p3(here, self._pos[normal])
        end = self._p3(here, seg.end_mm[normal])
        self._pos = end
        return replace(seg, start_mm=self._to_tip(start), end_mm=self._to_tip(end))

    def _corner_arc(self, following: Segment, corner: _Vec2, start: _Vec2, end: _Vec2) -> Segment:
        """The arc of radius r about a convex corner, with the following move's attributes."""
        h = self._pos[self._axes[2]]
        return replace(
            following,
            kind=MotionKind.ARC,
            start_mm=self._to_tip(self._p3(start, h)),
            end_mm=self._to_tip(self._p3(end, h)),
            center_mm=self._to_tip(self._p3(corner, h)),
            turns=-self._side,
            dwell_s=0.0,
            start_abc_deg=following.start_abc_deg,
            end_abc_deg=following.start_abc_deg,
        )

    def _entry_centre(self, held: _Held) -> _Vec2:
        """Centre of an arc entry: on the line programmed centre -> end, equidistant.

        The centre ``c + t u`` (``u`` the unit vector from the programmed centre ``c`` to
        the compensated end, at distance ``rho``) is as far from the start ``p`` as from
        the end: ``|c - p + t u|^2 = (rho - t)^2``, so ``t = (rho^2 - |c - p|^2) /
        (2 ((c - p).u + rho))``; the new radius ``rho - t`` must be positive.
        """
        c = held.path.centre
        assert c is not None
        u = _sub(held.end, c)
        rho = _norm(u)
        u = _scale(u, 1.0 / rho)
        w = _sub(c, self._p2(held.start))
        den = 2.0 * (_dot(w, u) + rho)
        num = rho * rho - _dot(w, w)
        if den <= 0.0 or num >= rho * den:
            raise self._error(
                held.seg,
                "cutter radius compensation: no arc entry from the current position to the "
                "compensated arc; enter with a straight move, or start farther from the arc",
            )
        return _add(c, _scale(u, num / den))

    def _check_arc_trim(self, held: _Held, centre: _Vec2) -> None:
        """Raise if trimming an arc at concave corners used it up (gouging)."""
        path = held.path
        if path.rho_end == 0.0:
            return  # the offset arc is its centre (tool radius = arc radius): nothing to trim
        lost_start = _wrap(
            _angle(_sub(self._p2(held.start), centre)) - _angle(_sub(path.start, centre))
        )
        lost_end = _wrap(_angle(_sub(path.end, centre)) - _angle(_sub(held.end, centre)))
        if path.sense * (lost_start + lost_end) >= abs(path.sweep):
            raise self._gouge(held.seg)

    def _gouge(self, seg: Segment) -> NCError:
        return self._error(
            seg,
            f"cutter radius compensation: the tool (radius {self._r:.6g} mm) does not fit the "
            "concave corner at this move (gouging); use a smaller tool or open the corner",
        )

    @staticmethod
    def _error(seg: Segment, message: str) -> NCError:
        return NCError(message, file=seg.file or "<string>", line=seg.line)


def _angle(v: _Vec2) -> float:
    return math.atan2(v[1], v[0])


def _nearest(points: list[_Vec2], corner: _Vec2) -> _Vec2 | None:
    """The point nearest the programmed corner, or None if there is none."""
    return min(points, key=lambda p: _norm(_sub(p, corner)), default=None)


def _along(path: _Path, origin: _Vec2, p: _Vec2) -> float:
    """Signed distance (mm) from ``origin`` to ``p`` along a path's direction of motion.

    Arcs measure the angle from ``origin`` to ``p`` about the centre, wrapped into
    (-pi, pi], times the offset radius.
    """
    if path.centre is None:
        return _dot(_sub(p, origin), _direction(path))
    turn = _wrap(_angle(_sub(p, path.centre)) - _angle(_sub(origin, path.centre)))
    return path.sense * turn * path.rho_end


def _direction(path: _Path) -> _Vec2:
    """Unit direction of a straight path."""
    assert path.direction is not None
    return path.direction


def _line_circle(p: _Vec2, d: _Vec2, c: _Vec2, rho: float) -> list[_Vec2]:
    """Points where the line ``p + s d`` (``d`` a unit vector) meets a circle."""
    w = _sub(p, c)
    b = _dot(w, d)
    disc = b * b - (_dot(w, w) - rho * rho)
    if disc < 0.0:
        return []
    root = math.sqrt(disc)
    return [_add(p, _scale(d, -b - root)), _add(p, _scale(d, -b + root))]


def _circle_circle(c1: _Vec2, r1: float, c2: _Vec2, r2: float) -> list[_Vec2]:
    """Points where two circles meet."""
    d = _sub(c2, c1)
    dist = _norm(d)
    if dist == 0.0:
        return []
    a = (r1 * r1 - r2 * r2 + dist * dist) / (2.0 * dist)
    h2 = r1 * r1 - a * a
    if h2 < 0.0:
        return []
    e = _scale(d, 1.0 / dist)
    mid = _add(c1, _scale(e, a))
    h = math.sqrt(h2)
    return [_add(mid, _scale(_perp(e), h)), _add(mid, _scale(_perp(e), -h))]
