"""Tests of cutter radius compensation (cnctwin.nc.cutter_comp).

Two kinds of checks:

1. closed forms on hand-built paths (squares offset outward and inward, arcs, tangent
   junctions, the errors);
2. LinuxCNC oracles driven by paths taken from the oracle itself: the programmed path
   is the uncompensated (or zero-radius) run of the same trace, or built by hand for the
   short ccomp programs; the compensated run of the trace is the expectation.
The same oracles run end to end through the interpreter in
test_golden_linuxcnc.py.

The traces print 4 decimals in program units, so positions are compared to 1e-4
program units (the printing error is 5e-5) unless a test says why it needs more.
"""

from __future__ import annotations

import itertools
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from cnctwin.errors import NCError
from cnctwin.nc.cutter_comp import CutterCompensator
from cnctwin.nc.segments import (
    PLANE_AXES,
    CutterComp,
    MachineState,
    MotionKind,
    Plane,
    Segment,
    Vec3,
)

MM_PER_INCH = 25.4


# --------------------------------------------------------------------------- data


def _data_dir() -> Path | None:
    env = os.environ.get("CNCTWIN_DATA")
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[3] / "shared" / "data")
    candidates.append(Path(__file__).resolve().parents[2] / ".." / "shared" / "data")
    for cand in candidates:
        if (cand / "gcode_golden").is_dir():
            return cand
    return None


def _golden(*parts: str) -> Path:
    base = _data_dir()
    if base is None:
        if os.environ.get("CNCTWIN_REQUIRE_DATA") == "1":
            pytest.fail("shared data folder not found (CNCTWIN_REQUIRE_DATA=1)")
        pytest.skip("shared data folder (../shared/data or $CNCTWIN_DATA) not found")
    return base.joinpath("gcode_golden", "linuxcnc", *parts)


# --------------------------------------------------------------------------- canonical traces


@dataclass(frozen=True)
class Move:
    """One motion of a LinuxCNC canonical trace, in machine coordinates and mm."""

    kind: str  # "traverse", "feed" or "arc"
    start: Vec3
    end: Vec3
    centre: Vec3 | None
    turns: int
    plane: Plane
    tol_mm: float  # 1e-4 program units, in mm


@dataclass
class Trace:
    """Motions of a trace, with the compensation comments as markers."""

    items: list[Move | str] = field(default_factory=list)


_CALL = re.compile(r"^\s*N\.+\s+([A-Z0-9_]+)\((.*)\)\s*$")
_PLANES = {
    "CANON_PLANE_XY": Plane.XY,
    "CANON_PLANE_XZ": Plane.ZX,
    "CANON_PLANE_YZ": Plane.YZ,
}


def read_trace(path: Path) -> Trace:
    """Parse a LinuxCNC canonical-call trace into moves in machine mm.

    Tracks USE_LENGTH_UNITS, SET_G5X_OFFSET, SET_G92_OFFSET, USE_TOOL_LENGTH_OFFSET and
    SELECT_PLANE; the positions a trace prints are in program units in the program frame.
    Compensation comments ``"on left"``, ``"on right"`` and ``"off"`` are kept as markers.
    """
    trace = Trace()
    scale = 1.0
    g5x = g92 = tlo = (0.0, 0.0, 0.0)
    plane = Plane.XY
    pos: Vec3 = (0.0, 0.0, 0.0)
    for line in path.read_text().splitlines():
        m = _CALL.match(line)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            scale = MM_PER_INCH if "INCHES" in args else 1.0
        elif name == "SELECT_PLANE":
            plane = _PLANES[args.strip()]
        elif name == "COMMENT" and "cutter radius compensation" in args:
            trace.items.append(args.strip('"').rsplit(" ", 1)[-1])
        elif name in ("SET_G5X_OFFSET", "SET_G92_OFFSET", "USE_TOOL_LENGTH_OFFSET"):
            nums = [float(v) for v in re.split(r"[,\s]+", args.strip()) if v]
            xyz = nums[1:4] if name == "SET_G5X_OFFSET" else nums[0:3]
            off = (xyz[0] * scale, xyz[1] * scale, xyz[2] * scale)
            if name == "SET_G5X_OFFSET":
                g5x = off
            elif name == "SET_G92_OFFSET":
                g92 = off
            else:
                tlo = off
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED"):
            v = [float(x) for x in args.split(",")]
            shift = tuple(g5x[i] + g92[i] + tlo[i] for i in range(3))

            def machine(p: list[float], shift: tuple[float, ...] = shift, k: float = scale) -> Vec3:
                return (p[0] * k + shift[0], p[1] * k + shift[1], p[2] * k + shift[2])

            if name == "ARC_FEED":
                i0, i1, i2 = PLANE_AXES[plane]
                e = [0.0, 0.0, 0.0]
                c = [0.0, 0.0, 0.0]
                e[i0], e[i1], e[i2] = v[0], v[1], v[5]
                c[i0], c[i1] = v[2], v[3]
                end = machine(e)
                cm = list(machine(c))
                cm[i2] = pos[i2]
                move = Move(
                    "arc",
                    pos,
                    end,
                    (cm[0], cm[1], cm[2]),
                    int(v[4]),
                    plane,
                    1e-4 * scale,
                )
            else:
                kind = "traverse" if name == "STRAIGHT_TRAVERSE" else "feed"
                end = machine(v[0:3])
                move = Move(kind, pos, end, None, 0, plane, 1e-4 * scale)
            trace.items.append(move)
            pos = end
    return trace


