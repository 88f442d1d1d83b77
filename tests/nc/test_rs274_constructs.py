"""Small programs, one construct each, run through cnctwin and LinuxCNC's ``rs274``.

Each program either runs in both with the same moves, arc centres and feeds, or is refused
by both (cnctwin with an :class:`~cnctwin.errors.NCError` naming the line). Where rs274
cannot show a behaviour (a warning, a time estimate) the test checks cnctwin alone against
the LinuxCNC documentation.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from rs274_oracle import DEFAULT_TOOLS, first_difference, rs274_fixture, run_cnctwin, run_rs274

from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.setup import NCSetup
from cnctwin.nc.summary import summarize
from cnctwin.nc.tool_table import parse_tool_table

__all__ = ["rs274_fixture"]  # the fixture, used by name

pytestmark = pytest.mark.validation


def _both(rs274: str, tmp_path: Path, text: str, tools: str = DEFAULT_TOOLS) -> tuple[str, str]:
    """Run ``text`` in both; return (cnctwin's error, rs274's error) after checking moves."""
    program = tmp_path / "p.ngc"
    program.write_text(text)
    ours, theirs = run_cnctwin(program, tools), run_rs274(rs274, program, tools)
    if not ours.error and not theirs.error:
        assert first_difference(ours, theirs) == ""
        assert ours.moves
    return ours.error, theirs.error


def _agree(rs274: str, tmp_path: Path, text: str, tools: str = DEFAULT_TOOLS) -> None:
    ours, theirs = _both(rs274, tmp_path, text, tools)
    assert (ours, theirs) == ("", "")


def _both_refuse(rs274: str, tmp_path: Path, text: str, tools: str = DEFAULT_TOOLS) -> str:
    ours, theirs = _both(rs274, tmp_path, text, tools)
    assert ours and theirs, (ours, theirs)
    return ours


# ----------------------------------------------------------------- canned cycles
@pytest.mark.parametrize("mode", ["", "G98", "G99"])
def test_canned_cycle_retract_modes(rs274: str, tmp_path: Path, mode: str) -> None:
    # Without G98 or G99 LinuxCNC retracts to the R plane (its initial mode is G99's).
    _agree(
        rs274,
        tmp_path,
        f"G21 G17 G90 G0 X0 Y0 Z10\n{mode} G81 X5 Y5 R2 Z-3 F100\nX10\nY10 R1\nG80\nG0 Z10\nM2\n",
    )


def test_canned_cycle_retract_mode_after_g98_then_g99(rs274: str, tmp_path: Path) -> None:
    _agree(
        rs274,
        tmp_path,
        "G21 G90 G0 X0 Y0 Z10\nG98 G83 X5 Y5 R2 Z-6 Q2 F100\nG99 X10\nG80\nM2\n",
    )


# ----------------------------------------------------------------- arc end radius
def _arc(units: str, radius: float, error: float) -> str:
    """A half circle from X0 whose end lies ``error`` beyond the start radius."""
    return f"{units} G17 G90 G0 X0 Y0 Z0\nG2 X{2 * radius + error:.6f} Y0 I{radius} J0 F100\nM2\n"


@pytest.mark.parametrize(
    ("units", "radius", "error"),
    [
        ("G21", 10.0, 0.028),  # within 0.028284 mm (a CAM centre rounded to 3 decimals)
        ("G21", 0.5, -0.028),
        ("G21", 1000.0, 0.99),  # over 0.028284 mm but within 0.1 % of the radius
        ("G20", 1.0, 0.0028),  # within 0.0028284 in
        ("G20", 100.0, 0.099),
    ],
)
def test_arc_end_radius_within_linuxcnc_tolerance_runs(
    rs274: str, tmp_path: Path, units: str, radius: float, error: float
) -> None:
    _agree(rs274, tmp_path, _arc(units, radius, error))


@pytest.mark.parametrize(
    ("units", "radius", "error"),
    [
        ("G21", 10.0, 0.029),
        ("G21", 1000.0, 1.02),  # over 0.1 % of the radius
        ("G21", 5000.0, 2.9),  # within 0.1 % but over 100 x 0.028284 mm
        ("G20", 1.0, 0.0029),
    ],
)
def test_arc_end_radius_beyond_linuxcnc_tolerance_is_refused(
    rs274: str, tmp_path: Path, units: str, radius: float, error: float
) -> None:
    assert "radii must agree" in _both_refuse(rs274, tmp_path, _arc(units, radius, error))


# ----------------------------------------------------------------- tools
def test_m61_sets_the_current_tool_without_a_change(rs274: str, tmp_path: Path) -> None:
    _agree(rs274, tmp_path, "G21 G0 X1\nM61 Q3\nG0 X2\nM61 Q0\nG0 X3\nM2\n")


def test_m61_then_g43_uses_the_new_tool_length() -> None:
    # LinuxCNC's documentation: G43 without H uses the current tool, which M61 sets. (The
    # standalone rs274 applies a zero length here: its tool data are not updated by M61.)
    setup = NCSetup(tools=parse_tool_table("T3 P3 D0.1 Z0.5\n", units="inch"))
    interp = Interpreter(setup)
    segments = list(interp.run_text("G21 M61 Q3\nG43\nG0 X1 Z0\nM2"))
    assert segments[-1].end_mm[2] == pytest.approx(12.7)
    assert segments[-1].state.tool == 3 and interp.tools_used == [3]


@pytest.mark.parametrize("block", ["M61", "M61 Q-1", "M61 Q1.5"])
def test_m61_without_a_tool_number_is_refused(block: str) -> None:
    with pytest.raises(NCError, match="M61 needs Q") as caught:
        list(Interpreter().run_text(f"G21\n{block}\nM2"))
    assert caught.value.line == 2


def test_m61_without_q_is_refused_by_both(rs274: str, tmp_path: Path) -> None:
    _both_refuse(rs274, tmp_path, "G21 G0 X1\nM61\nM2\n")


# ----------------------------------------------------------------- subroutines
def _nested_calls(depth: int) -> str:
    return (
        "o100 sub\n  G0 X#1\n  o101 if [#1 LT {depth}]\n    o100 call [#1 + 1]\n"
        "  o101 endif\no100 endsub\nG21\no100 call [1]\nM2\n"
    ).replace("{depth}", str(depth))


def test_nine_nested_calls_run(rs274: str, tmp_path: Path) -> None:
    _agree(rs274, tmp_path, _nested_calls(9))


def test_a_tenth_nested_call_is_refused(rs274: str, tmp_path: Path) -> None:
    assert "nested deeper than 9" in _both_refuse(rs274, tmp_path, _nested_calls(10))


# ----------------------------------------------------------------- reading
@pytest.mark.parametrize(
    "text",
    [
        "G21 G0 X\uff11\uff10\nM2\n",  # full-width digits
        "G21 G0 X1\nN\uff11 G0 X2\nM2\n",
        "G21 G0 X[\uff11 + 1]\nM2\n",
        "G21 G\u0661 X3\nM2\n",  # an Arabic-Indic digit
    ],
)
def test_non_ascii_digits_are_not_digits(rs274: str, tmp_path: Path, text: str) -> None:
    assert "found" in _both_refuse(rs274, tmp_path, text)


@pytest.mark.parametrize(
    ("text", "warning"),
    [
        ("", "the program is empty"),
        ("(only a comment)\n\n", "the program is empty"),
        ("G21\nG0 X1\n", "ends without M2, M30 or a closing '%'"),
    ],
)
def test_a_program_without_an_end_warns(
    rs274: str, tmp_path: Path, text: str, warning: str
) -> None:
    program = tmp_path / "p.ngc"
    program.write_text(text)
    interp = Interpreter()
    list(interp.run_file(program))
    assert len(interp.warnings) == 1 and warning in interp.warnings[0]
    # LinuxCNC's rs274 stops on them with an error; cnctwin runs them and warns.
    assert "File ended with no percent sign" in run_rs274(rs274, program).error


@pytest.mark.parametrize("end", ["M2", "M30", "%"])
def test_a_program_with_an_end_does_not_warn(end: str) -> None:
    interp = Interpreter()
    list(interp.run_text(f"%\nG21 G0 X1\n{end}\n"))
    assert interp.warnings == []


# ----------------------------------------------------------------- rotary feed moves
@pytest.mark.parametrize(
    ("text", "seconds"),
    [
        ("G21 G94 G1 A90 F360", 15.0),  # F in deg/min on a rotary-only move
        ("G20 G94 G1 A90 F360", 15.0),  # degrees are not inches
        ("G21 G93 G1 A90 F4", 15.0),  # inverse time: 1/4 min
        ("G21 G94 G1 A30 B40 F100", 30.0),  # 50 deg together
        ("G21 G94 G1 X10 A90 F600", 1.0),  # with a linear axis, F is along X Y Z
    ],
)
def test_rotary_only_feed_moves_take_time(
    rs274: str, tmp_path: Path, text: str, seconds: float
) -> None:
    _agree(rs274, tmp_path, f"{text}\nM2\n")
    result = summarize(Interpreter().run_text(f"{text}\nM2"), rapid_mm_min=10_000.0)
    assert result.machining_time_s == pytest.approx(seconds)
    assert result.zero_feed_moves == 0


# ----------------------------------------------------------------- cutter compensation
#: A tool of radius 0.25 in (diameter 0.5 in).
QUARTER_INCH_TOOL = "T1 P1 D0.5 Z0\n"


def _entry(length_in: float) -> str:
    return f"G20 G17 G90 T1 M6\nG0 X0 Y0 Z0\nG41 G1 X{length_in} F10\nY1\nG40 G0 X-1\nM2\n"


@pytest.mark.parametrize("length_in", [0.25, 0.26, 1.0])
def test_cutter_comp_entry_of_at_least_the_tool_radius_runs(
    rs274: str, tmp_path: Path, length_in: float
) -> None:
    _agree(rs274, tmp_path, _entry(length_in), QUARTER_INCH_TOOL)


@pytest.mark.parametrize("length_in", [0.1, 0.2499])
def test_cutter_comp_entry_shorter_than_the_tool_radius_is_refused(
    rs274: str, tmp_path: Path, length_in: float
) -> None:
    error = _both_refuse(rs274, tmp_path, _entry(length_in), QUARTER_INCH_TOOL)
    assert "shorter than the tool radius" in error and ":3:" in error


def _inside_arc(radius_in: float) -> str:
    return (
        "G20 G17 G90 T1 M6\nG0 X-1 Y-1 Z0\nG41 G1 X0 Y0 F10\n"
        f"G3 X{radius_in} Y{radius_in} I0 J{radius_in}\nG1 Y2\nG40 G0 X-1\nM2\n"
    )


@pytest.mark.parametrize("radius_in", [0.25, 0.3, 0.5])
def test_tool_as_large_as_an_inside_arc_runs(rs274: str, tmp_path: Path, radius_in: float) -> None:
    # At 0.25 in the offset arc shrinks to its centre; LinuxCNC prints it as an arc of
    # radius 0 there, and so does cnctwin.
    _agree(rs274, tmp_path, _inside_arc(radius_in), QUARTER_INCH_TOOL)


def test_tool_larger_than_an_inside_arc_is_refused(rs274: str, tmp_path: Path) -> None:
    error = _both_refuse(rs274, tmp_path, _inside_arc(0.2), QUARTER_INCH_TOOL)
    assert "larger than the arc radius" in error
