"""Runs of straight moves read in bulk give what the line-by-line path gives, to the bit.

:meth:`Interpreter.run_text_bulk` hands long runs of plain ``G0``/``G1`` lines to
:mod:`cnctwin.nc.runs` (numbers parsed and positions computed with numpy) and
:func:`~cnctwin.nc.summary.summarize` sums them in bulk. The reference is the
interpreter's line-by-line path (:meth:`Interpreter.run_text`) and the per-segment summary:
generated programs, with lines that must end a run mixed in, are run both ways and the
segments, warnings, lines read, errors and summaries compared exactly (``repr`` of floats,
so that -0.0 and 0.0 differ). The number parser is checked against Python's ``float``.
"""

from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.runs import MIN_RUN_LINES, StraightRun
from cnctwin.nc.segments import Segment
from cnctwin.nc.setup import NCSetup
from cnctwin.nc.summary import summarize

HEADER = "G21 G90 G17 G94\nT1 M6\nS1000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F300\n"

number = st.one_of(
    st.integers(-99999, 99999).map(str),
    st.decimals(-9999, 9999, places=4).map(lambda d: f"{d:f}"),
    st.floats(-5000, 5000, allow_nan=False).map(lambda v: f"{v:.3f}"),
    st.sampled_from(["-0", "+0", "0.", ".5", "-.25", "+3.", "007.50", "-0.000"]),
)

#: Lines that end a run (the line-by-line path or the general path takes them).
breakers = st.sampled_from(
    [
        "",
        "(a comment)",
        "G1 X1 (comment)",
        "G91",
        "G90",
        "G20",
        "G21",
        "G93",
        "G94",
        "F0",
        "G1 X2 F0",
        "G0 X1 F-3",
        "X1.2.3",
        "X1 5",
        "N 10 X1",
        "G 1 X2",
        "G2 X1 Y0 I0.5 J0",
        "G1X1234567890123456.5",
        "X0.12345678901234567",
        "G1 X1 Y2 Z3 A4",
        "/G1 X5",
        "G43 H1",
        "G49",
        "G92 X1",
        "G92.1",
        "G10 L2 P1 X3",
        "G54",
        "M5",
        "G0 Z5",
        "#1 = 3",
        "G1 X[#1]",
        "X1\tY2",
        "x1 y2",
        "G1 X2000000",
        "G80",
        "G4 P0.1",
    ]
)


@st.composite
def plain_line(draw: st.DrawFn) -> str:
    """A line of the kind runs take (optional N, G0/G1, X/Y/Z, F; some spacing)."""
    words = []
    if draw(st.booleans()) and draw(st.booleans()):
        words.append(f"N{draw(st.integers(0, 99999))}")
    if draw(st.booleans()):
        words.append(draw(st.sampled_from(["G0", "G1", "G00", "G01", "g1", "G001"])))
    axes = draw(st.sets(st.sampled_from("XYZ"), min_size=1))
    for axis in "XYZ":
        if axis in axes:
            letter = axis if draw(st.booleans()) else axis.lower()
            words.append(f"{letter}{draw(st.sampled_from(['', ' ']))}{draw(number)}")
    if draw(st.integers(0, 5)) == 0:
        words.append(f"F{draw(st.sampled_from(['100', '250.5', '2000', '.5', '75.']))}")
    gap = draw(st.sampled_from([" ", "", "  ", "\t"]))
    return draw(st.sampled_from(["", " "])) + gap.join(words)


@st.composite
def program(draw: st.DrawFn) -> str:
    blocks = []
    for _ in range(draw(st.integers(1, 4))):
        blocks.extend(draw(st.lists(plain_line(), min_size=0, max_size=3 * MIN_RUN_LINES)))
        blocks.extend(draw(st.lists(breakers, min_size=0, max_size=2)))
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    end = draw(st.sampled_from(["M2", "M2\n", ""]))
    return HEADER.replace("\n", eol) + eol.join(blocks) + eol + end


