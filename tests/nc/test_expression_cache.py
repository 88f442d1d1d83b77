"""Compiled expressions and lines are reused, never stale.

``cnctwin.nc.expressions`` compiles a value once per place of a line and the lexer a line
once per distinct text; parameters are read when the compiled form is evaluated. These
tests evaluate the same text again and again while the parameters change, and compare
with values computed independently: Python's arithmetic on the current parameter values,
and closed forms of what each loop pass must produce under RS274NGC's rule that a line's
parameter settings take effect after the line.
"""

from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.errors import NCError
from cnctwin.nc import interpret_text, lexer
from cnctwin.nc.expressions import (
    CACHE_SIZE,
    Parameters,
    compile_setting,
    compile_value,
    read_assignment,
    read_assignment_once,
    read_value,
    read_value_once,
)
from cnctwin.nc.lexer import lex_block

# The parameters an expression may read, as (RS274 text, Python name).
_REFERENCES = [("#1", "p1"), ("#2", "p2"), ("#<depth>", "depth"), ("#<_g>", "g"), ("##3", "p1")]
_PRECEDENCE = {"+": 1, "-": 1, "*": 2}


@st.composite
def _expression(draw: st.DrawFn, depth: int = 4) -> tuple[str, str, int]:
    """(RS274 text, Python text, precedence) of a random expression over parameters."""
    if depth == 0 or draw(st.integers(0, 2)) == 0:
        if draw(st.booleans()):
            rs274, python = draw(st.sampled_from(_REFERENCES))
            return rs274, python, 3
        number = str(draw(st.integers(0, 99)))
        return number, number, 3
    op = draw(st.sampled_from("+-*"))
    left = draw(_expression(depth - 1))
    right = draw(_expression(depth - 1))
    prec = _PRECEDENCE[op]
    lr, lp = (f"[{left[0]}]", f"({left[1]})") if left[2] < prec else left[:2]
    rr, rp = (f"[{right[0]}]", f"({right[1]})") if right[2] <= prec else right[:2]
    return f"{lr}{op}{rr}", f"{lp}{op}{rp}", prec


_VALUES = st.lists(
    st.tuples(
        st.integers(-50, 50), st.integers(-50, 50), st.integers(-50, 50), st.integers(-50, 50)
    ),
    min_size=2,
    max_size=5,
)


@settings(max_examples=200, deadline=None)
@given(_expression(), _VALUES)
def test_a_value_read_again_follows_the_parameters(
    case: tuple[str, str, int], values: list[tuple[int, int, int, int]]
) -> None:
    rs274, python, _ = case
    text = f"x[{rs274}]"
    params = Parameters()
    params[3] = 1.0  # ##3 reads #1
    for p1, p2, depth, g in values:  # the same text each time: compiled once
        params[1], params[2], params["depth"], params["_g"] = p1, p2, depth, g
        scope = {"p1": float(p1), "p2": float(p2), "depth": float(depth), "g": float(g)}
        expected = eval(compile(python, "<expr>", "eval"), {"__builtins__": {}}, scope)  # noqa: S307
        assert read_value(text, 1, params) == (expected, len(text))
        key, value, end = read_assignment(f"#2={text[1:]}", 0, params)
        assert (key, value, end) == (2, expected, len(text) + 2)
        word = abs(expected) <= 1e6  # a word's bound (cnctwin.nc.limits); settings have none
        block = lex_block(f"G1 X[{rs274 if word else 0}] #<depth>=[{rs274}]", params)
        assert block is not None
        assert block.words["x"] == (expected if word else 0.0)
        assert block.assignments == [("depth", expected)]


def test_loop_passes_read_the_parameters_of_their_own_pass() -> None:
    program = (
        "#1 = 0\n"
        "o1 while [#1 LT 5]\n"
        "  G1 X[#1 * 2] Y[#1 ** 2] F100\n"
        "  #1 = [#1 + 1] G1 Z-#1\n"  # the setting takes effect after this line
        "o1 endwhile\n"
        "M2\n"
    )
    ends = [seg.end_mm for seg in interpret_text(program)]
    expected = []
    for i in range(5):
        expected.append((2.0 * i, float(i * i), -float(i - 1) if i else 0.0))
        expected.append((2.0 * i, float(i * i), -float(i)))
    assert ends == expected


def test_a_subroutine_reads_the_locals_of_each_call() -> None:
    program = (
        "o10 sub\n"
        "  #<r> = [#1 * 2]\n"
        "  G1 X#<r> Y#1 F100\n"
        "o10 endsub\n"
        "o10 call [1]\n"
        "o10 call [3]\n"
        "M2\n"
    )
    assert [seg.end_mm[:2] for seg in interpret_text(program)] == [(2.0, 1.0), (6.0, 3.0)]