@dataclass
class Block:
    """A run of a trace between two ``off`` markers."""

    # "left", "right" or None (no "on" marker: compensation was never on)
    side: str | None
    before: Vec3  # position when compensation went on
    comp: list[Move]  # moves while compensation is on
    exit: Move | None  # the first move after ``off``


def comp_blocks(trace: Trace) -> list[Block]:
    """Split a trace at its ``off`` markers; blocks without moves are dropped.

    A block's compensated moves follow its ``on`` marker; a block without one (a run
    where the program skipped G41.1 for a zero diameter) starts after its last rapid.
    """
    blocks: list[Block] = []
    items = trace.items
    off_idx = [i for i, it in enumerate(items) if it == "off"]
    prev = -1
    for k in off_idx:
        seg = items[prev + 1 : k]
        on = [i for i, it in enumerate(seg) if it in ("left", "right")]
        if on:
            side: str | None = str(seg[on[-1]])
            body = seg[on[-1] + 1 :]
        else:
            side = None
            trav = [i for i, it in enumerate(seg) if isinstance(it, Move) and it.kind == "traverse"]
            body = seg[trav[-1] + 1 :] if trav else []
        moves = [m for m in body if isinstance(m, Move)]
        nxt = next((it for it in items[k + 1 :] if isinstance(it, Move)), None)
        if moves:
            blocks.append(Block(side, moves[0].start, moves, nxt))
        prev = k
    return blocks


# --------------------------------------------------------------------------- building segments


def _state(plane: Plane = Plane.XY, units: str = "mm") -> MachineState:
    return MachineState(units=units, plane=plane)  # type: ignore[arg-type]


def seg_from_move(move: Move, line: int = 0, feed: float = 100.0) -> Segment:
    """The Segment a trace move describes (its start is the previous end)."""
    kind = {
        "traverse": MotionKind.RAPID,
        "feed": MotionKind.LINEAR,
        "arc": MotionKind.ARC,
    }[move.kind]
    return Segment(
        kind=kind,
        line=line,
        start_mm=move.start,
        end_mm=move.end,
        feed_mm_min=0.0 if kind == MotionKind.RAPID else feed,
        spindle_rpm=0.0,
        state=_state(move.plane),
        center_mm=move.centre,
        turns=move.turns,
    )


class PathBuilder:
    """Hand-built programmed path in one plane, in program units (scaled to mm).

    ``line(end)`` and ``arc(end, centre, turns)`` take (x, y, z) of the program frame;
    the frame origin ``origin`` (work offset) is in program units too.
    """

    def __init__(
        self,
        start: Vec3,
        units: str = "mm",
        plane: Plane = Plane.XY,
        origin: Vec3 = (0, 0, 0),
    ):
        self.k = MM_PER_INCH if units == "inch" else 1.0
        self.units = units
        self.plane = plane
        self.origin = origin
        self.pos = self.mm(start)
        self.segs: list[Segment] = []

    def mm(self, p: Vec3) -> Vec3:
        return (
            (p[0] + self.origin[0]) * self.k,
            (p[1] + self.origin[1]) * self.k,
            (p[2] + self.origin[2]) * self.k,
        )

    def _add(self, kind: MotionKind, end: Vec3, centre: Vec3 | None = None, turns: int = 0) -> None:
        e = self.mm(end)
        c = None
        if centre is not None:
            c3 = list(self.mm(centre))
            c3[PLANE_AXES[self.plane][2]] = self.pos[PLANE_AXES[self.plane][2]]
            c = (c3[0], c3[1], c3[2])
        self.segs.append(
            Segment(
                kind=kind,
                line=len(self.segs) + 1,
                start_mm=self.pos,
                end_mm=e,
                feed_mm_min=0.0 if kind == MotionKind.RAPID else 100.0 + len(self.segs),
                spindle_rpm=1000.0,
                state=_state(self.plane, self.units),
                center_mm=c,
                turns=turns,
            )
        )
        self.pos = e

    def rapid(self, end: Vec3) -> PathBuilder:
        self._add(MotionKind.RAPID, end)
        return self

    def line(self, end: Vec3) -> PathBuilder:
        self._add(MotionKind.LINEAR, end)
        return self

    def arc(self, end: Vec3, centre: Vec3, turns: int) -> PathBuilder:
        self._add(MotionKind.ARC, end, centre, turns)
        return self