def _repr(value: object) -> object:
    """Floats by ``repr`` (so that -0.0 and 0.0 differ), deeply."""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, tuple | list):
        return [_repr(v) for v in value]
    if isinstance(value, dict):
        return {k: _repr(v) for k, v in value.items()}
    if isinstance(value, Segment):
        return [_repr(getattr(value, name)) for name in value.__slots__]
    return value


def both_ways(text: str, setup: NCSetup | None = None) -> tuple[object, object, int]:
    """(line-by-line result, bulk result, moves in runs), each the segments, warnings,
    lines read and summary, or the error message."""
    results = []
    in_runs = 0
    for bulk in (False, True):
        interpreter = Interpreter(setup)
        items: list[Segment | StraightRun] = []
        try:
            stream = (
                interpreter.run_text_bulk(text, "p.ngc")
                if bulk
                else interpreter.run_text(text, "p.ngc")
            )
            for item in stream:
                items.append(item)
        except NCError as err:
            results.append(str(err))
        else:
            segments = [
                s for i in items for s in (i.segments() if isinstance(i, StraightRun) else [i])
            ]
            summary = summarize(items, rapid_mm_min=5000.0).to_dict()
            results.append(_repr([segments, interpreter.warnings, interpreter.lines_read, summary]))
        if bulk:
            in_runs = sum(len(i) for i in items if isinstance(i, StraightRun))
    return results[0], results[1], in_runs


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(program())
def test_runs_equal_the_line_by_line_path(text: str) -> None:
    one_by_one, bulk, _ = both_ways(text)
    assert bulk == one_by_one


@pytest.mark.parametrize(
    "tail",
    [
        "",  # the last line without a line end
        "\nX1 F-5\nM2\n",  # an error after a run: its line is named
        "\nG1 X2000000\nM2\n",
        "\nM2\n",
    ],
)
def test_long_runs_are_taken_and_match(tail: str) -> None:
    lines = [
        f"G1 X{i * 0.001:.3f} Y{-i * 0.5:.4f}" + (" F200" if i % 7 == 0 else "")
        for i in range(3000)
    ]
    lines[1500] = "G0 Z3"
    lines[2000] = "N20 G01 Z-1 F100"
    text = HEADER + "\n".join(lines) + tail
    one_by_one, bulk, in_runs = both_ways(text)
    assert in_runs > 2500
    assert bulk == one_by_one


def test_offsets_inch_and_the_segment_limit() -> None:
    """Runs under work offsets, a tool length offset and inch units, and a run cut by the
    segment limit (the error names the same line both ways)."""
    body = "\n".join(f"X{i * 0.01:.2f} Y{(i % 13) * 0.1:.1f}" for i in range(400))
    text = "G20 G90 G10 L2 P1 X1.5 Y-2 Z0.25\nG54 T1 M6 G43 H1\nG1 X0 Y0 F20\n" + body + "\nM2\n"
    one_by_one, bulk, in_runs = both_ways(text)
    assert in_runs > 300
    assert bulk == one_by_one
    limited = NCSetup(max_segments=250)
    one_by_one, bulk, _ = both_ways(text, limited)
    assert isinstance(bulk, str) and bulk == one_by_one


def test_summary_json_is_byte_identical() -> None:
    """The summary's numbers, written as JSON, are the same characters both ways."""
    lines = [
        f"G1 X{(i * 37 % 101) / 7:.4f} Y{(i * 53 % 97) / 3:.4f} Z{-(i % 5) / 9:.5f}"
        for i in range(2000)
    ]
    text = HEADER + "\n".join(lines) + "\nG0 Z5\nM2\n"
    dumps = []
    for bulk in (False, True):
        interpreter = Interpreter()
        items = interpreter.run_text_bulk(text) if bulk else interpreter.run_text(text)
        dumps.append(json.dumps(summarize(items, rapid_mm_min=3000.0).to_dict()))
    assert dumps[0] == dumps[1]
