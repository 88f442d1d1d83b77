"""Bounded NC input: every defect found by an outside review, as a regression test.

Each test gives the interpreter an input that used to end in an OverflowError, invalid JSON,
a run of minutes or a misread line, and checks the bounded outcome: an NCError naming the
value, the line and the valid range, or, for line endings, the same path as LF. The command
line's side (exit 2 and one line from ``cnctwin nc inspect``) is tested in
tests/cli/test_nc_limits_cli.py.

The runaway programs are stopped by counters (segments, pecks, repeats, loop iterations,
lines read again), not by clocks, so these tests do not depend on the machine's speed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from cnctwin.errors import NCError
from cnctwin.finite_json import dumps
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.limits import MAX_CYCLE_REPEATS, MAX_LINE_BYTES, MAX_PECKS
from cnctwin.nc.owords import MAX_LOOP_ITERATIONS
from cnctwin.nc.segments import Segment
from cnctwin.nc.setup import NCSetup
from cnctwin.nc.source import CHUNK_BYTES, LineSource


def segments(text: str, setup: NCSetup | None = None) -> list[Segment]:
    return list(Interpreter(setup).run_text(text, "job.ngc"))


def error(text: str, setup: NCSetup | None = None) -> NCError:
    with pytest.raises(NCError) as caught:
        segments(text, setup)
    return caught.value


def strict_json(text: str) -> object:
    def refuse(constant: str) -> object:
        raise AssertionError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


# ---------------------------------------------------------------------------- numbers
def test_a_number_of_400_digits_is_refused_naming_its_length() -> None:
    err = error("G21 G90\nG0 X" + "9" * 400 + "\nM2")
    assert err.line == 2
    assert "400 characters; at most 64" in err.message


def test_a_number_of_400_digits_in_an_expression_is_refused() -> None:
    err = error("G21 G90\nG0 X[1+" + "1" * 400 + "]")
    assert err.line == 2 and "400 characters" in err.message


@pytest.mark.parametrize(
    ("text", "word"),
    [
        ("G1 X2000000 F100", "X2e+06"),
        ("G1 Y-1000000.5 F100", "Y-1e+06"),
        ("G0 A1e7", None),  # E is no word here: refused as such, never an overflow
        ("G1 X1 F1e3", None),
        ("G1 X1 F2000000000", "F2e+09"),
        ("S2000000 M3", "S2e+06"),
        ("T100000 M6", "T100000"),
        ("G4 P10000000", "P1e+07"),
        ("G0 X[10**300]", None),
        ("G0 X[1000**2*1000]", "X1e+09"),
    ],
)
def test_out_of_range_words_name_word_value_and_range(text: str, word: str | None) -> None:
    err = error("G21 G90 F100\n" + text)
    assert err.line == 2, err
    if word is not None:
        assert f"word {word} is out of range" in err.message
        assert "within +-" in err.message


def test_exponent_notation_is_not_an_overflow() -> None:
    # "X1e307" is the word X1 followed by the word E307, which nothing uses.
    err = error("G21 G90\nG1 X1e307 F100")
    assert err.line == 2 and "E307" in err.message


def test_an_arc_radius_beyond_the_limit_is_refused() -> None:
    err = error("G21 G90 F100\nG0 X0 Y0\nG2 X10 Y0 R" + "1" + "0" * 30)
    assert err.line == 3 and "word R1e+30 is out of range (length)" in err.message


def test_r1e300_arc_is_refused_not_an_overflow() -> None:
    err = error("G21 G90 F100\nG0 X0 Y0\nG2 X10 Y0 R1e300")
    assert err.line == 3


def test_inch_positions_beyond_one_kilometre_are_refused() -> None:
    # 100 000 in = 2540 m: each word is within its bound, the machine position is not.
    err = error("G20 G90\nG0 X100000")
    assert err.line == 2
    assert "X position 2.54e+06 mm is out of range" in err.message


def test_incremental_moves_cannot_run_off_to_infinity() -> None:
    err = error("G21 G91\no1 repeat [100]\nG0 X900000\no1 endrepeat")
    assert err.line == 3 and "X position" in err.message


@pytest.mark.parametrize(
    "expression", ["[10**400]", "exp[1000]", "[1/0]", "[2**2000]", "[ln[0]]", "[-1**0.5]"]
)
def test_overflowing_expressions_give_ncerror(expression: str) -> None:
    assert error(f"G0 X{expression}").line == 1


# ---------------------------------------------------------------------------- work guards
def test_a_tiny_peck_over_a_deep_hole_names_the_number_of_pecks() -> None:
    err = error("G21 G90 F100 S1000 M3\nG0 Z10\nG83 X0 Y0 Z-100000 R1 Q0.0001")
    assert err.line == 3
    # ceil(100 001 mm / 0.0001 mm) pecks
    assert "needs 1000010000 pecks" in err.message and f"at most {MAX_PECKS}" in err.message


def test_a_huge_repeat_count_is_refused() -> None:
    err = error("G21 G91 F100 S1000 M3\nG81 X1 Z-1 R1 L1000000000")
    assert err.line == 2 and "word L1e+09 is out of range" in err.message
    err = error(f"G21 G91 F100 S1000 M3\nG81 X1 Z-1 R1 L{MAX_CYCLE_REPEATS + 1}")
    assert f"from 1 to {MAX_CYCLE_REPEATS}" in err.message


def test_repeats_times_pecks_are_bounded_per_block() -> None:
    # 10 000 holes of 1000 pecks each: about 3e7 moves from one block.
    err = error("G21 G91 F100 S1000 M3\nG0 Z10\nG83 X1 Z-100 R1 Q0.1 L10000")
    assert err.line == 3 and "moves in one block" in err.message


def test_the_segment_cap_stops_a_long_program_at_the_line_past_it() -> None:
    text = "G21 G90\n" + "\n".join(f"G0 X{i}" for i in range(1, 31))
    assert len(segments(text, NCSetup(max_segments=30))) == 30
    err = error(text, NCSetup(max_segments=20))
    assert err.line == 22 and "more than 20 motion segments" in err.message


def test_an_endless_while_loop_stops_at_the_iteration_limit() -> None:
    err = error("o100 while [1]\nG0 X1\no100 endwhile")
    assert err.line == 3 and f"ran {MAX_LOOP_ITERATIONS} times" in err.message


def test_a_huge_repeat_loop_is_refused_at_once() -> None:
    err = error("o1 repeat [1000000000]\nG0 X1\no1 endrepeat")
    assert err.line == 1 and f"from 0 to {MAX_LOOP_ITERATIONS}" in err.message


def test_nested_loops_are_bounded_by_the_lines_read_again() -> None:
    # 1000 x 1000 iterations of a 3-line body: each loop is within its own limit, the
    # million lines read again are not.
    text = "o1 repeat [1000]\no2 repeat [1000]\nG0 X1\no2 endrepeat\no1 endrepeat"
    err = error(text, NCSetup(max_repeated_lines=5000))
    assert "more than 5000 lines were executed again" in err.message
    assert 1 <= err.line <= 5


def test_deep_recursion_is_bounded() -> None:
    err = error("o1 sub\no1 call\no1 endsub\no1 call")
    assert "nested deeper than" in err.message


# ---------------------------------------------------------------------------- reading
def test_cr_crlf_and_mixed_line_endings_read_like_lf() -> None:
    lines = ["G21 G90", "G0 X1", "G1 Y2 F100", "(comment)", "G0 Z3", "M2"]
    reference = [s.end_mm for s in segments("\n".join(lines))]
    assert reference == [(1.0, 0.0, 0.0), (1.0, 2.0, 0.0), (1.0, 2.0, 3.0)]
    for eol in ("\r", "\r\n", "\n\r"):
        got = segments(eol.join(lines))
        if eol == "\n\r":  # LF then CR: an empty line between each pair
            assert [s.line for s in got] == [3, 5, 9]
        else:
            assert [s.line for s in got] == [2, 3, 5]
        assert [s.end_mm for s in got] == reference
    mixed = "G21 G90\rG0 X1\r\nG1 Y2 F100\n(comment)\rG0 Z3\r\nM2"
    assert [s.end_mm for s in segments(mixed)] == reference


def test_line_numbers_in_errors_count_cr_only_lines() -> None:
    err = error("G21\rG0 X1\rG0 X2\rG0 Q1")
    assert err.line == 4


def test_crlf_split_across_two_chunks_is_one_line_break(tmp_path: Path) -> None:
    padding = "(pad)\n" * ((CHUNK_BYTES - 100) // 6)  # lines within the line limit
    first = padding + "G0 X1".ljust(CHUNK_BYTES - 1 - len(padding)) + "\r"
    assert len(first) == CHUNK_BYTES  # the CR ends the first chunk, its LF starts the next
    before = padding.count("\n")
    program = tmp_path / "split.ngc"
    program.write_bytes((first + "\nG0 X2\r\nG0 Q1\r\n").encode())
    source = LineSource.from_path(program)
    try:
        assert [n for n, _, _ in source][before:] == [before + 1, before + 2, before + 3]
    finally:
        source.close()
    with pytest.raises(NCError) as caught:
        list(Interpreter().run_file(program))
    assert caught.value.line == before + 3


def test_loops_jump_back_correctly_in_a_program_longer_than_a_chunk(tmp_path: Path) -> None:
    padding = "(pad)\n" * (2 * CHUNK_BYTES // 6)
    text = padding + "#1=0\no1 while [#1 lt 3]\nG0 X#1\n#1=[#1+1]\no1 endwhile\n" + padding
    program = tmp_path / "long.ngc"
    program.write_text(text)
    assert [s.end_mm[0] for s in Interpreter().run_file(program)] == [0.0, 1.0, 2.0]


def test_a_line_too_long_is_refused() -> None:
    err = error("G0 X1\n(" + "x" * MAX_LINE_BYTES + ")")
    assert err.line == 2 and f"longer than {MAX_LINE_BYTES} bytes" in err.message


def test_non_finite_numbers_are_written_as_null() -> None:
    value = {"a": math.inf, "b": [math.nan, 1.5, -math.inf], "c": (2.0, math.nan), "d": "x"}
    text = dumps(value)
    assert strict_json(text) == {"a": None, "b": [None, 1.5, None], "c": [2.0, None], "d": "x"}
    assert dumps({"n": 1, "ok": True, "none": None}, indent=2).startswith("{\n  ")
