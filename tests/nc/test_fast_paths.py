"""The raw-line fast paths of the interpreter give what the general path gives.

Plain ``G0``/``G1`` lines of X, Y, Z words and plain ``G2``/``G3`` lines of X, Y, Z, I, J, K
words skip the lexer (see ``_XYZ_LINE`` and ``_ARC_LINE`` in :mod:`cnctwin.nc.interpreter`).
A trailing comment sends the same block through the lexer and the general block executor,
so each program is run both ways and the segments, warnings and errors must be identical.
"""

from __future__ import annotations

import pytest
from skips import on_sources

import cnctwin.nc.interpreter as interpreter_module
from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter

PROGRAMS = {
    "straight": "G21 G90 F100\nG0 X0 Y0\nG1 X1 Y2\nX3\ng01 x4 y5 z-1\nN10 G0 X0 Y0 Z5\n"
    "G00X1\nG91 G1 X1 Y1\nG90\nG1 Z0\nG1 X2 Y1 F250\nX3 F300.5\nF80\nG0 X1 F90\nX0\nM2\n",
    "inverse time": "G21 G90 G93\nG0 X0 Y0\nG1 X1 Y2 F2\nX3 F0.5\nG94 G1 X0 F100\nM2\n",
    "arcs": "G21 G90 G17 F200\nG0 X0 Y0\nG3 X2 Y0 I1 J0\nG2 X0 Y0 I-1 J0\nX2 Y0 I1\n"
    "G18\nG2 X0 Z0 I-1 K0\nG17\nG20\nG3 X1 Y1 I0.5 J0.5\nN7 g02 x0 y0 i-0.5 j-0.5 z0.1\nM2\n",
    "rotated": "G21 G90 F100\nG10 L2 P1 R30\nG54\nG1 X1 Y1\nG2 X2 Y0 I0.5 J-0.5\nG0 X0\nM2\n",
    "modes": "G21 G91 F100\nG1 X1 Y1\nG3 X2 Y0 I1 J0\nG90 G91.1\nG2 X5 Y1 I1 J0\n"
    "G93 G1 X1 F2\nG94 F50\nG1 X0 Y0\nM2\n",
}

ERRORS = {
    "word out of range": "G21 G90 F100\nG0 X0 Y0\nG1 X2000000 Y0\nM2\n",
    "arc word out of range": "G21 G90 F100\nG0 X0 Y0\nG2 X2000000 Y0 I1000000 J0\nM2\n",
    "radii disagree": "G21 G90 F100\nG0 X0 Y0\nG2 X2 Y0 I5 J0\nM2\n",
    "no feed": "G21 G90\nG0 X0 Y0\nG1 X1 Y1\nM2\n",
    "negative feed": "G21 G90\nG0 X0 Y0\nG1 X1 Y1 F-5\nM2\n",
    "negative feed, modal": "G21 G90 G1 F10\nG0 X0 Y0\nX1 Y1 F-5\nM2\n",
    "feed out of range": "G21 G90\nG0 X0 Y0\nG1 X1 Y1 F2000000000\nM2\n",
    "inverse time without F": "G21 G90 G93\nG0 X0 Y0\nG1 X1 Y1\nM2\n",
    "position out of range with F": "G21 G90\nG0 X0 Y0\nX2000000 F100\nM2\n",
    "no feed on an arc": "G21 G90\nG0 X0 Y0\nG2 X2 Y0 I1 J0\nM2\n",
    "centre word off the plane": "G21 G90 G18 F100\nG0 X0 Y0\nG2 X2 Z0 I1 J0\nM2\n",
    "position out of range": "G20 G90 F100\nG0 X0 Y0\nG1 X900000 Y0\nM2\n",
}


def general(text: str) -> str:
    """The program with a comment after every block, which the fast paths never take."""
    return "".join(f"{line} (c)\n" for line in text.splitlines())


def run(text: str) -> tuple[list, list[str], int]:
    interpreter = Interpreter()
    segments = list(interpreter.run_text(text, "prog.ngc"))
    return segments, interpreter.warnings, interpreter.lines_read


@pytest.mark.parametrize("name", sorted(PROGRAMS))
def test_fast_path_segments_equal_the_general_path(name: str) -> None:
    text = PROGRAMS[name]
    fast = run(text)
    assert len(fast[0]) >= 3
    assert fast == run(general(text))


@pytest.mark.parametrize("name", sorted(ERRORS))
def test_fast_path_errors_equal_the_general_path(name: str) -> None:
    text = ERRORS[name]
    with pytest.raises(NCError) as fast:
        run(text)
    with pytest.raises(NCError) as slow:
        run(general(text))
    assert str(fast.value) == str(slow.value)
    assert ":3:" in str(fast.value)


def test_plain_motion_lines_skip_the_lexer(
    monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> None:
    """Without this the comparisons above would compare the general path with itself."""
    if on_sources(request):  # compiled modules call lex_block past the spy
        return
    lexed: list[str] = []
    lex = interpreter_module.lex_block

    def counting(raw, params):
        lexed.append(raw)
        return lex(raw, params)

    monkeypatch.setattr(interpreter_module, "lex_block", counting)
    run(PROGRAMS["straight"].replace("M2\n", "") + PROGRAMS["arcs"])
    for line in ("G1 X1 Y2", "X3", "g01 x4 y5 z-1", "X3 F300.5", "G3 X2 Y0 I1 J0", "X2 Y0 I1"):
        assert line not in lexed
    assert "G91 G1 X1 Y1" in lexed