def run_comp(
    segs: list[Segment],
    side: CutterComp,
    radius_mm: float,
    plane: Plane = Plane.XY,
    start: Vec3 | None = None,
    orientation: int = 0,
) -> list[Segment]:
    """Push ``segs`` through a compensator and finish it."""
    comp = CutterCompensator(
        side,
        radius_mm,
        plane,
        start if start is not None else segs[0].start_mm,
        orientation,
    )
    out: list[Segment] = []
    for s in segs:
        out.extend(comp.push(s))
    out.extend(comp.finish())
    return out


def exit_move(after: list[Segment], programmed: Segment) -> Segment:
    """The exit move after G40: from the last compensated point to the programmed end."""
    start = after[-1].end_mm
    return Segment(
        kind=programmed.kind,
        line=programmed.line,
        start_mm=start,
        end_mm=programmed.end_mm,
        feed_mm_min=programmed.feed_mm_min,
        spindle_rpm=programmed.spindle_rpm,
        state=programmed.state,
        center_mm=programmed.center_mm,
        turns=programmed.turns,
    )


# --------------------------------------------------------------------------- comparing


def _close(a: Vec3, b: Vec3, tol: float) -> bool:
    return all(abs(a[i] - b[i]) <= tol for i in range(3))


def mismatch(got: list[Segment], expected: list[Move]) -> str | None:
    """Why ``got`` differs from ``expected`` (None when they agree)."""
    kinds = {
        MotionKind.RAPID: "traverse",
        MotionKind.LINEAR: "feed",
        MotionKind.ARC: "arc",
    }
    lines = []
    for i in range(max(len(got), len(expected))):
        g = got[i] if i < len(got) else None
        e = expected[i] if i < len(expected) else None
        if g is None or e is None:
            lines.append(
                f"#{i}: got {g and (kinds[g.kind], g.end_mm)} expected {e and (e.kind, e.end)}"
            )
            break
        tol = e.tol_mm + 1e-9
        ok = (
            kinds[g.kind] == e.kind
            and _close(g.end_mm, e.end, tol)
            and _close(g.start_mm, e.start, tol)
        )
        if ok and e.kind == "arc":
            assert g.center_mm is not None and e.centre is not None
            ok = g.turns == e.turns and _close(g.center_mm, e.centre, tol)
        if not ok:
            lines.append(
                f"#{i}: got {kinds[g.kind]} {_fmt(g.start_mm)}->{_fmt(g.end_mm)} "
                f"c={g.center_mm and _fmt(g.center_mm)} t={g.turns}; "
                f"expected {e.kind} {_fmt(e.start)}->{_fmt(e.end)} "
                f"c={e.centre and _fmt(e.centre)} t={e.turns}"
            )
            break
    return "\n".join(lines) or None


def _fmt(p: Vec3) -> str:
    return "(" + ", ".join(f"{v:.4f}" for v in p) + ")"


def xy(p: Vec3) -> tuple[float, float]:
    return (p[0], p[1])


def assert_xy(p: Vec3, expected: tuple[float, float], tol: float = 1e-9) -> None:
    assert p[0] == pytest.approx(expected[0], abs=tol) and p[1] == pytest.approx(
        expected[1], abs=tol
    ), (p, expected)


def assert_continuous(segs: list[Segment]) -> None:
    for a, b in itertools.pairwise(segs):
        assert _close(a.end_mm, b.start_mm, 1e-9), (a, b)


# --------------------------------------------------------------------------- 1. closed forms

R_TOOL = 1.5  # mm


def _square(builder: PathBuilder) -> PathBuilder:
    """Entry along +X to the origin, then the 10 mm square counter-clockwise, then out along +X."""
    return (
        builder.line((0, 0, 0))
        .line((10, 0, 0))
        .line((10, 10, 0))
        .line((0, 10, 0))
        .line((0, 0, 0))
        .line((5, 0, 0))
    )


def test_square_outside_gets_corner_arcs_of_the_tool_radius_about_the_corners() -> None:
    segs = _square(PathBuilder((-5, 0, 0))).segs
    # counter-clockwise square, tool on the right: outside
    out = run_comp(segs, CutterComp.RIGHT, R_TOOL)
    r = R_TOOL
    # (end, corner centre for the inserted arcs)
    expected: list[tuple[tuple[float, float], tuple[float, float] | None]] = [
        ((0, -r), None),
        ((10, -r), None),
        ((10 + r, 0), (10, 0)),
        ((10 + r, 10), None),
        ((10, 10 + r), (10, 10)),
        ((0, 10 + r), None),
        ((-r, 10), (0, 10)),
        ((-r, 0), None),
        ((0, -r), (0, 0)),
        ((5, -r), None),
    ]
    assert len(out) == len(expected)
    for seg, (end, corner) in zip(out, expected, strict=True):
        assert_xy(seg.end_mm, end)
        if corner is not None:
            # G42 goes round convex corners counter-clockwise
            assert seg.kind == MotionKind.ARC and seg.turns == 1
            assert seg.center_mm is not None
            assert_xy(seg.center_mm, corner)
            assert math.dist(xy(seg.start_mm), corner) == pytest.approx(r)
        else:
            assert seg.kind == MotionKind.LINEAR
    assert_xy(out[0].start_mm, (-5, 0))  # the entry starts where the tool is
    assert_continuous(out)


