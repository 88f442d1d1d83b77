"""Motion segments: what the NC interpreter produces and everything downstream consumes.

Coordinates are **machine coordinates of the controlled point** in millimetres, i.e.
what the machine's axes read: tool tip + tool offset. The tool tip (TCP) in machine
coordinates is ``end_mm - state.tool_offset_mm`` (see :meth:`Segment.tcp_end_mm`).
The program (work) frame is given by :meth:`MachineState.to_program`.

Units follow the project convention: lengths in mm, feeds in mm/min, spindle in rpm,
angles of rotary axes in degrees, times in s; the names say so.

Arc convention (as LinuxCNC's canonical ``ARC_FEED``): an arc lies in a plane spanned
by the plane's *first* and *second* axes (G17: X, Y; G18: Z, X; G19: Y, Z), which form
a right-handed frame with the plane's normal (Z, Y, X). ``turns`` > 0 is counter-clockwise
(G3) seen from the positive normal, ``turns`` < 0 clockwise (G2); ``abs(turns)`` is the
number of times the arc passes its end angle (1 for an ordinary arc, P-word for more).
A helix moves linearly along the normal while sweeping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Final, Literal

__all__ = [
    "CutterComp",
    "FeedMode",
    "MachineState",
    "MotionKind",
    "Plane",
    "Segment",
    "Vec3",
    "arc_sweep_rad",
    "segment_length_mm",
    "PLANE_AXES",
]

Vec3 = tuple[float, float, float]
ZERO3: Final[Vec3] = (0.0, 0.0, 0.0)


class MotionKind(IntEnum):
    """Kind of a motion segment."""

    RAPID = 0
    LINEAR = 1
    ARC = 2
    DWELL = 3


class Plane(IntEnum):
    """Active plane, numbered after its G-code."""

    XY = 17
    ZX = 18
    YZ = 19


#: (first, second, normal) axis indices of each plane, as in LinuxCNC's canonical calls.
PLANE_AXES: Final[dict[Plane, tuple[int, int, int]]] = {
    Plane.XY: (0, 1, 2),
    Plane.ZX: (2, 0, 1),
    Plane.YZ: (1, 2, 0),
}


class FeedMode(IntEnum):
    """Feed-rate mode, numbered after its G-code."""

    INVERSE_TIME = 93
    UNITS_PER_MINUTE = 94
    UNITS_PER_REV = 95


class CutterComp(IntEnum):
    """Cutter radius compensation side, numbered after its G-code."""

    OFF = 40
    LEFT = 41
    RIGHT = 42


@dataclass(frozen=True, slots=True)
class MachineState:
    """Modal state of the control at a segment; shared by consecutive segments.

    Attributes
    ----------
    units
        Units of the source program at this point: ``"mm"`` (G21/G710) or ``"inch"`` (G20/G700).
    plane
        Active plane (G17/G18/G19).
    feed_mode
        G93, G94 or G95.
    programmed_feed
        The F word as programmed, in program units (per minute, per revolution,
        or 1/min for inverse time).
    spindle_direction
        1 clockwise (M3), -1 counter-clockwise (M4), 0 stopped (M5).
    programmed_speed
        The S word: rpm under G97, surface speed (m/min, or ft/min in inch mode) under G96.
    css
        True while constant surface speed (G96) is active.
    spindle_clamp_rpm
        Maximum spindle speed under G96 (G50 S / G96 D), ``math.inf`` if none.
    tool
        Tool number in the spindle.
    tool_offset_mm
        Active tool-length offset (x, y, z) in mm (G43; zero after G49).
    work_offset_mm
        Origin of the active work coordinate system (G54-G59.3) in machine coordinates, mm.
    axis_offset_mm
        The G92/G52 offset, mm, in the rotated work frame.
    xy_rotation_deg
        Rotation of the work coordinate system about Z (G10 L2 R), degrees CCW.
    coordinate_system
        Active work coordinate system, 1 (G54) to 9 (G59.3).
    cutter_comp
        Cutter radius compensation side.
    comp_radius_mm
        Compensation radius in mm while compensation is active.
    coolant
        ``"off"``, ``"flood"`` (M8) or ``"mist"`` (M7), or ``"flood+mist"``.
    diameter_mode
        Lathe diameter programming (G7) is active.
    """

    units: Literal["mm", "inch"] = "mm"
    plane: Plane = Plane.XY
    feed_mode: FeedMode = FeedMode.UNITS_PER_MINUTE
    programmed_feed: float = 0.0
    spindle_direction: int = 0
    programmed_speed: float = 0.0
    css: bool = False
    spindle_clamp_rpm: float = math.inf
    tool: int = 0
    tool_offset_mm: Vec3 = ZERO3
    work_offset_mm: Vec3 = ZERO3
    axis_offset_mm: Vec3 = ZERO3
    xy_rotation_deg: float = 0.0
    coordinate_system: int = 1
    cutter_comp: CutterComp = CutterComp.OFF
    comp_radius_mm: float = 0.0
    coolant: str = "off"
    diameter_mode: bool = False

    def with_feed(self, programmed_feed: float) -> MachineState:
        """This state with another ``programmed_feed`` (program units per minute): what
        ``dataclasses.replace(state, programmed_feed=...)`` gives, in a third of its time (the
        interpreter derives a state at every change of F)."""
        return MachineState(
            self.units,
            self.plane,
            self.feed_mode,
            programmed_feed,
            self.spindle_direction,
            self.programmed_speed,
            self.css,
            self.spindle_clamp_rpm,
            self.tool,
            self.tool_offset_mm,
            self.work_offset_mm,
            self.axis_offset_mm,
            self.xy_rotation_deg,
            self.coordinate_system,
            self.cutter_comp,
            self.comp_radius_mm,
            self.coolant,
            self.diameter_mode,
        )

    def to_program(self, point_mm: Vec3) -> Vec3:
        """Program-frame position (mm) of a machine position of the controlled point.

        Inverts ``machine = work_offset + Rz(xy_rotation) (program + axis_offset) + tool_offset``.
        """
        w, t, a = self.work_offset_mm, self.tool_offset_mm, self.axis_offset_mm
        x = point_mm[0] - w[0] - t[0]
        y = point_mm[1] - w[1] - t[1]
        z = point_mm[2] - w[2] - t[2]
        if self.xy_rotation_deg:
            c = math.cos(math.radians(self.xy_rotation_deg))
            s = math.sin(math.radians(self.xy_rotation_deg))
            x, y = c * x + s * y, -s * x + c * y
        return (x - a[0], y - a[1], z - a[2])

    def to_machine(self, point_mm: Vec3) -> Vec3:
        """Machine position (mm) of the controlled point for a program-frame position (mm)."""
        w, t, a = self.work_offset_mm, self.tool_offset_mm, self.axis_offset_mm
        x, y, z = point_mm[0] + a[0], point_mm[1] + a[1], point_mm[2] + a[2]
        if self.xy_rotation_deg:
            c = math.cos(math.radians(self.xy_rotation_deg))
            s = math.sin(math.radians(self.xy_rotation_deg))
            x, y = c * x - s * y, s * x + c * y
        return (x + w[0] + t[0], y + w[1] + t[1], z + w[2] + t[2])


@dataclass(slots=True, init=False)
class Segment:
    """One motion of the controlled point, in machine coordinates.

    Treat segments as immutable values (use :func:`dataclasses.replace` to derive one);
    the class is not frozen only because frozen dataclasses are six times slower to
    create, and the interpreter creates one per motion block.

    Attributes
    ----------
    kind
        Rapid, linear feed, arc (or helix) feed, or dwell.
    line
        1-based line of the source file that produced the segment.
    start_mm, end_mm
        Machine coordinates (x, y, z) of the controlled point in mm.
    feed_mm_min
        Path feed rate of this move in mm/min with G93/G95 resolved;
        0.0 for rapids (the machine's rapid rate applies) and dwells.
    spindle_rpm
        Spindle speed during the move in rpm (signed by direction is *not* applied;
        see ``state.spindle_direction``); under G96 the speed at the segment's start.
    state
        Modal state in force.
    center_mm
        Arcs: centre in machine coordinates in mm; its normal-axis component equals
        ``start_mm``'s. ``None`` otherwise.
    turns
        Arcs: signed turn count (> 0 CCW, < 0 CW, see module notes); 0 otherwise.
    dwell_s
        Dwells: duration in s.
    start_abc_deg, end_abc_deg
        Rotary axes (a, b, c) in degrees.
    file
        Name of the source file (differs from the main file inside called subprograms).
    """

    kind: MotionKind
    line: int
    start_mm: Vec3
    end_mm: Vec3
    feed_mm_min: float
    spindle_rpm: float
    state: MachineState
    center_mm: Vec3 | None = None
    turns: int = 0
    dwell_s: float = 0.0
    start_abc_deg: Vec3 = field(default=ZERO3)
    end_abc_deg: Vec3 = field(default=ZERO3)
    file: str = ""

    def __init__(
        self,
        kind: MotionKind,
        line: int,
        start_mm: Vec3,
        end_mm: Vec3,
        feed_mm_min: float,
        spindle_rpm: float,
        state: MachineState,
        center_mm: Vec3 | None = None,
        turns: int = 0,
        dwell_s: float = 0.0,
        start_abc_deg: Vec3 = ZERO3,
        end_abc_deg: Vec3 = ZERO3,
        file: str = "",
    ) -> None:
        # Written out (init=False above; the fields and defaults are the dataclass's, a
        # test compares them): compiled by mypyc, a dataclass's generated __init__ would
        # stay interpreted Python, and one runs per motion.
        self.kind = kind
        self.line = line
        self.start_mm = start_mm
        self.end_mm = end_mm
        self.feed_mm_min = feed_mm_min
        self.spindle_rpm = spindle_rpm
        self.state = state
        self.center_mm = center_mm
        self.turns = turns
        self.dwell_s = dwell_s
        self.start_abc_deg = start_abc_deg
        self.end_abc_deg = end_abc_deg
        self.file = file

    @property
    def tcp_start_mm(self) -> Vec3:
        """Tool tip at the start in machine coordinates, mm."""
        o = self.state.tool_offset_mm
        s = self.start_mm
        return (s[0] - o[0], s[1] - o[1], s[2] - o[2])

    @property
    def tcp_end_mm(self) -> Vec3:
        """Tool tip at the end in machine coordinates, mm."""
        o = self.state.tool_offset_mm
        e = self.end_mm
        return (e[0] - o[0], e[1] - o[1], e[2] - o[2])

    @property
    def length_mm(self) -> float:
        """Path length of the controlled point in mm (helix length for arcs, 0 for dwells)."""
        return segment_length_mm(self)


def arc_sweep_rad(
    start: Vec3, end: Vec3, center: Vec3, turns: int, plane: Plane
) -> tuple[float, float, float]:
    """Geometry of an arc segment.

    Parameters
    ----------
    start, end, center
        Start, end and centre points in mm (any consistent frame).
    turns
        Signed turn count: > 0 counter-clockwise, < 0 clockwise about the plane normal.
    plane
        Plane of the arc.

    Returns
    -------
    radius_mm, start_angle_rad, sweep_rad
        Radius at the start in mm, start angle in the (first, second) frame in rad,
        and the signed swept angle in rad (positive CCW). A start equal to the end
        (in the plane) sweeps full circles.
    """
    i0, i1, _ = PLANE_AXES[plane]
    u0 = start[i0] - center[i0]
    v0 = start[i1] - center[i1]
    u1 = end[i0] - center[i0]
    v1 = end[i1] - center[i1]
    a0 = math.atan2(v0, u0)
    a1 = math.atan2(v1, u1)
    radius = math.hypot(u0, v0)
    extra = (abs(turns) - 1) * 2.0 * math.pi if turns else 0.0
    # Angle to travel counter-clockwise, in [0, 2 pi); an end at the start (within
    # float noise, also across the +-pi cut) is a full circle.
    ccw = (a1 - a0) % (2.0 * math.pi)
    if turns >= 0:
        if ccw <= 1e-12 or ccw >= 2.0 * math.pi - 1e-12:
            ccw = 2.0 * math.pi
        return radius, a0, ccw + extra
    cw = 2.0 * math.pi - ccw
    if cw <= 1e-12 or cw >= 2.0 * math.pi - 1e-12:
        cw = 2.0 * math.pi
    return radius, a0, -(cw + extra)


def segment_length_mm(seg: Segment) -> float:
    """Path length of a segment in mm: straight distance, helix length for arcs, 0 for dwells."""
    s, e = seg.start_mm, seg.end_mm
    if seg.kind == MotionKind.ARC and seg.center_mm is not None:
        plane = seg.state.plane
        radius, _, sweep = arc_sweep_rad(s, e, seg.center_mm, seg.turns, plane)
        normal = PLANE_AXES[plane][2]
        return math.hypot(radius * sweep, e[normal] - s[normal])
    if seg.kind == MotionKind.DWELL:
        return 0.0
    return math.sqrt((e[0] - s[0]) ** 2 + (e[1] - s[1]) ** 2 + (e[2] - s[2]) ** 2)
