"""Every real NC program in ../shared/data/gcode interprets, or fails with a clear error.

The outcome of each program was derived by reading it: "ok", or the line and the
construct of the first block cnctwin rejects on purpose (lathe roughing/finishing/threading
cycles G70-G76). The Haas lathe programs run with ``NCSetup(lathe=True)`` (diameter mode,
G18, G50 S spindle clamp, G99 feed per revolution, T0101 offsets); everything else with the
default mill set-up (the LinuxCNC lathe samples select G18 and G7/G8 themselves and are
written for a radius-mode LinuxCNC lathe).

A few programs are also checked against numbers derived by hand from their text:
bounds and path lengths of the Sinumerik notch program, the first moves of a Fusion 360
program, the arc count of the large Fusion programs (counted with a regular expression),
hole positions of the LinuxCNC polar and bolt-circle samples, the tool sequence of
mmount.ngc, a G18 arc of a Haas program and the constant-surface-speed cut of a Haas lathe
program.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import pytest

from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.segments import PLANE_AXES, MotionKind, Plane, Segment
from cnctwin.nc.setup import NCSetup

pytestmark = pytest.mark.validation

INCH = 25.4
RAPID, LINEAR, ARC, DWELL = MotionKind.RAPID, MotionKind.LINEAR, MotionKind.ARC, MotionKind.DWELL

LATHE_PROGRAMS = {
    "haas_style_enier/lathe_hp_2.nc",
    "haas_style_enier/o20013.nc",
    "haas_style_enier/weld_pin.nc",
}

#: Program -> "ok", or (line, phrase) of the NCError it must raise.
EXPECTED: dict[str, str | tuple[int, str]] = {
    "camotics/bear/bear.nc": "ok",
    "camotics/buildbotics/buildbotics.gcode": "ok",
    "camotics/cat/tiny_cat_outline.ngc": "ok",
    "camotics/compass/compass.ngc": "ok",
    "camotics/heart/cutout.ngc": "ok",
    "camotics/heart/heart.ngc": "ok",
    "camotics/scorpion/scorpion.nc": "ok",
    "camotics/slant_test/slant_test.nc": "ok",
    "camotics/vcarve/vcarve.ngc": "ok",
    "camotics/wave/wave.gcode": "ok",
    "fusion360_grbl_shooshx/1024_block_14bit.nc": "ok",
    "fusion360_grbl_shooshx/1110_wall_265bit.nc": "ok",
    "fusion360_grbl_shooshx/1121_btn8copies_20bit.nc": "ok",
    "haas_style_enier/1003.nc": "ok",
    "haas_style_enier/1006.nc": "ok",
    # "G71 P10 Q20 U0.01 W0.005 D0.05 F0.010" (Fanuc-style roughing cycle) on line 24.
    "haas_style_enier/lathe_hp_2.nc": (24, "G71"),
    # A lathe program without canned turning cycles: G50 S3000 clamp, G96 S1000, G99.
    "haas_style_enier/o20013.nc": "ok",
    "haas_style_enier/slot_assembly_12.nc": "ok",
    # "G71 P10 Q20 ..." on line 23 (G70, G76 and G75 follow later).
    "haas_style_enier/weld_pin.nc": (23, "G71"),
    "linuxcnc/3D_Chips.ngc": "ok",
    "linuxcnc/arcspiral.ngc": "ok",
    "linuxcnc/cds.ngc": "ok",
    "linuxcnc/comp-g1.ngc": "ok",
    "linuxcnc/hole-circle.ngc": "ok",
    # The turning and facing part runs (inside a subroutine called 8 times); the
    # threading block "g76 p.05 z-.5 ..." is line 102.
    "linuxcnc/lathe-g76.ngc": (102, "G76"),
    # "G71.1 Q100 X15 Z3.041 D1 I1 R0.3" on line 28.
    "linuxcnc/lathe_g70_71_demo.ngc": (28, "G71.1"),
    # "G70 Q100 X15 Z4 D1 P1" on line 15, after the profile subroutine o100.
    "linuxcnc/lathe_g7x_quadrants.ngc": (15, "G70"),
    "linuxcnc/lathe_pawn.ngc": "ok",
    "linuxcnc/lathecomp.ngc": "ok",
    "linuxcnc/mmount.ngc": "ok",
    "linuxcnc/polar.ngc": "ok",
    "linuxcnc/skeleton.ngc": "ok",
    "linuxcnc/systems.ngc": "ok",
    "linuxcnc/tort.ngc": "ok",
    "siemens_kit_dmc60h/AL_2007_T4_Notch_Normal.mpf": "ok",
    "siemens_kit_dmc60h/AL_2007_T4_Plate_Normal.mpf": "ok",
}


@pytest.fixture(scope="module")
def gcode(shared_data: Path) -> Path:
    return shared_data / "gcode"


def _setup(name: str) -> NCSetup:
    return NCSetup(lathe=True) if name in LATHE_PROGRAMS else NCSetup()


def _run(gcode: Path, name: str) -> tuple[Interpreter, list[Segment]]:
    interp = Interpreter(_setup(name))
    return interp, list(interp.run_file(gcode / name))


def test_every_program_is_listed(gcode: Path) -> None:
    found = sorted(
        str(p.relative_to(gcode))
        for p in gcode.rglob("*")
        if p.is_file() and p.suffix != ".camotics"
    )
    assert found == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_program_outcome(gcode: Path, name: str) -> None:
    path = gcode / name
    n_lines = len(path.read_bytes().splitlines())
    interp = Interpreter(_setup(name))
    segs: list[Segment] = []
    expected = EXPECTED[name]
    try:
        segs.extend(interp.run_file(path))  # keeps the segments made before an error
    except NCError as err:
        assert expected != "ok", f"{name} must interpret, got {err}"
        line, phrase = expected
        assert err.line == line, str(err)
        assert Path(err.file) == path
        assert str(err).startswith(f"{path}:{line}: "), str(err)
        assert phrase.lower() in err.message.lower(), str(err)
        assert "not supported" in err.message, str(err)
        assert all(s.line < line or Path(s.file) != path for s in segs)
    else:
        assert expected == "ok", f"{name} must fail with {expected}, but interpreted"
        assert segs, name
    # Whatever was produced is a continuous, finite path inside the file.
    for a, b in itertools.pairwise(segs):
        assert a.end_mm == b.start_mm, (a, b)
    for seg in segs:
        assert all(math.isfinite(v) for v in (*seg.end_mm, seg.feed_mm_min, seg.spindle_rpm))
        if Path(seg.file) == path:
            assert 1 <= seg.line <= n_lines
        if seg.kind in (LINEAR, ARC):
            assert seg.feed_mm_min > 0, seg


# ---------------------------------------------------------------------------- hand checks
def _arc_points(seg: Segment, steps: int = 360) -> list[tuple[float, float, float]]:
    """Points along an arc segment (own parametrisation: start angle, signed sweep)."""
    i0, i1, n = PLANE_AXES[seg.state.plane]
    c, s, e = seg.center_mm, seg.start_mm, seg.end_mm
    a0 = math.atan2(s[i1] - c[i1], s[i0] - c[i0])
    a1 = math.atan2(e[i1] - c[i1], e[i0] - c[i0])
    r = math.hypot(s[i0] - c[i0], s[i1] - c[i1])
    if seg.turns > 0:
        sweep = (a1 - a0) % (2 * math.pi) or 2 * math.pi
        sweep += (seg.turns - 1) * 2 * math.pi
    else:
        sweep = -((a0 - a1) % (2 * math.pi) or 2 * math.pi)
        sweep -= (-seg.turns - 1) * 2 * math.pi
    pts = []
    for k in range(steps + 1):
        t = k / steps
        p = [0.0, 0.0, 0.0]
        p[i0] = c[i0] + r * math.cos(a0 + sweep * t)
        p[i1] = c[i1] + r * math.sin(a0 + sweep * t)
        p[n] = s[n] + (e[n] - s[n]) * t
        pts.append((p[0], p[1], p[2]))
    return pts


def _bounds(segs: list[Segment]) -> tuple[tuple[float, ...], tuple[float, ...]]:
    pts = [segs[0].tcp_start_mm]
    for seg in segs:
        if seg.kind == ARC:
            o = seg.state.tool_offset_mm
            pts += [(x - o[0], y - o[1], z - o[2]) for x, y, z in _arc_points(seg)]
        pts.append(seg.tcp_end_mm)
    return tuple(min(p[k] for p in pts) for k in range(3)), tuple(
        max(p[k] for p in pts) for k in range(3)
    )


def test_sinumerik_notch_bounds_and_lengths(gcode: Path) -> None:
    # The program (G710 mm, G90, no offsets) from machine (0, 0, 0): G0 Z10, G0 X-10 Y60,
    # then three passes at Z -6, -12, -18 of: G1 X30 (40 mm), G2 X60 Y30 I0 J-30 (quarter
    # circle r=30 about (30, 30): 15*pi), G1 Y10 (20), G1 X40 (20), G1 X-10 Y60 (50*sqrt2).
    # Rapids: 10 + sqrt(10^2 + 60^2) + 16 (Z10 -> Z-6) + 6 + 6.
    interp, segs = _run(gcode, "siemens_kit_dmc60h/AL_2007_T4_Notch_Normal.mpf")
    low, high = _bounds(segs)
    assert low == pytest.approx((-10, 0, -18), abs=1e-9)
    assert high == pytest.approx((60, 60, 10), abs=1e-9)
    feed = sum(s.length_mm for s in segs if s.kind in (LINEAR, ARC))
    rapid = sum(s.length_mm for s in segs if s.kind == RAPID)
    assert feed == pytest.approx(3 * (40 + 15 * math.pi + 20 + 20 + 50 * math.sqrt(2)))
    assert rapid == pytest.approx(10 + math.sqrt(3700) + 16 + 6 + 6)
    arcs = [s for s in segs if s.kind == ARC]
    assert [s.center_mm for s in arcs] == [pytest.approx((30, 30, z)) for z in (-6, -12, -18)]
    assert [s.turns for s in arcs] == [-1, -1, -1]
    cutting = [s for s in segs if s.kind != RAPID]
    assert {s.feed_mm_min for s in cutting} == {350.0}  # F350 mm/min
    assert {s.spindle_rpm for s in cutting} == {3800.0}  # S3800 M3
    assert interp.units == "mm"


def test_fusion_block_first_moves_and_lengths(gcode: Path) -> None:
    # 1024_block_14bit.nc: G90 G94 G17 G21, T1, S5000 M3, G54 (no offset set), then
    # line 15 G0 X-0.7 Y-0.7, 16 Z10, 17 G1 Z5 F1000, 18 Z2 F333.3, 19 Z-1, 20 Y20 F1000.
    _, segs = _run(gcode, "fusion360_grbl_shooshx/1024_block_14bit.nc")
    first = [(s.line, s.kind, s.end_mm, s.feed_mm_min) for s in segs[:6]]
    assert first == [
        (15, RAPID, pytest.approx((-0.7, -0.7, 0)), 0.0),
        (16, RAPID, pytest.approx((-0.7, -0.7, 10)), 0.0),
        (17, LINEAR, pytest.approx((-0.7, -0.7, 5)), 1000.0),
        (18, LINEAR, pytest.approx((-0.7, -0.7, 2)), 333.3),
        (19, LINEAR, pytest.approx((-0.7, -0.7, -1)), 333.3),
        (20, LINEAR, pytest.approx((-0.7, 20, -1)), 1000.0),
    ]
    assert all(s.spindle_rpm == 5000.0 for s in segs)
    # 26 moves: 5 to the first depth, 3 square passes of 6 moves, 2 step-downs, and the
    # final "Z10", still G1 (modal) from Z-3.
    assert len(segs) == 26
    # Feed path: 5 + 3 + 3 down, 3 x (20.7 + 0.7 + 20.7 + 0.7 + 21.4 + 21.4), 1 + 1 down,
    # 13 up.
    feed = sum(s.length_mm for s in segs if s.kind == LINEAR)
    assert feed == pytest.approx(11 + 3 * 85.6 + 2 + 13)
    rapid = sum(s.length_mm for s in segs if s.kind == RAPID)
    assert rapid == pytest.approx(math.hypot(0.7, 0.7) + 10)
    low, high = _bounds(segs)
    assert low == pytest.approx((-0.7, -0.7, -3))
    assert high == pytest.approx((20.7, 20.7, 10))


@pytest.mark.parametrize(
    "name",
    [
        "fusion360_grbl_shooshx/1110_wall_265bit.nc",
        "fusion360_grbl_shooshx/1121_btn8copies_20bit.nc",
    ],
)
def test_fusion_arc_count(gcode: Path, name: str) -> None:
    # Count arc blocks in the text: a block with an I, J or K word (the post writes
    # centres as IJK offsets and uses them for nothing else), clockwise if the last
    # motion G-word (G0-G3, modal) is G2, counter-clockwise if G3.
    cw = ccw = 0
    modal = None
    for raw in (gcode / name).read_text().splitlines():
        text = re.sub(r"\(.*?\)", "", raw).upper()
        codes = re.findall(r"G0*([0-3])(?![0-9.])", text)
        if codes:
            modal = codes[-1]
        if re.search(r"[IJK][-+]?\.?\d", text):
            assert modal in ("2", "3"), raw
            cw += modal == "2"
            ccw += modal == "3"
    _, segs = _run(gcode, name)
    arcs = [s for s in segs if s.kind == ARC]
    assert cw > 500 and ccw > 500
    assert sum(1 for s in arcs if s.turns == -1) == cw
    assert sum(1 for s in arcs if s.turns == 1) == ccw
    assert len(arcs) == cw + ccw
    # The posts write G18/G19 before arcs in those planes; every arc lies in a plane and
    # keeps its start and end radius.
    for s in arcs:
        i0, i1, _ = PLANE_AXES[s.state.plane]
        r0 = math.hypot(s.start_mm[i0] - s.center_mm[i0], s.start_mm[i1] - s.center_mm[i1])
        r1 = math.hypot(s.end_mm[i0] - s.center_mm[i0], s.end_mm[i1] - s.center_mm[i1])
        assert r0 == pytest.approx(r1, abs=0.005), s


def _hole_bottoms(segs: list[Segment]) -> list[tuple[float, float, float]]:
    return [tuple(v / INCH for v in s.end_mm) for s in segs if s.kind == LINEAR]


def test_bolt_hole_circle(gcode: Path) -> None:
    # hole-circle.ngc: G20; G0 X1.5 Y0 Z0; G91 G81 R.1 Z-.5 ^60 L6. Incremental: R plane
    # 0 + 0.1, bottom 0.1 - 0.5 = -0.4; each repeat turns the polar angle by 60 deg about
    # the origin at radius 1.5.
    _, segs = _run(gcode, "linuxcnc/hole-circle.ngc")
    expected = [
        (1.5 * math.cos(math.radians(60 * k)), 1.5 * math.sin(math.radians(60 * k)), -0.4)
        for k in range(1, 7)
    ]
    got = _hole_bottoms(segs)
    assert len(got) == 6
    for g, e in zip(got, expected, strict=True):
        assert g == pytest.approx(e, abs=1e-9)


def test_polar_sample(gcode: Path) -> None:
    # polar.ngc (G20): G0 X2.5 Y0 at Z0, G81 R.1 Z-0.5 drills there (R above the start:
    # up to R first; the clearance level is then R = 0.1); ^120 and ^240 keep the radius
    # 2.5. "G90 @1 ^33" is still G81: a hole at radius 1, 33 deg. "G91 G81 @1 R.1 Z-0.5
    # L5": radius +1 per repeat (2..6), R = 0.1 + 0.1, bottom 0.2 - 0.5 = -0.3.
    # "G90 G0 X2 Y0" at Z 0.2, "G91 G81 ^[360/17] R.1 Z-0.5 L17": radius 2, 17 steps of
    # 360/17 deg, R 0.3, bottom -0.2.
    def polar(r: float, deg: float, z: float) -> tuple[float, float, float]:
        return (r * math.cos(math.radians(deg)), r * math.sin(math.radians(deg)), z)

    expected = [polar(2.5, a, -0.5) for a in (0, 120, 240)] + [polar(1, 33, -0.5)]
    expected += [polar(r, 33, -0.3) for r in (2, 3, 4, 5, 6)]
    expected += [polar(2, 360 * k / 17, -0.2) for k in range(1, 18)]
    _, segs = _run(gcode, "linuxcnc/polar.ngc")
    got = _hole_bottoms(segs)
    assert len(got) == len(expected) == 26
    for g, e in zip(got, expected, strict=True):
        assert g == pytest.approx(e, abs=1e-9)


def test_mmount_tool_sequence(gcode: Path) -> None:
    # The tools loaded by "T<n> M6" blocks, in order of first use; T0 M6 unloads.
    text = (gcode / "linuxcnc/mmount.ngc").read_text()
    tools: list[int] = []
    for raw in text.splitlines():
        code = re.sub(r"\(.*?\)", "", raw).upper()
        found = re.search(r"T(\d+)", code)
        if found and re.search(r"M0*6(?!\d)", code) and int(found.group(1)) not in tools:
            tools.append(int(found.group(1)))
    tools = [t for t in tools if t != 0]
    interp, _ = _run(gcode, "linuxcnc/mmount.ngc")
    assert tools == [1, 4, 3, 2, 5, 6]
    assert interp.tools_used == tools
    assert interp.units == "inch"


def test_haas_g18_arc(gcode: Path) -> None:
    # 1003.nc, inch: line 18 "G1 X7.1884 Y0.159 F650.", line 22 "G1 Z0.15 F13.333",
    # line 23 "G18 G3 X6.9884 Z-0.05 I-0.2 K0. F91.673". G18 centre = start + (I, K):
    # (6.9884, 0.159, 0.15); start and end are 0.2 from it; from +X to -Z about +Y is a
    # quarter turn counter-clockwise (Z x X = Y): length 0.2 * pi/2 in.
    _, segs = _run(gcode, "haas_style_enier/1003.nc")
    line18 = next(s for s in segs if s.line == 18)
    assert line18.kind == LINEAR and line18.feed_mm_min == pytest.approx(650 * INCH)
    assert line18.end_mm == pytest.approx((7.1884 * INCH, 0.159 * INCH, 0.0))
    arc = next(s for s in segs if s.line == 23)
    assert arc.kind == ARC and arc.state.plane == Plane.ZX and arc.turns == 1
    assert arc.center_mm == pytest.approx((6.9884 * INCH, 0.159 * INCH, 0.15 * INCH))
    assert arc.end_mm == pytest.approx((6.9884 * INCH, 0.159 * INCH, -0.05 * INCH))
    assert arc.length_mm == pytest.approx(0.2 * math.pi / 2 * INCH)
    assert arc.feed_mm_min == pytest.approx(91.673 * INCH)


def test_haas_lathe_constant_surface_speed(gcode: Path) -> None:
    # o20013.nc (lathe, inch, diameter mode): G28 (home 0), T0101 (no table: zero offset),
    # G50 S3000, G96 S1000 M03, line 19 G00 X2.1 Z0.1 (radius 1.05 in), line 22 G00 G42
    # X1.94 Z0.1 (no radius in the table: no compensation), line 23 G01 Z-1.6 F0.01 (G99:
    # in/rev). At radius 0.97 in = 24.638 mm, 1000 ft/min = 304800 mm/min gives
    # 304800 / (2 pi 24.638) = 1968.9 rpm (< 3000): feed 0.01 * 25.4 * rpm mm/min.
    _, segs = _run(gcode, "haas_style_enier/o20013.nc")
    line19 = next(s for s in segs if s.line == 19)
    assert line19.end_mm == pytest.approx((1.05 * INCH, 0.0, 0.1 * INCH))
    cut = next(s for s in segs if s.line == 23)
    assert cut.kind == LINEAR
    assert cut.start_mm == pytest.approx((0.97 * INCH, 0.0, 0.1 * INCH))
    assert cut.end_mm == pytest.approx((0.97 * INCH, 0.0, -1.6 * INCH))
    rpm = 304_800 / (2 * math.pi * 0.97 * INCH)
    assert cut.spindle_rpm == pytest.approx(rpm)
    assert cut.feed_mm_min == pytest.approx(0.01 * INCH * rpm)
    assert cut.state.spindle_clamp_rpm == 3000.0