def test_square_inside_corners_are_the_offset_lines_intersections() -> None:
    segs = _square(PathBuilder((-5, 0, 0))).segs
    # counter-clockwise square, tool on the left: inside
    out = run_comp(segs, CutterComp.LEFT, R_TOOL)
    r = R_TOOL
    ends = [(0, r), (10 - r, r), (10 - r, 10 - r), (r, 10 - r), (r, r), (5, r)]
    assert [s.kind for s in out] == [MotionKind.LINEAR] * 6
    for seg, end in zip(out, ends, strict=True):
        assert_xy(seg.end_mm, end)
    assert_continuous(out)


@pytest.mark.parametrize(
    ("side", "sense", "radius"),
    [
        (CutterComp.LEFT, 1, 10.0 - R_TOOL),  # left of a CCW arc: inside
        (CutterComp.RIGHT, 1, 10.0 + R_TOOL),
        (CutterComp.LEFT, -1, 10.0 + R_TOOL),  # left of a CW arc: outside
        (CutterComp.RIGHT, -1, 10.0 - R_TOOL),
    ],
)
def test_arc_is_offset_to_radius_r_plus_or_minus_tool_radius(
    side: CutterComp, sense: int, radius: float
) -> None:
    # tangent line along -Y into a half circle about the origin from (10, 0) to (-10, 0)
    y0 = -20.0 if sense == 1 else 20.0
    b = PathBuilder((10, y0, 0)).line((10, 0, 0)).arc((-10, 0, 0), (0, 0, 0), sense)
    b.line((-10, y0, 0))
    out = run_comp(b.segs, side, R_TOOL)
    arcs = [s for s in out if s.kind == MotionKind.ARC]
    assert len(arcs) == 1  # tangent junctions: nothing inserted
    (arc,) = arcs
    assert arc.center_mm is not None
    assert_xy(arc.center_mm, (0, 0))
    assert math.dist(xy(arc.start_mm), (0, 0)) == pytest.approx(radius)
    assert math.dist(xy(arc.end_mm), (0, 0)) == pytest.approx(radius)
    assert arc.turns == sense
    assert_continuous(out)


def test_tangent_line_arc_junction_inserts_nothing() -> None:
    b = PathBuilder((-10, 5, 0)).line((0, 5, 0)).arc((5, 0, 0), (0, 0, 0), -1)
    out = run_comp(b.segs, CutterComp.LEFT, R_TOOL)
    assert [s.kind for s in out] == [MotionKind.LINEAR, MotionKind.ARC]
    assert_xy(out[0].end_mm, (0, 5 + R_TOOL))
    assert_xy(out[1].start_mm, (0, 5 + R_TOOL))
    assert_xy(out[1].end_mm, (5 + R_TOOL, 0))


def test_straight_entry_is_offset_perpendicular_to_its_own_direction() -> None:
    # entry at 45 degrees, then along +X: LinuxCNC offsets the entry end normal to the entry
    # (ccomp/mill-zchanges), then goes round the convex corner with an arc
    b = PathBuilder((0, 0, 0)).line((10, 10, 0)).line((20, 10, 0))
    out = run_comp(b.segs, CutterComp.LEFT, R_TOOL)
    s = R_TOOL / math.sqrt(2.0)
    assert_xy(out[0].end_mm, (10 - s, 10 + s))
    assert out[1].kind == MotionKind.ARC and out[1].turns == -1
    assert_xy(out[1].end_mm, (10, 10 + R_TOOL))
    assert_xy(out[2].end_mm, (20, 10 + R_TOOL))


def test_corner_arc_takes_the_following_moves_line_and_feed_and_is_emitted_before_it() -> None:
    b = PathBuilder((-5, 0, 0)).line((0, 0, 0)).line((10, 0, 0)).line((10, 10, 0))
    comp = CutterCompensator(CutterComp.RIGHT, R_TOOL, Plane.XY, b.segs[0].start_mm)
    assert comp.push(b.segs[0]) == []  # the entry is held until the next move is known
    first = comp.push(b.segs[1])
    assert [s.line for s in first] == [1]
    second = comp.push(b.segs[2])  # convex corner at (10, 0): move 2, then the arc
    assert [s.kind for s in second] == [MotionKind.LINEAR, MotionKind.ARC]
    assert second[0].line == 2 and second[0].feed_mm_min == b.segs[1].feed_mm_min
    assert second[1].line == 3 and second[1].feed_mm_min == b.segs[2].feed_mm_min
    last = comp.finish()
    assert [s.line for s in last] == [3]
    assert comp.position_mm == last[-1].end_mm
    assert comp.finish() == []


