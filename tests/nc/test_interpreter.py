"""Unit tests of cnctwin.nc.interpreter beyond the LinuxCNC oracles.

Every expectation here is derived by hand, in the comments next to it, from the
RS274NGC definition (NIST RS274NGC v3, as LinuxCNC implements it) or from a closed form:
an arc of radius r sweeping an angle a is r*|a| long, a helix adds its rise in
quadrature, an inch is 25.4 mm, inverse time feed is length*F, feed per revolution is
F*rpm, constant surface speed is rpm = 1000*V/(2*pi*r). Nothing is compared with an
earlier output of the interpreter itself.

Conventions of the checks: machine coordinates of the controlled point in mm
(``Segment.end_mm``); the tool tip is ``Segment.tcp_end_mm``. Tolerances are float noise
(1e-9 mm) unless a comment says otherwise.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

import cnctwin.nc.owords as owords_module
from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter, interpret_text
from cnctwin.nc.segments import MotionKind, Plane, Segment
from cnctwin.nc.setup import NCSetup, ToolEntry

TOL = 1e-9
R75 = math.sqrt(75.0)  # half-chord 5, radius 10: distance of the centre from the chord
PI = math.pi
RAPID, LINEAR, ARC, DWELL = MotionKind.RAPID, MotionKind.LINEAR, MotionKind.ARC, MotionKind.DWELL


# ---------------------------------------------------------------------------- helpers
def run(
    text: str, setup: NCSetup | None = None, name: str = "job.ngc"
) -> tuple[Interpreter, list[Segment]]:
    """Interpret ``text`` completely; return the interpreter and all segments."""
    interp = Interpreter(setup)
    return interp, list(interp.run_text(text, name))


def segments(text: str, setup: NCSetup | None = None) -> list[Segment]:
    return run(text, setup)[1]


def moving(segs: list[Segment]) -> list[Segment]:
    """Segments that move the controlled point (zero-length moves and dwells dropped)."""
    return [s for s in segs if (s.kind != DWELL and s.start_mm != s.end_mm) or s.kind == ARC]


def ends(segs: list[Segment]) -> list[tuple[float, float, float]]:
    return [s.end_mm for s in segs]


def assert_point(actual, expected, tol: float = TOL) -> None:
    assert len(actual) == len(expected)
    for a, e in zip(actual, expected, strict=True):
        assert abs(a - e) <= tol, f"{tuple(actual)} != {tuple(expected)}"


def assert_moves(segs: list[Segment], expected: list[tuple], tol: float = TOL) -> None:
    """``expected``: (kind, end point) or (DWELL, seconds) per segment, in order."""
    got = [(s.kind.name, s.dwell_s if s.kind == DWELL else s.end_mm) for s in segs]
    assert len(segs) == len(expected), f"got {got}"
    for seg, exp in zip(segs, expected, strict=True):
        assert seg.kind == exp[0], f"got {got}"
        if seg.kind == DWELL:
            assert seg.dwell_s == pytest.approx(exp[1]), f"got {got}"
        else:
            assert_point(seg.end_mm, exp[1], tol)


def expect_error(
    text: str, line: int, *phrases: str, setup: NCSetup | None = None, name: str = "job.ngc"
) -> NCError:
    """The program must fail with an NCError at ``line`` whose text has every phrase."""
    with pytest.raises(NCError) as info:
        run(text, setup, name)
    err = info.value
    assert err.line == line, str(err)
    assert str(err).startswith(f"{name}:{line}: "), str(err)
    for phrase in phrases:
        assert phrase.lower() in str(err).lower(), str(err)
    return err


# ---------------------------------------------------------------------------- arcs
# Plane frames (first, second, normal): G17 (X, Y, Z), G18 (Z, X, Y), G19 (Y, Z, X); G3
# is counter-clockwise seen from the positive normal, so G3 turns first -> second.
# (program, centre, end, turns, length). All start from the end of the previous line.
ARC_CASES = {
    # G17 quarter from +X to +Y about the origin: CCW 90 deg, r=10 -> 10*pi/2.
    "g17-g3-ij": ("G17\nG0 X10 Y0\nG3 X0 Y10 I-10 J0", (0, 0, 0), (0, 10, 0), 1, 5 * PI),
    # From +Y to +X clockwise: 90 deg.
    "g17-g2-ij": ("G17\nG0 X0 Y10\nG2 X10 Y0 I0 J-10", (0, 0, 0), (10, 0, 0), -1, 5 * PI),
    # From +X to +Y clockwise is the long way round: 270 deg.
    "g17-g2-long": ("G17\nG0 X10 Y0\nG2 X0 Y10 I-10", (0, 0, 0), (0, 10, 0), -1, 15 * PI),
    # G18: from +Z to +X is CCW about +Y (Z x X = Y): 90 deg for G3, 270 for G2. The
    # centre keeps the start's Y (3).
    "g18-g3-ik": ("G18\nG0 X0 Y3 Z10\nG3 X10 Z0 I0 K-10", (0, 3, 0), (10, 3, 0), 1, 5 * PI),
    "g18-g2-ik": ("G18\nG0 X0 Y3 Z10\nG2 X10 Z0 I0 K-10", (0, 3, 0), (10, 3, 0), -1, 15 * PI),
    # G19: from +Y to +Z is CCW about +X.
    "g19-g3-jk": ("G19\nG0 X-2 Y10 Z0\nG3 Y0 Z10 J-10 K0", (-2, 0, 0), (-2, 0, 10), 1, 5 * PI),
    "g19-g2-jk": ("G19\nG0 X-2 Y10 Z0\nG2 Y0 Z10 J-10 K0", (-2, 0, 0), (-2, 0, 10), -1, 15 * PI),
    # R format, chord (0,0)->(10,0), r=10: centre 5 along the chord and sqrt(75) off it.
    # G2 R+ (< 180 deg): centre right of the chord (-Y); the arc sweeps 60 deg.
    "g17-g2-r+": ("G0 X0 Y0\nG2 X10 Y0 R10", (5, -R75, 0), (10, 0, 0), -1, 10 * PI / 3),
    "g17-g3-r+": ("G0 X0 Y0\nG3 X10 Y0 R10", (5, R75, 0), (10, 0, 0), 1, 10 * PI / 3),
    # Negative R: the other centre, the arc sweeps 300 deg.
    "g17-g2-r-": ("G0 X0 Y0\nG2 X10 Y0 R-10", (5, R75, 0), (10, 0, 0), -1, 50 * PI / 3),
    "g17-g3-r-": ("G0 X0 Y0\nG3 X10 Y0 R-10", (5, -R75, 0), (10, 0, 0), 1, 50 * PI / 3),
    # R equal to half the chord: a half circle.
    "g17-g3-r-half": ("G0 X0 Y0\nG3 X10 Y0 R5", (5, 0, 0), (10, 0, 0), 1, 5 * PI),
    # G18 chord along Z (first axis); CCW with R+ puts the centre on the left of the
    # chord in the (Z, X) frame, i.e. at +X.
    "g18-g3-r+": ("G18\nG0 X0 Y0 Z0\nG3 X0 Z10 R10", (R75, 0, 5), (0, 0, 10), 1, 10 * PI / 3),
    # G19 chord along Y (first axis); CW with R+: centre on the right, i.e. at -Z.
    "g19-g2-r+": ("G19\nG0 X0 Y0 Z0\nG2 Y10 Z0 R10", (0, 5, -R75), (0, 10, 0), -1, 10 * PI / 3),
    # Inch: radius 1 in = 25.4 mm.
    "g20-g3": ("G20\nG0 X1 Y0\nG3 X0 Y1 I-1", (0, 0, 0), (0, 25.4, 0), 1, 25.4 * PI / 2),
    # Incremental end point (G91) with incremental centre (G91.1 default).
    "g91-g3": ("G0 X10 Y0\nG91 G3 X-10 Y10 I-10", (0, 0, 0), (0, 10, 0), 1, 5 * PI),
    # Full circles: end == start, one turn, 2*pi*r.
    "full-g3": ("G0 X10 Y0\nG3 X10 Y0 I-10", (0, 0, 0), (10, 0, 0), 1, 20 * PI),
    "full-g2": ("G0 X10 Y0\nG2 X10 Y0 I-10", (0, 0, 0), (10, 0, 0), -1, 20 * PI),
    "full-g2-no-axis-words": ("G0 X10 Y0\nG2 I-10", (0, 0, 0), (10, 0, 0), -1, 20 * PI),
    "full-g18": ("G18\nG0 X0 Z10\nG2 Z10 K-10", (0, 0, 0), (0, 0, 10), -1, 20 * PI),
    # P-word helix: 3 full turns of r=10 while Z falls 6: sqrt((2*pi*10*3)^2 + 6^2).
    "helix-p3": (
        "G0 X10 Y0 Z0\nG3 X10 Y0 Z-6 I-10 P3",
        (0, 0, 0),
        (10, 0, -6),
        3,
        math.hypot(60 * PI, 6),
    ),
    # P2 with a partial end: CW from +X to +Y is 270 deg, plus one extra turn: 630 deg.
    "helix-p2-partial": (
        "G0 X10 Y0 Z0\nG2 X0 Y10 Z-3 I-10 P2",
        (0, 0, 0),
        (0, 10, -3),
        -2,
        math.hypot(10 * 3.5 * PI, 3),
    ),
    # Quarter helix.
    "helix-quarter": (
        "G0 X10 Y0 Z0\nG3 X0 Y10 Z-3 I-10",
        (0, 0, 0),
        (0, 10, -3),
        1,
        math.hypot(5 * PI, 3),
    ),
    # G90.1: I/J are absolute centre coordinates in the program frame.
    "g90.1": ("G90.1\nG0 X10 Y0\nG3 X0 Y10 I0 J0", (0, 0, 0), (0, 10, 0), 1, 5 * PI),
    # ... and follow the work offset: G54 at (100, 50) puts the centre at machine (100, 50).
    "g90.1-offset": (
        "G10 L2 P1 X100 Y50\nG54 G90.1\nG0 X10 Y0\nG3 X0 Y10 I0 J0",
        (100, 50, 0),
        (100, 60, 0),
        1,
        5 * PI,
    ),
    # The same arc with G91.1 incremental centre offsets.
    "g91.1-offset": (
        "G10 L2 P1 X100 Y50\nG54 G91.1\nG0 X10 Y0\nG3 X0 Y10 I-10 J0",
        (100, 50, 0),
        (100, 60, 0),
        1,
        5 * PI,
    ),
}


@pytest.mark.parametrize("name", list(ARC_CASES))
def test_arc_geometry(name: str) -> None:
    program, centre, end, turns, length = ARC_CASES[name]
    segs = segments("G21 G90 F100\n" + program)
    arc = segs[-1]
    assert arc.kind == ARC
    assert_point(arc.center_mm, centre)
    assert_point(arc.end_mm, end)
    assert arc.turns == turns
    assert arc.length_mm == pytest.approx(length, abs=1e-9)
    # Start and end lie on one circle about the centre (in the plane).
    plane = arc.state.plane
    i0, i1 = {Plane.XY: (0, 1), Plane.ZX: (2, 0), Plane.YZ: (1, 2)}[plane]
    r0 = math.hypot(arc.start_mm[i0] - arc.center_mm[i0], arc.start_mm[i1] - arc.center_mm[i1])
    r1 = math.hypot(arc.end_mm[i0] - arc.center_mm[i0], arc.end_mm[i1] - arc.center_mm[i1])
    assert r0 == pytest.approx(r1, abs=1e-9)
    # The arc starts where the previous move ended.
    assert arc.start_mm == segs[-2].end_mm


def test_helical_pitch_from_the_closed_form_length() -> None:
    # Quarter helix r=10, rise -3: a full turn would rise 4*3 = 12. From L^2 = (r*a)^2 + h^2
    # the swept angle is a = sqrt(L^2 - h^2)/r, so the pitch is 2*pi*h/a.
    arc = segments("G21 F100\nG0 X10 Y0 Z0\nG3 X0 Y10 Z-3 I-10")[-1]
    h = arc.end_mm[2] - arc.start_mm[2]
    sweep = math.sqrt(arc.length_mm**2 - h**2) / 10.0
    assert sweep == pytest.approx(PI / 2)
    assert 2 * PI * h / sweep == pytest.approx(-12.0)


def test_arc_feed_and_start_on_circle_after_units_switch() -> None:
    # G20 arc after a G21 move: the start stays where the G21 move left it (10 mm).
    segs = segments("G21 F100\nG0 X10 Y0\nG20\nG3 X0 Y[10/25.4] I[-10/25.4] F10")
    arc = segs[-1]
    assert_point(arc.center_mm, (0, 0, 0))
    assert arc.length_mm == pytest.approx(5 * PI)
    assert arc.feed_mm_min == pytest.approx(254.0)


ARC_ERRORS = {
    # Centre (0,0): start radius 10, end (0, 11) radius 11.
    "radius-mismatch": ("G21 F100\nG0 X10 Y0\nG3 X0 Y11 I-10", 3, ("10.0000", "11.0000")),
    # G90.1 makes I-10 an absolute centre (-10, 0): start radius 20, end sqrt(200).
    "g90.1-with-incremental-centre": (
        "G21 F100 G90.1\nG0 X10 Y0\nG3 X0 Y10 I-10 J0",
        3,
        ("20.0000", "14.1421"),
    ),
    # Chord 10, R4 < 5.
    "r-too-small": ("G21 F100\nG0 X0 Y0\nG2 X10 Y0 R4", 3, ("R4", "smaller")),
    "full-circle-with-r": ("G21 F100\nG0 X0 Y0\nG2 X0 Y0 R5", 3, ("full circle",)),
    "k-in-g17": ("G21 F100\nG17 G2 X1 Y1 K1", 2, ("K word",)),
    "i-in-g19": ("G21 F100\nG19 G2 Y1 Z1 I1", 2, ("I word",)),
    "no-centre": ("G21 F100\nG2 X1 Y1", 2, ("centre",)),
    "r-and-ij": ("G21 F100\nG2 X1 Y1 R1 I1", 2, ("R",)),
    "p-zero": ("G21 F100\nG0 X10\nG3 X10 I-10 P0", 3, ("P0",)),
    "p-fraction": ("G21 F100\nG0 X10\nG3 X10 I-10 P1.5", 3, ("P1.5",)),
    "zero-radius": ("G21 F100\nG0 X10\nG3 X20 I0 J0", 3, ("radi",)),
}


@pytest.mark.parametrize("name", list(ARC_ERRORS))
def test_arc_errors(name: str) -> None:
    program, line, phrases = ARC_ERRORS[name]
    expect_error(program, line, *phrases)


def test_radius_tolerance_is_small() -> None:
    # 0.1 mm end-radius error on r=10 is far beyond any controller tolerance.
    expect_error("G21 F100\nG0 X10 Y0\nG3 X0 Y10.1 I-10", 3, "radii")


# ---------------------------------------------------------------------------- units
def test_inch_program_values_are_converted_to_mm() -> None:
    interp, segs = run("G20\nG0 X1 Y2 Z-0.5")
    assert_point(segs[-1].end_mm, (25.4, 50.8, -12.7))
    assert segs[-1].state.units == "inch"
    assert interp.units == "inch"


def test_units_switch_mid_program() -> None:
    # The position is kept across a switch; only the meaning of new numbers changes.
    interp, segs = run("G20 G0 X1\nG21 G0 Y1\nG20 G91 G0 X1\nG21 X1 Z-2")
    assert_moves(
        segs,
        [
            (RAPID, (25.4, 0, 0)),
            (RAPID, (25.4, 1, 0)),
            (RAPID, (50.8, 1, 0)),
            (RAPID, (51.8, 1, -2)),
        ],
    )
    assert [s.state.units for s in segs] == ["inch", "mm", "inch", "mm"]
    assert interp.units == "inch"  # the first units the program selected


def test_program_without_units_defaults_to_mm() -> None:
    interp, segs = run("G0 X1")
    assert_point(segs[0].end_mm, (1, 0, 0))
    assert interp.units is None or interp.units == "mm"


@pytest.mark.parametrize(
    ("program", "feed"),
    [
        ("G21 G1 X1 F100", 100.0),
        ("G20 G1 X1 F10", 254.0),  # 10 in/min
        ("G20 G1 X1 F0.5", 12.7),
    ],
)
def test_feed_units(program: str, feed: float) -> None:
    assert segments(program)[-1].feed_mm_min == pytest.approx(feed)


def test_units_switch_keeps_the_physical_feed_rate() -> None:
    # LinuxCNC convert_length_units: "feed rate ... in effect [is] converted by rereading
    # [it] from the canon level": the machine keeps feeding at the same speed, F254 mm/min
    # becomes F10 in/min. Both directions.
    segs = segments("G21 F254\nG1 X1\nG20\nG1 X1")
    assert [s.feed_mm_min for s in segs] == pytest.approx([254.0, 254.0])
    segs = segments("G20 F10\nG1 X1\nG21\nG1 X30")
    assert [s.feed_mm_min for s in segs] == pytest.approx([254.0, 254.0])


def test_sinumerik_g700_g710() -> None:
    # Sinumerik G700 = inch (lengths and feeds), G710 = metric.
    interp = Interpreter()
    segs = list(interp.run_text("G700 G1 X1 Y1 F10\nG710 G1 X1 F100\n", "part.mpf"))
    assert_moves(segs, [(LINEAR, (25.4, 25.4, 0)), (LINEAR, (1, 25.4, 0))])
    assert segs[0].feed_mm_min == pytest.approx(254.0)
    assert segs[1].feed_mm_min == pytest.approx(100.0)
    assert [s.state.units for s in segs] == ["inch", "mm"]


def test_inch_work_offset_and_g92() -> None:
    # G10 L2 in inch: offset 1 in; G92 X0 at machine 50.8 mm.
    segs = segments("G20\nG10 L2 P1 X1\nG0 X0\nG0 X1\nG92 X0\nG0 X1")
    assert_moves(segs, [(RAPID, (25.4, 0, 0)), (RAPID, (50.8, 0, 0)), (RAPID, (76.2, 0, 0))])


# -------------------------------------------------------------------------- distance and feed modes
def test_absolute_and_incremental_distance() -> None:
    segs = segments("G21 G90 G0 X10 Y10 Z5\nG91 G0 X5 Y-2\nZ-1\nG90 X0")
    assert_moves(
        segs,
        [
            (RAPID, (10, 10, 5)),
            (RAPID, (15, 8, 5)),
            (RAPID, (15, 8, 4)),
            (RAPID, (0, 8, 4)),
        ],
    )


def test_g93_inverse_time_straight() -> None:
    # 3-4-5 triangle: length 50 mm; F2 means the move takes 1/2 min: 100 mm/min.
    seg = segments("G21 G93 G1 X30 Y40 F2")[-1]
    assert seg.length_mm == pytest.approx(50.0)
    assert seg.feed_mm_min == pytest.approx(100.0)
    assert seg.state.feed_mode == 93


def test_g93_inverse_time_arc_and_inch() -> None:
    # Quarter arc r=10: 5*pi mm long; F4 -> 20*pi mm/min.
    seg = segments("G21\nG0 X10 Y0\nG93 G3 X0 Y10 I-10 F4")[-1]
    assert seg.feed_mm_min == pytest.approx(20 * PI)
    # Inch: 3-4-5 in = 127 mm, F2 -> 254 mm/min.
    seg = segments("G20 G93 G1 X3 Y4 F2")[-1]
    assert seg.feed_mm_min == pytest.approx(254.0)


def test_g93_needs_f_on_every_feed_move() -> None:
    expect_error("G21 G93 G1 X1 F1\nG1 X2", 2, "inverse time")


def test_g95_feed_per_revolution_and_back_to_g94() -> None:
    segs = segments(
        "G21 S1000 M3\nG95 G1 X10 F0.1\n"  # 0.1 mm/rev * 1000 rpm = 100 mm/min
        "G20 S500\nG1 X1 F0.004\n"  # 0.004 in/rev * 25.4 * 500 rpm = 50.8 mm/min
        "G21 G94 G1 X20 F200"  # back to mm/min
    )
    assert [s.feed_mm_min for s in segs] == pytest.approx([100.0, 50.8, 200.0])
    assert [int(s.state.feed_mode) for s in segs] == [95, 95, 94]


def test_rapids_have_no_feed_and_feed_move_needs_f() -> None:
    seg = segments("G21 F500 G0 X1")[-1]
    assert seg.feed_mm_min == 0.0
    expect_error("G21\nG1 X10", 2, "F")


# ---------------------------------------------------------------------------- offsets
WORK_SYSTEMS = [
    ("54", 1),
    ("55", 2),
    ("56", 3),
    ("57", 4),
    ("58", 5),
    ("59", 6),
    ("59.1", 7),
    ("59.2", 8),
    ("59.3", 9),
]


@pytest.mark.parametrize(("code", "p"), WORK_SYSTEMS)
def test_work_coordinate_systems_with_g10_l2(code: str, p: int) -> None:
    # G10 L2 Pp stores the origin of system p; G5x selects it; machine = program + origin.
    origin = (10.0 * p, -1.0 * p, 0.5 * p)
    segs = segments(
        "G21\n"
        + "".join(f"G10 L2 P{q} X{10 * q} Y{-q} Z{0.5 * q}\n" for q in range(1, 10))
        + f"G{code}\nG0 X1 Y2 Z3"
    )
    seg = segs[-1]
    assert_point(seg.end_mm, (origin[0] + 1, origin[1] + 2, origin[2] + 3))
    assert seg.state.coordinate_system == p
    assert_point(seg.state.work_offset_mm, origin)
    assert_point(seg.state.to_program(seg.end_mm), (1, 2, 3))


def test_g10_l2_p0_is_the_active_system_and_setup_offsets() -> None:
    setup = NCSetup(work_offsets_mm={2: (1.0, 2.0, 3.0)})
    segs = segments("G21 G55\nG0 X0 Y0 Z0\nG10 L2 P0 X7\nG0 X0\nG54 G0 X0 Y0 Z0", setup)
    assert_moves(segs, [(RAPID, (1, 2, 3)), (RAPID, (7, 2, 3)), (RAPID, (0, 0, 0))])


def test_g10_l20_sets_the_origin_from_the_current_position() -> None:
    # At machine (10, 10): G10 L20 P2 X20 Y20 makes that point (20, 20) in G55, so the G55
    # origin is (-10, -10); G55 X0 Y0 is machine (-10, -10).
    segs = segments("G21\nG0 X10 Y10\nG10 L20 P2 X20 Y20\nG55 G0 X0 Y0\nG0 X5 Y5")
    assert_moves(segs, [(RAPID, (10, 10, 0)), (RAPID, (-10, -10, 0)), (RAPID, (-5, -5, 0))])


def test_g92_family() -> None:
    segs = segments(
        "G21\nG10 L2 P1 X100\nG0 X10 Y10\n"  # machine (110, 10)
        "G92 X0 Y0\nG0 X5 Y5\n"  # program origin at machine (110, 10): -> (115, 15)
        "G92.2\nG0 X5 Y5\n"  # suspended: G54 only -> (105, 5)
        "G92.3\nG0 X5 Y5\n"  # restored -> (115, 15)
        "G92.1\nG0 X5 Y5\n"  # cleared -> (105, 5)
        "G92.3\nG0 X6 Y6\n"  # G92.1 zeroed the saved values too -> (106, 6)
    )
    assert_moves(
        segs,
        [
            (RAPID, (110, 10, 0)),
            (RAPID, (115, 15, 0)),
            (RAPID, (105, 5, 0)),
            (RAPID, (115, 15, 0)),
            (RAPID, (105, 5, 0)),
            (RAPID, (106, 6, 0)),
        ],
    )
    assert_point(segs[1].state.axis_offset_mm, (10, 10, 0))
    assert_point(segs[2].state.axis_offset_mm, (0, 0, 0))


def test_g52_local_offset() -> None:
    segs = segments(
        "G21\nG10 L2 P1 X100\nG0 X10 Y10\n"  # (110, 10)
        "G52 X20 Y20\nG0 X10 Y10\n"  # (130, 30)
        "G52 X0 Y0\nG0 X10 Y10\n"  # cancelled: (110, 10)
    )
    assert_moves(segs, [(RAPID, (110, 10, 0)), (RAPID, (130, 30, 0)), (RAPID, (110, 10, 0))])


def test_g53_machine_coordinates_are_non_modal() -> None:
    segs = segments(
        "G21\nG10 L2 P1 X100 Y100 Z10\nG54 G0 X0 Y0 Z0\n"  # (100, 100, 10)
        "G53 G0 X5 Y6\n"  # machine (5, 6), Z unchanged
        "G53 G1 Z-1 F100\n"  # machine Z -1
        "G0 X0\n"  # G53 is not modal: program X0 = machine 100
    )
    assert_moves(
        segs,
        [
            (RAPID, (100, 100, 10)),
            (RAPID, (5, 6, 10)),
            (LINEAR, (5, 6, -1)),
            (RAPID, (100, 6, -1)),
        ],
    )
    expect_error("G21 F100\nG53 G2 X1 Y1 I1", 2, "G53")


TOOLS = {1: ToolEntry(1, length_mm=50.0), 2: ToolEntry(2, length_mm=-20.5)}


def test_g43_tool_length_offset_and_g49() -> None:
    setup = NCSetup(tools=TOOLS)
    segs = segments(
        "G21\nT1 M6\nG43 H1\nG0 X0 Y0 Z10\n"  # machine Z = 10 + 50
        "G43 H2\nG0 Z10\n"  # 10 - 20.5
        "G49\nG0 Z10\n",  # no offset
        setup,
    )
    assert [s.end_mm[2] for s in segs] == pytest.approx([60.0, -10.5, 10.0])
    # The tool tip is the programmed point in every case.
    assert [s.tcp_end_mm[2] for s in segs] == pytest.approx([10.0, 10.0, 10.0])
    assert_point(segs[0].state.tool_offset_mm, (0, 0, 50))
    assert segs[0].state.tool == 1


def test_g43_without_h_uses_the_tool_in_the_spindle() -> None:
    segs = segments("G21\nT2 M6\nG43\nG0 Z0", NCSetup(tools=TOOLS))
    assert segs[-1].end_mm[2] == pytest.approx(-20.5)


def test_g43_with_inch_program_and_work_offset() -> None:
    # Tool table in mm; program Z1 in = 25.4 mm; G54 Z origin -100 mm.
    segs = segments("G20\nG10 L2 P1 Z[-100/25.4]\nT1 M6 G43 H1\nG0 Z1", NCSetup(tools=TOOLS))
    assert segs[-1].end_mm[2] == pytest.approx(25.4 - 100 + 50)
    assert segs[-1].tcp_end_mm[2] == pytest.approx(25.4 - 100)


def test_g43_1_dynamic_offset_in_program_units() -> None:
    # LinuxCNC: "G43.1 does not cause any motion"; the offset applies to the next move.
    # Offset Z0.5 in = 12.7 mm; the next G0 Z1 ends at machine 25.4 + 12.7.
    segs = segments("G20\nG0 X0\nG43.1 Z0.5\nG0 Z1")
    assert [s.line for s in segs] == [2, 4]
    assert segs[-1].end_mm[2] == pytest.approx(38.1)
    assert segs[-1].tcp_end_mm[2] == pytest.approx(25.4)
    # Without an earlier motion mode it is no error either.
    segs = segments("G20\nG43.1 Z0.5\nG0 Z1")
    assert segs[-1].end_mm[2] == pytest.approx(38.1)


@pytest.mark.parametrize(
    ("program", "z"),
    [
        # G10 L1: tool 1 length 5 mm; G43 H1 then Z0 is machine 5.
        ("G21\nT1 M6\nG10 L1 P1 Z5\nG43 H1\nG0 Z0", 5.0),
        # Inch: length 1 in.
        ("G20\nT1 M6\nG10 L1 P1 Z1\nG43 H1\nG0 Z0", 25.4),
        # G10 L10: the length that makes the current point Z10. At machine Z-100 with a
        # G54 Z origin of -100 (program Z0): -100 = 10 - 100 + L, L = -10; G43 H1 Z10
        # returns to machine -100.
        ("G21\nG10 L2 P1 Z-100\nG0 Z0\nG10 L10 P1 Z10\nG43 H1\nG0 Z10", -100.0),
    ],
)
def test_g10_l1_l10_set_the_tool_table(program: str, z: float) -> None:
    assert segments(program)[-1].end_mm[2] == pytest.approx(z)


def test_g43_unknown_tool_warns_with_file_and_line() -> None:
    interp, _ = run("G21\nG43 H7\nG0 Z1")
    assert any(w.startswith("job.ngc:2: ") and "7" in w for w in interp.warnings), interp.warnings


HOMES = NCSetup(g28_home_mm=(1.0, 2.0, 3.0), g30_home_mm=(-4.0, -5.0, -6.0))


@pytest.mark.parametrize(
    ("program", "expected"),
    [
        # No axis words: every axis to the stored point.
        ("G28", [(1, 2, 3)]),
        ("G30", [(-4, -5, -6)]),
        # Axis words: through the intermediate point (program coordinates), then only
        # the named axes to the stored point.
        ("G28 Z20", [(10, 10, 20), (10, 10, 3)]),
        ("G30 X0", [(0, 10, 10), (-4, 10, 10)]),
        # Haas style: incremental zero intermediate point, Z only.
        ("G91 G28 Z0", [(10, 10, 3)]),
    ],
)
def test_g28_g30(program: str, expected: list) -> None:
    segs = segments("G21\nG0 X10 Y10 Z10\n" + program, HOMES)
    motion = moving(segs)[1:]
    assert_moves(motion, [(RAPID, e) for e in expected])


def test_g28_intermediate_point_is_in_program_coordinates() -> None:
    segs = segments("G21\nG10 L2 P1 Z100\nG0 X10 Y10 Z10\nG28 Z20", HOMES)
    assert_moves(
        moving(segs), [(RAPID, (10, 10, 110)), (RAPID, (10, 10, 120)), (RAPID, (10, 10, 3))]
    )


def test_g28_1_stores_the_current_position() -> None:
    segs = segments("G21\nG0 X7 Y8 Z9\nG28.1\nG0 X0 Y0 Z0\nG28\nG30.1\nG0 X1\nG30", HOMES)
    assert_point(moving(segs)[2].end_mm, (7, 8, 9))
    assert_point(segs[-1].end_mm, (7, 8, 9))


# ---------------------------------------------------------------------------- canned cycles
# Hand expansion of the RS274NGC cycles (NIST RS274NGC v3 section 3.5.16-3.5.25, LinuxCNC
# interp_cycles). Start: hole at (5, 6), initial Z 10, R 2, bottom -5, spindle CW.
# Preliminary motion: rapid to the hole at the current level, rapid down to R. Retract to
# the initial level (G98) or to R (G99). G73/G83 back off 0.254 mm (0.010 in).
CYCLE_HEAD = "G17 G21 G90 F100 S1000 M3\nG0 X0 Y0 Z10\n"
OVER, AT_R = (RAPID, (5, 6, 10)), (RAPID, (5, 6, 2))
CYCLES = {
    "g81-g98": ("G98 G81 X5 Y6 R2 Z-5", [OVER, AT_R, (LINEAR, (5, 6, -5)), (RAPID, (5, 6, 10))]),
    "g81-g99": ("G99 G81 X5 Y6 R2 Z-5", [OVER, AT_R, (LINEAR, (5, 6, -5)), (RAPID, (5, 6, 2))]),
    "g82-g98": (
        "G98 G82 X5 Y6 R2 Z-5 P0.5",
        [OVER, AT_R, (LINEAR, (5, 6, -5)), (DWELL, 0.5), (RAPID, (5, 6, 10))],
    ),
    # Pecks Q3 from R=2: -1, -4, then the bottom -5; back off 0.254 after each peck.
    "g73-g98": (
        "G98 G73 X5 Y6 R2 Z-5 Q3",
        [
            OVER,
            AT_R,
            (LINEAR, (5, 6, -1)),
            (RAPID, (5, 6, -0.746)),
            (LINEAR, (5, 6, -4)),
            (RAPID, (5, 6, -3.746)),
            (LINEAR, (5, 6, -5)),
            (RAPID, (5, 6, 10)),
        ],
    ),
    # G83: out to R after each peck, then rapid back down to 0.254 above the last depth.
    "g83-g99": (
        "G99 G83 X5 Y6 R2 Z-5 Q3",
        [
            OVER,
            AT_R,
            (LINEAR, (5, 6, -1)),
            (RAPID, (5, 6, 2)),
            (RAPID, (5, 6, -0.746)),
            (LINEAR, (5, 6, -4)),
            (RAPID, (5, 6, 2)),
            (RAPID, (5, 6, -3.746)),
            (LINEAR, (5, 6, -5)),
            (RAPID, (5, 6, 2)),
        ],
    ),
    # G85 (LinuxCNC): feed in, feed out to R, rapid to the clearance level.
    "g85-g98": (
        "G98 G85 X5 Y6 R2 Z-5",
        [OVER, AT_R, (LINEAR, (5, 6, -5)), (LINEAR, (5, 6, 2)), (RAPID, (5, 6, 10))],
    ),
    "g85-g99": ("G99 G85 X5 Y6 R2 Z-5", [OVER, AT_R, (LINEAR, (5, 6, -5)), (LINEAR, (5, 6, 2))]),
    # G86: feed in, dwell P, spindle stop, rapid out.
    "g86-g98": (
        "G98 G86 X5 Y6 R2 Z-5 P0.5",
        [OVER, AT_R, (LINEAR, (5, 6, -5)), (DWELL, 0.5), (RAPID, (5, 6, 10))],
    ),
    # G89: feed in, dwell P, feed out *to the clearance level* (RS274NGC 3.5.25).
    "g89-g99": (
        "G99 G89 X5 Y6 R2 Z-5 P0.5",
        [OVER, AT_R, (LINEAR, (5, 6, -5)), (DWELL, 0.5), (LINEAR, (5, 6, 2))],
    ),
    "g89-g98": (
        "G98 G89 X5 Y6 R2 Z-5 P0.5",
        [OVER, AT_R, (LINEAR, (5, 6, -5)), (DWELL, 0.5), (LINEAR, (5, 6, 10))],
    ),
    # G84: feed in, spindle reversed, feed out to the clearance level.
    "g84-g98": ("G98 G84 X5 Y6 R2 Z-5", [OVER, AT_R, (LINEAR, (5, 6, -5)), (LINEAR, (5, 6, 10))]),
    # Start below R: first up to R, and the clearance level is R even under G98.
    "below-r": (
        "G0 Z0\nG98 G81 X5 Y6 R2 Z-5",
        [(RAPID, (0, 0, 0)), (RAPID, (0, 0, 2)), AT_R, (LINEAR, (5, 6, -5)), (RAPID, (5, 6, 2))],
    ),
    # Modal: the next block drills another hole with the same R and Z; G80 ends it.
    "modal": (
        "G99 G81 X5 Y6 R2 Z-5\nX15\nG80\nG0 X0",
        [
            OVER,
            AT_R,
            (LINEAR, (5, 6, -5)),
            (RAPID, (5, 6, 2)),
            (RAPID, (15, 6, 2)),
            (LINEAR, (15, 6, -5)),
            (RAPID, (15, 6, 2)),
            (RAPID, (0, 6, 2)),
        ],
    ),
    # G91 with L3: R is relative to the start level (10-8 = 2), Z to R (2-7 = -5), and X
    # steps 10 per repeat.
    "g91-l3-g98": (
        "G91 G98 G81 X10 Y0 R-8 Z-7 L3",
        [
            step
            for x in (10, 20, 30)
            for step in (
                (RAPID, (x, 0, 10)),
                (RAPID, (x, 0, 2)),
                (LINEAR, (x, 0, -5)),
                (RAPID, (x, 0, 10)),
            )
        ],
    ),
    # G99: after the first hole the tool travels at the R level.
    "g91-l3-g99": (
        "G91 G99 G81 X10 Y0 R-8 Z-7 L3",
        [
            (RAPID, (10, 0, 10)),
            (RAPID, (10, 0, 2)),
            (LINEAR, (10, 0, -5)),
            (RAPID, (10, 0, 2)),
            (RAPID, (20, 0, 2)),
            (LINEAR, (20, 0, -5)),
            (RAPID, (20, 0, 2)),
            (RAPID, (30, 0, 2)),
            (LINEAR, (30, 0, -5)),
            (RAPID, (30, 0, 2)),
        ],
    ),
    # G18: the drilling axis is Y.
    "g18": (
        "G0 Y10 Z0\nG18 G98 G81 X5 Z6 R2 Y-5",
        [
            (RAPID, (0, 10, 0)),
            (RAPID, (5, 10, 6)),
            (RAPID, (5, 2, 6)),
            (LINEAR, (5, -5, 6)),
            (RAPID, (5, 10, 6)),
        ],
    ),
    # R and Z are program coordinates: with a G54 Z origin of -100 they are -98 and -105.
    "work-offset": (
        "G10 L2 P1 Z-100\nG0 Z10\nG99 G81 X5 Y6 R2 Z-5",
        [
            (RAPID, (0, 0, -90)),
            (RAPID, (5, 6, -90)),
            (RAPID, (5, 6, -98)),
            (LINEAR, (5, 6, -105)),
            (RAPID, (5, 6, -98)),
        ],
    ),
    # Inch: R0.1 = 2.54 mm, Z-0.2 = -5.08 mm, X1 Y1 = 25.4 mm.
    "inch": (
        "G20 G99 G81 X1 Y1 R0.1 Z-0.2",
        [
            (RAPID, (25.4, 25.4, 10)),
            (RAPID, (25.4, 25.4, 2.54)),
            (LINEAR, (25.4, 25.4, -5.08)),
            (RAPID, (25.4, 25.4, 2.54)),
        ],
    ),
}


#: Expectations the interpreter does not meet yet: name -> "interpreter bug: ...".
@pytest.mark.parametrize(
    "name",
    CYCLES,
)
def test_canned_cycle_moves(name: str) -> None:
    program, expected = CYCLES[name]
    segs = segments(CYCLE_HEAD + program)
    assert_moves(segs[1:], expected)  # segs[0] is the G0 to (0, 0, 10)


def test_cycle_feed_moves_use_the_programmed_feed() -> None:
    segs = segments(CYCLE_HEAD + "G98 G81 X5 Y6 R2 Z-5")
    assert [s.feed_mm_min for s in segs if s.kind == LINEAR] == [100.0]


def test_g84_reverses_the_spindle_to_retract() -> None:
    segs = segments(CYCLE_HEAD + "G98 G84 X5 Y6 R2 Z-5\nG80\nG1 X0 Y0")
    down, up = [s for s in segs if s.kind == LINEAR][:2]
    assert down.state.spindle_direction == 1
    assert up.state.spindle_direction == -1
    assert up.end_mm[2] == pytest.approx(10.0)
    # After the cycle the spindle turns forward again.
    assert segs[-1].state.spindle_direction == 1


def test_g86_stops_the_spindle_for_the_retract() -> None:
    segs = segments(CYCLE_HEAD + "G98 G86 X5 Y6 R2 Z-5 P0\nG80\nG1 X0")
    motion = moving(segs)
    retract = motion[-2]
    assert retract.kind == RAPID and retract.end_mm[2] == pytest.approx(10.0)
    assert retract.state.spindle_direction == 0
    assert motion[-1].state.spindle_direction == 1


CYCLE_ERRORS = {
    "no-r": ("G21 F100\nG81 X1 Y1 Z-1", 2, ("R word",)),
    "no-z": ("G21 F100\nG81 X1 Y1 R1", 2, ("Z word",)),
    "bottom-above-r": ("G21 F100\nG81 X1 Y1 R1 Z2", 2, ("above",)),
    "g83-no-q": ("G21 F100\nG83 X1 Y1 R1 Z-2", 2, ("Q",)),
    "negative-l": ("G21 F100\nG81 X1 Y1 R1 Z-2 L-1", 2, ("L-1",)),
}


@pytest.mark.parametrize("name", list(CYCLE_ERRORS))
def test_canned_cycle_errors(name: str) -> None:
    program, line, phrases = CYCLE_ERRORS[name]
    expect_error(program, line, *phrases)


# LinuxCNC interp_cycles: G84 (right-hand tapping) needs the spindle turning clockwise
# ("Spindle not turning in G84", "Spindle turning counterclockwise in G84"); G86 needs
# it turning (NCE_SPINDLE_NOT_TURNING_IN_G86).
SPINDLE_CYCLE_ERRORS = {
    "g84-stopped": "G21 F100\nG0 Z10\nG84 X0 Y0 R2 Z-5",
    "g84-ccw": "G21 F100 S500 M4\nG0 Z10\nG84 X0 Y0 R2 Z-5",
    "g86-stopped": "G21 F100\nG0 Z10\nG86 X0 Y0 R2 Z-5 P1",
}


@pytest.mark.parametrize("name", list(SPINDLE_CYCLE_ERRORS))
def test_tapping_and_boring_need_the_spindle_turning(name: str) -> None:
    expect_error(SPINDLE_CYCLE_ERRORS[name], 3, "spindle")


def test_canned_cycle_without_feed_is_an_error() -> None:
    # LinuxCNC convert_cycle: "Cannot feed with zero feed rate".
    expect_error("G21\nG0 Z10\nG81 X1 Y1 R1 Z-2", 3, "feed")


def test_canned_cycle_in_inverse_time_is_an_error() -> None:
    # LinuxCNC convert_cycle: "Cannot use inverse time feed with canned cycles".
    expect_error("G21 F100\nG0 Z10\nG93 G81 X1 Y1 R1 Z-2 F2", 3, "inverse time")


# ---------------------------------------------------------------------------- parameters, O-words
def xs(text: str, setup: NCSetup | None = None) -> list[float]:
    """X end points (mm) of every segment of a program."""
    return [round(s.end_mm[0], 9) for s in segments("G21\n" + text, setup)]


def test_numbered_and_named_parameters() -> None:
    assert xs("#1=5\nG0 X#1\n#<depth>=-2\nG0 Z#<depth> X[#1*#<depth>]") == [5.0, -10.0]


def test_parameter_settings_take_effect_after_the_line() -> None:
    # RS274NGC: all settings on a line are made after the line is read, so X#1 sees 1.
    assert xs("#1=1\n#1=5 G0 X#1\nG0 X#1") == [1.0, 5.0]


def test_sub_with_arguments_and_local_scope() -> None:
    program = (
        "#1=100\n#<a>=7\n"
        "o100 sub\n  #<a>=#2\n  G0 X[#1+#<a>]\no100 endsub\n"
        "o100 call [3] [4]\n"  # 3 + 4
        "G0 X[#1+#<a>]\n"  # the caller's #1 and #<a> are restored: 107
    )
    assert xs(program) == [7.0, 107.0]


def test_while_loop() -> None:
    assert xs("#1=1\no101 while [#1 le 3]\nG0 X#1\n#1=[#1+1]\no101 endwhile\nG0 X0") == [
        1.0,
        2.0,
        3.0,
        0.0,
    ]


def test_do_while_runs_the_body_once_even_if_false() -> None:
    assert xs("#1=0\no1 do\nG0 X[#1+1]\n#1=[#1+1]\no1 while [#1 lt 0]\nG0 X9") == [1.0, 9.0]
    assert xs("#1=0\no1 do\n#1=[#1+1]\nG0 X#1\no1 while [#1 lt 3]") == [1.0, 2.0, 3.0]


def test_repeat() -> None:
    assert xs("G91\no2 repeat [3]\nG0 X1.5\no2 endrepeat") == [1.5, 3.0, 4.5]
    assert xs("o2 repeat [0]\nG0 X1\no2 endrepeat\nG0 X2") == [2.0]


@pytest.mark.parametrize(("value", "x"), [(0, 10.0), (1, 20.0), (2, 30.0), (5, 30.0)])
def test_if_elseif_else(value: int, x: float) -> None:
    program = (
        f"#1={value}\n"
        "o3 if [#1 eq 0]\nG0 X10\n"
        "o3 elseif [#1 eq 1]\nG0 X20\n"
        "o3 else\nG0 X30\n"
        "o3 endif\nG0 Y1"
    )
    assert xs(program) == [x, x]


@pytest.mark.parametrize(("value", "x"), [(0, 10.0), (1, 20.0), (2, 30.0)])
def test_a_skipped_branch_finds_its_statements_however_written(value: int, x: float) -> None:
    # Skipping a branch reads the statements as the lexer does: case, spaces and tabs,
    # comments, statements of other labels and a program number are told apart.
    program = (
        f"#1={value}\n"
        "O3 IF [#1 EQ 0]\nG0 X10\n"
        "(o3 else) ; o3 endif\n"
        "o33 if [1]\no33 endif\n"
        "o 3\tElseIf [#1 eq 1]\nG0 X20\n"
        "o1003\n"
        "o3 (comment) else\nG0 X30\n"
        "o<3> if [0]\no<3> endif\n"
        "o3 endif ; done\nG0 Y1"
    )
    assert xs(program) == [x, x]


def test_a_malformed_statement_in_a_skipped_branch_is_refused() -> None:
    # The lexer refuses it wherever it stands, as when its branch runs.
    with pytest.raises(NCError, match="unrecognised O-word statement 'o3nothing'") as caught:
        run("o3 if [0]\no3 nothing\no3 endif\n")
    assert caught.value.line == 2


@pytest.mark.parametrize("comment", ["", " (note)"])
def test_o_word_statements_read_alike_with_or_without_a_comment(comment: str) -> None:
    # A statement without a comment is read apart from the lexer's blocks: written in
    # capitals, with tabs, after a program number or reading system parameters, it runs
    # as the same statement with a comment does.
    program = (
        f"O1003{comment}\n"
        "G10 L2 P1 X2\n"
        f"O1\tREPEAT [#5221 + 1]{comment}\nG91 G0 X1\nO1 ENDREPEAT{comment}\n"
        f"o2 if [#5221 eq 2]{comment}\nG0 Y1\no2 endif{comment}\n"
    )
    # #5221 (G54 X) is 2: three incremental steps of X1 from X0, then the if's Y1.
    assert [seg.end_mm for seg in segments(program)] == [
        (1.0, 0.0, 0.0),
        (2.0, 0.0, 0.0),
        (3.0, 0.0, 0.0),
        (3.0, 1.0, 0.0),
    ]
    with pytest.raises(NCError) as caught:
        run(f"G0 X1\nO3 Nothing{comment}\n")
    assert (caught.value.line, caught.value.column) == (2, 1)
    assert caught.value.message.startswith("unrecognised O-word statement 'o3nothing'")


def test_break_and_continue() -> None:
    program = (
        "#1=0\n"
        "o3 while [#1 lt 10]\n"
        "  #1=[#1+1]\n"
        "  o4 if [#1 eq 2]\n    o3 continue\n  o4 endif\n"
        "  o5 if [#1 eq 4]\n    o3 break\n  o5 endif\n"
        "  G0 X#1\n"
        "o3 endwhile\n"
        "G0 X#1 Y1\n"
    )
    assert xs(program) == [1.0, 3.0, 4.0]


def test_return_value() -> None:
    program = "o10 sub\n  o10 return [#1*2]\no10 endsub\no10 call [21]\nG0 X#<_value>"
    assert xs(program) == [42.0]


def test_nested_calls() -> None:
    program = (
        "o20 sub\n  G0 X#1\no20 endsub\n"
        "o21 sub\n  o20 call [#1+1]\n  G0 Y#1\no21 endsub\n"
        "o21 call [5]"
    )
    segs = segments("G21\n" + program)
    assert_moves(segs, [(RAPID, (6, 0, 0)), (RAPID, (6, 5, 0))])


def test_subroutine_in_a_separate_file(tmp_path: Path) -> None:
    sub = tmp_path / "shift.ngc"
    sub.write_text("(helper)\no<shift> sub\n  G0 X#1 Y#2\no<shift> endsub\n")
    main = tmp_path / "main.ngc"
    main.write_text("G21\no<shift> call [7] [8]\nG0 X0\nM2\n")
    interp = Interpreter()
    segs = list(interp.run_file(main))
    assert_moves(segs, [(RAPID, (7, 8, 0)), (RAPID, (0, 8, 0))])
    assert Path(segs[0].file) == sub and segs[0].line == 3
    assert Path(segs[1].file) == main and segs[1].line == 3


def test_error_inside_a_subroutine_file_names_that_file(tmp_path: Path) -> None:
    sub = tmp_path / "bad.ngc"
    sub.write_text("o<bad> sub\n  G1 X1\no<bad> endsub\n")
    main = tmp_path / "main.ngc"
    main.write_text("G21\no<bad> call\n")
    with pytest.raises(NCError) as info:
        list(Interpreter().run_file(main))
    assert info.value.line == 2
    assert Path(info.value.file) == sub
    assert str(info.value).startswith(f"{sub}:2: ")


def test_runaway_loop_is_stopped(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(owords_module, "MAX_LOOP_ITERATIONS", 1000)
    expect_error("G21\no1 while [1]\n  #2=[#2+1]\no1 endwhile", 4, "runaway")
    expect_error("G21\no1 do\n  #2=[#2+1]\no1 while [1]", 4, "runaway")


def test_runaway_recursion_is_stopped() -> None:
    expect_error("G21\no1 sub\n  o1 call\no1 endsub\no1 call", 3, "o1")


O_ERRORS = {
    "undefined-sub": ("G21\no100 call [1]", 2, ("o100",)),
    "endsub-without-sub": ("G21\no1 endsub", 2, ("endsub",)),
    "endwhile-without-while": ("G21\no2 endwhile", 2, ("endwhile",)),
    "unclosed-while": ("G21\no2 while [0]\nG0 X1", 2, ("endwhile",)),
    "undefined-named-parameter": ("G21\nG0 X#<nope>", 2, ("#<nope>",)),
    "break-outside-loop": ("G21\no7 break", 2, ("break",)),
}


@pytest.mark.parametrize("name", list(O_ERRORS))
def test_o_word_errors(name: str) -> None:
    program, line, phrases = O_ERRORS[name]
    expect_error(program, line, *phrases)


# ---------------------------------------------------------------------------- RS274NGC block rules
# NIST RS274NGC v3, 3.4: "It is an error to put a G-code from group 1 and a G-code from
# group 0 on the same line if both of them use axis words" (LinuxCNC:
# NCE_CANNOT_USE_TWO_G_CODES_THAT_BOTH_USE_AXIS_VALUES). cnctwin silently drops one.
TWO_AXIS_CODES = {
    "g1-g92": "G21 F100\nG1 G92 X5",
    "g0-g28": "G21\nG0 G28 X5",
    "g0-g10": "G21\nG0 G10 L2 P1 X5",
    "g1-g52": "G21 F100\nG1 G52 X1",
}


@pytest.mark.parametrize("name", list(TWO_AXIS_CODES))
def test_two_g_codes_that_use_axis_words(name: str) -> None:
    expect_error(TWO_AXIS_CODES[name], 2, "axis")


def test_g53_in_incremental_mode_is_an_error() -> None:
    err = expect_error("G21\nG0 X1\nG91 G53 G0 X5", 3, "G53")
    assert "g91" in str(err).lower() or "incremental" in str(err).lower()


# NCE_TWO_M_CODES_USED_FROM_SAME_MODAL_GROUP: M3/M4/M5 are one group.
@pytest.mark.parametrize("program", ["G21 S100 M3 M4", "G21 S100 M3 M5"])
def test_two_m_codes_from_one_group(program: str) -> None:
    expect_error(program, 1, "M")


# LinuxCNC check_other_codes: NCE_R_WORD_WITH_NO_G_CODE_THAT_USES_IT,
# NCE_I_WORD_WITH_NO_G2_OR_G3_OR_G87_TO_USE_IT, Q without G73/G83. A word that nothing
# uses is usually a typo (G1 where G2 was meant).
STRAY_WORDS = {
    "r-with-g0": ("G21\nG0 X1 R5", "R"),
    "i-with-g1": ("G21 F100\nG1 X1 I5", "I"),
    "q-with-g1": ("G21 F100\nG1 X1 Q2", "Q"),
}


@pytest.mark.parametrize("name", list(STRAY_WORDS))
def test_words_without_a_code_that_uses_them(name: str) -> None:
    program, letter = STRAY_WORDS[name]
    expect_error(program, 2, letter)


def test_u_v_w_words() -> None:
    expect_error("G21\nG0 X1 V2", 2, "V")
    # Fanuc/Haas lathe (G-code system A): U and W are incremental X and Z, U on the
    # diameter. From X1 (radius 12.7 mm) Z0: U-0.2 W-0.1 ends at radius 0.4 in, Z -0.1 in.
    segs = lathe("G20\nG0 X1 Z0\nG0 U-0.2 W-0.1")
    assert_point(segs[-1].end_mm, (0.4 * 25.4, 0, -0.1 * 25.4))


def test_percent_delimited_file_ends_at_the_second_percent() -> None:
    # RS274NGC v3 (3.3.1): "The useful contents of a file demarcated by percents stop after
    # the second percent line. Anything after that is ignored."
    segs = segments("%\nG21\nG0 X1\n%\nG0 X2\nnot G-code at all\n")
    assert ends(segs) == [(1.0, 0.0, 0.0)]


# ---------------------------------------------------------------------------- lathe
LATHE_TOOLS = {
    1: ToolEntry(1, length_mm=3.0, x_offset_mm=2.0),
    2: ToolEntry(2, length_mm=-1.0, x_offset_mm=0.5),
}


def lathe(text: str, **kw) -> list[Segment]:
    return segments(text, NCSetup(lathe=True, **kw))


def test_lathe_diameter_and_radius_mode() -> None:
    segs = lathe("G21\nG0 X20 Z5\nG91 G0 X-4\nG90 G8\nG0 X20\nG7\nG0 X20")
    # Diameter 20 -> radius 10; incremental -4 on the diameter is -2 on the radius;
    # G8: X is a radius; G7: diameter again.
    assert [s.end_mm[0] for s in segs] == pytest.approx([10.0, 8.0, 20.0, 10.0])
    assert segs[0].state.plane == Plane.ZX
    assert segs[0].state.diameter_mode and not segs[2].state.diameter_mode


def test_lathe_css_rpm_and_clamp() -> None:
    # G96 S200 (m/min) at diameter 50 (radius 25 mm): 200000/(2*pi*25) = 1273.24 rpm.
    rpm = 200_000 / (2 * PI * 25)
    segs = lathe("G21\nG0 X50 Z0\nG96 S200 M3\nG95 G1 Z-10 F0.1")
    assert segs[-1].spindle_rpm == pytest.approx(rpm)
    assert segs[-1].feed_mm_min == pytest.approx(0.1 * rpm)
    # G50 S1000 clamps it.
    segs = lathe("G21\nG50 S1000\nG0 X50 Z0\nG96 S200 M3\nG95 G1 Z-10 F0.1")
    assert segs[-1].spindle_rpm == pytest.approx(1000.0)
    assert segs[-1].feed_mm_min == pytest.approx(100.0)
    # ... and so does the machine's limit.
    segs = lathe("G21\nG0 X50 Z0\nG96 S200 M3\nG95 G1 Z-10 F0.1", max_spindle_rpm=900.0)
    assert segs[-1].spindle_rpm == pytest.approx(900.0)


def test_lathe_css_clamped_by_g96_d() -> None:
    # LinuxCNC form of the clamp: G96 D<max rpm>.
    segs = lathe("G21\nG0 X50 Z0\nG96 D1000 S200 M3\nG95 G1 Z-10 F0.1")
    assert segs[-1].spindle_rpm == pytest.approx(1000.0)


def test_lathe_arc_in_diameter_mode() -> None:
    # Haas lathe_hp_2.nc, P3-P4: Z-0.85 at diameter 0.48, then "G02 X0.58 Z-0.9 R0.05".
    # Radii 0.24 -> 0.29 in; a fillet of R0.05 tangent to the shaft (X 0.24) at Z-0.85 and
    # to the shoulder (Z-0.9) at X 0.29 has its centre at (X 0.29, Z -0.85); the quarter
    # arc is 0.05*pi/2 in long.
    arc = lathe("G20 F10\nG0 X0.48 Z-0.85\nG2 X0.58 Z-0.9 R0.05")[-1]
    assert arc.kind == ARC and arc.turns == -1
    assert_point(arc.center_mm, (0.29 * 25.4, 0, -0.85 * 25.4), 1e-9)
    assert_point(arc.end_mm, (0.29 * 25.4, 0, -0.9 * 25.4), 1e-9)
    assert arc.length_mm == pytest.approx(0.05 * PI / 2 * 25.4)


def test_lathe_css_in_inch() -> None:
    # S500 ft/min = 152400 mm/min at diameter 2 in (radius 25.4 mm): 954.93 rpm.
    segs = lathe("G20\nG0 X2 Z0\nG96 S500 M3\nG98 G1 Z-1 F10")
    assert segs[-1].spindle_rpm == pytest.approx(152_400 / (2 * PI * 25.4))
    assert segs[-1].feed_mm_min == pytest.approx(254.0)  # G98 on a lathe: per minute


def test_lathe_css_at_the_axis_needs_a_clamp() -> None:
    expect_error("G21\nG0 X0 Z0\nG96 S200 M3\nG95 G1 Z-1 F0.1", 4, "G50", setup=NCSetup(lathe=True))


def test_lathe_g97_and_g99_feed_per_rev() -> None:
    segs = lathe("G21\nG97 S800 M3\nG99 G1 X10 Z-1 F0.2\nG98 G1 Z-2 F50")
    assert segs[0].spindle_rpm == pytest.approx(800.0)
    assert segs[0].feed_mm_min == pytest.approx(160.0)
    assert segs[1].feed_mm_min == pytest.approx(50.0)


@pytest.mark.parametrize(
    ("tword", "expected", "tool"),
    [
        ("T0101", (10 + 2.0, 0, 3.0), 1),  # tool 1, offset register 1
        ("T0102", (10 + 0.5, 0, -1.0), 1),  # tool 1, offset register 2
        ("T0200", (10, 0, 0), 2),  # register 0: no offset
    ],
)
def test_lathe_t_word_applies_the_offset_register(tword: str, expected: tuple, tool: int) -> None:
    interp, segs = run(f"G21\n{tword}\nG0 X20 Z0", NCSetup(lathe=True, tools=LATHE_TOOLS))
    assert_point(segs[-1].end_mm, expected)
    assert_point(segs[-1].tcp_end_mm, (10, 0, 0))
    assert segs[-1].state.tool == tool
    assert interp.tools_used == [tool]


def test_g50_is_a_lathe_code() -> None:
    expect_error("G21\nG50 S1000", 2, "lathe")


# ---------------------------------------------------------------------------- polar coordinates
@pytest.mark.parametrize(
    ("program", "end"),
    [
        ("G0 @10 ^90", (0, 10, 0)),
        ("G0 @10 ^45", (10 / math.sqrt(2), 10 / math.sqrt(2), 0)),
        # Incremental angle and radius about the program origin.
        ("G0 @10 ^0\nG91 G0 ^90", (0, 10, 0)),
        ("G0 @10 ^0\nG91 G0 @5", (15, 0, 0)),
        ("G0 @10 ^30\nG91 G0 @-5 ^60", (0, 5, 0)),
        # About the program origin, which the work offset moves.
        ("G10 L2 P1 X100\nG0 @10 ^180", (90, 0, 0)),
        ("G20\nG0 @1 ^90", (0, 25.4, 0)),
    ],
)
def test_polar_coordinates(program: str, end: tuple) -> None:
    assert_point(segments("G21 G17\n" + program)[-1].end_mm, end, 1e-9)


def test_polar_with_x_is_an_error() -> None:
    expect_error("G21\nG0 @10 X5", 2, "polar")


# ---------------------------------------------------------------------------- errors
ERRORS = {
    "g71": ("G21\nG71 P1 Q2 U0.1 W0.1 D1", 2, "G71"),
    "g76": ("G21\nG0 X1\nG76 P1 Z-1 I-0.1 J0.01 K0.1", 3, "G76"),
    "g68": ("G68 X0 Y0 R45", 1, "G68"),
    "g5": ("G21 F100\nG5 I1 J1 P1 Q1 X2", 2, "G5"),
    "m98": ("G21\nM98 P1000", 2, "M98"),
    "m99": ("M99", 1, "M99"),
    "unknown-g": ("G21\nG12.5 X1", 2, "G12.5"),
    "g54.1": ("G54.1 P1", 1, "G54.1"),
    "duplicate-word": ("G21\nG1 X1 X2 F1", 2, "twice"),
    "duplicate-word-expression": ("G21\nG1 X[1] X[2] F1", 2, "twice"),
    "conflicting-motion": ("G21\nG0 G1 X1 F100", 2, "modal group"),
    "conflicting-units": ("G20 G21", 1, "modal group"),
    "conflicting-planes": ("G17 G18", 1, "modal group"),
    "two-non-modal": ("G21\nG4 G92 P1 X0", 2, "cannot share"),
    "g1-without-f": ("G21\nG0 X1\nG1 X10", 3, "F"),
    "unclosed-comment": ("G21\nG0 X1 (oops", 2, "unclosed comment"),
    "nested-comment": ("G0 X1 (a (b) c)", 1, "nested"),
    "bad-character": ("G21\nG0 X1 $", 2, "'$'"),
    "missing-value": ("G0 X1 Y", 1, "value"),
    "negative-feed": ("G1 X1 F-5", 1, "F-5"),
    "negative-speed": ("S-100 M3", 1, "S-100"),
    "bad-tool-number": ("T1.5 M6", 1, "T1.5"),
    "g4-without-p": ("G4", 1, "P"),
    "axis-words-without-motion": ("G80 X1", 1, "motion"),
    "fractional-m": ("M3.5", 1, "M3.5"),
    "division-by-zero": ("G21\nG0 X[1/0]", 2, "division by zero"),
    "o-word-garbage": ("o12 frobnicate", 1, "o-word"),
}


@pytest.mark.parametrize("name", list(ERRORS))
def test_errors_name_the_construct_and_the_line(name: str) -> None:
    program, line, phrase = ERRORS[name]
    err = expect_error(program, line, phrase)
    assert err.line > 0 and err.file == "job.ngc"


def test_error_line_counts_blank_and_comment_lines() -> None:
    expect_error("%\n(header)\n\n; note\nG21\n\nG76 P1", 7, "G76")


def test_errors_are_raised_lazily_after_earlier_segments() -> None:
    it = interpret_text("G21\nG0 X1\nG0 X2\nG68 R1", name="lazy.ngc")
    assert next(it).end_mm[0] == 1.0
    assert next(it).end_mm[0] == 2.0
    with pytest.raises(NCError) as info:
        next(it)
    assert str(info.value).startswith("lazy.ngc:4: ")


# ---------------------------------------------------------------------------- messages and warnings
def test_messages_and_warnings() -> None:
    interp, segs = run(
        "G21\n(MSG, Hello world)\nG0 X1 (msg,second one)\nM123\n(DEBUG, dbg)\nM2\nG0 X5"
    )
    assert interp.messages == ["Hello world", "second one", "dbg"]
    assert len(interp.warnings) == 1
    assert interp.warnings[0].startswith("job.ngc:4: ") and "M123" in interp.warnings[0]
    # M2 ends the program: the line after it is not run.
    assert [s.end_mm[0] for s in segs] == [1.0]


def test_plain_comments_are_not_messages() -> None:
    interp, _ = run("G21 (a comment)\n; another\n(message, not a MSG)\nG0 X1\nM2")
    assert interp.messages == []
    assert interp.warnings == []


# ---------------------------------------------------------------------------- segment bookkeeping
def test_segments_carry_line_file_feed_and_spindle() -> None:
    segs = segments("G21\nS1200 M3\nG0 X1\n\nG1 X2 F300\nM5\nG1 X3\nG4 P1.5")
    assert [s.line for s in segs] == [3, 5, 7, 8]
    assert all(s.file == "job.ngc" for s in segs)
    assert [s.feed_mm_min for s in segs[:3]] == [0.0, 300.0, 300.0]
    assert [s.spindle_rpm for s in segs[:3]] == [1200.0, 1200.0, 0.0]
    assert segs[-1].kind == DWELL and segs[-1].dwell_s == 1.5 and segs[-1].length_mm == 0.0
    # Consecutive segments are continuous.
    for a, b in itertools.pairwise(segs):
        assert a.end_mm == b.start_mm


def test_initial_position_from_setup() -> None:
    segs = segments("G21 G91 G0 X1", NCSetup(initial_position_mm=(5.0, 6.0, 7.0)))
    assert segs[0].start_mm == (5.0, 6.0, 7.0)
    assert_point(segs[0].end_mm, (6, 6, 7))


def test_rotary_axes_in_degrees_not_scaled_by_inch() -> None:
    seg = segments("G20 G0 X1 A90 B-45")[-1]
    assert_point(seg.end_mm, (25.4, 0, 0))
    assert_point(seg.end_abc_deg, (90, -45, 0))
