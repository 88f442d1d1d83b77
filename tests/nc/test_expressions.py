"""Tests for cnctwin.nc.expressions: RS274NGC parameters and expressions.

Expected values are derived by hand from the LinuxCNC G-code overview (parameters,
expressions, binary operators, functions) and from the behaviour of its interpreter
where the overview is silent (comparison tolerance, MOD sign, ROUND halves).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnctwin.errors import NCError
from cnctwin.nc.expressions import (
    MAX_PARAMETER,
    Parameters,
    read_assignment,
    read_value,
)


def value_of(text: str, params: Parameters | None = None) -> float:
    """Evaluate ``text`` from index 0 and check that the whole text was consumed."""
    value, end = read_value(text, 0, params if params is not None else Parameters())
    assert end == len(text), f"{text!r} consumed up to {end}, not {len(text)}"
    return value


# --------------------------------------------------------------------------- values

# (text, expected): every value is exact in binary floating point, so compared with ==.
EXACT_CASES = [
    # numbers as RS274NGC writes them: optional sign, optional point, no exponent
    ("7", 7.0),
    ("007", 7.0),
    ("-1.5", -1.5),
    ("+.5", 0.5),
    ("3.", 3.0),
    (".5", 0.5),
    ("-.25", -0.25),
    # precedence: ** above * / mod above + - above comparisons above and/or/xor
    ("[2**3*2]", 16.0),
    ("[2*2**3]", 16.0),
    ("[1+2*3]", 7.0),
    ("[1+2*3-4/2]", 5.0),
    ("[2.0/3*1.5-5.5/11.0]", 0.5),  # the overview's own example: [[2/3]*1.5]-[5.5/11]
    ("[1+2eq3]", 1.0),  # + binds tighter than eq: [1+2] eq 3
    ("[2gt1and3lt2]", 0.0),  # [2 gt 1] and [3 lt 2] = 1 and 0
    ("[2gt1or3lt2]", 1.0),
    ("[1lt2eq1]", 1.0),  # comparisons are left-associative: [1 lt 2] eq 1
    ("[0or0and1]", 0.0),  # and/or/xor share one level, left to right: [0 or 0] and 1
    ("[1or0and0]", 0.0),  # [1 or 0] and 0
    ("[1xor1]", 0.0),
    ("[1xor0]", 1.0),
    ("[0xor-2]", 1.0),
    ("[5and-1]", 1.0),
    ("[0and5]", 0.0),
    # left associativity at equal precedence, ** included
    ("[10-2-3]", 5.0),
    ("[8/2/2]", 2.0),
    ("[2**3**2]", 64.0),  # [2**3]**2, not 2**[3**2] = 512
    ("[2*3mod4]", 2.0),  # [2*3] mod 4
    ("[7mod4*2]", 6.0),  # [7 mod 4] * 2
    # a sign belongs to its value, so it binds tighter than **
    ("[-2**2]", 4.0),
    ("[2*-3]", -6.0),
    ("[2--3]", 5.0),
    ("[2+-3]", -1.0),
    ("--2", 2.0),
    ("-[2]", -2.0),
    ("+[2]", 2.0),
    ("-[-[3]]", 3.0),
    # mod: fmod, then |divisor| added when negative -> always in [0, |b|)
    ("[7mod3]", 1.0),
    ("[-7mod3]", 2.0),
    ("[7mod-3]", 1.0),
    ("[-7mod-3]", 2.0),
    ("[7.5mod2]", 1.5),
    ("[6mod3]", 0.0),
    # power
    ("[2**-1]", 0.5),
    ("[[-2]**3]", -8.0),
    ("[4**.5]", 2.0),
    ("[0**0]", 1.0),
    # comparisons: eq ne ge le use a 1e-6 tolerance, gt lt compare exactly
    ("[1eq1]", 1.0),
    ("[1eq1.0000005]", 1.0),
    ("[1eq1.00001]", 0.0),
    ("[1ne1.0000005]", 0.0),
    ("[1ne1.00001]", 1.0),
    ("[1ge1.0000005]", 1.0),
    ("[1le0.9999995]", 1.0),
    ("[1.0000005gt1]", 1.0),
    ("[1lt1.0000005]", 1.0),
    ("[1ge2]", 0.0),
    ("[2le1]", 0.0),
    ("[1gt1]", 0.0),
    ("[1lt1]", 0.0),
    # exactly representable function results
    ("abs[-3]", 3.0),
    ("abs[3]", 3.0),
    ("sqrt[16]", 4.0),
    ("fix[2.5]", 2.0),
    ("fix[-2.5]", -3.0),
    ("fup[2.1]", 3.0),
    ("fup[-2.5]", -2.0),
    ("round[2.5]", 3.0),  # halves away from zero, not Python's half-to-even (2)
    ("round[-2.5]", -3.0),
    ("round[0.5]", 1.0),
    ("round[2.4999]", 2.0),
    ("round[-0.4]", 0.0),
    ("asin[1]", 90.0),
    ("acos[1]", 0.0),
    ("acos[-1]", 180.0),
    ("exp[0]", 1.0),
    ("ln[1]", 0.0),
    ("atan[0]/[1]", 0.0),
    ("atan[0]/[-1]", 180.0),
    ("atan[1]/[0]", 90.0),
    ("atan[-1]/[0]", -90.0),
    ("-sin[0]", 0.0),
    ("sqrt[[3*3]+[4*4]]", 5.0),
    ("[1+sqrt[4]*3]", 7.0),
    ("[abs[-2]**2]", 4.0),
]


@pytest.mark.parametrize(("text", "expected"), EXACT_CASES)
def test_exact_values(text: str, expected: float) -> None:
    assert value_of(text) == expected


# (text, expected) where the value is not exact in floating point: checked to 1e-12.
APPROX_CASES = [
    ("sin[30]", 0.5),
    ("sin[90]", 1.0),
    ("sin[-30]", -0.5),
    ("cos[60]", 0.5),
    ("cos[180]", -1.0),
    ("cos[90]", 0.0),
    ("tan[45]", 1.0),
    ("tan[-45]", -1.0),
    ("asin[.5]", 30.0),
    ("acos[.5]", 60.0),
    ("acos[0]", 90.0),
    ("exp[1]", math.e),
    ("ln[exp[2]]", 2.0),
    ("-sin[30]", -0.5),
    ("[sin[30]**2+cos[30]**2]", 1.0),
    # atan[y]/[x] is the four-quadrant arc tangent, in degrees
    ("atan[1]/[1]", 45.0),
    ("atan[1]/[-1]", 135.0),
    ("atan[-1]/[-1]", -135.0),
    ("atan[-1]/[1]", -45.0),
    ("atan[sqrt[3]]/[1]", 60.0),
    ("[atan[1]/[1]/3]", 15.0),  # '/[1]' belongs to atan, the second '/' divides
    ("[2*atan[1]/[1]]", 90.0),
]


@pytest.mark.parametrize(("text", "expected"), APPROX_CASES)
def test_approximate_values(text: str, expected: float) -> None:
    assert value_of(text) == pytest.approx(expected, abs=1e-12)


def test_reading_stops_after_the_value() -> None:
    params = Parameters()
    params[1] = 4.0
    params[2] = 10.0
    params[5] = 3.0
    # g1x#1y[#2+[#5/2]]: the lexer calls read_value just after each word letter
    text = "g1x#1y[#2+[#5/2]]"
    assert read_value(text, 3, params) == (4.0, 5)
    assert read_value(text, 6, params) == (11.5, len(text))
    assert read_value("x-#1", 1, params) == (-4.0, 4)
    assert read_value("z-[#2]f3", 1, params) == (-10.0, 6)
    assert read_value("g1ysqrt[2]", 3, params) == (pytest.approx(math.sqrt(2.0)), 10)
    assert read_value("x1.5.5", 1, params) == (1.5, 4)  # the second '.5' is not ours
    assert read_value("x3.y2", 1, params) == (3.0, 3)
    assert read_value("n10g1", 1, params) == (10.0, 3)


def test_linuxcnc_overview_example() -> None:
    # [1 + acos[0] - [#3 ** [4.0/2]]] with #3 = 2: 1 + 90 - 4
    params = Parameters()
    params[3] = 2.0
    assert value_of("[1+acos[0]-[#3**[4.0/2]]]", params) == pytest.approx(87.0, abs=1e-12)


def test_systems_ngc_style_expression() -> None:
    params = Parameters()
    params[3] = 0.000120
    params[5] = 1.0
    params[6] = 2.0
    text = "g0x[2019*#3+#5]y[1098*#3+#6]"
    x, end = read_value(text, 3, params)
    assert x == pytest.approx(2019 * 0.000120 + 1.0, abs=1e-12)
    assert text[end] == "y"
    y, end = read_value(text, end + 1, params)
    assert y == pytest.approx(1098 * 0.000120 + 2.0, abs=1e-12)
    assert end == len(text)


# ----------------------------------------------------------------------- parameters


def test_parameter_references() -> None:
    params = Parameters()
    params[1] = 3.0
    params[3] = 7.0
    params[123] = 1.25
    params["depth"] = -2.0
    params["_global"] = 5.0
    assert value_of("#123", params) == 1.25
    assert value_of("##1", params) == 7.0  # the parameter whose number is in #1
    assert value_of("#[#1]", params) == 7.0
    assert value_of("#[1+2]", params) == 7.0
    assert value_of("#[0.1*30]", params) == 7.0  # 3.0000000000000004 is close enough
    assert value_of("#<depth>", params) == -2.0
    assert value_of("#<_global>", params) == 5.0
    assert value_of("[#<depth>*-#1]", params) == 6.0
    assert value_of("#4", params) == 0.0  # unset numbered parameters read 0
    assert value_of(f"#{MAX_PARAMETER}", params) == 0.0


def test_named_parameters_are_case_and_space_insensitive_in_the_api() -> None:
    params = Parameters()
    params["X Scale"] = 2.0
    assert params["xscale"] == 2.0
    assert params["XSCALE"] == 2.0
    assert value_of("#<xscale>", params) == 2.0
    assert params.exists("XScale")
    assert not params.exists("yscale")


def test_exists_function() -> None:
    params = Parameters()
    params["depth"] = 1.0
    params["_g"] = 0.0
    assert value_of("exists[#<depth>]", params) == 1.0
    assert value_of("exists[#<_g>]", params) == 1.0
    assert value_of("exists[#<nothing>]", params) == 0.0
    assert value_of("[exists[#<nothing>]eq0]", params) == 1.0
    # a numbered parameter exists when its number is valid
    assert value_of("exists[#5]", params) == 1.0
    assert value_of(f"exists[#{MAX_PARAMETER + 1}]", params) == 0.0


def test_numbered_parameter_range_and_errors() -> None:
    params = Parameters()
    params[1] = 1.5
    params[MAX_PARAMETER] = 2.5
    params[5220] = 1.0  # a system parameter, stored like any other
    assert params[1] == 1.5
    assert params[MAX_PARAMETER] == 2.5
    assert params[5220] == 1.0
    for bad in (0, -1, MAX_PARAMETER + 1):
        with pytest.raises(NCError, match=rf"#{bad} is out of range.*#1 to #{MAX_PARAMETER}"):
            params[bad]
        with pytest.raises(NCError, match="out of range"):
            params[bad] = 1.0
    with pytest.raises(NCError, match="not a finite number"):
        params[1] = math.nan
    with pytest.raises(NCError, match="not a finite number"):
        params["x"] = math.inf
    with pytest.raises(NCError, match="not valid"):
        params[""] = 1.0
    # A key of the wrong type: the sources say why; compiled, mypyc's check of the
    # annotated type raises TypeError first.
    with pytest.raises((NCError, TypeError), match="neither a parameter number|int"):
        params[2.5]  # type: ignore[index]


def test_undefined_named_parameter_message() -> None:
    params = Parameters()
    expected = "named parameter #<depth> is not defined; assign it first, e.g. #<depth> = 1"
    with pytest.raises(NCError) as caught:
        params["depth"]
    assert caught.value.message == expected
    with pytest.raises(NCError) as caught:
        read_value("x[1+#<depth>]", 1, params)
    assert caught.value.message == expected
    assert caught.value.column == 5


def test_subroutine_scoping() -> None:
    params = Parameters()
    params[1] = 11.0
    params[3] = 33.0
    params[30] = 30.0
    params[31] = 31.0
    params["outer"] = 1.0
    params["_shared"] = 2.0
    assert params.call_depth == 0

    params.push_call([5.0, 6.0])
    assert params.call_depth == 1
    assert (params[1], params[2], params[3], params[30]) == (5.0, 6.0, 0.0, 0.0)
    assert params[31] == 31.0  # above #30 is global
    assert value_of("[#1+#2]", params) == 11.0
    assert not params.exists("outer")  # the caller's locals are not visible
    with pytest.raises(NCError, match=r"#<outer> is not defined") as caught:
        read_value("[1+#<outer>]", 0, params)
    assert caught.value.column == 4
    assert params["_shared"] == 2.0  # globals are
    params[1] = 99.0
    params[31] = 32.0
    params["inner"] = 3.0
    params["_shared"] = 4.0

    params.push_call([])  # nested call without arguments: #1..#30 all 0
    assert params.call_depth == 2
    assert params[1] == 0.0
    assert not params.exists("inner")
    params.pop_call()
    assert params[1] == 99.0
    assert params["inner"] == 3.0

    params.pop_call()
    assert params.call_depth == 0
    assert (params[1], params[3], params[30]) == (11.0, 33.0, 30.0)
    assert params[31] == 32.0
    assert params["outer"] == 1.0
    assert not params.exists("inner")
    assert params["_shared"] == 4.0

    with pytest.raises(NCError, match="no subroutine call is open"):
        params.pop_call()
    with pytest.raises(NCError, match="at most 30 arguments, got 31"):
        params.push_call([1.0] * 31)
    with pytest.raises(NCError, match="argument 2"):
        params.push_call([1.0, math.inf])
    assert params.call_depth == 0


# ----------------------------------------------------------------------- assignments


def test_read_assignment() -> None:
    params = Parameters()
    params[1] = 7.0
    params[5] = 1.0
    params[1110] = 2.0
    params[1120] = 3.14 * 2.0 * 3.0
    assert read_assignment("#<xscale>=1.0", 0, params) == ("xscale", 1.0, 13)
    assert read_assignment("#<_global>=3", 0, params) == ("_global", 3.0, 12)
    assert read_assignment("#[1+2]=4", 0, params) == (3, 4.0, 8)
    assert read_assignment("##1=5", 0, params) == (7, 5.0, 5)
    key, value, end = read_assignment("#5=[#5-.020]", 0, params)
    assert (key, end) == (5, 12)
    assert value == pytest.approx(0.98, abs=1e-12)
    key, value, end = read_assignment("#1=[#1120/[3.14*#1110]]", 0, params)
    assert (key, end) == (1, 23)
    assert value == pytest.approx(3.0, abs=1e-12)
    # several settings on one line: each returns where the next one starts
    text = "#1=2#2=[#1+1]"
    assert read_assignment(text, 0, params) == (1, 2.0, 4)
    assert read_assignment(text, 4, params) == (2, 8.0, len(text))  # old #1 = 7
    # nothing is stored
    assert params[1] == 7.0
    assert params[5] == 1.0
    assert not params.exists("xscale")


ASSIGNMENT_ERRORS = [
    ("#1", 3, "expected '='"),
    ("#<a>2", 5, "expected '='"),
    ("#0=1", 1, "out of range"),
    ("#2.5=1", 1, "not an integer"),
    ("x=1", 1, "expected a parameter setting"),
    ("#1=", 4, "line ends"),
    ("#<a=1", 1, "closing '>'"),
    ("#1=[1/0]", 6, "division by zero"),
]


@pytest.mark.parametrize(("text", "column", "message"), ASSIGNMENT_ERRORS)
def test_assignment_errors(text: str, column: int, message: str) -> None:
    with pytest.raises(NCError, match=re.escape(message)) as caught:
        read_assignment(text, 0, Parameters())
    assert caught.value.column == column


# ---------------------------------------------------------------------------- errors

ERROR_CASES = [
    # (text, column of the problem, fragment of the message)
    ("[1/0]", 3, "division by zero"),
    ("[1+[2*[3/0]]]", 9, "division by zero: 3 / 0"),
    ("[1mod0]", 3, "modulo by zero"),
    ("[1+2", 5, "missing ']' to close the '[' at column 1"),
    ("[1+[2", 6, "missing ']' to close the '[' at column 4"),
    ("[", 2, "line ends"),
    ("", 1, "line ends"),
    ("]", 1, "found ']'"),
    ("-", 1, "found '-'"),
    ("[2$3]", 3, "expected a binary operator"),
    ("[1e5]", 3, "expected a binary operator"),
    ("[]", 2, "found ']'"),
    ("foo[1]", 1, "unknown function or word 'foo'"),
    ("[1+bar[2]]", 4, "unknown function or word 'bar'"),
    ("sin30", 4, "must be followed by '['"),
    ("atan[1]", 8, "atan[y]/[x]"),
    ("atan[1]/2", 8, "atan[y]/[x]"),
    ("sqrt[-4]", 1, "sqrt[-4]"),
    ("[1+sqrt[-4]]", 4, "must not be negative"),
    ("ln[0]", 1, "ln[0]"),
    ("ln[-1]", 1, "must be positive"),
    ("asin[1.5]", 1, "asin[1.5]"),
    ("acos[-2]", 1, "must lie in [-1, 1]"),
    ("exp[1000]", 1, "exp[1000] overflows"),
    ("[[-8]**.5]", 6, "integer power"),
    ("[0**-1]", 3, "negative power"),
    ("[10**400]", 4, "overflows"),
    ("#2.5", 1, "#2.5 is not an integer"),
    (f"#{MAX_PARAMETER + 1}", 1, f"#1 to #{MAX_PARAMETER}"),
    ("#0", 1, "out of range"),
    ("[1+#-1]", 4, "#-1 is out of range"),
    ("##1", 1, "#0 is out of range"),  # #1 is 0
    ("#<abc", 1, "closing '>'"),
    ("#<>", 1, "empty parameter name"),
    ("exists[5]", 8, "exists takes a parameter"),
    ("exists[#<a>+1]", 12, "expected ']'"),
]


@pytest.mark.parametrize(("text", "column", "message"), ERROR_CASES)
def test_errors_carry_a_column(text: str, column: int, message: str) -> None:
    with pytest.raises(NCError) as caught:
        read_value(text, 0, Parameters())
    assert caught.value.column == column, caught.value.message
    assert message in caught.value.message


def test_deep_nesting_is_refused_not_a_recursion_error() -> None:
    text = "[" * 500 + "1" + "]" * 500
    with pytest.raises(NCError, match="nested deeper") as caught:
        read_value(text, 0, Parameters())
    assert caught.value.column is not None
    assert value_of("[" * 50 + "1" + "]" * 50) == 1.0
    with pytest.raises(NCError, match="nested deeper"):
        read_value("-" * 500 + "[1]", 0, Parameters())


def test_huge_number_literal() -> None:
    with pytest.raises(NCError, match="has 400 characters; at most 64") as caught:
        read_value("[1+" + "9" * 400 + "]", 0, Parameters())
    assert caught.value.column == 4


def test_start_index_outside_text() -> None:
    with pytest.raises(NCError, match="outside the text"):
        read_value("[1]", 7, Parameters())
    with pytest.raises(NCError, match="outside the text"):
        read_assignment("#1=2", -1, Parameters())


# ------------------------------------------------------------------------ properties

_LITERAL = st.builds(
    lambda sign, whole, frac, form: (
        sign
        + (
            str(whole)
            if form == 0
            else f"{whole}.{frac}"
            if form == 1
            else f".{frac}"
            if form == 2
            else f"{whole}."
        )
    ),
    st.sampled_from(["", "-"]),
    st.integers(0, 999),
    st.integers(0, 999).map(lambda f: f"{f:03d}"),
    st.integers(0, 3),
)

_PRECEDENCE = {"+": 1, "-": 1, "*": 2, "/": 2}


@st.composite
def _arithmetic(draw: st.DrawFn, depth: int = 4) -> tuple[str, str, float, int]:
    """A random expression as (RS274 text, Python text, value, precedence).

    Brackets appear where the structure needs them and at random elsewhere, so the
    parse of either text has the structure the value was computed from.
    """
    if depth == 0 or draw(st.integers(0, 2)) == 0:
        literal = draw(_LITERAL)
        return literal, literal, float(literal), 3
    op = draw(st.sampled_from("+-*/"))
    left = draw(_arithmetic(depth - 1))
    right = draw(_arithmetic(depth - 1))
    if op == "/" and abs(right[2]) < 1e-3:
        op = "*"  # keep well away from division by (nearly) zero
    prec = _PRECEDENCE[op]

    def wrap(part: tuple[str, str, float, int], needed: bool) -> tuple[str, str]:
        if needed or draw(st.integers(0, 4)) == 0:
            return f"[{part[0]}]", f"({part[1]})"
        return part[0], part[1]

    lr, lp = wrap(left, left[3] < prec)
    rr, rp = wrap(right, right[3] <= prec)
    a, b = left[2], right[2]
    value = a + b if op == "+" else a - b if op == "-" else a * b if op == "*" else a / b
    return f"{lr}{op}{rr}", f"{lp}{op}{rp}", value, prec


@settings(max_examples=300, deadline=None)
@given(_arithmetic())
def test_arithmetic_matches_python(case: tuple[str, str, float, int]) -> None:
    rs274, python, value, _ = case
    text = f"[{rs274}]"
    expected = eval(compile(python, "<expr>", "eval"), {"__builtins__": {}})  # noqa: S307
    assert expected == value  # the generator's own structure, as a cross-check
    assert read_value(text, 0, Parameters()) == (expected, len(text))


_FUZZ_ALPHABET = "0123456789.+-*/[]#<>=_ abcdefgilmnopqrstuxzE$"
_FUZZ_TOKENS = [
    "[",
    "]",
    "[",
    "]",
    "#",
    "#1",
    "#<a>",
    "#<_g>",
    "#<",
    ">",
    "<",
    "=",
    "1",
    "0",
    "2.5",
    ".",
    "-",
    "+",
    "*",
    "**",
    "/",
    "mod",
    "eq",
    "ne",
    "gt",
    "ge",
    "lt",
    "le",
    "and",
    "or",
    "xor",
    "sin",
    "atan",
    "/[",
    "exists",
    "sqrt",
    "ln",
    "round",
    "fix",
    "exp",
    "acos",
    "9" * 30,
    "x",
    "-[",
]
_FUZZ_TEXT = st.one_of(
    st.text(alphabet=_FUZZ_ALPHABET, max_size=40),
    st.lists(st.sampled_from(_FUZZ_TOKENS), max_size=25).map("".join),
)


def _fuzz_params() -> Parameters:
    params = Parameters()
    params[1] = 2.0
    params["a"] = 0.5
    params["_g"] = -3.0
    return params


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_FUZZ_TEXT, st.integers(0, 3))
def test_fuzz_read_value_raises_only_ncerror(text: str, start: int) -> None:
    start = min(start, len(text))
    params = _fuzz_params()
    try:
        value, end = read_value(text, start, params)
    except NCError as error:
        assert error.column is not None
        assert 1 <= error.column <= len(text) + 1
    else:
        assert math.isfinite(value)
        assert start < end <= len(text)


@settings(max_examples=300, deadline=None)
@given(_FUZZ_TEXT.map(lambda t: "#" + t))
def test_fuzz_read_assignment_raises_only_ncerror(text: str) -> None:
    params = _fuzz_params()
    try:
        key, value, end = read_assignment(text, 0, params)
    except NCError as error:
        assert error.column is not None
        assert 1 <= error.column <= len(text) + 1
    else:
        assert isinstance(key, (int, str))
        assert math.isfinite(value)
        assert 0 < end <= len(text)


# ------------------------------------------------------------------ real NC programs


@pytest.mark.validation
def test_3d_chips_expressions(shared_data: Path) -> None:
    """Every scaled coordinate of LinuxCNC's 3D_Chips.ngc evaluates to scale * literal.

    The program writes each coordinate as ``X[#<xscale>*53.]``; with the scales set to
    distinct values each expression must give that scale times the literal.
    """
    lines = (shared_data / "gcode/linuxcnc/3D_Chips.ngc").read_text().splitlines()
    params = Parameters()
    scales = {"x": 2.0, "y": -0.5, "z": 4.0, "f": 10.0}
    for axis, scale in scales.items():
        params[f"{axis}scale"] = scale
    pattern = re.compile(r"\[#<([xyzf])scale>\*(-?[0-9.]+)\]")
    checked = 0
    for line in lines:
        text = "".join(re.sub(r"\(.*?\)|;.*", "", line).split()).lower()
        for found in pattern.finditer(text):
            value, end = read_value(text, found.start(), params)
            assert end == found.end()
            assert value == pytest.approx(scales[found.group(1)] * float(found.group(2)))
            checked += 1
    assert checked > 5000  # ~two scaled words on nearly every one of its 4711 lines


@pytest.mark.validation
def test_mmount_subroutine_expressions(shared_data: Path) -> None:
    """The o100 subroutine of LinuxCNC's mmount.ngc, first call's arguments."""
    assert (shared_data / "gcode/linuxcnc/mmount.ngc").is_file()
    params = Parameters()
    # o100 call [1.1880] [-0.9380] [0.25] [0.55] [0.4375] [0.25]
    params.push_call([1.1880, -0.9380, 0.25, 0.55, 0.4375, 0.25])
    # line settings are applied after the line: apply each one as the lexer would
    for text in ("#9=#5", "#5=[#5-.020]", "#4=[0-#4]", "#7=[#6/2]", "#8=[#3-#7]"):
        key, value, _ = read_assignment(text, 0, params)
        params[key] = value
    assert params[5] == pytest.approx(0.4175)
    assert params[4] == -0.55
    assert params[8] == pytest.approx(0.125)
    assert value_of("[#8gt#4]", params) == 1.0  # o101 while [#8 GT #4]
    assert value_of("[0-[[#5+#9]/4]]", params) == pytest.approx(-0.21375)
    params.pop_call()
    assert params[5] == 0.0
