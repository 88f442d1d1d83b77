"""Modal state of the control: units, distance modes, motion mode, plane, feed, spindle
and coolant.

:class:`ModalState` holds the :class:`~cnctwin.nc.segments.MachineState` that segments
carry, and the modes the interpreter reads on every move (the mm per program unit, G90/G91,
G90.1/G91.1, the motion mode, diameter mode). Feed rates are kept as programmed (program
units per minute, per revolution, or 1/min under G93); :meth:`ModalState.feed_mm_min`
resolves them to mm/min.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Final

from cnctwin.nc.arcs import MM_PER_INCH
from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.segments import FeedMode, MachineState, Plane, Vec3

__all__ = ["ModalState"]

_SPINDLE: Final = {3: 1, 4: -1, 5: 0}


class ModalState:
    """The modes in force, changed block by block.

    Parameters
    ----------
    where
        Where errors are reported.
    lathe
        A lathe starts in G18 and in diameter mode (G7).
    max_spindle_rpm
        The machine's top spindle speed, rpm: the limit of G96 without a clamp.

    Attributes
    ----------
    state
        The modal state that segments carry (replaced, never mutated).
    factor
        mm per program unit: 1 under G21, 25.4 under G20.
    incremental
        G91 distance mode.
    arc_absolute
        G90.1 (arc centres I, J, K absolute).
    motion
        Motion mode as a G-code key (0, 10, 20, 30, 51, 331, 730, 810-890), ``None``
        after G80 or before any.
    diameter_mode
        G7 (lathe X words are diameters).
    units
        Units the program first selected, ``"mm"`` or ``"inch"``; ``None`` before any.
    """

    __slots__ = (
        "state",
        "factor",
        "incremental",
        "arc_absolute",
        "motion",
        "diameter_mode",
        "units",
        "_where",
        "_max_spindle_rpm",
    )

    def __init__(self, where: ProgramCursor, lathe: bool, max_spindle_rpm: float) -> None:
        self.state = MachineState(plane=Plane.ZX if lathe else Plane.XY, diameter_mode=lathe)
        self.factor = 1.0
        self.incremental = False
        self.arc_absolute = False
        self.motion: int | None = None
        self.diameter_mode = lathe
        self.units: str | None = None
        self._where = where
        self._max_spindle_rpm = max_spindle_rpm

    # ------------------------------------------------------------------ feed and units
    def set_feed(self, value: float) -> None:
        """F word, program units per minute (per revolution under G95, 1/min under G93)."""
        if value < 0:
            raise self._where.error(f"feed rate F{value:g} is negative: F must be >= 0")
        if value != self.state.programmed_feed:
            self.state = self.state.with_feed(value)

    def set_feed_mode(self, mode: FeedMode) -> None:
        """G93, G94 or G95."""
        if mode != self.state.feed_mode:
            self.state = replace(self.state, feed_mode=mode)

    def set_units(self, units: str) -> None:
        """G20/G21 (``"inch"``/``"mm"``); the feed rate keeps its physical value (LinuxCNC)."""
        if self.units is None:
            self.units = units
        factor = MM_PER_INCH if units == "inch" else 1.0
        if factor != self.factor:
            feed = self.state.programmed_feed
            if self.state.feed_mode != FeedMode.INVERSE_TIME:
                feed = feed * self.factor / factor
            self.factor = factor
            self.state = replace(self.state, units=units, programmed_feed=feed)  # type: ignore[arg-type]

    def require_feed(self, has_f: bool) -> None:
        """Refuse a feed move that cannot run: no feed rate, G93 without an F word in the
        block (``has_f``), or G95 with the spindle stopped."""
        state = self.state
        mode = state.feed_mode
        if mode == FeedMode.INVERSE_TIME:
            if not has_f:
                raise self._where.error("G93 inverse time mode needs an F word on every feed move")
            if state.programmed_feed <= 0.0:
                raise self._where.error("G93 inverse time F0 would take forever: F must be > 0")
        elif state.programmed_feed <= 0.0:
            raise self._where.error(
                "feed move with feed rate 0: program F (e.g. F100) before G1/G2/G3"
            )
        elif mode == FeedMode.UNITS_PER_REV and (
            state.spindle_direction == 0 or state.programmed_speed <= 0.0
        ):
            raise self._where.error(
                "G95 feed per revolution with the spindle stopped: start it (M3/M4 S...)"
            )

    def feed_mm_min(self, length_mm: float, position_mm: Vec3) -> float:
        """Path feed rate in mm/min of a move ``length_mm`` long that starts at the machine
        position ``position_mm`` (which sets the spindle speed under G96)."""
        state = self.state
        mode = state.feed_mode
        if mode == FeedMode.UNITS_PER_MINUTE:
            return state.programmed_feed * self.factor
        if mode == FeedMode.INVERSE_TIME:
            # F is 1/minutes: the move takes 1/F minutes.
            return length_mm * state.programmed_feed
        return state.programmed_feed * self.factor * self.spindle_rpm(position_mm)

    def axis_values(self, words: dict[str, float]) -> dict[int, float]:
        """Axis words of a block by axis index (0-5) in mm (degrees for A, B, C), X halved
        in diameter mode."""
        values: dict[int, float] = {}
        for i, letter in enumerate("xyzabc"):
            if letter in words:
                v = words[letter] * (self.factor if i < 3 else 1.0)
                if i == 0 and self.diameter_mode:
                    v *= 0.5
                values[i] = v
        return values

    # ------------------------------------------------------------------ spindle and coolant
    def set_speed(self, value: float) -> None:
        """S word: rpm, or surface speed (m/min, ft/min in inch mode) under G96."""
        if value < 0:
            raise self._where.error(f"spindle speed S{value:g} is negative: S must be >= 0")
        if value != self.state.programmed_speed:
            self.state = replace(self.state, programmed_speed=value)

    def set_spindle(self, m: int) -> None:
        """M3 (clockwise), M4 (counter-clockwise) or M5 (stop)."""
        direction = _SPINDLE[m]
        if direction != self.state.spindle_direction:
            self.state = replace(self.state, spindle_direction=direction)

    def set_css(self, on: bool, clamp_rpm: float | None) -> None:
        """G96 (``on``, with the D word's clamp in rpm if given) or G97."""
        if on and clamp_rpm is not None:
            self.state = replace(self.state, spindle_clamp_rpm=clamp_rpm)
        self.state = replace(self.state, css=on)

    def clamp_spindle(self, words: dict[str, float]) -> None:
        """Lathe G50 S<rpm>: the spindle speed clamp of G96."""
        if "s" not in words or any(k in words for k in "xyz"):
            raise self._where.error(
                "G50 on a lathe is supported as spindle speed clamp only (G50 S<rpm>); "
                "coordinate setting with G50 X/Z is not supported"
            )
        self.state = replace(self.state, spindle_clamp_rpm=words["s"])

    def spindle_rpm(self, position_mm: Vec3) -> float:
        """Spindle speed in rpm at the machine position ``position_mm``: the S word, or under
        G96 the speed that gives the surface speed at the tool's radius about program X = 0,
        clamped (G50 S, G96 D, the machine's top speed)."""
        state = self.state
        if state.spindle_direction == 0:
            return 0.0
        if not state.css:
            return state.programmed_speed
        # Constant surface speed: S in m/min (mm mode) or ft/min (inch mode).
        radius_mm = abs(state.to_program(position_mm)[0])
        surface_mm_min = state.programmed_speed * (1000.0 if self.factor == 1.0 else 304.8)
        clamp = min(state.spindle_clamp_rpm, self._max_spindle_rpm)
        rpm = math.inf if radius_mm <= 1e-9 else surface_mm_min / (2.0 * math.pi * radius_mm)
        if rpm > clamp:
            rpm = clamp
        if math.isinf(rpm):
            raise self._where.error(
                "G96 constant surface speed at X0 with no spindle limit: program G50 S<rpm> "
                "(Fanuc) or G96 D<rpm> (LinuxCNC), or set machine.max_spindle_rpm"
            )
        return rpm

    def set_coolant(self, m: int) -> None:
        """M7 (mist), M8 (flood), M9 (off); mist and flood add up."""
        current = self.state.coolant
        if m == 9:
            new = "off"
        else:
            kind = "mist" if m == 7 else "flood"
            parts = set() if current == "off" else set(current.split("+"))
            parts.add(kind)
            new = "+".join(sorted(parts))
        if new != current:
            self.state = replace(self.state, coolant=new)

    # ------------------------------------------------------------------ plane, tool
    def set_plane(self, plane: Plane) -> None:
        """G17, G18 or G19."""
        if plane != self.state.plane:
            self.state = replace(self.state, plane=plane)

    def set_diameter_mode(self, on: bool) -> None:
        """G7 (``on``: lathe X words are diameters) or G8."""
        self.diameter_mode = on
        self.state = replace(self.state, diameter_mode=on)

    def set_tool(self, tool: int) -> None:
        """The tool in the spindle."""
        if tool != self.state.tool:
            self.state = replace(self.state, tool=tool)
