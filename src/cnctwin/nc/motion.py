"""Motion: the tool's machine position and the segments that move it.

:class:`Motion` turns axis words into machine targets (absolute or incremental, G53, polar
``@ ^`` and lathe ``U W`` words, the rotated frame of G10 L2 R) and emits straight moves,
arcs and helices, G5.1 splines, G33.1 rigid tapping, dwells, G28/G30 returns and the moves
of drilling cycles, through cutter radius compensation when it is on. Positions are machine
coordinates of the controlled point in mm (A, B, C in degrees); feeds in mm/min.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Final

from cnctwin.nc.arcs import arc_end_refused, arc_turns, center_from_radius, spline_points
from cnctwin.nc.blocks import g_text
from cnctwin.nc.canned_cycles import CycleModes, expand_cycle
from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.cutter_comp import CutterCompensator
from cnctwin.nc.limits import MAX_POSITION_MM, check_position
from cnctwin.nc.modal import ModalState
from cnctwin.nc.offsets import Offsets
from cnctwin.nc.segments import (
    PLANE_AXES,
    CutterComp,
    FeedMode,
    MachineState,
    MotionKind,
    Plane,
    Segment,
    Vec3,
    arc_sweep_rad,
)
from cnctwin.nc.tool_state import ToolState

__all__ = ["Motion", "check_target"]

_AXES: Final = "xyz"
_ROTARY: Final = "abc"
#: The centre words in each plane.
_IN_PLANE: Final = {
    plane: frozenset("ijk"[axis] for axis in PLANE_AXES[plane][:2]) for plane in Plane
}


def check_target(point: list[float] | tuple[float, float, float]) -> None:
    """Refuse a machine position (mm) beyond the bounds of :mod:`cnctwin.nc.limits`."""
    x, y, z = point[0], point[1], point[2]
    if (
        -MAX_POSITION_MM <= x <= MAX_POSITION_MM
        and -MAX_POSITION_MM <= y <= MAX_POSITION_MM
        and -MAX_POSITION_MM <= z <= MAX_POSITION_MM
    ):
        return  # the common case, without a call per axis (also false for NaN)
    for axis, value in zip("XYZ", point[:3], strict=True):
        check_position(axis, value)


class Motion:
    """The tool's position and the segments produced, in program order.

    Parameters
    ----------
    where
        Where errors are reported; segments carry its file and line.
    modal, offsets, tools, cycles
        The modes, the offsets, the tool table (cutter compensation reads diameters from
        it) and the drilling cycles' sticky words, shared with the block executor.
    initial_mm
        Machine position (x, y, z) at the start, mm.

    Attributes
    ----------
    pos
        Machine position (x, y, z) of the controlled point, mm.
    abc
        Positions of the rotary axes A, B, C, degrees.
    out
        Segments produced and not yet taken (the interpreter empties it; the list object
        is never replaced).
    comp
        The cutter radius compensator while G41/G42 is on with a radius > 0, else ``None``.
    """

    __slots__ = (
        "pos",
        "abc",
        "out",
        "comp",
        "_exit_base",
        "_where",
        "_modal",
        "_offsets",
        "_tools",
        "_cycles",
    )

    def __init__(
        self,
        where: ProgramCursor,
        modal: ModalState,
        offsets: Offsets,
        tools: ToolState,
        cycles: CycleModes,
        initial_mm: Vec3,
    ) -> None:
        self.pos: list[float] = list(initial_mm)
        self.abc: Vec3 = (0.0, 0.0, 0.0)
        self.out: list[Segment] = []
        self.comp: CutterCompensator | None = None
        # Where the axes a block does not name stay, after compensation ends (mm).
        self._exit_base: list[float] | None = None
        self._where = where
        self._modal = modal
        self._offsets = offsets
        self._tools = tools
        self._cycles = cycles

    # ------------------------------------------------------------------ G0/G1 shortcut
    def xyz_move(
        self, motion: int, vx: float | None, vy: float | None, vz: float | None, has_f: bool
    ) -> None:
        """Straight G0 (``motion`` 0) or G1 (10) move to X, Y, Z words (program units,
        ``None`` if absent); ``has_f``: the block has an F word. The bulk of CAM output:
        the general :meth:`straight` inlined for the plain frame."""
        modal = self._modal
        state = modal.state
        if modal.diameter_mode or state.xy_rotation_deg or state.css or self._exit_base:
            words = {k: v for k, v in zip("xyz", (vx, vy, vz), strict=True) if v is not None}
            if has_f:
                words["f"] = state.programmed_feed
            if motion == 10:
                modal.require_feed(has_f)
            kind = MotionKind.LINEAR if motion == 10 else MotionKind.RAPID
            self.straight(kind, self.target(words))
            return
        x0, y0, z0 = self.pos
        f = modal.factor
        off = self._offsets.total
        inc = modal.incremental
        x, y, z = x0, y0, z0
        if vx is not None:
            x = x0 + vx * f if inc else vx * f + off[0]
        if vy is not None:
            y = y0 + vy * f if inc else vy * f + off[1]
        if vz is not None:
            z = z0 + vz * f if inc else vz * f + off[2]
        if not (
            -MAX_POSITION_MM <= x <= MAX_POSITION_MM
            and -MAX_POSITION_MM <= y <= MAX_POSITION_MM
            and -MAX_POSITION_MM <= z <= MAX_POSITION_MM
        ):
            check_target((x, y, z))
        if motion == 10:
            kind = MotionKind.LINEAR
            if state.feed_mode == FeedMode.UNITS_PER_MINUTE and state.programmed_feed > 0.0:
                feed = state.programmed_feed * f
            else:
                modal.require_feed(has_f)
                length = math.sqrt((x - x0) ** 2 + (y - y0) ** 2 + (z - z0) ** 2)
                feed = modal.feed_mm_min(length, (x0, y0, z0))
        else:
            kind = MotionKind.RAPID
            feed = 0.0
        abc = self.abc
        where = self._where
        self.out.append(
            Segment(
                kind,
                where.line,
                (x0, y0, z0),
                (x, y, z),
                feed,
                state.programmed_speed if state.spindle_direction else 0.0,
                state,
                None,
                0,
                0.0,
                abc,
                abc,
                where.file,
            )
        )
        self.pos = [x, y, z]

    @property
    def plain_absolute(self) -> bool:
        """Straight moves take :meth:`xyz_move`'s inlined path, in absolute distances and
        feed per minute, without cutter compensation: what runs of straight moves
        (:mod:`cnctwin.nc.runs`) assume."""
        modal = self._modal
        state = modal.state
        return not (
            modal.diameter_mode
            or modal.incremental
            or state.xy_rotation_deg
            or state.css
            or self._exit_base
            or self.comp is not None
        ) and (state.feed_mode == FeedMode.UNITS_PER_MINUTE)

    # ------------------------------------------------------------------ targets
    def target(self, words: dict[str, float], g53: bool = False) -> list[float]:
        """Machine target (x, y, z) in mm of the axis words of a block (program units).

        Axes the block does not name keep their programmed position, which differs from
        the tool's after cutter compensation ends (see :meth:`finish_comp`).
        """
        if "@" in words or "^" in words:
            words = self._polar(words, g53)
        if "u" in words or "w" in words:
            words = self._incremental_words(words)
        pos = self.pos
        if self._exit_base is not None:
            pos = self._exit_base
            self._exit_base = None
        modal = self._modal
        state = modal.state
        if state.xy_rotation_deg and not g53:
            prog = list(state.to_program((pos[0], pos[1], pos[2])))
            for i, v in modal.axis_values(words).items():
                if i < 3:
                    prog[i] = prog[i] + v if modal.incremental else v
            return list(state.to_machine((prog[0], prog[1], prog[2])))
        target = [pos[0], pos[1], pos[2]]
        f = modal.factor
        off = self._offsets.total
        for i, letter in enumerate(_AXES):
            value = words.get(letter)
            if value is None:
                continue
            v = value * f
            if i == 0 and modal.diameter_mode:
                v *= 0.5
            if g53:
                target[i] = v
            elif modal.incremental:
                target[i] = pos[i] + v
            else:
                target[i] = v + off[i]
        return target

    def target_abc(self, words: dict[str, float], g53: bool = False) -> list[float]:
        """Target of the rotary axes A, B, C in degrees."""
        target = list(self.abc)
        incremental = self._modal.incremental
        off = self._offsets.total
        for i, letter in enumerate(_ROTARY):
            value = words.get(letter)
            if value is None:
                continue
            if g53:
                target[i] = value
            elif incremental:
                target[i] += value
            else:
                target[i] = value + off[3 + i]
        return target

    def _polar(self, words: dict[str, float], g53: bool) -> dict[str, float]:
        """Replace the polar words @ (radius) and ^ (angle, degrees) by X and Y.

        As in LinuxCNC, polar coordinates are about the program origin in G17; under G91
        @ and ^ increment the current radius and angle.
        """
        modal = self._modal
        if g53 or modal.state.plane != Plane.XY or "x" in words or "y" in words:
            raise self._where.error(
                "polar coordinates (@ radius, ^ angle) need G17 and no X/Y/G53 in the block"
            )
        pos = self.pos
        here = modal.state.to_program((pos[0], pos[1], pos[2]))
        f = modal.factor
        inc = modal.incremental
        radius = math.hypot(here[0], here[1])
        angle = math.degrees(math.atan2(here[1], here[0])) if radius > 0 else 0.0
        if "@" in words:
            radius = radius + words["@"] * f if inc else words["@"] * f
        if "^" in words:
            angle = angle + words["^"] if inc else words["^"]
        x = radius * math.cos(math.radians(angle))
        y = radius * math.sin(math.radians(angle))
        out = {k: v for k, v in words.items() if k not in "@^"}
        if inc:
            out["x"], out["y"] = (x - here[0]) / f, (y - here[1]) / f
        else:
            out["x"], out["y"] = x / f, y / f
        return out

    def _incremental_words(self, words: dict[str, float]) -> dict[str, float]:
        """Fanuc lathe U and W (incremental X and Z, U in diameter in diameter mode)
        replaced by X and Z in the current distance mode."""
        modal = self._modal
        out = {k: v for k, v in words.items() if k not in "uw"}
        here = modal.state.to_program((self.pos[0], self.pos[1], self.pos[2]))
        for inc, axis, index in (("u", "x", 0), ("w", "z", 2)):
            if inc not in words:
                continue
            if axis in words:
                raise self._where.error(
                    f"{axis.upper()} and {inc.upper()} in one block: use one of them"
                )
            if modal.incremental:
                out[axis] = words[inc]
            else:
                current = here[index] / modal.factor
                if index == 0 and modal.diameter_mode:
                    current *= 2.0
                out[axis] = current + words[inc]
        return out

    # ------------------------------------------------------------------ segments
    def move(self, code: int, words: dict[str, float], g53: bool) -> None:
        """The motion of a block in motion mode ``code`` (G-code key) with its words."""
        if g53 and code not in (0, 10):
            raise self._where.error("G53 needs G0 or G1 motion")
        if g53 and self.comp is not None:
            raise self._where.error("G53 is not allowed while cutter compensation is on")
        if code in (0, 10):
            target = self.target(words, g53)
            abc = self.target_abc(words, g53)
            if code == 10:
                self._modal.require_feed("f" in words)
            self.straight(MotionKind.LINEAR if code == 10 else MotionKind.RAPID, target, abc)
        elif code in (20, 30):
            self._modal.require_feed("f" in words)
            self.arc(code == 30, words)
        elif code == 51:
            self._modal.require_feed("f" in words)
            self._spline(words)
        elif code == 331:
            self._rigid_tap(words)
        else:
            self._drill(code // 10, words)

    def _segment(
        self,
        kind: MotionKind,
        start: list[float],
        end: list[float],
        length: float,
        center: Vec3 | None = None,
        turns: int = 0,
        abc_end: list[float] | None = None,
    ) -> Segment:
        """A segment from ``start`` to ``end`` (mm), ``length`` mm long, in the modes in force."""
        modal = self._modal
        here = (start[0], start[1], start[2])
        feed = 0.0 if kind == MotionKind.RAPID else modal.feed_mm_min(length, here)
        state = modal.state
        rpm = (
            0.0
            if state.spindle_direction == 0
            else (modal.spindle_rpm(here) if state.css else state.programmed_speed)
        )
        abc0 = self.abc
        abc1 = abc0 if abc_end is None else abc_end
        return Segment(
            kind,
            self._where.line,
            here,
            (end[0], end[1], end[2]),
            feed,
            rpm,
            state,
            center,
            turns,
            0.0,
            (abc0[0], abc0[1], abc0[2]),
            (abc1[0], abc1[1], abc1[2]),
            self._where.file,
        )

    def _emit(self, seg: Segment) -> None:
        if self.comp is None:
            self.out.append(seg)
            return
        for out in self.comp.push(seg):
            if out.kind == MotionKind.ARC and out.feed_mm_min <= 0.0:
                # A corner arc inserted next to a rapid is cut at the programmed feed.
                feed = out.state.programmed_feed * self._modal.factor
                if feed <= 0.0 or out.state.feed_mode != FeedMode.UNITS_PER_MINUTE:
                    raise self._where.error(
                        "cutter compensation inserts a corner arc next to a rapid here, "
                        "and no feed rate (G94 F) is programmed to cut it"
                    )
                out = replace(out, feed_mm_min=feed)
            self.out.append(out)

    def straight(
        self, kind: MotionKind, target: list[float], abc: list[float] | None = None
    ) -> None:
        """Straight move (rapid or feed) to the machine ``target`` (mm) and rotary ``abc``
        (degrees; unchanged if ``None``)."""
        check_target(target)
        pos = self.pos
        length = math.sqrt(
            (target[0] - pos[0]) ** 2 + (target[1] - pos[1]) ** 2 + (target[2] - pos[2]) ** 2
        )
        self._emit(self._segment(kind, pos, target, length, abc_end=abc))
        self.pos = target
        if abc is not None:
            self.abc = (abc[0], abc[1], abc[2])

    def arc(self, ccw: bool, words: dict[str, float]) -> None:
        """G2 (clockwise) or G3 (``ccw``) arc or helix of a block's words (program units)."""
        state = self._modal.state
        plane = state.plane
        i0, i1, normal = PLANE_AXES[plane]
        target = self.target(words)
        abc = self.target_abc(words)
        start = self.pos
        turns = arc_turns(words.get("p"), ccw)
        if "r" in words:
            if any(k in words for k in "ijk" if k in _IN_PLANE[plane]):
                raise self._where.error("arc with both R and I/J/K: use one format")
            factor = self._modal.factor
            center = center_from_radius(words["r"] * factor, start, target, i0, i1, ccw, factor)
        else:
            center = self._center_from_offsets(words, start, target)
        check_target(target)
        check_target(center)
        center_t = (center[0], center[1], center[2])
        radius, _, sweep = arc_sweep_rad(
            (start[0], start[1], start[2]),
            (target[0], target[1], target[2]),
            center_t,
            turns,
            plane,
        )
        length = math.hypot(radius * sweep, target[normal] - start[normal])
        self._emit(
            self._segment(MotionKind.ARC, start, target, length, center_t, turns, abc_end=abc)
        )
        self.pos = target
        self.abc = (abc[0], abc[1], abc[2])

    def _center_from_offsets(
        self, words: dict[str, float], start: list[float], target: list[float]
    ) -> list[float]:
        """Centre (mm) of an I/J/K arc, checked against LinuxCNC's end-radius test."""
        modal = self._modal
        state = modal.state
        plane = state.plane
        i0, i1, normal = PLANE_AXES[plane]
        in_plane = _IN_PLANE[plane]
        f = modal.factor
        for k in "ijk":
            if k in words and k not in in_plane:
                raise self._where.error(
                    f"{k.upper()} word is not allowed in an arc in the "
                    f"{plane.name} plane (G{int(plane)}); use "
                    + " and ".join(sorted(x.upper() for x in in_plane))
                )
        if in_plane.isdisjoint(words):
            raise self._where.error(
                "arc without centre: give "
                + " and/or ".join(sorted(x.upper() for x in in_plane))
                + " (centre offsets) or R (radius)"
            )
        if state.xy_rotation_deg and plane != Plane.XY:
            raise self._where.error(
                "arcs in G18/G19 with a rotated coordinate system (G10 L2 R) are not supported"
            )
        if modal.arc_absolute:
            prog = list(state.to_program((start[0], start[1], start[2])))
            for axis in (i0, i1):
                value = words.get("ijk"[axis], 0.0) * f
                prog[axis] = value * 0.5 if axis == 0 and modal.diameter_mode else value
            center = list(state.to_machine((prog[0], prog[1], prog[2])))
        else:
            offsets = [words.get("i", 0.0) * f, words.get("j", 0.0) * f, words.get("k", 0.0) * f]
            if state.xy_rotation_deg:
                rot = math.radians(state.xy_rotation_deg)
                c, s_ = math.cos(rot), math.sin(rot)
                offsets[0], offsets[1] = (
                    c * offsets[0] - s_ * offsets[1],
                    s_ * offsets[0] + c * offsets[1],
                )
            center = [start[0] + offsets[0], start[1] + offsets[1], start[2] + offsets[2]]
        center[normal] = start[normal]
        r0 = math.hypot(start[i0] - center[i0], start[i1] - center[i1])
        r1 = math.hypot(target[i0] - center[i0], target[i1] - center[i1])
        if arc_end_refused(r0, r1, state.units):
            raise self._where.error(
                f"arc end is {r1:.4f} mm from the centre but the start is {r0:.4f} mm: "
                "the radii must agree (check I/J/K, incremental vs absolute G90.1/G91.1)"
            )
        if r0 <= 0.0:
            raise self._where.error("arc of zero radius: the centre equals the start point")
        return center

    def _spline(self, words: dict[str, float]) -> None:
        """G5.1 quadratic spline in the XY plane, as chords (see :func:`spline_points`)."""
        if self._modal.state.plane != Plane.XY:
            raise self._where.error("G5.1 splines are only defined in the XY plane (G17)")
        if "i" not in words and "j" not in words:
            raise self._where.error("G5.1 needs I and/or J (control point offsets)")
        start = list(self.pos)
        target = self.target(words)
        f = self._modal.factor
        control = (start[0] + words.get("i", 0.0) * f, start[1] + words.get("j", 0.0) * f)
        for point in spline_points(start, control, target):
            self.straight(MotionKind.LINEAR, point)

    def _rigid_tap(self, words: dict[str, float]) -> None:
        """G33.1: feed to the target at K (pitch, program units) per spindle revolution
        and back with the spindle reversed."""
        if "k" not in words or words["k"] <= 0:
            raise self._where.error(
                "G33.1 rigid tapping needs K<pitch> > 0 (distance per revolution)"
            )
        modal = self._modal
        state = modal.state
        if state.spindle_direction == 0 or state.programmed_speed <= 0:
            raise self._where.error("G33.1 rigid tapping needs the spindle turning (M3/M4 with S)")
        start: Vec3 = (self.pos[0], self.pos[1], self.pos[2])
        end = self.target(words)
        target: Vec3 = (end[0], end[1], end[2])
        rpm = modal.spindle_rpm(start)
        feed = words["k"] * modal.factor * rpm
        abc = self.abc
        if math.dist(start, target) > 0:
            reverse = replace(state, spindle_direction=-state.spindle_direction)
            for a, b, st in ((start, target, state), (target, start, reverse)):
                self._emit(
                    Segment(
                        MotionKind.LINEAR,
                        self._where.line,
                        a,
                        b,
                        feed,
                        rpm,
                        st,
                        start_abc_deg=abc,
                        end_abc_deg=abc,
                        file=self._where.file,
                    )
                )

    def dwell(self, words: dict[str, float]) -> None:
        """G4: dwell P seconds (X or U on Fanuc lathes) where the tool is."""
        seconds = words.get("p")
        if seconds is None:
            seconds = words.get("x", words.get("u"))
        if seconds is None or seconds < 0:
            raise self._where.error("G4 dwell needs P<seconds> >= 0 (or X/U seconds)")
        pos = (self.pos[0], self.pos[1], self.pos[2])
        state = self._modal.state
        rpm = self._modal.spindle_rpm(pos) if state.spindle_direction else 0.0
        self._emit(self._dwell_segment(pos, rpm, state, seconds))

    def _dwell_segment(self, pos: Vec3, rpm: float, state: MachineState, seconds: float) -> Segment:
        """A dwell of ``seconds`` s at ``pos`` (mm) with the spindle at ``rpm``."""
        abc = (self.abc[0], self.abc[1], self.abc[2])
        where = self._where
        return Segment(
            MotionKind.DWELL,
            where.line,
            pos,
            pos,
            0.0,
            rpm,
            state,
            None,
            0,
            seconds,
            abc,
            abc,
            where.file,
        )

    def go_home(self, code: int, words: dict[str, float]) -> None:
        """G28 (``code`` 280) or G30 (300): rapid through the intermediate point (the axis
        words; the current position if none) to the stored reference point, on the named
        axes (all if none)."""
        home = self._offsets.reference_point(code)
        if self.comp is not None:
            raise self._where.error("G28/G30 is not allowed while cutter compensation is on")
        axes = [i for i, letter in enumerate("xyzabc") if letter in words] or list(range(6))
        self.straight(MotionKind.RAPID, self.target(words), self.target_abc(words))
        target = list(self.pos)
        abc = list(self.abc)
        for i in axes:
            if i < 3:
                target[i] = home[i]
            else:
                abc[i - 3] = home[i]
        self.straight(MotionKind.RAPID, target, abc)

    def _drill(self, code: int, words: dict[str, float]) -> None:
        """Drilling cycle G``code`` (73, 81-86, 89) at the holes of a block's words."""
        if self.comp is not None:
            raise self._where.error(
                f"canned cycle G{code} is not allowed with cutter compensation on"
            )
        modal = self._modal
        state_before = modal.state
        i0, i1, n = PLANE_AXES[state_before.plane]
        spec, repeats = self._cycles.plan(
            code,
            words,
            state_before,
            modal.factor,
            modal.incremental,
            self.pos[n],
            self._offsets.total[n],
        )
        if self.pos[n] < spec.r_mm:
            target = list(self.pos)
            target[n] = spec.r_mm
            self.straight(MotionKind.RAPID, target)
        self._cycles.check_size(spec, repeats)
        hole_words = {k: v for k, v in words.items() if k in (_AXES[i0], _AXES[i1], "@", "^")}
        for _ in range(repeats):
            hole = self.target(hole_words)
            for move in expand_cycle(spec, (hole[0], hole[1], hole[2]), tuple(self.pos)):  # type: ignore[arg-type]
                if move.spindle_direction is not None:
                    modal.state = replace(state_before, spindle_direction=move.spindle_direction)
                if move.kind == MotionKind.DWELL:
                    pos = (self.pos[0], self.pos[1], self.pos[2])
                    state = modal.state
                    self.out.append(
                        self._dwell_segment(pos, state.programmed_speed, state, move.dwell_s)
                    )
                else:
                    self.straight(move.kind, list(move.position_mm))
            modal.state = state_before

    # ------------------------------------------------------------------ cutter compensation
    def set_comp(self, code: int, words: dict[str, float]) -> None:
        """G40 (``code`` 400), G41/G42 (410/420: radius from tool D, default the current
        tool) or G41.1/G42.1 (411/421: D is the diameter, program units)."""
        modal = self._modal
        if code == 400:
            self.finish_comp()
            if modal.state.cutter_comp != CutterComp.OFF:
                modal.state = replace(modal.state, cutter_comp=CutterComp.OFF, comp_radius_mm=0.0)
            return
        if self.comp is not None:
            raise self._where.error(
                "cutter compensation is already on: turn it off with G40 before G41/G42"
            )
        side = CutterComp.LEFT if code in (410, 411) else CutterComp.RIGHT
        orientation = 0
        if code in (411, 421):
            if "d" not in words:
                raise self._where.error(f"G{g_text(code)} needs D<diameter>")
            radius = words["d"] * modal.factor / 2.0
        else:
            number = words.get("d", float(modal.state.tool))
            if number != int(number) or number < 0:
                raise self._where.error(f"D{number:g} must be a tool number")
            entry = self._tools.entry(int(number), "cutter compensation uses radius 0")
            radius = entry.diameter_mm / 2.0
            orientation = entry.orientation
        if radius < 0:
            # A negative diameter compensates on the other side (as LinuxCNC does).
            side = CutterComp.RIGHT if side == CutterComp.LEFT else CutterComp.LEFT
            radius = -radius
        modal.state = replace(modal.state, cutter_comp=side, comp_radius_mm=radius)
        if radius > 0:
            pos = self.pos
            self.comp = CutterCompensator(
                side, radius, modal.state.plane, (pos[0], pos[1], pos[2]), orientation
            )

    def finish_comp(self) -> None:
        """G40 or program end: flush the compensator.

        The tool stays where compensation left it; the next (exit) move starts there,
        while the axes its block does not name keep their programmed values (LinuxCNC).
        """
        if self.comp is None:
            return
        out = self.comp.finish()
        self.comp = None
        self.out.extend(out)
        if out:
            end = out[-1].end_mm
            self._exit_base = self.pos
            self.pos = [end[0], end[1], end[2]]