def test_moves_along_the_normal_pass_through_at_the_corrected_corner() -> None:
    # a Z-only move between two sides of a pocket: emitted after the held move, at the
    # inside-corner point the next side decides, and the corner keeps the new height
    b = (
        PathBuilder((-5, 0, 0))
        .line((0, 0, 0))
        .line((10, 0, 0))
        .line((10, 0, -2))
        .line((10, 10, -2))
    )
    out = run_comp(b.segs, CutterComp.LEFT, R_TOOL)
    assert [s.line for s in out] == [1, 2, 3, 4]
    assert out[2].start_mm == pytest.approx((10 - R_TOOL, R_TOOL, 0))
    assert out[2].end_mm == pytest.approx((10 - R_TOOL, R_TOOL, -2))
    assert out[3].end_mm == pytest.approx((10 - R_TOOL, 10, -2))
    assert_continuous(out)


def test_normal_moves_before_the_entry_pass_through_immediately() -> None:
    b = PathBuilder((0, 0, 5)).line((0, 0, 0)).line((10, 0, 0))
    comp = CutterCompensator(CutterComp.LEFT, R_TOOL, Plane.XY, b.segs[0].start_mm)
    (plunge,) = comp.push(b.segs[0])
    assert plunge.start_mm == (0, 0, 5) and plunge.end_mm == (0, 0, 0)


def test_negative_radius_compensates_on_the_other_side() -> None:
    segs = _square(PathBuilder((-5, 0, 0))).segs
    right = run_comp(segs, CutterComp.RIGHT, R_TOOL)
    left_negative = run_comp(segs, CutterComp.LEFT, -R_TOOL)
    assert [s.end_mm for s in right] == [s.end_mm for s in left_negative]


def test_zero_radius_reproduces_the_programmed_path() -> None:
    segs = _square(PathBuilder((-5, 0, 0))).arc((10, 0, 0), (7.5, 0, 0), 1).segs
    out = run_comp(segs, CutterComp.LEFT, 0.0)
    assert [s.end_mm for s in out] == [s.end_mm for s in segs]
    assert [s.center_mm for s in out] == [s.center_mm for s in segs]


def test_helix_keeps_its_normal_travel_and_arc_centre_height() -> None:
    b = PathBuilder((20, -10, 0)).line((20, 0, 0)).arc((-20, 0, -3), (0, 0, 0), 1)
    out = run_comp(b.segs, CutterComp.RIGHT, R_TOOL)
    arc = out[-1]
    assert arc.start_mm[2] == 0 and arc.end_mm[2] == -3
    assert arc.center_mm is not None and arc.center_mm[2] == 0


def test_tool_larger_than_an_inside_arc_is_an_error() -> None:
    b = PathBuilder((0.3, -5, 0)).line((0.3, 0, 0)).arc((-0.3, 0, 0), (0, 0, 0), 1)
    with pytest.raises(
        NCError, match=r"tool radius 0\.5 mm is larger than the arc radius 0\.3 mm"
    ) as err:
        run_comp(b.segs, CutterComp.LEFT, 0.5)
    assert err.value.line == 2


def test_tool_on_the_outside_of_a_small_arc_is_fine() -> None:
    b = PathBuilder((0.3, -5, 0)).line((0.3, 0, 0)).arc((-0.3, 0, 0), (0, 0, 0), 1)
    out = run_comp(b.segs, CutterComp.RIGHT, 0.5)
    assert math.dist(xy(out[-1].end_mm), (0, 0)) == pytest.approx(0.8)


def test_concave_corner_the_tool_cannot_reach_is_a_gouging_error() -> None:
    # line along +X, then a left turn into a CCW arc of radius 0.8 about (-0.8, 0): its
    # inside offset (radius 0.3) never reaches the line's offset at y = 0.5
    b = PathBuilder((-10, 0, 0)).line((0, 0, 0)).arc((-1.6, 0, 0), (-0.8, 0, 0), 1)
    with pytest.raises(NCError, match="gouging") as err:
        run_comp(b.segs, CutterComp.LEFT, 0.5)
    assert err.value.line == 2


def test_slot_narrower_than_the_tool_is_a_gouging_error() -> None:
    b = (
        PathBuilder((-5, 0, 0))
        .line((0, 0, 0))
        .line((10, 0, 0))
        .line((10, 0.4, 0))
        .line((0, 0.4, 0))
    )
    with pytest.raises(NCError, match="gouging") as err:
        run_comp(b.segs, CutterComp.LEFT, 1.0)
    assert err.value.line == 3  # the 0.4 mm side would run backwards


def test_arc_outside_the_compensation_plane_is_an_error() -> None:
    b = PathBuilder((0, 0, 0), plane=Plane.ZX).line((0, 0, 5)).arc((5, 0, 10), (0, 0, 10), 1)
    comp = CutterCompensator(CutterComp.LEFT, 1.0, Plane.XY, (0, 0, 0))
    comp.push(b.segs[0])
    with pytest.raises(NCError, match="G18"):
        comp.push(b.segs[1])