def test_an_error_on_a_later_pass_names_its_line_and_column() -> None:
    program = (
        "#1 = 0\no1 while [#1 LT 5]\n  G1 X[10 / [3 - #1]] F100\n  #1 = [#1 + 1]\no1 endwhile\n"
    )
    with pytest.raises(NCError) as caught:
        list(interpret_text(program))
    assert caught.value.line == 3
    assert caught.value.message == "division by zero: 10 / 0; the divisor must not be 0"
    assert caught.value.column == 7  # the '/' in "g1x[10/[3-#1]]f100"


@pytest.mark.parametrize(
    ("line", "message"),
    [
        # Read and evaluated in one pass: an error met first is the one raised, even
        # when the text after it is malformed (LinuxCNC's interp_read order).
        ("G1 X[1/#2] Y[1+", "division by zero: 1 / 0; the divisor must not be 0"),
        ("G1 X[#<nope> + ] Y1", "named parameter #<nope> is not defined"),
        ("G1 X[1/#1] Y[1+", "expected a value (number, #parameter, [expression] or function) but"),
        ("G1 X[1/#1] Y[1", "missing ']' to close the '[' at column 11"),
        ("G1 X[1/#1] Y[1+1] $", "unexpected character '$'"),
    ],
)
def test_a_compiled_line_raises_its_errors_in_reading_order(line: str, message: str) -> None:
    params = Parameters()
    params[1] = 1.0
    for _ in range(3):  # compiled on the first pass, reused on the others
        with pytest.raises(NCError, match=re.escape(message)):
            lex_block(line, params)


def test_the_stores_stay_bounded() -> None:
    params = Parameters()
    for i in range(CACHE_SIZE + 10):
        lex_block(f"#1 = [{i} + 1]", params)
        read_value(f"[{i}*2]", 0, params)
    assert len(lexer._COMPILED_LINES) <= CACHE_SIZE
    from cnctwin.nc import expressions

    assert len(expressions._COMPILED) <= CACHE_SIZE


_TOKENS = ["[", "]", "#1", "#2", "##1", "#<depth>", "#<nope>", "#", "1", "0", "2.5", "-", "+"]
_TOKENS += ["*", "**", "/", "mod", "gt", "eq", "and", "sin[", "atan[", "]/[", "exists[", "sqrt["]
_TOKENS += ["ln[", "round[", "=", "x", "$", "9" * 70]


@settings(max_examples=400, deadline=None)
@given(st.lists(st.sampled_from(_TOKENS), max_size=16).map("".join), st.booleans())
def test_compiled_and_one_pass_readers_agree_on_any_text(body: str, setting: bool) -> None:
    # A place met once is read in one pass, met again it is compiled: both must give the
    # same value, or the same error at the same column, for well-formed and broken text.
    text = "g1x" + ("#1=" if setting else "") + body

    def outcome(read: object) -> object:
        params = Parameters()
        params[1], params[2], params["depth"] = 2.0, 0.0, 0.5
        try:
            return read(params)  # type: ignore[operator]
        except NCError as error:
            return (error.message, error.column)

    if setting:
        once = outcome(lambda p: read_assignment_once(text, 3, p))
        read_key, evaluate, end = compile_setting(text, 3)
        compiled = outcome(lambda p: (read_key(p), evaluate(p), end))
    else:
        once = outcome(lambda p: read_value_once(text, 3, p))
        evaluate, end = compile_value(text, 3)
        compiled = outcome(lambda p: (evaluate(p), end))
    assert compiled == once


def test_an_o_word_argument_shared_by_labels_raises_at_its_statements_columns() -> None:
    """Statements of different labels with one argument share its compiled reading; its
    errors still name the column in each statement's own text, in the message too."""
    program = "".join(
        f"#1 = {n}\no{label} if [10 / [3 - #1] GT 0]\no{label} endif\n"
        for n, label in enumerate(("1", "22", "333", "4444"))
    )
    with pytest.raises(NCError) as caught:
        list(interpret_text(program))
    assert caught.value.line == 11
    assert caught.value.message == "division by zero: 10 / 0; the divisor must not be 0"
    assert caught.value.column == 11  # the "/" in "o4444if[10/[3-#1]gt0]"
    for label in ("5", "66", "777"):  # read once, compiled, then evaluated
        with pytest.raises(NCError) as caught:
            list(interpret_text(f"o{label} repeat [1 + [2]\no{label} endrepeat\n"))
        column = len(f"o{label}repeat") + 1
        assert caught.value.message == f"missing ']' to close the '[' at column {column}"
        assert caught.value.line == 1
