"""Property tests of bounded NC input: hostile programs end in a result or an NCError.

Programs are built from random words whose values include the extremes an attacker
(or a corrupted file) would write: huge exponents in expressions, hundreds of digits,
``nan``/``inf`` text, unicode, control characters, empty lines, and CR, LF and CR LF
line endings, plus loops and canned cycles that ask for unbounded work. Each goes
through the lexer, the interpreter and ``cnctwin nc inspect --json`` (in process). The
property: either every number produced is finite and within the documented limits, or
the input is refused with an :class:`~cnctwin.errors.NCError` (exit 2 and one line on
the command line). Work per example is capped by the interpreter's own counters
(``max_segments`` and ``max_repeated_lines`` of 2000), not by wall-clock time, so the
tests pass on a loaded machine; the profile is derandomized for reproducible CI.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cnctwin.cli.app import run
from cnctwin.errors import NCError
from cnctwin.nc.expressions import Parameters
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.lexer import lex_block
from cnctwin.nc.limits import MAX_POSITION_MM, WORD_LIMITS
from cnctwin.nc.setup import NCSetup

FUZZ = settings(
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
WORK_CAP = 2000
SETUP = NCSetup(max_segments=WORK_CAP, max_repeated_lines=WORK_CAP)

_EXTREME = st.sampled_from(
    [
        "9" * 400,
        "1" * 65,
        "1" * 64,
        "0." + "0" * 70 + "1",
        "1e308",
        "1e-308",
        "nan",
        "inf",
        "-inf",
        "-0",
        "1000001",
        "999999.9999",
        "[10**400]",
        "[10**300*10**300]",
        "exp[1000]",
        "[1/0]",
        "[0 mod 0]",
        "[sqrt[-1]]",
        "[2**1024]",
        "[-8**0.5]",
        "[1e3]",
        "#<undefined>",
        "#99999",
        "[" * 120 + "1" + "]" * 120,
    ]
)
_NUMBER = st.one_of(
    st.integers(-(10**12), 10**12).map(str),
    st.floats(allow_nan=False, allow_infinity=False).map(lambda v: f"{v:.6f}"),
    st.floats(-1e4, 1e4).map(lambda v: f"{v:.3f}"),
    st.floats(-100, 100).map(lambda v: f"{v:.3f}"),
    st.integers(0, 100).map(str),
    _EXTREME,
)
_LETTER = st.sampled_from(list("GMXYZABCIJKRFSPQLTHDNUWE@^XYZXYZ"))
_WORD = st.tuples(_LETTER, _NUMBER).map("".join)
_JUNK = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12)
_STATEMENT = st.sampled_from(
    [
        "G21 G90 F100 S1000 M3",
        "G20",
        "G91",
        "G83 X0 Y0 Z-50 R1 Q0.001",
        "G81 X1 Z-1 R1 L9999",
        "G73 Z-1000000 R0 Q1",
        "o1 while [1]",
        "o1 endwhile",
        "o2 repeat [99999]",
        "o2 endrepeat",
        "o3 sub",
        "o3 call",
        "o3 endsub",
        "G5.1 X1000000 I-1000000 J1000000",
        "G2 X1 Y1 R0.5 P999999",
        "G93 G1 X0.000001 F999999999",
        "#1=[#1+1]",
        "(MSG, \u00e9\u4e2d)",
        "",
        "%",
    ]
)
_SANE = st.floats(-100, 100).map(lambda v: f"{v:.3f}")
_VALID = st.tuples(
    st.sampled_from(["G0", "G1", ""]),
    st.lists(st.sampled_from("XYZ"), min_size=1, max_size=3, unique=True),
    st.lists(_SANE, min_size=3, max_size=3),
).map(lambda t: " ".join([t[0]] + [f"{a}{v}" for a, v in zip(t[1], t[2], strict=False)]))
_BIG = st.sampled_from(
    ["1000001", "99999999", "123456789012", "1" + "0" * 40, "-" + "9" * 30, "[10**20]"]
)
_EXTREME_MOVE = st.tuples(
    st.sampled_from(["G0", "G1", "G91 G0", "G20 G1", "G0 G93 F1 G1"]),
    st.sampled_from(list("XYZABC")),
    st.one_of(_BIG, _EXTREME),
).map(lambda t: f"{t[0]} {t[1]}{t[2]}")
_HOSTILE = st.one_of(
    _EXTREME_MOVE,
    _EXTREME_MOVE,
    st.lists(_WORD, min_size=1, max_size=5).map(" ".join),
    st.tuples(st.sampled_from(["G0", "G1", "G2", "G3"]), _WORD, _WORD).map(" ".join),
    _STATEMENT,
    _STATEMENT,
    _JUNK,
    st.tuples(_STATEMENT, _JUNK).map("".join),
)
_HEADER = "G21 G90 G17 G0 F100 S1000 M3"


def _program(header: bool, valid: list[str], hostile: list[tuple[int, str]], eol: str) -> str:
    """Valid moves with a few hostile lines inserted, joined by ``eol``."""
    lines = list(valid)
    for at, line in hostile:
        lines.insert(at % (len(lines) + 1), line)
    return eol.join(([_HEADER] if header else []) + lines)


_PROGRAM = st.builds(
    _program,
    st.sampled_from([True, True, True, False]),
    st.lists(_VALID, min_size=1, max_size=10),
    st.lists(st.tuples(st.integers(0, 10), _HOSTILE), min_size=0, max_size=3),
    st.sampled_from(["\n", "\r", "\r\n"]),
)
_LINE = st.one_of(_VALID, _HOSTILE)


def _within_limits(letter: str, value: float) -> bool:
    limit = WORD_LIMITS.get(letter, (1e6, ""))[0]
    return math.isfinite(value) and abs(value) <= limit


@settings(FUZZ, max_examples=200)
@given(st.lists(_LINE, min_size=1, max_size=4).map(" ".join))
def test_the_lexer_gives_bounded_words_or_ncerror(line: str) -> None:
    try:
        block = lex_block(line, Parameters())
    except NCError as err:
        assert err.message
        return
    if block is None:
        return
    assert all(_within_limits(k, v) for k, v in block.words.items()), block
    assert all(0 <= g < 10_000 for g in block.gcodes) and all(
        0 <= m <= 10_000 for m in block.mcodes
    )
    assert all(math.isfinite(v) for _, v in block.assignments)


@settings(FUZZ, max_examples=150)
@given(_PROGRAM)
def test_the_interpreter_gives_finite_segments_or_ncerror(text: str) -> None:
    lines = len(re.split(r"\r\n|\r|\n", text))
    count = 0
    try:
        for seg in Interpreter(SETUP).run_text(text, "fuzz.ngc"):
            count += 1
            for point in (seg.start_mm, seg.end_mm, seg.center_mm or (0.0, 0.0, 0.0)):
                assert all(math.isfinite(v) and abs(v) <= MAX_POSITION_MM for v in point), seg
            assert all(math.isfinite(v) for v in (*seg.start_abc_deg, *seg.end_abc_deg)), seg
            assert all(math.isfinite(v) for v in (seg.feed_mm_min, seg.spindle_rpm, seg.dwell_s))
            assert math.isfinite(seg.length_mm), seg
            assert 1 <= seg.line <= lines, seg
    except NCError as err:
        assert err.message and str(err).startswith("fuzz.ngc")
        assert 0 <= err.line <= lines, err
    assert count <= WORK_CAP


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_cli")


_TOTALS = (
    "motion_blocks",
    "feed_length_mm",
    "rapid_length_mm",
    "machining_time_s",
    "rapid_time_s",
    "dwell_time_s",
    "total_time_s",
)


def _all_finite(report: dict) -> bool:
    """Every total is a finite number (not null) and the bounds are null or finite."""
    numbers = [report[key] for key in _TOTALS]
    for corner in report["bounds_mm"].values():
        if corner is not None:
            numbers.extend(corner)
    return all(isinstance(v, int | float) and math.isfinite(v) for v in numbers)


def _refuse(constant: str) -> object:
    raise AssertionError(f"{constant} in JSON output")


@settings(FUZZ, max_examples=100)
@given(_PROGRAM.map(lambda t: t.encode("utf-8", "surrogatepass")))
def test_nc_inspect_json_is_strict_json_or_one_line_exit_2(
    folder: Path, capsys: pytest.CaptureFixture[str], data: bytes
) -> None:
    program = folder / "fuzz.ngc"
    program.write_bytes(data)
    cap = str(WORK_CAP)
    code = run(
        ["nc", "inspect", str(program), "--json", "--max-segments", cap]
        + ["--max-repeated-lines", cap]
    )
    out, err = capsys.readouterr()
    assert code in (0, 2), err
    if code == 0:
        report = json.loads(out, parse_constant=_refuse)
        assert _all_finite(report), report
    else:
        assert out == "" and err.count("\n") == 1 and "Traceback" not in err