@pytest.mark.parametrize("side", [CutterComp.OFF])
def test_side_must_be_left_or_right(side: CutterComp) -> None:
    with pytest.raises(NCError, match="LEFT"):
        CutterCompensator(side, 1.0, Plane.XY, (0, 0, 0))


def test_lathe_orientation_moves_the_path_to_the_imaginary_tip() -> None:
    # G18, facing along -X to x=1, then turning along +Z: G41 keeps the nose centre on +Z of
    # the face and on +X of the diameter, so the inside corner puts it at (x 1.5, z 0.5);
    # orientation 2 has the tip r lower in Z and in X (ccomp/lathe-comp, tool T2)
    b = PathBuilder((5, 0, 0), plane=Plane.ZX).line((1, 0, 0)).line((1, 0, 10))
    out = run_comp(b.segs, CutterComp.LEFT, 0.5, plane=Plane.ZX, orientation=2)
    # the entry starts at the tip, where the tool is
    assert out[0].start_mm == (5, 0, 0)
    assert out[0].end_mm == pytest.approx((1.0, 0, 0))
    assert out[-1].end_mm == pytest.approx((1.0, 0, 9.5))
    plain = run_comp(b.segs, CutterComp.LEFT, 0.5, plane=Plane.ZX)
    assert plain[-1].end_mm == pytest.approx((1.5, 0, 10))
    assert (
        run_comp(b.segs, CutterComp.LEFT, 0.5, plane=Plane.ZX, orientation=9)[-1].end_mm
        == plain[-1].end_mm
    )


# --------------------------------------------------------------------------- property


def _convex_polygon(angles: list[float], radii: list[float]) -> list[tuple[float, float]]:
    pts = [
        (rr * math.cos(a), rr * math.sin(a)) for a, rr in zip(sorted(angles), radii, strict=False)
    ]
    # keep the convex hull (counter-clockwise)
    pts.sort()
    hull: list[tuple[float, float]] = []
    for sweep in (pts, pts[::-1]):
        part: list[tuple[float, float]] = []
        for p in sweep:
            while (
                len(part) >= 2
                and (part[-1][0] - part[-2][0]) * (p[1] - part[-2][1])
                - (part[-1][1] - part[-2][1]) * (p[0] - part[-2][0])
                <= 1e-6
            ):
                part.pop()
            part.append(p)
        hull.extend(part[:-1])
    return hull


def _dist_to_polygon(p: tuple[float, float], poly: list[tuple[float, float]]) -> float:
    best = math.inf
    for a, b in zip(poly, poly[1:] + poly[:1], strict=True):
        ab = (b[0] - a[0], b[1] - a[1])
        t = max(
            0.0,
            min(
                1.0,
                ((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / (ab[0] ** 2 + ab[1] ** 2),
            ),
        )
        best = min(best, math.dist(p, (a[0] + t * ab[0], a[1] + t * ab[1])))
    return best


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0, 2 * math.pi), min_size=5, max_size=9, unique=True),
    st.lists(st.floats(20, 40), min_size=9, max_size=9),
    st.floats(0.5, 5),
)
def test_outside_offset_of_a_convex_polygon_stays_at_the_tool_radius(
    angles: list[float], radii: list[float], r: float
) -> None:
    poly = _convex_polygon(angles, radii)
    if len(poly) < 3:
        return
    # the first edge is the entry move, which LinuxCNC (and cnctwin) refuse when it is shorter
    # than the tool radius (tests/nc/test_rs274_constructs.py, against rs274)
    assume(math.dist(poly[0], poly[1]) > r)
    start = poly[0]
    b = PathBuilder((start[0] - 50, start[1] - 50, 0)).line((start[0], start[1], 0))
    for p in poly[1:] + poly[:1]:
        b.line((p[0], p[1], 0))
    out = run_comp(b.segs[1:], CutterComp.RIGHT, r, start=b.segs[1].start_mm)
    assert_continuous(out)
    for seg in out[1:]:  # all but the entry lie on the offset contour
        assert _dist_to_polygon(xy(seg.end_mm), poly) == pytest.approx(r, abs=1e-7)
    # an arc at every corner but the tangent-like ones (offset ends within 0.0025 mm)
    turns = []
    for p0, p1, p2 in zip(poly, poly[1:] + poly[:1], poly[2:] + poly[:2], strict=True):
        a0 = math.atan2(p1[1] - p0[1], p1[0] - p0[0])
        a1 = math.atan2(p2[1] - p1[1], p2[0] - p1[0])
        turns.append(abs(math.remainder(a1 - a0, 2 * math.pi)))
    expected = sum(2 * r * math.sin(t / 2) > 0.0025 for t in turns[:-1])
    assert sum(s.kind == MotionKind.ARC for s in out) == expected


# ---------------------------------------------------------- 2. oracles, paths from the traces

INCH = MM_PER_INCH


def _moves(trace: Trace) -> list[Move]:
    return [it for it in trace.items if isinstance(it, Move)]


