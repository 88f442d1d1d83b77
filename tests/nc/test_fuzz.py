"""Property tests of the NC interpreter: it fails only with NCError, and its output is finite.

Two program generators, and a metamorphic check:

(a) random programs built from a grammar of valid-looking blocks: motion (G0-G3 with
    random words), planes, units, distance and feed modes, F/S/M words, offsets, tool
    length and radius compensation, canned cycles, polar words, comments and messages,
    parameter assignments and expressions;
(b) real programs (LinuxCNC mmount.ngc and cds.ngc, CAMotics heart.ngc) with random line
    deletions, duplications and insertions and character deletions, insertions, swaps and
    replacements.

Each program is interpreted to the end. The only exception allowed is
:class:`cnctwin.errors.NCError`, which must name a line (> 0) of the program and print as
``FILE:LINE: message``; every segment produced must have finite coordinates, feed, speed
and length.

(c) a random path of straight moves and arcs, built in Python, must
    come out the same when written in inches, incrementally, or under a work offset.

Reproducible: the hypothesis profile below is derandomized and has no example database,
so CI runs the same examples every time. The loop guard is lowered to 500 iterations
(a mutation can turn a loop counter into a constant) and at most MAX_SEGMENTS segments
are read from one program (a mutated canned cycle can legitimately ask for millions of
pecks); both keep the file well under 20 s on two cores.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cnctwin.nc.owords as owords_module
from cnctwin.errors import NCError
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.setup import NCSetup, ToolEntry

settings.register_profile(
    "cnctwin-nc-fuzz",
    derandomize=True,
    database=None,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
FUZZ = settings.get_profile("cnctwin-nc-fuzz")

MAX_SEGMENTS = 20_000
SETUP = NCSetup(
    tools={
        1: ToolEntry(1, length_mm=50.0, diameter_mm=6.0),
        2: ToolEntry(2, length_mm=-10.0, diameter_mm=0.5),
        3: ToolEntry(3, length_mm=0.0, diameter_mm=-4.0),
    },
    g28_home_mm=(0.0, 0.0, 100.0),
)


@pytest.fixture(scope="module", autouse=True)
def _small_loop_guard() -> Iterator[None]:
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(owords_module, "MAX_LOOP_ITERATIONS", 500)
        yield


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def check_program(text: str, name: str = "fuzz.ngc", setup: NCSetup = SETUP) -> None:
    """Interpret ``text``; only NCError may escape, and everything produced is finite."""
    interp = Interpreter(setup)
    lines = text.count("\n") + 1
    try:
        for seg in itertools.islice(interp.run_text(text, name), MAX_SEGMENTS):
            assert _finite(*seg.start_mm, *seg.end_mm, *seg.start_abc_deg, *seg.end_abc_deg), seg
            assert _finite(seg.feed_mm_min, seg.spindle_rpm, seg.dwell_s, seg.length_mm), seg
            assert seg.feed_mm_min >= 0.0 and seg.spindle_rpm >= 0.0 and seg.dwell_s >= 0.0, seg
            if seg.center_mm is not None:
                assert _finite(*seg.center_mm), seg
            assert 1 <= seg.line <= lines, seg
    except NCError as err:
        assert 1 <= err.line <= lines, f"{err!r} has line {err.line}"
        assert str(err).startswith(f"{err.file}:{err.line}: "), str(err)
        assert err.message, repr(err)


# ---------------------------------------------------------------------------- (a) grammar
_NUMBER = st.one_of(
    st.integers(-300, 300).map(str),
    st.floats(-500, 500, allow_nan=False).map(lambda v: f"{v:.4f}"),
    st.sampled_from(["0", ".5", "-.5", "1.", "+2", "-0", "0.0001", "1234.5678"]),
)
_POSITIVE = st.one_of(st.integers(1, 3000).map(str), st.floats(0.01, 500).map(lambda v: f"{v:.3f}"))
_EXPRESSION = st.sampled_from(
    [
        "#1",
        "#2",
        "#<a>",
        "#<_g>",
        "[#1*2]",
        "[#1+#<a>]",
        "[#<a>/4]",
        "[sin[30]*10]",
        "[sqrt[2]]",
        "[#1 mod 3]",
        "-[2**3]",
        "[atan[1]/[1]]",
        "[#2-#1]",
        "[abs[#<a>]]",
        "[fix[#1]]",
        "[cos[#1]*#<a>]",
        "#5220",
        "#5420",
        "#<_x>",
        "[#5422+1]",
    ]
)
_VALUE = st.one_of(_NUMBER, _NUMBER, _EXPRESSION)
_HEADER = "G21 G17 G90 G94 F300 S1000 M3\n#1=1.5\n#2=-2\n#<a>=3\n#<_g>=4\nG0 X0 Y0 Z10"


def _words(letters: str, max_size: int = 4) -> st.SearchStrategy[list[str]]:
    """Distinct words (one per letter) with random values."""
    return st.lists(st.sampled_from(letters), max_size=max_size, unique=True).flatmap(
        lambda ls: st.tuples(*[_VALUE.map(lambda v, c=c: f"{c}{v}") for c in ls]).map(list)
    )


def _turn(i: float, j: float, angle: float) -> tuple[float, float]:
    """Incremental end of an arc whose centre is (i, j) from its start, after turning by
    ``angle`` (rad) about the centre."""
    c, s_ = math.cos(angle), math.sin(angle)
    return i + (c * -i - s_ * -j), j + (s_ * -i + c * -j)


_OFFSET = st.floats(-50, 50).filter(lambda v: abs(v) > 0.01)


def _ij_arc(code: str, i: float, j: float, angle: float, z: str, p: str) -> str:
    x, y = _turn(i, j, angle)
    return f"G17 G91 G91.1 {code} X{x:.6f} Y{y:.6f} I{i:.6f} J{j:.6f}{z}{p}\nG90"


def _r_arc(code: str, dx: float, dy: float, scale: float, sign: int) -> str:
    return f"G17 G91 {code} X{dx:.6f} Y{dy:.6f} R{sign * scale * math.hypot(dx, dy):.6f}\nG90"


# Arcs that are consistent wherever they start: incremental end, incremental centre (or
# a radius at least half the chord).
_IJ_ARC = st.tuples(
    st.sampled_from(["G2", "G3"]),
    _OFFSET,
    _OFFSET,
    st.floats(0, 2 * math.pi),
    st.sampled_from(["", " Z-1", " Z2.5"]),
    st.sampled_from(["", " P2", " P3"]),
).map(lambda t: _ij_arc(*t))
_R_ARC = st.tuples(
    st.sampled_from(["G2", "G3"]),
    _OFFSET,
    _OFFSET,
    st.floats(0.5, 5),
    st.sampled_from([1, -1]),
).map(lambda t: _r_arc(*t))
_MOTION = st.tuples(st.sampled_from(["G0", "G1", "G00", "G01"]), _words("XYZABC")).map(
    lambda t: " ".join([t[0], *t[1]])
)
_RANDOM_ARC = st.tuples(st.sampled_from(["G2", "G3"]), _words("XYZIJKRP", 5)).map(
    lambda t: " ".join([t[0], *t[1]])
)
_POLAR = st.tuples(st.sampled_from(["G0", "G1", ""]), _NUMBER, _NUMBER).map(
    lambda t: f"{t[0]} @{t[1]} ^{t[2]}"
)
_MODAL = st.one_of(
    st.sampled_from(
        [
            "G17",
            "G18",
            "G19",
            "G20",
            "G21",
            "G90",
            "G91",
            "G90.1",
            "G91.1",
            "G93 G1 X1 F2",
            "G94",
            "G95",
            "M3",
            "M4",
            "M5",
            "M7",
            "M8",
            "M9",
            "M6 T1",
            "T2 M6",
            "M6 T3",
            "G43 H1",
            "G43",
            "G49",
            "G43.1 Z1",
            "G10 L2 P1 X10 Y-5 Z2",
            "G10 L2 P2 X-20",
            "G10 L20 P1 X0",
            "G10 L1 P2 Z3",
            "G10 L10 P1 Z0",
            "G54",
            "G55",
            "G59.3",
            "G92 X0 Y0",
            "G92.1",
            "G92.2",
            "G92.3",
            "G52 X5",
            "G28",
            "G30",
            "G28 Z5",
            "G28.1",
            "G53 G0 Z0",
            "G40",
            "G41",
            "G42",
            "G41 D1",
            "G42 D2",
            "G41.1 D4",
            "G42.1 D1",
            "G80",
            "G98",
            "G99",
            "G4 P0.5",
            "G61",
            "G64 P0.01",
            "G7",
            "G8",
            "G96 S100 D2000",
            "G97",
            "G5.1 X5 I2 J3",
            "G33.1 Z-1 K1",
            "M0",
            "M1",
            "M60",
            "/G0 X1",
            "N100 G0 X1",
            "%",
            "G91 G28 Z0",
        ]
    ),
    _POSITIVE.map(lambda v: f"F{v}"),
    _POSITIVE.map(lambda v: f"S{v}"),
)
_CYCLE = st.tuples(
    st.sampled_from(["G73", "G81", "G82", "G83", "G84", "G85", "G86", "G89"]),
    _words("XY", 2),
    st.floats(-20, 20).map(lambda v: f"{v:.3f}"),
    st.floats(-40, 20).map(lambda v: f"{v:.3f}"),
    st.floats(0.5, 10).map(lambda q: f"{q:.3f}"),
    st.integers(1, 3),
    st.sampled_from(["G98", "G99", "G91", ""]),
).map(lambda t: f"{t[6]} {t[0]} {' '.join(t[1])} R{t[2]} Z{t[3]} Q{t[4]} P0.1 L{t[5]}")
_ASSIGNMENT = st.tuples(
    st.sampled_from(["#1", "#2", "#<a>", "#<_g>", "#31", "#<_value>"]), _VALUE
).map(lambda t: f"{t[0]}={t[1]}")
_COMMENT = st.sampled_from(
    [
        "(plain comment)",
        "; semicolon comment",
        "(MSG, hello)",
        "(DEBUG, a=#1 b=#<a>)",
        "(PRINT,#<_x>)",
        "()",
        "G0 X1 (inline) Y2",
        "(debug,#5420 #[1+1])",
    ]
)
_CONTROL = st.sampled_from(
    [
        "o10 if [#1 gt 0]\nG0 X1\no10 else\nG0 X2\no10 endif",
        "o11 repeat [3]\nG91 G0 X1\nG90\no11 endrepeat",
        "#3=0\no12 while [#3 lt 2]\nG1 X#3 F100\n#3=[#3+1]\no12 endwhile",
        "o13 sub\nG0 X#1 Y#2\no13 return [#1]\no13 endsub\no13 call [1] [2]",
        "o14 call [1]",
    ]
)
_RARE = st.sampled_from(
    [
        "(unclosed",
        "(nested (x))",
        "G0 X#<undefined>",
        "G0 X[1/0]",
        "G0 X[ln[0]]",
        "G1 X1 X2",
        "G0 G1 X1",
        "S-5",
        "G2 X1 Y1 R0.1",
        "G12.5",
        "G76 P1",
        "M98 P1",
        "G0 X1 $",
        "G1 X1 F-1",
        "M2",
        "M30",
    ]
)
_LINE = st.one_of(
    _MOTION,
    _MOTION,
    _MOTION,
    _IJ_ARC,
    _IJ_ARC,
    _R_ARC,
    _RANDOM_ARC,
    _POLAR,
    _MODAL,
    _MODAL,
    _MODAL,
    _CYCLE,
    _ASSIGNMENT,
    _COMMENT,
    _CONTROL,
    _words("XYZ").map(" ".join),
    _RARE,
)
_PROGRAM = st.tuples(
    st.sampled_from([True, True, True, False]), st.lists(_LINE, min_size=6, max_size=30)
).map(lambda t: "\n".join(([_HEADER] if t[0] else []) + t[1]))


@settings(FUZZ, max_examples=250)
@given(_PROGRAM)
def test_grammar_programs_fail_only_with_ncerror(text: str) -> None:
    check_program(text)


@settings(FUZZ, max_examples=100)
@given(
    st.lists(_LINE, min_size=6, max_size=30).map(
        lambda ls: "\n".join(["G20 G0 X0 F10 S500 M3", *ls])
    )
)
def test_grammar_programs_in_inch_fail_only_with_ncerror(text: str) -> None:
    check_program(text)


@settings(FUZZ, max_examples=100)
@given(_PROGRAM)
def test_grammar_programs_on_a_lathe_fail_only_with_ncerror(text: str) -> None:
    check_program(text, setup=NCSetup(lathe=True, tools={1: ToolEntry(1, 2.0, 1.0, 0.8)}))


# ---------------------------------------------------------------------------- (c) metamorphic
# One random path (straight moves and IJ arcs, absolute mm) written three more ways must
# give the same machine path: in inches (G20, every value / 25.4), incrementally (G91),
# and under a G54 origin (every point shifted by the origin). The oracle is the path
# itself, built here in Python, not an earlier interpreter output.
_COORD = st.floats(-200, 200)
_STEP = st.one_of(
    st.tuples(st.sampled_from(["G0", "G1"]), _COORD, _COORD, _COORD),
    st.tuples(st.sampled_from(["G2", "G3"]), _OFFSET, _OFFSET, st.floats(0.1, 6.18), _COORD),
)


def _build(steps: list[tuple]) -> list[tuple[str, tuple[float, float, float], tuple | None]]:
    """(code, absolute end, centre offset or None) for each step, starting at the origin."""
    cur = (0.0, 0.0, 0.0)
    moves = []
    for step in steps:
        if step[0] in ("G0", "G1"):
            end, ij = (step[1], step[2], step[3]), None
        else:
            i, j, angle, z = step[1:]
            dx, dy = _turn(i, j, angle)
            end, ij = (cur[0] + dx, cur[1] + dy, z), (i, j)
        moves.append((step[0], end, ij))
        cur = end
    return moves


def _render(moves: list, scale: float = 1.0, incremental: bool = False, origin=None) -> str:
    lines = ["G20" if scale != 1.0 else "G21", "G17 G90 G91.1 G94 F100"]
    if origin is not None:
        lines.append("G10 L2 P1 X{:.10f} Y{:.10f} Z{:.10f}".format(*(v / scale for v in origin)))
    if incremental:
        lines.append("G91")
    prev = (0.0, 0.0, 0.0)
    for code, end, ij in moves:
        v = [e - p for e, p in zip(end, prev, strict=True)] if incremental else list(end)
        words = " ".join(f"{a}{x / scale:.10f}" for a, x in zip("XYZ", v, strict=True))
        if ij is not None:
            words += f" I{ij[0] / scale:.10f} J{ij[1] / scale:.10f}"
        lines.append(f"{code} {words}")
        prev = end
    return "\n".join(lines)


def _path(text: str):
    return list(Interpreter().run_text(text, "meta.ngc"))


def _same(a, b, shift=(0.0, 0.0, 0.0), tol: float = 1e-6) -> None:
    assert len(a) == len(b)
    for k, (s, t) in enumerate(zip(a, b, strict=True)):
        assert s.kind == t.kind and s.turns == t.turns, (k, s, t)
        assert all(
            abs(x + d - y) <= tol for x, d, y in zip(s.end_mm, shift, t.end_mm, strict=True)
        ), (k, s, t)
        if s.center_mm is not None:
            assert all(
                abs(x + d - y) <= tol
                for x, d, y in zip(s.center_mm, shift, t.center_mm, strict=True)
            ), (
                k,
                s,
                t,
            )
        if k > 0 or shift == (0.0, 0.0, 0.0):  # the first move starts at machine zero
            assert abs(s.length_mm - t.length_mm) <= tol, (k, s, t)


@settings(FUZZ, max_examples=150)
@given(st.lists(_STEP, min_size=1, max_size=12), st.tuples(_COORD, _COORD, _COORD))
def test_units_distance_mode_and_offsets_do_not_change_the_path(
    steps: list[tuple], origin: tuple[float, float, float]
) -> None:
    # Start with a move to the program origin, so that under the G54 origin every move
    # starts at a shifted point.
    moves = _build([("G0", 0.0, 0.0, 0.0), *steps])
    base = _path(_render(moves))
    # The absolute mm program reproduces the path it was written from.
    for seg, (_, end, _) in zip(base, moves, strict=True):
        assert all(abs(x - y) <= 1e-9 for x, y in zip(seg.end_mm, end, strict=True))
    _same(base, _path(_render(moves, scale=25.4)))
    _same(base, _path(_render(moves, incremental=True)))
    _same(base, _path(_render(moves, scale=25.4, incremental=True)))
    _same(base, _path(_render(moves, origin=origin)), shift=origin)


# ---------------------------------------------------------------------------- (b) mutations
REAL_PROGRAMS = ("linuxcnc/mmount.ngc", "linuxcnc/cds.ngc", "camotics/heart/heart.ngc")
_ALPHABET = "GMXYZIJKRFPQSTH0123456789.-+[]#<>=()/;@^ \nOo%_*"


@pytest.fixture(scope="module")
def real_programs(shared_data: Path) -> dict[str, list[str]]:
    folder = shared_data / "gcode"
    out = {}
    for name in REAL_PROGRAMS:
        path = folder / name
        if not path.is_file():
            pytest.skip(f"{path} is absent")
        out[name] = path.read_text(errors="replace").splitlines()
    return out


def _mutate(data: st.DataObject, lines: list[str]) -> list[str]:
    lines = list(lines)
    for _ in range(data.draw(st.integers(1, 6), label="mutations")):
        op = data.draw(
            st.sampled_from(
                [
                    "delete_line",
                    "dup_line",
                    "insert_line",
                    "delete_char",
                    "insert_char",
                    "swap_chars",
                    "replace_char",
                ]
            ),
            label="op",
        )
        if not lines:
            lines.append("")
        i = data.draw(st.integers(0, len(lines) - 1), label="line")
        line = lines[i]
        if op == "delete_line":
            del lines[i]
        elif op == "dup_line":
            lines.insert(i, line)
        elif op == "insert_line":
            lines.insert(i, data.draw(_LINE, label="new line"))
        elif op == "insert_char":
            at = data.draw(st.integers(0, len(line)), label="at")
            char = data.draw(st.sampled_from(_ALPHABET), label="char")
            lines[i] = line[:at] + char + line[at:]
        elif line:
            at = data.draw(st.integers(0, len(line) - 1), label="at")
            if op == "delete_char":
                lines[i] = line[:at] + line[at + 1 :]
            elif op == "swap_chars" and at + 1 < len(line):
                lines[i] = line[:at] + line[at + 1] + line[at] + line[at + 2 :]
            elif op == "replace_char":
                char = data.draw(st.sampled_from(_ALPHABET), label="char")
                lines[i] = line[:at] + char + line[at + 1 :]
    return lines


@pytest.mark.validation
@settings(FUZZ, max_examples=200)
@given(st.data())
def test_mutated_real_programs_fail_only_with_ncerror(
    real_programs: dict[str, list[str]], data: st.DataObject
) -> None:
    name = data.draw(st.sampled_from(REAL_PROGRAMS), label="program")
    text = "\n".join(_mutate(data, real_programs[name]))
    check_program(text, name=name)


@pytest.mark.validation
def test_unmutated_real_programs_pass_the_check(real_programs: dict[str, list[str]]) -> None:
    # The property holds trivially for the originals, which must interpret cleanly.
    for name, lines in real_programs.items():
        interp = Interpreter(SETUP)
        segs = list(interp.run_text("\n".join(lines), name))
        assert segs, name
        check_program("\n".join(lines), name=name)
