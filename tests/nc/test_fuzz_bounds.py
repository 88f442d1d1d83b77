"""Property tests of bounded NC input: hostile programs end in a result or an NCError.

Programs are built from random words whose values include the extremes an attacker
(or a corrupted file) would write: huge exponents in expressions, hundreds of digits,
``nan``/``inf`` text, unicode, control characters, empty lines, and CR, LF and CR LF
line endings, plus loops and canned cycles that ask for unbounded work (tests/hostile_inputs.py).
Each goes through the lexer and the interpreter (``cnctwin nc inspect --json``: in
tests/cli/test_fuzz_cli.py). The property: either every number produced is finite and within
the documented limits, or the input is refused with an :class:`~cnctwin.errors.NCError`.
Work per example is capped by the interpreter's own counters (``max_segments`` and
``max_repeated_lines`` of 2000), not by wall-clock time, so the tests pass on a loaded
machine; the profile is derandomized for reproducible CI.
"""

from __future__ import annotations

import math
import re

from hostile_inputs import FUZZ, LINES, PROGRAMS, WORK_CAP
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.errors import NCError
from cnctwin.nc.expressions import Parameters
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.lexer import lex_block
from cnctwin.nc.limits import MAX_POSITION_MM, WORD_LIMITS
from cnctwin.nc.setup import NCSetup

SETUP = NCSetup(max_segments=WORK_CAP, max_repeated_lines=WORK_CAP)


def _within_limits(letter: str, value: float) -> bool:
    limit = WORD_LIMITS.get(letter, (1e6, ""))[0]
    return math.isfinite(value) and abs(value) <= limit


@settings(FUZZ, max_examples=200)
@given(st.lists(LINES, min_size=1, max_size=4).map(" ".join))
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
@given(PROGRAMS)
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