def _check_block(
    programmed: list[Segment],
    expected: list[Move],
    side: CutterComp,
    radius_mm: float,
    plane: Plane,
    start: Vec3,
    exit_programmed: Segment | None = None,
    orientation: int = 0,
    extra_tol_mm: float = 0.0,
) -> None:
    out = run_comp(programmed, side, radius_mm, plane, start=start, orientation=orientation)
    if exit_programmed is not None:
        out.append(exit_move(out, exit_programmed))
    if extra_tol_mm:
        expected = [replace_tol(m, m.tol_mm + extra_tol_mm) for m in expected]
    problem = mismatch(out, expected)
    assert problem is None, problem


def replace_tol(m: Move, tol: float) -> Move:
    return Move(m.kind, m.start, m.end, m.centre, m.turns, m.plane, tol)


@pytest.mark.validation
def test_oracle_mill_line_arc_entry() -> None:
    """Handbook figure 3: line entry, tangent arcs, convex and concave junctions (G20, D=1 in)."""
    moves = _moves(read_trace(_golden("ccomp", "mill-line-arc-entry", "expected")))
    # moves[0] rapid to (1, 5); 1-9 the outline without compensation; 10 rapid back;
    # 11- the outline with G41 and tool 4 (diameter 1.0 inch in the tool table)
    assert moves[10].kind == "traverse" and moves[10].end == moves[0].end
    programmed = [seg_from_move(m, i + 1) for i, m in enumerate(moves[1:10])]
    _check_block(programmed, moves[11:], CutterComp.LEFT, 0.5 * INCH, Plane.XY, moves[10].end)


@pytest.mark.validation
def test_oracle_mill_g90g91g92() -> None:
    """Arc entry (new centre), convex corners between arcs and lines, helices, a Z move, G92."""
    trace = read_trace(_golden("ccomp", "mill-g90g91g92", "expected"))
    (block,) = comp_blocks(trace)
    # the program after G92 Z.5 (program z + 0.5 = machine z), G20, tool 3 (D 0.25 in)
    b = PathBuilder((2, 0, 0.5), units="inch", origin=(0, 0, 0.5))
    half = 0.5 * math.sqrt(2.0)
    b.arc((1, 0, 0), (1.5, -0.5, 0), 1)  # G3 X1Y0 R[.5*SQRT[2]] Z0 (R chord half = .5)
    b.arc((0, 1, 0), (1, 1, 0), -1)  # G91 G2 X-1Y1 R1
    # G90 G3 X1Y2Z.4 R2: centre 1.8708 left of the chord midpoint
    d = math.sqrt(4.0 - 0.5)
    b.arc((1, 2, 0.4), (0.5 - d * half, 1.5 + d * half, 0), 1)
    b.line((2, 1, 0.2)).line((1, 0, 0)).rapid((1, 0, 1))
    _check_block(b.segs, block.comp, CutterComp.LEFT, 0.125 * INCH, Plane.XY, block.before)


def _zchanges_path(
    y: float, arc_entry: bool, zs: tuple[float, float, float, float]
) -> tuple[PathBuilder, Segment]:
    """One block of ccomp/mill-zchanges; ``zs``: z before G41, after entry, after the line,
    after G40."""
    b = PathBuilder((0.25, y, zs[0]), units="inch")
    if arc_entry:
        b.arc((0.5, 0.75, zs[1]), (0.5, 0.5, 0), -1)  # g41 g2 x.5 y.75 i.25
        b.line((0.75, 0.75, zs[2]))
    else:
        b.line((0.5, -0.25, zs[1]))  # g41 g1 x.5 y-.25
        b.line((0.75, -0.25, zs[2]))
    exit_b = PathBuilder((0.75, b.segs[-1].end_mm[1] / INCH, zs[2]), units="inch").line(
        (1, b.segs[-1].end_mm[1] / INCH, zs[3])
    )
    return b, exit_b.segs[0]


_ZCHANGES = [  # (z before, z after the entry, after the next move, after the exit), radius in
    ((0.25, 0.25, 0.25, 0.25), 0.0),  # d0: tool 0, no radius
    ((0.0, 0.0, 0.0, 0.0), 0.0625),  # d2: tool 2, D 0.125 in
    ((0.25, 0.0, 0.0, 0.0), 0.0625),
    ((0.25, 0.25, 0.0, 0.0), 0.0625),
    ((0.25, 0.25, 0.25, 0.0), 0.0625),
]


@pytest.mark.validation
@pytest.mark.parametrize("entry", ["arc", "line"])
@pytest.mark.parametrize("case", range(len(_ZCHANGES)))
def test_oracle_mill_zchanges(entry: str, case: int) -> None:
    """Entry by arc and by line, with the Z change in the entry, the next move or the exit."""
    blocks = comp_blocks(read_trace(_golden("ccomp", "mill-zchanges", "expected")))
    assert len(blocks) == 10
    block = blocks[case + (0 if entry == "arc" else 5)]
    zs, r_in = _ZCHANGES[case]
    b, exit_seg = _zchanges_path(0.5 if entry == "arc" else -0.5, entry == "arc", zs)
    assert block.exit is not None
    _check_block(
        b.segs,
        block.comp + [block.exit],
        CutterComp.LEFT,
        r_in * INCH,
        Plane.XY,
        block.before,
        exit_seg,
    )


