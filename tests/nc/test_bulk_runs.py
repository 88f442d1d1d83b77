"""Runs of moves read in bulk give what the line-by-line path gives, to the bit.

:meth:`Interpreter.run_text_bulk` hands long runs of plain ``G0``/``G1`` and ``G2``/``G3``
lines (alone or mixed) to
:mod:`cnctwin.nc.runs` (numbers parsed and positions computed with numpy) and
:func:`~cnctwin.nc.summary.summarize` sums them in bulk. The reference is the
interpreter's line-by-line path (:meth:`Interpreter.run_text`) and the per-segment summary:
generated programs, with lines that must end a run mixed in, are run both ways and the
segments, warnings, lines read, errors and summaries compared exactly (``repr`` of floats,
so that -0.0 and 0.0 differ), and the canonical trace that ``nc trace`` prints of runs
(:func:`~cnctwin.nc.trace.trace_text`, numbers printed with numpy) against the lines of
:func:`~cnctwin.nc.trace.format_trace` (Python's ``%.4f``), character for character. The
number parser is checked against Python's ``float``, the trace's number printer against
Python's ``%.4f``.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.runs import MIN_RUN_LINES, MoveRun, arc_sweeps, xy_atan2, xy_hypot
from cnctwin.nc.segments import Plane, Segment, arc_sweep_rad
from cnctwin.nc.setup import NCSetup, ToolEntry
from cnctwin.nc.summary import summarize
from cnctwin.nc.trace import _lines_text, format_trace, trace_text

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
        "G94",
        "X1 5",
        "N 10 X1",
        "G 1 X2",
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
        "G80",
        "G4 P0.1",
        "G17",
        "G18",
        "G90.1",
        "G91.1",
        "G43 H1",
    ]
)


#: Lines that stop the program with an error (the same one both ways, at the same line).
errors = st.sampled_from(
    [
        "G1 X2 F0",
        "G0 X1 F-3",
        "X1.2.3",
        "G2 X1 Y0 I0.5 J0",
        "G1X1234567890123456.5",
        "G1 X2000000",
        "G3 X0 Y0 I1 J0 K1",
        "G2 X3 Y0 I1 J0 P2",
        "G2 X1 Y1 R1",
        "G93",
        "F0",
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
def arc_lines(draw: st.DrawFn) -> list[str]:
    """A rapid to a start point, then arcs from there (I J centres, end on the circle to
    four decimals; now and then a Z rise, an N word, a modal arc, or a wrong radius)."""
    x, y = draw(st.integers(-50, 50)), draw(st.integers(-50, 50))
    lines = [f"G90 G91.1 G17 G0 X{x} Y{y}"]
    for _ in range(draw(st.sampled_from([0, 5, MIN_RUN_LINES, 2 * MIN_RUN_LINES + 3]))):
        i, j = draw(st.sampled_from([(1.5, 0.0), (0.0, -2.0), (-0.75, 0.5), (3.0, 4.0)]))
        angle = draw(st.floats(-3.1, 3.1))
        radius = math.hypot(i, j) * draw(st.sampled_from([1.0] * 199 + [1.2]))
        cx, cy = x + i, y + j
        ex, ey = round(cx + radius * math.cos(angle), 4), round(cy + radius * math.sin(angle), 4)
        words = [
            draw(st.sampled_from(["G2", "G3", "G02", "g3"] + ([""] if len(lines) > 1 else [])))
        ]
        if draw(st.integers(0, 9)) == 0:
            words.insert(0, "N5")
        words += [f"X{ex:.4f}", f"Y{ey:.4f}"]
        if draw(st.integers(0, 4)) == 0:
            words.append(f"Z{draw(st.integers(-5, 5)) / 4}")
        if i or draw(st.booleans()):
            words.append(f"I{i}")
        if j or not i:
            words.append(f"J{j}")
        lines.append(" ".join(w for w in words if w))
        x, y = ex, ey
    return lines


@st.composite
def program(draw: st.DrawFn) -> str:
    blocks = []
    for _ in range(draw(st.integers(1, 4))):
        if draw(st.booleans()):
            blocks.extend(draw(arc_lines()))
        else:
            size = draw(st.sampled_from([0, MIN_RUN_LINES - 1, MIN_RUN_LINES, 2 * MIN_RUN_LINES]))
            blocks.append(draw(st.sampled_from(["G0 X1", "G1 Y2", "G90 G1 Z0"])))
            blocks.extend(draw(st.lists(plain_line(), min_size=size, max_size=size + 8)))
        blocks.extend(draw(st.lists(breakers, min_size=0, max_size=2)))
    if draw(st.sampled_from([False] * 7 + [True])):
        blocks.insert(draw(st.integers(0, len(blocks))), draw(errors))
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
        return [_repr(getattr(value, field.name)) for field in dataclasses.fields(value)]
    return value


def both_ways(text: str, setup: NCSetup | None = None) -> tuple[object, object, int]:
    """(line-by-line result, bulk result, moves in runs), each the segments, warnings,
    lines read, summary and traces in both frames, or the error message."""
    results = []
    in_runs = 0
    for bulk in (False, True):
        interpreter = Interpreter(setup)
        items: list[Segment | MoveRun] = []
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
            segments = [s for i in items for s in (i.segments() if isinstance(i, MoveRun) else [i])]
            summary = summarize(items, rapid_mm_min=5000.0).to_dict()
            traces = [
                "".join(trace_text(items, frame))
                if bulk
                else "".join(f"{line}\n" for line in format_trace(segments, frame))
                for frame in ("program", "machine")
            ]
            result = [segments, interpreter.warnings, interpreter.lines_read, summary, traces]
            results.append(_repr(result))
        if bulk:
            in_runs = sum(len(i) for i in items if isinstance(i, MoveRun))
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
    tools = NCSetup(tools={1: ToolEntry(1, length_mm=42.125, diameter_mm=6.0)})
    one_by_one, bulk, in_runs = both_ways(text, tools)
    assert in_runs > 300
    assert bulk == one_by_one
    limited = NCSetup(tools=tools.tools, max_segments=250)
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


@pytest.mark.parametrize("offset", ["", "G10 L2 P1 X2 Y-3 Z1\nG43 H1\n", "G20\n"])
def test_long_arc_runs_are_taken_and_match(offset: str) -> None:
    """Half circles out and back (the benchmark's arcs), with a helix now and then, under
    work and tool offsets and in inches."""
    lines = []
    for n in range(1500):
        r = 1.0 + (n * 7919 % 1000) / 500.0
        lift = f" Z{-(n % 3) / 4}" if n % 5 == 0 else ""
        lines += [f"G3 X{2 * r:.4f} Y0{lift} I{r:.4f} J0", f"G2 X0 Y0 I{-r:.4f} J0"]
    text = "G21 G90 G17 G94 F300\nT1 M6\n" + offset + "G0 X0 Y0\n" + "\n".join(lines) + "\nM2\n"
    tools = NCSetup(tools={1: ToolEntry(1, length_mm=42.125, diameter_mm=6.0)})
    one_by_one, bulk, in_runs = both_ways(text, tools)
    assert in_runs > 2900
    assert bulk == one_by_one


@st.composite
def cam_mix(draw: st.DrawFn) -> str:
    """CAM-style output: straight moves and arcs in any order (two G1 lines then a half
    circle out and back, as the benchmark's ``mixed``, or drawn one by one), with N words,
    lower case, modal G words, F changes, rapids, helices and now and then a line that must
    end a run (a wrong radius, an arc under G18 or G90.1 or without centre, a straight move
    in arc mode or with I, F0)."""
    lines = [draw(st.sampled_from(["G17 G91.1"] * 7 + ["G17 G91.1 F0", "G18", "G17 G90.1"]))]
    x = y = 0.0
    motion = ""
    for _ in range(draw(st.integers(MIN_RUN_LINES, 3 * MIN_RUN_LINES))):
        kind = draw(st.sampled_from(["G1"] * 6 + ["G0", "x", "G2", "G3", "G2", "G3"]))
        if kind == "x" and motion not in ("G0", "G1"):
            kind = "G1"
        if kind in ("G0", "G1", "x"):
            x = round(x + draw(st.floats(-2, 2)), 3)
            y = round(y + draw(st.floats(-2, 2)), 3)
            g = "" if kind == "x" else draw(st.sampled_from([kind, kind.lower(), "G0" + kind[1]]))
            feed = draw(st.sampled_from(["", "", "", " F250", " f1000.5"]))
            lines.append(f"{g} X{x:.3f} y{y:.3f}{feed}".strip())
            motion = kind if kind != "x" else motion
        else:
            r = draw(st.sampled_from([0.5, 1.25, 3.0]))
            wrong = draw(st.sampled_from([1.0] * 199 + [1.3]))
            lift = draw(st.sampled_from(["", "", "", " Z-0.5", " z0.25"]))
            n = draw(st.sampled_from(["", "", "N7 "]))
            g = "" if motion == kind and draw(st.booleans()) else kind
            lines.append(f"{n}{g} X{x + 2 * r * wrong:.3f} Y{y:.3f}{lift} I{r} J0".strip())
            lines.append(f"{n}{'G2' if kind == 'G3' else 'g3'} X{x:.3f} Y{y:.3f} i{-r * wrong} j0")
            motion = "G3" if kind == "G2" else "G2"
    if draw(st.integers(0, 3)) == 0:
        breaker = ["X1.5", "G1 X1 I2", "G3 X1 Y1 K1", "G2 X1 Y0", "G17 G90.1", "G1 F0", "G18"]
        lines.insert(draw(st.integers(1, len(lines))), draw(st.sampled_from(breaker)))
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    return HEADER.replace("\n", eol) + eol.join(lines) + eol + "M2" + eol


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cam_mix())
def test_mixed_runs_equal_the_line_by_line_path(text: str) -> None:
    one_by_one, bulk, _ = both_ways(text)
    assert bulk == one_by_one


@pytest.mark.parametrize("shift", [0, 1, 2, 3])
def test_alternating_lines_are_read_in_bulk(shift: int) -> None:
    """CAM output alternating G1 and G2/G3 lines (the benchmark's ``mixed``, starting with
    each kind of line, and with work and tool offsets) is read in runs that take both kinds
    of line, and equals the line-by-line path."""
    lines = []
    for n in range(400):
        r = 1.0 + (n * 7919 % 1000) / 500.0
        x = (n * 37 % 100) / 10.0
        lines += [f"G1 X{x:.3f} Y1", f"G1 X{x:.3f} Y0"]
        lines += [f"G3 X{x + 2 * r:.4f} Y0 I{r:.4f} J0", f"G2 X{x:.3f} Y0 I{-r:.4f} J0"]
    body = "\n".join(lines[shift:] + lines[:shift])
    tools = NCSetup(tools={1: ToolEntry(1, length_mm=42.125, diameter_mm=6.0)})
    offsets = "G10 L2 P1 X2 Y-3 Z1\nG43 H1\n" if shift % 2 else ""
    text = HEADER + offsets + "G0 X0 Y0\nG1 Z-1\n" + body + "\nM2\n"
    one_by_one, bulk, in_runs = both_ways(text, tools)
    assert in_runs > 1500
    assert bulk == one_by_one


@pytest.mark.parametrize(
    "odd",
    [
        "G1 X1 X2",  # a word twice: an error line by line
        "G1 Y1 X2",  # words out of the run's order
        "X1 G1 Y2",
        "F100 G1 X1",
        "G1 X1 F100 Y2",
        "I1 X2 J0",
        "G2 X1 Y0 J0 I0.5",
        "N5 N6 G1 X1",
        "G1 G0 X1",
        "G1 X1 Y1 Z1 Z2",
    ],
)
@pytest.mark.parametrize("at", [40, 999])
def test_a_line_with_words_out_of_order_or_twice_ends_a_run(odd: str, at: int) -> None:
    # The bytes of each window pass the character checks; only the word order of each
    # line (its letters) keeps such a line out of the run.
    lines = [f"G1 X{i * 0.01:.2f} Y{(i % 11) * 0.1:.1f}" for i in range(1000)]
    lines[at] = odd
    one_by_one, bulk, in_runs = both_ways(HEADER + "\n".join(lines) + "\nM2\n")
    assert in_runs >= at - 1  # the lines before it (but the first) in runs
    assert bulk == one_by_one


@pytest.mark.parametrize(
    "odd", ["G1 Y1 X2", "N5 N6 G1 X1", "X1 G1", "G1 X1 X2", "F9 X1", "I1 J1 X1"]
)
def test_the_word_order_check_stops_at_the_first_line_out_of_order(odd: str) -> None:
    from cnctwin.nc import runs

    good = "".join(f"N{i} G1 X{i}.5 Y-2 F100\nG2 X1 Y0 I0.5 J0\n" for i in range(20))
    for data in (good + odd + "\n" + good, good + odd.lower() + "\nX1\n"):
        assert runs._valid_prefix(runs._MOVES, data.encode()) == len(good)
    assert runs._valid_prefix(runs._MOVES, good.encode()) == len(good)


coordinate = st.one_of(
    st.floats(-1000, 1000, allow_nan=False),
    st.sampled_from([0.0, -0.0, 1e-13, -1e-13, math.pi, -math.pi, 2.5, -2.5]),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(*[coordinate] * 6, st.sampled_from([1, -1])), min_size=1, max_size=40))
def test_arc_sweeps_equal_the_one_arc_function(arcs: list[tuple[float, ...]]) -> None:
    """The bulk sweeps (numpy's ``mod`` for Python's ``%``, a radius passed in or not) are
    :func:`arc_sweep_rad`'s numbers arc by arc, to the bit (starts at the centre, ends at
    the start and angles across +-pi among them)."""
    start = np.array([(a[0], a[1], 0.0) for a in arcs])
    end = np.array([(a[2], a[3], 1.0) for a in arcs])
    center = np.array([(a[4], a[5], 0.0) for a in arcs])
    turns = np.array([a[6] for a in arcs])
    expected = [
        arc_sweep_rad(tuple(s), tuple(e), tuple(c), int(t), Plane.XY)
        for s, e, c, t in zip(start.tolist(), end.tolist(), center.tolist(), turns, strict=True)
    ]
    radius = np.array([r for r, _, _ in expected])
    for given_radius in (None, radius):
        got = arc_sweeps(start, end, center, turns, given_radius)
        assert repr([tuple(v) for v in zip(*(g.tolist() for g in got), strict=True)]) == repr(
            expected
        )


@settings(max_examples=300, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False), st.sampled_from([0.0, -0.0]))
def test_hypot_with_a_zero_is_abs_to_the_bit(a: float, zero: float) -> None:
    """The bulk summary takes ``abs`` for ``math.hypot`` of a flat arc's length, and
    :func:`xy_hypot` for a radius with a zero offset, in either order."""
    assert repr(math.hypot(a, zero)) == repr(abs(a))
    assert repr(math.hypot(zero, a)) == repr(abs(a))


special = st.sampled_from(
    [0.0, -0.0, 5e-324, -5e-324, 1e308, -1e308, math.inf, -math.inf, math.nan, math.pi, -2.5]
)
pair_item = st.one_of(st.floats(), special, special)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(pair_item, pair_item), min_size=1, max_size=40))
def test_xy_hypot_and_atan2_are_maths_to_the_bit(pairs: list[tuple[float, float]]) -> None:
    """:func:`xy_hypot` and :func:`xy_atan2` (no call per item where one side is a zero)
    give ``math.hypot`` and ``math.atan2`` of each pair by ``repr``: zeros of both signs,
    NaN, infinities and subnormals among the pairs."""
    u = np.array([p[0] for p in pairs])
    v = np.array([p[1] for p in pairs])
    assert repr(xy_hypot(u, v).tolist()) == repr([math.hypot(a, b) for a, b in pairs])
    assert repr(xy_atan2(v, u).tolist()) == repr([math.atan2(b, a) for a, b in pairs])


number_text = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(lambda x: f"{x:f}"),
    st.floats(-1e4, 1e4).map(repr).filter(lambda t: "e" not in t),
    st.text("0123456789.+-", min_size=1, max_size=24),
    st.sampled_from(["-0", "+0", "-0.0", ".5", "5.", "-.5", "0000000000000000001", "1" * 16]),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(number_text, min_size=1, max_size=40))
def test_numbers_read_in_bulk_are_float_of_their_text(texts: list[str]) -> None:
    """:func:`cnctwin.nc.runs._numbers` gives ``float()`` of each number by ``repr`` (the
    integer over a power of ten up to 15 digits, ``float()`` beyond), says which ones
    ``float()`` refuses and which are digits only."""
    from cnctwin.nc import runs

    head = "".join(f"X{text}\n" if i % 2 else f" Y {text}\r\n" for i, text in enumerate(texts))
    values, digits_only, refused, _ = runs._numbers(head.encode())
    for text, value, plain, wrong in zip(
        texts, values.tolist(), digits_only.tolist(), refused.tolist(), strict=True
    ):
        assert plain == text.isdigit()
        try:
            expected = float(text)
        except ValueError:
            assert wrong
        else:
            assert not wrong and repr(value) == repr(expected)


#: Numbers that the trace's printer must print as ``"%.4f"`` does: signed zeros, values that
#: round to a signed zero, exact halves of the last digit, near halves, wide values.
awkward = st.sampled_from(
    [0.0, -0.0, -0.00004, 0.00005, 0.03125, -0.03125, 1.00005, 2.5e-5, 0.15625, 1e-300]
    + [123456789.98765, 4.5e11, -4.6e11, 1e15, 9999.99995, 0.99995, -0.99995]
)
trace_number = st.one_of(
    st.floats(-1e6, 1e6, allow_nan=False),
    st.floats(-5000, 5000).map(lambda v: round(v, 3)),
    st.integers(-(10**9), 10**9).map(lambda k: k / 20000),  # halves of the last digit
    awkward,
)


@settings(max_examples=400, deadline=None)
@given(
    st.lists(
        st.tuples(st.sampled_from([0, 1]), st.lists(trace_number, min_size=3, max_size=3)),
        min_size=1,
        max_size=30,
    ),
    st.integers(1, 10**7),
)
def test_trace_numbers_are_printed_as_python_prints_them(
    rows: list[tuple[int, list[float]]], first_line: int
) -> None:
    """:func:`_lines_text` (numpy, or Python's ``%`` where a product is near a half or a
    number too wide) against one ``%`` format a line."""
    texts = [[" A(", ", ", ")\n"], [" BB(", "; ", ", ", " end\n"]]
    kind = np.array([k for k, _ in rows])
    numbers = np.array([values for _, values in rows])
    lines = []
    for i, (k, (a, b, c)) in enumerate(rows):
        call = f"A({a:.4f}, {b:.4f})" if k == 0 else f"BB({a:.4f}; {b:.4f}, {c:.4f} end"
        lines.append(f"{first_line + i} {call}\n")
    expected = "".join(lines)
    assert _lines_text(np, first_line, kind, texts, numbers) == expected
