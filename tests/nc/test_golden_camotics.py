"""CAMotics interpreter oracles: our machine-coordinate moves must match CAMotics' output.

Each case in ``gcode_golden/camotics/<suite>/<case>`` holds ``data/stdin`` (a program) and
``expect/stdout``, what CAMotics' ``gcodetool`` printed for it. The output format, read
from all 15 cases:

- a first line ``G21`` or ``G20``: the units of the numbers that follow (every case here
  runs in mm; CAMotics defaults to G21);
- ``(File: <stdin>)``;
- one line per move that changes the position, ``N<source line> G0|G1 <axes>``, with the
  **absolute machine coordinates** of the axes (``N6 G0 X30. Y30.`` after G52 X20 Y20 and
  G0 X10 Y10). Moves that leave the position unchanged are not printed (varRefTests/
  GlobalNamedTest line 11);
- ``N<line> M6 T<n>`` for a tool change;
- ``(MSG,<text>)`` for every MSG and DEBUG comment, DEBUG parameters replaced by their
  values (printed like %g);
- ``M2`` at the end.

What we compare: every printed move (source line, rapid or feed, each printed axis) with
our segments that change the position, in order; tool changes with
``Interpreter.tools_used``; MSG texts exactly; DEBUG values field by field (``NAME=value``),
each field knowing from the program which parameter it prints.

Where CAMotics and LinuxCNC disagree we follow LinuxCNC (cnctwin's reference dialect) and
check LinuxCNC's value, derived by hand, instead; each such place is listed in
``DIVERGENCES`` with the reason.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.segments import MotionKind, Segment

pytestmark = pytest.mark.validation

#: CAMotics prints coordinates as %g-like decimals (none here has more than one decimal);
#: the tolerance is float noise well below the printed precision.
TOLERANCE = 6e-5

CASES = [
    "oCodeTests/ElseIfTest",
    "offsetTests/CSMultiTest",
    "offsetTests/CSRelativeTest",
    "offsetTests/CSTest",
    "offsetTests/G52Test",
    "offsetTests/G53Test",
    "offsetTests/GlobalTest",
    "offsetTests/ToolOffsetTest",
    "offsetTests/ToolRelativeOffsetTest",
    "varRefTests/GlobalNamedTest",
    "varRefTests/GlobalNumericTest",
    "varRefTests/LocalNamedTest",
    "varRefTests/LocalNumericTest",
    "varRefTests/NamedTest",
    "varRefTests/NumericTest",
]

#: Cases where CAMotics is not LinuxCNC: (line, phrase) of the NCError we raise instead.
#: LocalNamedTest reads #<x> in the main program after the subroutine that set it has
#: returned. A named parameter without a leading underscore is local to the call that
#: assigned it (LinuxCNC G-code overview, "Scope of Named Parameters"), so LinuxCNC stops
#: with "named parameter #<x> not defined"; CAMotics reads it as 0.
#: GlobalNamedTest assigns #<_x> in a subroutine (line 4) and moves to X#<_x>. In LinuxCNC
#: #<_x> is a predefined, read-only parameter (the current X), so the assignment stops
#: with "Cannot assign to read-only parameter #<_x>"; CAMotics treats it as a user global.
ERROR_DIVERGENCES = {
    "varRefTests/LocalNamedTest": (11, "#<x>"),
    "varRefTests/GlobalNamedTest": (4, "#<_x>"),
}

#: DEBUG fields where CAMotics and LinuxCNC disagree: (case, message index, field) -> the
#: LinuxCNC value. #5422 is the current Z in the program frame *including the tool
#: offset*; LinuxCNC updates it when G43 changes the offset (no motion is needed), so after
#: G43 with the tool at machine Z 10 it is 10 - 1.5 = 8.5 (ToolOffsetTest: G10 L1 length
#: 1.5) and 10 - 8.5 = 1.5 (ToolRelativeOffsetTest: G10 L10 makes the length 10 - 1.5 =
#: 8.5). CAMotics still prints 10 there.
DIVERGENCES = {
    ("offsetTests/ToolOffsetTest", 0, "Z"): 8.5,
    ("offsetTests/ToolRelativeOffsetTest", 0, "Z"): 1.5,
}

#: DEBUG parameters of the position, compared in test_debug_position_values: #5220
#: coordinate system, #5420-#5422 current position. Every other field (offsets) is
#: compared in test_debug_offset_values.
POSITION_PARAMETERS = {"#5220", "#5420", "#5421", "#5422"}

_MOVE = re.compile(r"^N(\d+)\s+G([0-3])\s+(.*)$")
_TOOL = re.compile(r"^N(\d+)\s+M6\s+T(\d+)$")
_AXIS = re.compile(r"([XYZABC])([-+]?\d*\.?\d*)")
_MSG = re.compile(r"^\(MSG,(.*)\)$")
_DEBUG_SOURCE = re.compile(r"\(\s*debug\s*,(.*)\)", re.IGNORECASE)
_FIELD = re.compile(r"^\s*([^=]+?)\s*=\s*(\S+)\s*$")


@dataclass
class Expected:
    units: str
    moves: list[tuple[int, int, dict[str, float]]]
    tools: list[tuple[int, int]]
    messages: list[str]


def parse_stdout(text: str) -> Expected:
    lines = [raw.strip() for raw in text.splitlines() if raw.strip()]
    assert lines[0] in ("G20", "G21"), lines[0]
    assert lines[-1] == "M2", lines[-1]
    out = Expected("inch" if lines[0] == "G20" else "mm", [], [], [])
    for raw in lines[1:-1]:
        if raw.startswith("(File:"):
            continue
        if found := _MOVE.match(raw):
            axes = {a: float(v) for a, v in _AXIS.findall(found.group(3))}
            assert axes, raw
            out.moves.append((int(found.group(1)), int(found.group(2)), axes))
        elif found := _TOOL.match(raw):
            out.tools.append((int(found.group(1)), int(found.group(2))))
        elif found := _MSG.match(raw):
            out.messages.append(found.group(1))
        else:
            raise AssertionError(f"unknown CAMotics output line {raw!r}")
    return out


@pytest.fixture(scope="module")
def root(shared_data: Path) -> Path:
    return shared_data / "gcode_golden" / "camotics"


def _run(program: Path) -> tuple[Interpreter, list[Segment], NCError | None]:
    interp = Interpreter()
    segs: list[Segment] = []
    try:
        segs.extend(interp.run_file(program))  # keeps the segments made before an error
    except NCError as err:
        return interp, segs, err
    return interp, segs, None


def _moves(segs: list[Segment]) -> list[Segment]:
    """Segments CAMotics would print: those that change the position."""
    return [s for s in segs if s.kind != MotionKind.DWELL and s.start_mm != s.end_mm]


def test_every_case_is_listed(root: Path) -> None:
    found = sorted(str(p.parent.parent.relative_to(root)) for p in root.glob("*/*/expect/stdout"))
    assert found == CASES


@pytest.mark.parametrize("case", CASES)
def test_oracle_exits_cleanly(root: Path, case: str) -> None:
    # Every oracle is a successful CAMotics run: exit status 0; stderr holds at most
    # warnings.
    assert (root / case / "expect" / "return").read_text().strip() == "0"
    assert "ERROR" not in (root / case / "expect" / "stderr").read_text()


#: Cases whose expectations the interpreter does not meet yet.
MOVE_BUGS: dict[str, str] = {}


@pytest.mark.parametrize(
    "case",
    [
        pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=MOVE_BUGS[c]))
        if c in MOVE_BUGS
        else c
        for c in CASES
    ],
)
def test_moves(root: Path, case: str) -> None:
    expected = parse_stdout((root / case / "expect" / "stdout").read_text())
    interp, segs, error = _run(root / case / "data" / "stdin")
    ours = _moves(segs)
    if case in ERROR_DIVERGENCES:
        line, phrase = ERROR_DIVERGENCES[case]
        assert error is not None, f"{case}: expected an NCError at line {line}"
        assert error.line == line and phrase in str(error), str(error)
        # Compare the moves CAMotics made before that line.
        expected.moves = [m for m in expected.moves if m[0] < line]
    else:
        assert error is None, str(error)
    scale = 25.4 if expected.units == "inch" else 1.0
    assert len(ours) == len(expected.moves), (
        f"{len(ours)} moves {[(s.line, s.end_mm) for s in ours]}, CAMotics {expected.moves}"
    )
    for seg, (line, g, axes) in zip(ours, expected.moves, strict=True):
        where = f"line {line}: ours {seg.kind.name} {seg.end_mm}, CAMotics G{g} {axes}"
        assert seg.line == line, where
        assert seg.kind == (MotionKind.RAPID if g == 0 else MotionKind.LINEAR), where
        for axis, value in axes.items():
            ours_v = (seg.end_mm + seg.end_abc_deg)["XYZABC".index(axis)]
            if axis in "XYZ":
                ours_v /= scale
            assert abs(ours_v - value) <= TOLERANCE, where
    # Tool changes: CAMotics prints "N<line> M6 T<n>"; we record the tool numbers.
    assert interp.tools_used == [t for _, t in expected.tools]


def _message_pairs(root: Path, case: str) -> list[tuple[int, str, str, str]]:
    """(index, our message, CAMotics message, DEBUG source text) for a case without
    control flow (the sources are the DEBUG comments in file order)."""
    expected = parse_stdout((root / case / "expect" / "stdout").read_text())
    interp, _, error = _run(root / case / "data" / "stdin")
    assert error is None, str(error)
    program = (root / case / "data" / "stdin").read_text()
    sources = [m.group(1).strip() for m in _DEBUG_SOURCE.finditer(program)]
    assert len(interp.messages) == len(expected.messages) == len(sources), (
        interp.messages,
        expected.messages,
    )
    return list(zip(range(len(sources)), interp.messages, expected.messages, sources, strict=True))


def _fields(text: str) -> list[tuple[str, str]]:
    out = []
    for part in text.split(","):
        found = _FIELD.match(part)
        assert found, f"cannot read field {part!r} of {text!r}"
        out.append((found.group(1), found.group(2)))
    return out


def test_msg_texts(root: Path) -> None:
    # ElseIfTest: MSG comments inside a subroutine with if/elseif/else, called with 0, 1
    # and 2; MSG texts are printed as written (without the leading space).
    case = "oCodeTests/ElseIfTest"
    expected = parse_stdout((root / case / "expect" / "stdout").read_text())
    interp, segs, error = _run(root / case / "data" / "stdin")
    assert error is None and segs == []
    assert interp.messages == expected.messages


DEBUG_CASES = [c for c in CASES if c.startswith("offsetTests/")]


def _compare_fields(root: Path, case: str, wanted: set[str] | None) -> int:
    """Compare the DEBUG fields whose parameter is in ``wanted`` (None: all the others).
    Returns how many fields were compared."""
    compared = 0
    for index, ours, theirs, source in _message_pairs(root, case):
        src_fields = _fields(source)
        exp_fields = _fields(theirs)
        our_fields = _fields(ours)
        assert (
            [n for n, _ in src_fields] == [n for n, _ in exp_fields] == [n for n, _ in our_fields]
        )
        for (name, ref), (_, exp_v), (_, our_v) in zip(
            src_fields, exp_fields, our_fields, strict=True
        ):
            if (ref in POSITION_PARAMETERS) != (wanted is not None):
                continue
            value = DIVERGENCES.get((case, index, name), float(exp_v))
            assert "#" not in our_v, f"{case} message {index}: {name} not expanded: {ours!r}"
            assert abs(float(our_v) - value) <= TOLERANCE, (
                f"{case} message {index}: {name}={our_v} ({ref}), expected {value} "
                f"(CAMotics printed {theirs!r})"
            )
            compared += 1
    return compared


@pytest.mark.parametrize("case", DEBUG_CASES)
def test_debug_position_values(root: Path, case: str) -> None:
    # #5220 (active coordinate system) and #5420-#5422 (position in the program frame).
    assert _compare_fields(root, case, POSITION_PARAMETERS) > 0


#: DEBUG cases whose expectations the interpreter does not meet yet.
DEBUG_BUGS: dict[str, str] = {}


@pytest.mark.parametrize(
    "case",
    [
        pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=DEBUG_BUGS[c]))
        if c in DEBUG_BUGS
        else c
        for c in DEBUG_CASES
    ],
)
def test_debug_offset_values(root: Path, case: str) -> None:
    # Every other DEBUG field: #5210 (G92 active), #5211-#5212 (G92/G52 offset),
    # #5241-#5242 (G55 origin), #5403 (tool Z offset). GlobalTest checks that G92.2 keeps
    # #5211/#5212 (it only suspends the offset) while G92.1 zeroes them, and that G92.3
    # restores the offset from them.
    assert _compare_fields(root, case, None) > 0