@pytest.mark.validation
def test_oracle_lathe_comp_tool_2() -> None:
    """G18 lathe profile, G41, tool 2: orientation 2, D 0.1 in; path as cut with tool 0 first."""
    moves = _moves(read_trace(_golden("ccomp", "lathe-comp", "expected")))
    # 0 rapid to x.3 z0; 1-6 the profile without compensation; 7-8 rapids; 9-14 with G41; 15 exit
    assert moves[8].end == moves[0].end
    programmed = [seg_from_move(m, i + 1) for i, m in enumerate(moves[1:7])]
    _check_block(
        programmed,
        moves[9:16],
        CutterComp.LEFT,
        0.05 * INCH,
        Plane.ZX,
        moves[8].end,
        exit_programmed=seg_from_move(moves[15]),
        orientation=2,
    )


@pytest.mark.validation
def test_oracle_lathe_comp_tool_7() -> None:
    """The same profile the other way with G42, tool 7: orientation 7, D 0.1 in."""
    moves = _moves(read_trace(_golden("ccomp", "lathe-comp", "expected")))
    b = PathBuilder((-0.3, 0, 1.85), units="inch", plane=Plane.ZX)
    b.line((-0.4, 0, 1.85))  # g42 g1 x-.4
    b.arc((-0.5, 0, 1.75), (-0.4, 0, 1.75), -1)  # g2 x-.5 z1.75 r.1
    b.line((-0.5, 0, 1.5))
    b.arc((-0.25, 0, 1.25), (-0.25, 0, 1.5), -1)  # g2 r.25 x-.25 z1.25
    b.arc((0, 0, 1), (-0.25, 0, 1), 1)  # g3 r.25 x0 z1
    b.line((0, 0, 0.1))
    b.arc((0.1, 0, 0), (0.1, 0, 0.1), -1)  # g2 r.1 x.1 z0
    _check_block(
        b.segs,
        moves[18:26],
        CutterComp.RIGHT,
        0.05 * INCH,
        Plane.ZX,
        moves[17].end,
        exit_programmed=seg_from_move(moves[25]),
        orientation=7,
    )


@pytest.mark.validation
@pytest.mark.parametrize("plane", [Plane.XY, Plane.ZX])
@pytest.mark.parametrize("side", ["right", "left"])
def test_oracle_inside_corners(plane: Plane, side: str) -> None:
    """Every line/arc junction: concave, convex, tangent, cusps; G41.1 D+-0.15 in, XY and ZX.

    The programmed path is the run with D0 (compensation on, radius 0) of the same trace;
    the program's coordinates have 4 decimals, so that run is exact.
    """
    blocks = comp_blocks(read_trace(_golden("interp", "inside-corners", "expected")))
    assert len(blocks) == 6
    base = 0 if plane == Plane.XY else 3
    prog = blocks[base]
    block = blocks[base + (1 if side == "right" else 2)]
    assert block.side == side and prog.exit is not None
    programmed = [seg_from_move(m, i + 1) for i, m in enumerate(prog.comp)]
    _check_block(
        programmed,
        block.comp + [block.exit] if block.exit else block.comp,
        CutterComp.LEFT if side == "left" else CutterComp.RIGHT,
        0.075 * INCH,
        plane,
        block.before,
        exit_programmed=seg_from_move(prog.exit),
    )


@pytest.mark.validation
@pytest.mark.parametrize("sub", range(25))
def test_oracle_crazy_paths(sub: int) -> None:
    """The compensation torture test: 25 random paths, G41.1 D-0.5 (right) and D0.5 (left), mm.

    The programmed path is the uncompensated run of the same trace, whose 4 printed
    decimals round the program's 6: the inputs carry up to 5e-5 mm of error, which the
    intersections at shallow concave corners amplify up to 3.4e-4 mm; hence 5e-4 mm here
    (the end-to-end test through the interpreter keeps 1e-4).
    """
    blocks = comp_blocks(read_trace(_golden("interp", "crazy-paths", "expected")))
    assert len(blocks) == 75
    prog = blocks[3 * sub]
    assert prog.side is None and prog.exit is not None
    programmed = [seg_from_move(m, i + 1) for i, m in enumerate(prog.comp)]
    for block, side in (
        (blocks[3 * sub + 1], CutterComp.RIGHT),
        (blocks[3 * sub + 2], CutterComp.LEFT),
    ):
        assert block.exit is not None
        _check_block(
            programmed,
            block.comp + [block.exit],
            side,
            0.25,
            Plane.XY,
            block.before,
            exit_programmed=seg_from_move(prog.exit),
            extra_tol_mm=4e-4,
        )
