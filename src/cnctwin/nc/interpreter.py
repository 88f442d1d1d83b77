"""RS274/ISO 6983 interpreter: NC program text to motion segments in machine coordinates.

The interpreter follows the RS274NGC language as LinuxCNC implements it (modal groups,
order of execution within a block, parameters, expressions, O-word subroutines and
control flow) and accepts the Fanuc/Haas, grbl and Sinumerik basics that real CAM posts
emit. Everything it does not implement is rejected with an :class:`~cnctwin.errors.NCError`
that names the construct and the line. The list is in ``docs/nc.md``.

Segments are produced lazily: a program of any length is interpreted in constant memory.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import NoReturn

from cnctwin.errors import NCError
from cnctwin.nc.canned_cycles import CycleSpec, expand_cycle, peck_count
from cnctwin.nc.cutter_comp import CutterCompensator
from cnctwin.nc.expressions import Parameters, read_value
from cnctwin.nc.lexer import Block, lex_block
from cnctwin.nc.limits import (
    MAX_CYCLE_REPEATS,
    MAX_NUMBER_CHARS,
    MAX_POSITION_MM,
    MAX_SEGMENTS_PER_BLOCK,
    WORD_LIMITS,
    check_position,
)
from cnctwin.nc.owords import OWordControl
from cnctwin.nc.segments import (
    PLANE_AXES,
    CutterComp,
    FeedMode,
    MachineState,
    MotionKind,
    Plane,
    Segment,
    Vec3,
    arc_sweep_rad,
)
from cnctwin.nc.setup import NCSetup, ToolEntry
from cnctwin.nc.source import LineSource, RepeatBudget

__all__ = ["Interpreter", "interpret_file", "interpret_text"]

logger = logging.getLogger(__name__)

MM_PER_INCH = 25.4
#: Largest amount by which an R-format arc's radius may fall short of half its chord, mm.
ARC_RADIUS_TOLERANCE_MM = 0.005
#: LinuxCNC's test of an I/J/K arc's end radius (measured with its rs274): refused when the
#: end radius differs from the start radius by more than the absolute tolerance and by more
#: than ARC_RADIUS_TOLERANCE_REL of the larger radius, or by more than
#: ARC_RADIUS_LIMIT_FACTOR times the absolute tolerance. The absolute tolerance is in program
#: units: 0.028284 mm under G21, 0.0028284 in (0.0718 mm) under G20.
ARC_END_TOLERANCE_MM = 0.028284
ARC_END_TOLERANCE_INCH = 0.0028284
ARC_RADIUS_TOLERANCE_REL = 0.001
ARC_RADIUS_LIMIT_FACTOR = 100.0
#: Chord tolerance of the line segments that approximate G5.1 splines, mm.
SPLINE_TOLERANCE_MM = 0.001

_AXES = "xyz"
_ROTARY = "abc"

# Modal groups of G-codes (keys are ten times the G number).
_GROUPS: dict[int, int] = {}
for _group, _codes in {
    1: (0, 10, 20, 30, 51, 331, 730, 800, 810, 820, 830, 840, 850, 860, 890),
    2: (170, 180, 190),
    3: (900, 910),
    4: (901, 911),
    5: (930, 940, 950),
    6: (200, 210, 7000, 7100),
    7: (400, 410, 420, 411, 421),
    8: (430, 431, 432, 490),
    10: (980, 990),
    12: (540, 550, 560, 570, 580, 590, 591, 592, 593),
    13: (610, 611, 640),
    14: (960, 970),
    15: (70, 80),
    0: (40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923, 500),
}.items():
    for _code in _codes:
        _GROUPS[_code] = _group

_FAST_WORDS = frozenset("xyzf")
#: Words that every block may carry (feed, speed, tool, axes).
_PLAIN_WORDS = frozenset("fstxyzabc@^")
#: Words that move an axis; the centre words of an arc.
_AXIS_WORDS = frozenset("xyzabcuw@^")
_CENTRE_WORDS = frozenset("ijk")
#: The centre words in each plane.
_IN_PLANE = {plane: frozenset("ijk"[axis] for axis in PLANE_AXES[plane][:2]) for plane in Plane}
#: Words an arc block (G2/G3) may carry.
_ARC_WORDS = _PLAIN_WORDS | frozenset("ijkrp")
#: Modal groups of M-codes (RS274NGC): stops, tool change, spindle, coolant, overrides.
_M_GROUPS = {
    0: 4,
    1: 4,
    2: 4,
    30: 4,
    60: 4,
    6: 6,
    61: 6,
    3: 7,
    4: 7,
    5: 7,
    7: 8,
    8: 8,
    9: 8,
    48: 9,
    49: 9,
}
_READ_ONLY = frozenset(("_x", "_y", "_z", "_abs_x", "_abs_y", "_abs_z"))
_NUM = r"\s*([-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+))\s*"
#: A raw line of only an optional N word, an optional G0/G1 (G00, G01, ...), X, Y, Z and
#: F words in that order; group 1 is the G-code's digit.
_XYZ_LINE = re.compile(
    rf"\s*(?:[nN][0-9]+\s*)?(?:[gG]0*([01])(?![0-9.])\s*)?"
    rf"(?:[xX]{_NUM})?(?:[yY]{_NUM})?(?:[zZ]{_NUM})?(?:[fF]{_NUM})?"
)
#: A raw line of only an optional N word, an optional G2/G3 (G02, G03, ...) and X, Y, Z,
#: I, J, K words in that order; group 1 is the G-code's digit.
_ARC_LINE = re.compile(
    rf"\s*(?:[nN][0-9]+\s*)?(?:[gG]0*([23])(?![0-9.])\s*)?"
    rf"(?:[xX]{_NUM})?(?:[yY]{_NUM})?(?:[zZ]{_NUM})?"
    rf"(?:[iI]{_NUM})?(?:[jJ]{_NUM})?(?:[kK]{_NUM})?"
)
_ARC_LETTERS = "xyzijk"
#: The bound of a length word (X Y Z I J K), program units.
_LENGTH_WORD_LIMIT = WORD_LIMITS["x"][0]
#: The bound of an F word, program units per minute.
_FEED_WORD_LIMIT = WORD_LIMITS["f"][0]
_NON_MODAL_WITH_AXES = {100, 280, 300, 520, 920}
_CYCLES = {730, 810, 820, 830, 840, 850, 860, 890}
_COORD_SYSTEMS = {540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8, 593: 9}

#: G-codes recognised but not implemented, with what they are.
_UNSUPPORTED_G: dict[int, str] = {
    50: "cubic spline (G5)",
    52: "NURBS (G5.2)",
    53: "NURBS (G5.3)",
    120: "circular pocket (G12)",
    130: "circular pocket (G13)",
    330: "spindle-synchronized motion (G33)",
    382: "probing (G38.2)",
    383: "probing (G38.3)",
    384: "probing (G38.4)",
    385: "probing (G38.5)",
    510: "scaling (G51)",
    541: "extended work offsets (G54.1)",
    680: "coordinate rotation (G68)",
    690: "coordinate rotation cancel (G69)",
    700: "lathe finishing cycle (G70)",
    710: "lathe roughing cycle (G71)",
    711: "lathe roughing cycle (G71.1)",
    712: "lathe roughing cycle (G71.2)",
    720: "lathe facing cycle (G72)",
    721: "lathe facing cycle (G72.1)",
    722: "lathe facing cycle (G72.2)",
    740: "left-hand tapping / lathe peck cycle (G74)",
    750: "lathe grooving cycle (G75)",
    760: "threading cycle (G76)",
    870: "back boring cycle (G87)",
    880: "boring cycle with manual retract (G88)",
    1000: "macro call (G100)",
}
_UNSUPPORTED_M: dict[int, str] = {
    98: "Fanuc subprogram call (M98)",
    99: "Fanuc subprogram return (M99)",
}
_KNOWN_M = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 30, 48, 49, 60, 61}


class Interpreter(OWordControl):
    """Interpret NC programs into :class:`~cnctwin.nc.segments.Segment` objects.

    Parameters
    ----------
    setup
        Tool table, lathe flag, initial work offsets, reference points (mm).

    Attributes
    ----------
    lines_read
        Lines read so far (every line, including those skipped by control flow).
    units
        Units the program first selected, ``"mm"`` or ``"inch"``; ``None`` if it never
        selects any (then it runs in mm).
    warnings
        ``"FILE:LINE: message"`` for everything accepted but worth a look.
    messages
        Texts of ``(MSG, ...)`` comments, in order.
    tools_used
        Tool numbers loaded by the program, in order of first use.

    Examples
    --------
    >>> from cnctwin.nc.interpreter import interpret_text
    >>> [s.end_mm for s in interpret_text("G21 G90\\nG0 X10 Y5\\nG1 Z-1 F100\\nM2")]
    [(10.0, 5.0, 0.0), (10.0, 5.0, -1.0)]
    """

    def __init__(self, setup: NCSetup | None = None) -> None:
        self.setup = setup if setup is not None else NCSetup()
        self.lines_read = 0
        self.units: str | None = None
        self.warnings: list[str] = []
        self.messages: list[str] = []
        self.tools_used: list[int] = []
        self.params = Parameters()
        self._file = "<string>"
        self._line = 0
        lathe = self.setup.lathe
        # Positions are machine coordinates of the controlled point, mm / degrees.
        self._pos: list[float] = list(self.setup.initial_position_mm)
        self._abc: Vec3 = (0.0, 0.0, 0.0)
        self._factor = 1.0
        self._incremental = False
        self._arc_absolute = False
        self._motion: int | None = None
        self._g5x: dict[int, list[float]] = {
            n: list(self.setup.work_offsets_mm.get(n, (0.0, 0.0, 0.0))) + [0.0, 0.0, 0.0]
            for n in range(1, 10)
        }
        self._cs = 1
        self._rotation_deg: dict[int, float] = dict.fromkeys(range(1, 10), 0.0)
        self._off = [0.0] * 6
        self._g92 = [0.0] * 6
        self._g92_saved = [0.0] * 6
        self._g92_enabled = False
        self._tool_offset = [0.0, 0.0, 0.0]
        self._tools: dict[int, ToolEntry] = dict(self.setup.tools)
        self._selected_tool = 0
        # Retract to the R plane until G98 (LinuxCNC's and RS274/NGC's initial mode).
        self._retract_r = True
        self._cycle_r: float | None = None
        self._cycle_bottom: float | None = None
        self._cycle_q = 0.0
        self._cycle_p = 0.0
        self._g28 = [*self.setup.g28_home_mm, 0.0, 0.0, 0.0]
        self._g30 = [*self.setup.g30_home_mm, 0.0, 0.0, 0.0]
        self._comp: CutterCompensator | None = None
        self._exit_base: list[float] | None = None
        self._diameter_mode = lathe
        self._state = MachineState(
            plane=Plane.ZX if lathe else Plane.XY,
            diameter_mode=lathe,
        )
        self._ended = False
        self._started = False
        self._frames: list[tuple] = []
        self._subs: dict[str, tuple[LineSource, int, int]] = {}
        self._sources: list[LineSource] = []
        self._out: list[Segment] = []
        self._line_start = 0
        self._budget = RepeatBudget(self.setup.max_repeated_lines)
        self._segments_left = self.setup.max_segments

    # ------------------------------------------------------------------ entry points
    def run_file(self, path: str | Path) -> Iterator[Segment]:
        """Interpret a program file lazily.

        Parameters
        ----------
        path
            NC program file (``.ngc``, ``.nc``, ``.tap``, ``.gcode``, ``.mpf``, ...).

        Yields
        ------
        Segment
            Motion segments in program order.

        Raises
        ------
        NCError
            ``"FILE:LINE: message"`` for anything the interpreter cannot honour.
        OSError
            If the file cannot be opened.
        """
        setup = self.setup
        source = LineSource.from_path(path, setup.max_program_bytes, self._budget)
        return self._run(source)

    def run_text(self, text: str, name: str = "<string>") -> Iterator[Segment]:
        """Interpret program text held in memory; see :meth:`run_file`."""
        return self._run(LineSource.from_text(text, name, self._budget))

    # ------------------------------------------------------------------ main loop
    def _run(self, source: LineSource) -> Iterator[Segment]:
        self._sources.append(source)
        try:
            while self._sources and not self._ended:
                src = self._sources[-1]
                self._file = src.name
                finished = True
                main = len(self._sources) == 1 and src is source
                for lineno, start, raw in src:
                    self._line = lineno
                    self._line_start = start
                    if main and lineno > self.lines_read:
                        self.lines_read = lineno
                    plain = (
                        _XYZ_LINE.fullmatch(raw)
                        if self._comp is None and len(raw) <= MAX_NUMBER_CHARS
                        else None
                    )
                    if plain is not None:
                        # Fastest path: a line of only (N) (G0/G1) X Y Z (F) words, in
                        # that order.
                        g, gx, gy, gz, gf = plain.groups()
                        motion = self._motion if g is None else 10 if g == "1" else 0
                        moves = not (gx is None and gy is None and gz is None)
                        if g is None and gf is None and not moves and (motion == 10 or motion == 0):
                            continue
                        feed = 0.0 if gf is None else float(gf)
                        if moves and (motion == 10 or motion == 0) and feed <= _FEED_WORD_LIMIT:
                            self._motion = motion
                            self._started = True
                            try:
                                if gf is not None:
                                    self._set_feed(feed)
                                self._xyz_move(
                                    motion,
                                    None if gx is None else float(gx),
                                    None if gy is None else float(gy),
                                    None if gz is None else float(gz),
                                    gf is not None,
                                )
                            except NCError as err:
                                if g is None and gf is None:
                                    raise self._locate(err) from None
                                # A G or F line is read again below: its words' own checks
                                # come first there, as for any block.
                            else:
                                self._segments_left -= 1
                                if self._segments_left < 0:
                                    raise self._too_many_segments()
                                yield self._out.pop()
                                continue
                    elif self._comp is None:
                        arc = _arc_words(raw, self._motion)
                        if arc is not None:
                            # Fast path: a line of only (N) (G2/G3) X Y Z I J K words.
                            self._started = True
                            code, words = arc
                            self._motion = code
                            try:
                                self._require_feed(words)
                                self._arc(code == 30, words)
                            except NCError as err:
                                raise self._locate(err) from None
                            self._segments_left -= 1
                            if self._segments_left < 0:
                                raise self._too_many_segments()
                            yield self._out.pop()
                            continue
                    try:
                        if "#5" in raw or "#<_" in raw:
                            self._sync_parameters()
                        block = lex_block(raw, self.params)
                        if block is None:
                            if self._started and raw.strip() == "%":
                                # The closing tape mark ends the program.
                                self._ended = True
                                break
                            continue
                        self._started = True
                        if block.oword is not None:
                            if self._control(block.oword, src):
                                finished = False
                                break
                            continue
                        self._execute(block)
                    except NCError as err:
                        raise self._locate(err) from None
                    out = self._out
                    if out:
                        self._segments_left -= len(out)
                        if self._segments_left < 0:
                            raise self._too_many_segments()
                        if len(out) == 1:
                            yield out.pop()
                        else:
                            yield from out
                            out.clear()
                        if self._ended:
                            break
                    elif self._ended:
                        break
                if finished and self._sources and self._sources[-1] is src:
                    if len(self._sources) > 1:
                        raise self._error(
                            "end of subroutine file reached without 'endsub' or 'return'"
                        )
                    self._sources.pop()
            if not self._started:
                self._warn("the program is empty: no block to run")
            elif not self._ended:
                self._warn(
                    "the program ends without M2, M30 or a closing '%' "
                    "(LinuxCNC stops with an error there)"
                )
            self._finish_comp()
            if self._out:
                self._segments_left -= len(self._out)
                if self._segments_left < 0:
                    raise self._too_many_segments()
                yield from self._out
                self._out.clear()
        finally:
            for src in self._sources:
                src.close()
            source.close()

    def _sync_parameters(self) -> None:
        """Refresh the read-only system parameters a program may read.

        Only lines that mention ``#5`` or ``#<_`` refresh them (it costs a few
        microseconds). Lengths are in the program's current units:

        - #5210 G92 enabled (1/0), #5211-#5216 the stored G92/G52 offset (X Y Z A B C,
          kept while G92.2 suspends it);
        - #5220 coordinate system (1-9); #5221 + 20 (n - 1) + i the origin of system n
          (G54 = 1 ... G59.3 = 9) on axis i (X Y Z A B C), #5230 + 20 (n - 1) its rotation;
        - #5400 tool number, #5401-#5403 its offsets X Y Z;
        - #5420-#5425 the current position X Y Z A B C in the program frame;
        - #<_x> #<_y> #<_z> (same) and #<_abs_x> #<_abs_y> #<_abs_z> (machine position).
        """
        params = self.params
        f = self._factor
        pos = (self._pos[0], self._pos[1], self._pos[2])
        here = self._state.to_program(pos)
        params[5210] = 1.0 if self._g92_enabled else 0.0
        for i in range(6):
            scale = f if i < 3 else 1.0
            params[5211 + i] = self._g92_saved[i] / scale
            for n in range(1, 10):
                params[5201 + 20 * n + i] = self._g5x[n][i] / scale
        for n in range(1, 10):
            params[5210 + 20 * n] = self._rotation_deg[n]
        params[5220] = float(self._cs)
        params[5400] = float(self._state.tool)
        for i in range(3):
            params[5401 + i] = self._tool_offset[i] / f
            params[5420 + i] = here[i] / f
            params[5423 + i] = self._abc[i] - self._off[3 + i]
            params["_" + _AXES[i]] = here[i] / f
            params["_abs_" + _AXES[i]] = pos[i] / f

    def _expand(self, text: str) -> str:
        """DEBUG/PRINT text with each #n, #<name> or #[expr] replaced by its value (%.6f)."""
        out: list[str] = []
        pos = 0
        while True:
            at = text.find("#", pos)
            if at < 0:
                out.append(text[pos:])
                return "".join(out)
            out.append(text[pos:at])
            end = at + 1
            if text[end : end + 1] == "<":
                close = text.find(">", end)
                end = close + 1 if close > 0 else len(text)
            elif text[end : end + 1] == "[":
                close = text.find("]", end)
                end = close + 1 if close > 0 else len(text)
            else:
                while end < len(text) and text[end] in "0123456789.":
                    end += 1
            ref = "".join(text[at:end].split()).lower()
            try:
                value, used = read_value(ref, 0, self.params)
                out.append(f"{value:.6f}" + ref[used:])
            except NCError:
                out.append(text[at:end])
            pos = end

    def _locate(self, err: NCError) -> NCError:
        if err.line:
            return err
        return NCError(err.message, self._file, self._line, err.column)

    def _error(self, message: str) -> NCError:
        return NCError(message, self._file, self._line)

    def _too_many_segments(self) -> NCError:
        limit = self.setup.max_segments
        return self._error(
            f"the program produces more than {limit} motion segments: stopped as runaway "
            "work (raise the limit with --max-segments or NCSetup.max_segments for a "
            "program meant to be this long)"
        )

    def _warn(self, message: str) -> None:
        self.warnings.append(f"{self._file}:{self._line}: {message}")

    # ------------------------------------------------------------------ blocks
    def _execute(self, block: Block) -> None:
        for key, value in block.assignments:
            if key in _READ_ONLY:
                raise self._error(f"#<{key}> is a read-only system parameter and cannot be set")
            self.params[key] = value
        for kind, text in block.messages:
            self.messages.append(text if kind == "msg" else self._expand(text))
        gcodes = block.gcodes
        words = block.words
        if not block.mcodes and self._comp is None and words.keys() <= _FAST_WORDS:
            if not gcodes:
                if not words:
                    return
                motion = self._motion
                if motion == 10 or motion == 0:
                    self._fast_straight(words, motion)
                    return
            elif len(gcodes) == 1 and (gcodes[0] == 10 or gcodes[0] == 0) and words:
                self._motion = gcodes[0]
                self._fast_straight(words, gcodes[0])
                return
        self._execute_general(block)

    def _fast_straight(self, words: dict[str, float], motion: int) -> None:
        """A modal G0/G1 block of X, Y, Z and F words only: the bulk of CAM output.

        Equivalent to ``_straight(kind, _target(words))``, inlined for speed.
        """
        if "f" in words:
            self._set_feed(words["f"])
            if len(words) == 1:
                return
        self._xyz_move(motion, words.get("x"), words.get("y"), words.get("z"), "f" in words)

    def _xyz_move(
        self, motion: int, vx: float | None, vy: float | None, vz: float | None, has_f: bool
    ) -> None:
        """Straight G0/G1 move to X, Y, Z words (program units, ``None`` if absent)."""
        state = self._state
        if self._diameter_mode or state.xy_rotation_deg or state.css or self._exit_base:
            words = {k: v for k, v in zip("xyz", (vx, vy, vz), strict=True) if v is not None}
            if has_f:
                words["f"] = state.programmed_feed
            if motion == 10:
                self._require_feed(words)
            kind = MotionKind.LINEAR if motion == 10 else MotionKind.RAPID
            self._straight(kind, self._target(words))
            return
        pos = self._pos
        x0, y0, z0 = pos
        f = self._factor
        off = self._off
        inc = self._incremental
        x, y, z = x0, y0, z0
        if vx is not None:
            x = x0 + vx * f if inc else vx * f + off[0]
        if vy is not None:
            y = y0 + vy * f if inc else vy * f + off[1]
        if vz is not None:
            z = z0 + vz * f if inc else vz * f + off[2]
        if not (
            -MAX_POSITION_MM <= x <= MAX_POSITION_MM
            and -MAX_POSITION_MM <= y <= MAX_POSITION_MM
            and -MAX_POSITION_MM <= z <= MAX_POSITION_MM
        ):
            _check_target((x, y, z))
        if motion == 10:
            kind = MotionKind.LINEAR
            if state.feed_mode == FeedMode.UNITS_PER_MINUTE and state.programmed_feed > 0.0:
                feed = state.programmed_feed * f
            else:
                self._require_feed({"f": state.programmed_feed} if has_f else {})
                feed = self._feed_mm_min(math.sqrt((x - x0) ** 2 + (y - y0) ** 2 + (z - z0) ** 2))
        else:
            kind = MotionKind.RAPID
            feed = 0.0
        abc = self._abc
        self._out.append(
            Segment(
                kind,
                self._line,
                (x0, y0, z0),
                (x, y, z),
                feed,
                state.programmed_speed if state.spindle_direction else 0.0,
                state,
                None,
                0,
                0.0,
                abc,
                abc,
                self._file,
            )
        )
        self._pos = [x, y, z]

    def _execute_general(self, block: Block) -> None:
        words = block.words
        seen_groups: dict[int, int] = {}
        motion_code: int | None = None
        non_modal: int | None = None
        g53 = False
        gcodes = block.gcodes
        if 800 in gcodes and any(_GROUPS.get(c) == 1 and c != 800 for c in gcodes):
            # Fanuc/Haas safe-start lines combine G80 with G0/G1: cancel the cycle, then
            # take the other motion code.
            gcodes = [c for c in gcodes if c != 800]
            self._cycle_r = None
            self._cycle_bottom = None
        for code in gcodes:
            group = _GROUPS.get(code)
            if group is None:
                self._reject_g(code)
            if code == 530:
                g53 = True
            elif group == 0:
                if code == 500 and not self.setup.lathe:
                    raise self._error(
                        "G50 (spindle speed clamp) is a lathe code: use a lathe "
                        "configuration (machine.kind = 'lathe')"
                    )
                if non_modal is not None:
                    raise self._error(f"G{_g(non_modal)} and G{_g(code)} cannot share a block")
                non_modal = code
            else:
                if group in seen_groups:
                    raise self._error(
                        f"G{_g(seen_groups[group])} and G{_g(code)} are in the same modal "
                        "group and cannot share a block"
                    )
                seen_groups[group] = code
                if group == 1:
                    motion_code = code
        if self.setup.lathe and (980 in seen_groups.values() or 990 in seen_groups.values()):
            # Fanuc lathe (G-code system A): G98/G99 select feed per minute/revolution.
            code = seen_groups.pop(10)
            seen_groups[5] = 940 if code == 980 else 950

        for m in block.mcodes:
            if m not in _KNOWN_M:
                if m in _UNSUPPORTED_M:
                    raise self._error(f"{_UNSUPPORTED_M[m]} is not supported")
                self._warn(f"M{m} is machine-specific and was ignored")
        self._check_block(block, seen_groups, motion_code, non_modal, g53)
        # Units first: the F, S and axis words of this block are in the new units.
        if 6 in seen_groups:
            self._set_units("inch" if seen_groups[6] in (200, 7000) else "mm")
        # 1-3: feed mode, feed, spindle speed.
        if 5 in seen_groups:
            mode = FeedMode(seen_groups[5] // 10)
            if mode != self._state.feed_mode:
                self._state = replace(self._state, feed_mode=mode)
        if "f" in words:
            self._set_feed(words["f"])
        if "s" in words and non_modal != 500:
            self._set_speed(words["s"])
        # 4-5: tool select and change.
        if "t" in words:
            self._select_tool(words["t"])
        if 6 in block.mcodes:
            self._change_tool()
        elif 61 in block.mcodes:
            self._set_current_tool(words.get("q"))
        # 6: spindle.
        for m in block.mcodes:
            if m in (3, 4, 5):
                direction = {3: 1, 4: -1, 5: 0}[m]
                if direction != self._state.spindle_direction:
                    self._state = replace(self._state, spindle_direction=direction)
            elif m in (7, 8, 9):
                self._coolant(m)
        # 7: dwell.
        if non_modal == 40:
            self._dwell(words)
        # 8: plane, diameter mode, css.
        if 2 in seen_groups:
            plane = Plane(seen_groups[2] // 10)
            if plane != self._state.plane:
                if self._comp is not None:
                    raise self._error("cannot change the plane while cutter compensation is on")
                self._state = replace(self._state, plane=plane)
        if 15 in seen_groups:
            self._diameter_mode = seen_groups[15] == 70
            self._state = replace(self._state, diameter_mode=self._diameter_mode)
        if 14 in seen_groups:
            self._set_css(seen_groups[14] == 960, words)
        if non_modal == 500:
            self._spindle_clamp(words)
        # 9: cutter compensation.
        if 7 in seen_groups:
            self._set_comp(seen_groups[7], words)
        # 10: tool length offset.
        if 8 in seen_groups:
            self._set_tool_offset(seen_groups[8], words)
        # 11: coordinate system.
        if 12 in seen_groups:
            if self._comp is not None:
                raise self._error(
                    "cannot change the coordinate system while cutter compensation is on"
                )
            self._cs = _COORD_SYSTEMS[seen_groups[12]]
            self._update_offsets()
        # 12: path control mode (G61/G64): no effect on the programmed path.
        # 13: distance modes, retract mode.
        if 3 in seen_groups:
            self._incremental = seen_groups[3] == 910
        if 4 in seen_groups:
            self._arc_absolute = seen_groups[4] == 901
        if 10 in seen_groups:
            self._retract_r = seen_groups[10] == 990
        # 14: reference points, offsets.
        axis_words = not _AXIS_WORDS.isdisjoint(words)
        if non_modal in (280, 300):
            self._go_home(non_modal, words)
        elif non_modal in (281, 301):
            target = self._g28 if non_modal == 281 else self._g30
            target[:] = [*self._pos, *self._abc]
        elif non_modal == 100:
            self._g10(words)
        elif non_modal in (920, 921, 922, 923, 520):
            self._set_g92(non_modal, words)
        # 15: motion.
        if motion_code is not None:
            if motion_code == 800:
                self._motion = None
                self._cycle_r = None
                self._cycle_bottom = None
            else:
                self._motion = motion_code
        if non_modal not in _NON_MODAL_WITH_AXES and seen_groups.get(8) != 431:
            motion = self._motion
            if (
                axis_words
                or motion_code in _CYCLES
                or (motion in (20, 30) and not _CENTRE_WORDS.isdisjoint(words))
            ):
                if motion is None:
                    raise self._error(
                        "axis words after G80 with no motion mode: add G0 or G1"
                        if motion_code == 800
                        else "axis words with no active motion mode: add G0, G1, G2 or G3"
                    )
                self._motion_block(motion, words, g53)
        # 16: program end (M0, M1 and M60 pauses do not change the path).
        if 2 in block.mcodes or 30 in block.mcodes:
            self._ended = True

    def _check_block(
        self,
        block: Block,
        groups: dict[int, int],
        motion_code: int | None,
        non_modal: int | None,
        g53: bool,
    ) -> None:
        """RS274NGC block rules: one M-code per modal group, one user of the axis words,
        and no word that nothing in the block uses."""
        words = block.words
        if (
            not block.mcodes
            and not g53
            and non_modal not in _NON_MODAL_WITH_AXES
            and words.keys() <= _PLAIN_WORDS
        ):
            return
        motion = motion_code if motion_code not in (None, 800) else self._motion
        if (
            (motion == 20 or motion == 30)
            and not block.mcodes
            and not g53
            and non_modal is None
            and words.keys() <= _ARC_WORDS
            and not (_AXIS_WORDS.isdisjoint(words) and _CENTRE_WORDS.isdisjoint(words))
        ):
            return  # an arc block: every word it carries is the arc's
        seen_m: dict[int, int] = {}
        for m in block.mcodes:
            group = _M_GROUPS.get(m)
            if group is None:
                continue
            if group in seen_m and not (group == 8 and {m, seen_m[group]} == {7, 8}):
                raise self._error(
                    f"M{seen_m[group]} and M{m} are in the same modal group "
                    "and cannot share a block"
                )
            seen_m[group] = m
        if (
            non_modal in _NON_MODAL_WITH_AXES
            and motion_code not in (None, 800)
            and not _AXIS_WORDS.isdisjoint(words)
        ):
            raise self._error(
                f"G{_g(motion_code)} and G{_g(non_modal)} both use the axis words "
                "and cannot share a block"
            )
        if g53 and (self._incremental and groups.get(3) != 900 or groups.get(3) == 910):
            raise self._error("G53 cannot be used in incremental mode (G91): use G90")
        moving = not _AXIS_WORDS.isdisjoint(words) or motion_code in _CYCLES
        arc = motion in (20, 30) and (moving or not _CENTRE_WORDS.isdisjoint(words))
        cycle = motion in _CYCLES and moving
        allowed = set("fstxyzabc@^")
        if self.setup.lathe:
            allowed |= {"u", "w"}
        if arc:
            allowed |= {"i", "j", "k", "r", "p"}
        if motion == 51 and moving:
            allowed |= {"i", "j"}
        if motion == 331 and moving:
            allowed.add("k")
        if cycle:
            allowed |= {"r", "l", "p"}
            if motion in (730, 830):
                allowed.add("q")
        if non_modal == 40:
            allowed |= {"p", "x", "u"}
        if non_modal == 100:
            allowed |= {"l", "p", "r", "q"}
        if groups.get(7) in (410, 420, 411, 421) or groups.get(14) == 960:
            allowed.add("d")
        if groups.get(8) in (430, 432):
            allowed.add("h")
        if groups.get(13) == 640:
            allowed |= {"p", "q"}
        if 61 in block.mcodes:
            allowed.add("q")
        for letter in words:
            if letter not in allowed:
                raise self._error(
                    f"word {letter.upper()}{words[letter]:g} is not used by anything in this "
                    "block; remove it or add the G-code that takes it"
                )

    def _reject_g(self, code: int) -> NoReturn:
        if code in _UNSUPPORTED_G:
            raise self._error(f"{_UNSUPPORTED_G[code]} is not supported")
        raise self._error(
            f"G{_g(code)} is not a G-code cnctwin knows; see docs/nc.md for the supported list"
        )

    # ------------------------------------------------------------------ modal settings
    def _set_feed(self, value: float) -> None:
        if value < 0:
            raise self._error(f"feed rate F{value:g} is negative: F must be >= 0")
        if value != self._state.programmed_feed:
            self._state = replace(self._state, programmed_feed=value)

    def _set_speed(self, value: float) -> None:
        if value < 0:
            raise self._error(f"spindle speed S{value:g} is negative: S must be >= 0")
        if value != self._state.programmed_speed:
            self._state = replace(self._state, programmed_speed=value)

    def _set_units(self, units: str) -> None:
        if self.units is None:
            self.units = units
        factor = MM_PER_INCH if units == "inch" else 1.0
        if factor != self._factor:
            # The feed rate keeps its physical value (LinuxCNC): F is re-expressed.
            feed = self._state.programmed_feed
            if self._state.feed_mode != FeedMode.INVERSE_TIME:
                feed = feed * self._factor / factor
            self._factor = factor
            self._state = replace(self._state, units=units, programmed_feed=feed)  # type: ignore[arg-type]

    def _set_css(self, on: bool, words: dict[str, float]) -> None:
        if on and "d" in words:
            self._state = replace(self._state, spindle_clamp_rpm=words["d"])
        self._state = replace(self._state, css=on)

    def _spindle_clamp(self, words: dict[str, float]) -> None:
        if "s" not in words or any(k in words for k in "xyz"):
            raise self._error(
                "G50 on a lathe is supported as spindle speed clamp only (G50 S<rpm>); "
                "coordinate setting with G50 X/Z is not supported"
            )
        self._state = replace(self._state, spindle_clamp_rpm=words["s"])

    def _coolant(self, m: int) -> None:
        current = self._state.coolant
        if m == 9:
            new = "off"
        else:
            kind = "mist" if m == 7 else "flood"
            parts = set() if current == "off" else set(current.split("+"))
            parts.add(kind)
            new = "+".join(sorted(parts))
        if new != current:
            self._state = replace(self._state, coolant=new)

    def _select_tool(self, value: float) -> None:
        if value < 0 or value != int(value):
            raise self._error(f"tool number T{value:g} must be a non-negative integer")
        number = int(value)
        if self.setup.lathe and number >= 100:
            # Fanuc lathe: T0101 = tool 01 with offset register 01, applied at once.
            tool, register = divmod(number, 100)
            self._selected_tool = tool
            self._change_tool()
            entry = self._tool_entry(register, f"T{number:04d} applies a zero offset")
            self._tool_offset = [entry.x_offset_mm, 0.0, entry.length_mm]
            self._update_offsets()
            return
        self._selected_tool = number
        if self.setup.tool_change_on_t:
            self._change_tool()

    def _change_tool(self) -> None:
        self._make_current(self._selected_tool)

    def _make_current(self, tool: int) -> None:
        if tool not in self.tools_used and tool != 0:
            self.tools_used.append(tool)
        if tool != self._state.tool:
            self._state = replace(self._state, tool=tool)

    def _set_current_tool(self, value: float | None) -> None:
        """M61 Q: make tool Q the current tool without a tool change (LinuxCNC)."""
        if value is None or value < 0 or value != int(value):
            q = "no Q word" if value is None else f"Q{value:g}"
            raise self._error(f"M61 needs Q<tool number>, a non-negative integer; got {q}")
        self._make_current(int(value))

    def _set_tool_offset(self, code: int, words: dict[str, float]) -> None:
        if code == 490:
            self._tool_offset = [0.0, 0.0, 0.0]
        elif code == 430:
            number = words.get("h", float(self._state.tool))
            if number != int(number) or number < 0:
                raise self._error(f"G43 H{number:g}: H must be a non-negative integer")
            entry = self._tool_entry(int(number), "G43 applies a zero length offset")
            self._tool_offset = [entry.x_offset_mm, 0.0, entry.length_mm]
        elif code == 431:
            f = self._factor
            self._tool_offset = [
                words.get("x", 0.0) * f,
                words.get("y", 0.0) * f,
                words.get("z", 0.0) * f,
            ]
        elif code == 432:
            extra = self._tools.get(int(words.get("h", -1.0)))
            if extra is None:
                raise self._error("G43.2 needs H<tool> with a tool in the tool table")
            self._tool_offset[0] += extra.x_offset_mm
            self._tool_offset[2] += extra.length_mm
        self._update_offsets()

    def _tool_entry(self, number: int, consequence: str) -> ToolEntry:
        """Tool-table entry, or an empty one with a warning when the table lacks it."""
        entry = self._tools.get(number)
        if entry is None:
            entry = ToolEntry(number)
            if number != 0:
                self._warn(
                    f"tool {number} is not in the tool table: {consequence} "
                    "(add it to the configuration's [[tools]] or tool_table)"
                )
        return entry

    def _update_offsets(self) -> None:
        g5x = self._g5x[self._cs]
        g92 = self._g92
        tool = self._tool_offset
        self._off = [g5x[i] + g92[i] + (tool[i] if i < 3 else 0.0) for i in range(6)]
        state = self._state
        new = (
            (g5x[0], g5x[1], g5x[2]),
            (g92[0], g92[1], g92[2]),
            (tool[0], tool[1], tool[2]),
            self._rotation_deg[self._cs],
            self._cs,
        )
        if new != (
            state.work_offset_mm,
            state.axis_offset_mm,
            state.tool_offset_mm,
            state.xy_rotation_deg,
            state.coordinate_system,
        ):
            self._state = replace(
                state,
                work_offset_mm=new[0],
                axis_offset_mm=new[1],
                tool_offset_mm=new[2],
                xy_rotation_deg=new[3],
                coordinate_system=new[4],
            )

    def _offset(self, axis: int) -> float:
        """Offset from program to machine coordinates on an axis not turned by the XY
        rotation (Z, A, B, C; X and Y when the rotation is 0), mm or degrees."""
        return self._off[axis]

    # ------------------------------------------------------------------ positions
    def _target(self, words: dict[str, float], g53: bool = False) -> list[float]:
        """Machine target of the axis words of a block, mm.

        Axes the block does not name keep their programmed position, which differs from
        the tool's after cutter compensation ends (see :meth:`_finish_comp`).
        """
        if "@" in words or "^" in words:
            words = self._polar(words, g53)
        if "u" in words or "w" in words:
            words = self._incremental_words(words)
        pos = self._pos
        if self._exit_base is not None:
            pos = self._exit_base
            self._exit_base = None
        target = [pos[0], pos[1], pos[2]]
        f = self._factor
        if self._state.xy_rotation_deg and not g53:
            prog = list(self._state.to_program((pos[0], pos[1], pos[2])))
            for i, v in self._axis_values(words).items():
                if i < 3:
                    prog[i] = prog[i] + v if self._incremental else v
            return list(self._state.to_machine((prog[0], prog[1], prog[2])))
        for i, letter in enumerate(_AXES):
            value = words.get(letter)
            if value is None:
                continue
            v = value * f
            if i == 0 and self._diameter_mode:
                v *= 0.5
            if g53:
                target[i] = v
            elif self._incremental:
                target[i] = pos[i] + v
            else:
                target[i] = v + self._offset(i)
        return target

    def _polar(self, words: dict[str, float], g53: bool) -> dict[str, float]:
        """Replace the polar words @ (radius) and ^ (angle, degrees) by X and Y.

        As in LinuxCNC, polar coordinates are about the program origin in G17; under G91
        @ and ^ increment the current radius and angle.
        """
        if g53 or self._state.plane != Plane.XY or "x" in words or "y" in words:
            raise self._error(
                "polar coordinates (@ radius, ^ angle) need G17 and no X/Y/G53 in the block"
            )
        pos = self._pos
        here = self._state.to_program((pos[0], pos[1], pos[2]))
        f = self._factor
        radius = math.hypot(here[0], here[1])
        angle = math.degrees(math.atan2(here[1], here[0])) if radius > 0 else 0.0
        if "@" in words:
            radius = radius + words["@"] * f if self._incremental else words["@"] * f
        if "^" in words:
            angle = angle + words["^"] if self._incremental else words["^"]
        x = radius * math.cos(math.radians(angle))
        y = radius * math.sin(math.radians(angle))
        out = {k: v for k, v in words.items() if k not in "@^"}
        if self._incremental:
            out["x"], out["y"] = (x - here[0]) / f, (y - here[1]) / f
        else:
            out["x"], out["y"] = x / f, y / f
        return out

    def _incremental_words(self, words: dict[str, float]) -> dict[str, float]:
        """Fanuc lathe U and W (incremental X and Z, U in diameter in diameter mode)
        replaced by X and Z in the current distance mode."""
        out = {k: v for k, v in words.items() if k not in "uw"}
        here = self._state.to_program((self._pos[0], self._pos[1], self._pos[2]))
        for inc, axis, index in (("u", "x", 0), ("w", "z", 2)):
            if inc not in words:
                continue
            if axis in words:
                raise self._error(f"{axis.upper()} and {inc.upper()} in one block: use one of them")
            if self._incremental:
                out[axis] = words[inc]
            else:
                current = here[index] / self._factor
                if index == 0 and self._diameter_mode:
                    current *= 2.0
                out[axis] = current + words[inc]
        return out

    def _target_abc(self, words: dict[str, float], g53: bool = False) -> list[float]:
        target = list(self._abc)
        for i, letter in enumerate(_ROTARY):
            value = words.get(letter)
            if value is None:
                continue
            if g53:
                target[i] = value
            elif self._incremental:
                target[i] += value
            else:
                target[i] = value + self._offset(3 + i)
        return target

    # ------------------------------------------------------------------ motion
    def _motion_block(self, code: int, words: dict[str, float], g53: bool) -> None:
        if g53 and code not in (0, 10):
            raise self._error("G53 needs G0 or G1 motion")
        if g53 and self._comp is not None:
            raise self._error("G53 is not allowed while cutter compensation is on")
        if code in (0, 10):
            target = self._target(words, g53)
            abc = self._target_abc(words, g53)
            if code == 10:
                self._require_feed(words)
            self._straight(MotionKind.LINEAR if code == 10 else MotionKind.RAPID, target, abc)
        elif code in (20, 30):
            self._require_feed(words)
            self._arc(code == 30, words)
        elif code == 51:
            self._require_feed(words)
            self._spline(words)
        elif code == 331:
            self._rigid_tap(words)
        elif code in _CYCLES:
            self._cycle(code // 10, words)

    def _require_feed(self, words: dict[str, float]) -> None:
        state = self._state
        mode = state.feed_mode
        if mode == FeedMode.INVERSE_TIME:
            if "f" not in words:
                raise self._error("G93 inverse time mode needs an F word on every feed move")
            if state.programmed_feed <= 0.0:
                raise self._error("G93 inverse time F0 would take forever: F must be > 0")
        elif state.programmed_feed <= 0.0:
            raise self._error("feed move with feed rate 0: program F (e.g. F100) before G1/G2/G3")
        elif mode == FeedMode.UNITS_PER_REV and (
            state.spindle_direction == 0 or state.programmed_speed <= 0.0
        ):
            raise self._error(
                "G95 feed per revolution with the spindle stopped: start it (M3/M4 S...)"
            )

    def _feed_mm_min(self, length_mm: float) -> float:
        state = self._state
        mode = state.feed_mode
        if mode == FeedMode.UNITS_PER_MINUTE:
            return state.programmed_feed * self._factor
        if mode == FeedMode.INVERSE_TIME:
            # F is 1/minutes: the move takes 1/F minutes.
            return length_mm * state.programmed_feed
        return state.programmed_feed * self._factor * self._spindle_rpm()

    def _spindle_rpm(self) -> float:
        state = self._state
        if state.spindle_direction == 0:
            return 0.0
        if not state.css:
            return state.programmed_speed
        # Constant surface speed: S in m/min (mm mode) or ft/min (inch mode) at the
        # current radius of the tool tip about the spindle axis (program X = 0).
        radius_mm = abs(self._state.to_program((self._pos[0], self._pos[1], self._pos[2]))[0])
        surface_mm_min = state.programmed_speed * (1000.0 if self._factor == 1.0 else 304.8)
        clamp = min(state.spindle_clamp_rpm, self.setup.max_spindle_rpm)
        if radius_mm <= 1e-9:
            rpm = math.inf
        else:
            rpm = surface_mm_min / (2.0 * math.pi * radius_mm)
        if rpm > clamp:
            rpm = clamp
        if math.isinf(rpm):
            raise self._error(
                "G96 constant surface speed at X0 with no spindle limit: program G50 S<rpm> "
                "(Fanuc) or G96 D<rpm> (LinuxCNC), or set machine.max_spindle_rpm"
            )
        return rpm

    def _make(
        self,
        kind: MotionKind,
        start: list[float],
        end: list[float],
        length: float,
        center: Vec3 | None = None,
        turns: int = 0,
        abc_start: list[float] | None = None,
        abc_end: list[float] | None = None,
    ) -> Segment:
        feed = 0.0 if kind == MotionKind.RAPID else self._feed_mm_min(length)
        state = self._state
        rpm = (
            0.0
            if state.spindle_direction == 0
            else (self._spindle_rpm() if state.css else state.programmed_speed)
        )
        abc0 = self._abc if abc_start is None else abc_start
        abc1 = abc0 if abc_end is None else abc_end
        return Segment(
            kind,
            self._line,
            (start[0], start[1], start[2]),
            (end[0], end[1], end[2]),
            feed,
            rpm,
            state,
            center,
            turns,
            0.0,
            (abc0[0], abc0[1], abc0[2]),
            (abc1[0], abc1[1], abc1[2]),
            self._file,
        )

    def _emit(self, seg: Segment) -> None:
        if self._comp is None:
            self._out.append(seg)
            return
        for out in self._comp.push(seg):
            if out.kind == MotionKind.ARC and out.feed_mm_min <= 0.0:
                # A corner arc inserted next to a rapid is cut at the programmed feed.
                feed = out.state.programmed_feed * self._factor
                if feed <= 0.0 or out.state.feed_mode != FeedMode.UNITS_PER_MINUTE:
                    raise self._error(
                        "cutter compensation inserts a corner arc next to a rapid here, "
                        "and no feed rate (G94 F) is programmed to cut it"
                    )
                out = replace(out, feed_mm_min=feed)
            self._out.append(out)

    def _straight(
        self, kind: MotionKind, target: list[float], abc: list[float] | None = None
    ) -> None:
        _check_target(target)
        pos = self._pos
        length = math.sqrt(
            (target[0] - pos[0]) ** 2 + (target[1] - pos[1]) ** 2 + (target[2] - pos[2]) ** 2
        )
        seg = self._make(kind, pos, target, length, abc_end=abc)
        self._emit(seg)
        self._pos = target
        if abc is not None:
            self._abc = (abc[0], abc[1], abc[2])

    def _arc(self, ccw: bool, words: dict[str, float]) -> None:
        plane = self._state.plane
        i0, i1, normal = PLANE_AXES[plane]
        target = self._target(words)
        abc = self._target_abc(words)
        start = self._pos
        f = self._factor
        letters = "ijk"
        in_plane = _IN_PLANE[plane]
        if "p" in words:
            turns_word = words["p"]
            if abs(turns_word - round(turns_word)) < 1e-9:
                turns_word = float(round(turns_word))
            if turns_word < 1 or turns_word != int(turns_word):
                raise self._error(f"arc turn count P{turns_word:g} must be a positive integer")
            turns = int(turns_word) * (1 if ccw else -1)
        else:
            turns = 1 if ccw else -1
        if "r" in words:
            if any(k in words for k in "ijk" if k in in_plane):
                raise self._error("arc with both R and I/J/K: use one format")
            center = self._center_from_radius(words["r"] * f, start, target, i0, i1, ccw)
        else:
            for k in "ijk":
                if k in words and k not in in_plane:
                    raise self._error(
                        f"{k.upper()} word is not allowed in an arc in the "
                        f"{plane.name} plane (G{int(plane)}); use "
                        + " and ".join(sorted(x.upper() for x in in_plane))
                    )
            if in_plane.isdisjoint(words):
                raise self._error(
                    "arc without centre: give "
                    + " and/or ".join(sorted(x.upper() for x in in_plane))
                    + " (centre offsets) or R (radius)"
                )
            if self._state.xy_rotation_deg and plane != Plane.XY:
                raise self._error(
                    "arcs in G18/G19 with a rotated coordinate system (G10 L2 R) are not supported"
                )
            if self._arc_absolute:
                prog = list(self._state.to_program((start[0], start[1], start[2])))
                for axis in (i0, i1):
                    value = words.get(letters[axis], 0.0) * f
                    prog[axis] = value * 0.5 if axis == 0 and self._diameter_mode else value
                center = list(self._state.to_machine((prog[0], prog[1], prog[2])))
            else:
                offsets = [
                    words.get("i", 0.0) * f,
                    words.get("j", 0.0) * f,
                    words.get("k", 0.0) * f,
                ]
                if self._state.xy_rotation_deg:
                    rot = math.radians(self._state.xy_rotation_deg)
                    c, s_ = math.cos(rot), math.sin(rot)
                    offsets[0], offsets[1] = (
                        c * offsets[0] - s_ * offsets[1],
                        s_ * offsets[0] + c * offsets[1],
                    )
                center = [start[0] + offsets[0], start[1] + offsets[1], start[2] + offsets[2]]
            center[normal] = start[normal]
            r0 = math.hypot(start[i0] - center[i0], start[i1] - center[i1])
            r1 = math.hypot(target[i0] - center[i0], target[i1] - center[i1])
            if _arc_end_refused(r0, r1, self._state.units):
                raise self._error(
                    f"arc end is {r1:.4f} mm from the centre but the start is {r0:.4f} mm: "
                    "the radii must agree (check I/J/K, incremental vs absolute G90.1/G91.1)"
                )
            if r0 <= 0.0:
                raise self._error("arc of zero radius: the centre equals the start point")
        _check_target(target)
        _check_target(center)
        center_t = (center[0], center[1], center[2])
        radius, _, sweep = arc_sweep_rad(
            (start[0], start[1], start[2]),
            (target[0], target[1], target[2]),
            center_t,
            turns,
            plane,
        )
        length = math.hypot(radius * sweep, target[normal] - start[normal])
        seg = self._make(MotionKind.ARC, start, target, length, center_t, turns, abc_end=abc)
        self._emit(seg)
        self._pos = target
        self._abc = (abc[0], abc[1], abc[2])

    def _center_from_radius(
        self, radius: float, start: list[float], end: list[float], i0: int, i1: int, ccw: bool
    ) -> list[float]:
        du = end[i0] - start[i0]
        dv = end[i1] - start[i1]
        chord = math.hypot(du, dv)
        if chord < 1e-9:
            raise self._error(
                "full circle with R format: the centre is undefined; use I/J/K offsets"
            )
        half = chord / 2.0
        r = abs(radius)
        if r < half:
            if half - r > ARC_RADIUS_TOLERANCE_MM:
                raise self._error(
                    f"arc radius R{radius / self._factor:g} is smaller than half the distance "
                    f"to the end point ({half / self._factor:.4f}): no such arc"
                )
            r = half
        h = math.sqrt(max(r * r - half * half, 0.0))
        # Left normal of the chord; CCW arcs of less than 180 deg have their centre on the left.
        nu, nv = -dv / chord, du / chord
        side = 1.0 if ccw else -1.0
        if radius < 0:
            side = -side
        center = list(start)
        center[i0] = start[i0] + du / 2.0 + side * h * nu
        center[i1] = start[i1] + dv / 2.0 + side * h * nv
        return center

    def _spline(self, words: dict[str, float]) -> None:
        if self._state.plane != Plane.XY:
            raise self._error("G5.1 splines are only defined in the XY plane (G17)")
        if "i" not in words and "j" not in words:
            raise self._error("G5.1 needs I and/or J (control point offsets)")
        start = list(self._pos)
        target = self._target(words)
        f = self._factor
        control = (start[0] + words.get("i", 0.0) * f, start[1] + words.get("j", 0.0) * f)
        # Quadratic B-spline (Bezier) start -> control -> end, split into chords whose
        # deviation |P0 - 2 P1 + P2| / (8 n^2) stays below the tolerance.
        ax = start[0] - 2 * control[0] + target[0]
        ay = start[1] - 2 * control[1] + target[1]
        bend = math.hypot(ax, ay)
        n = max(1, math.ceil(math.sqrt(bend / (8.0 * SPLINE_TOLERANCE_MM))))
        for k in range(1, n + 1):
            t = k / n
            u = 1.0 - t
            point = [
                u * u * start[0] + 2 * u * t * control[0] + t * t * target[0],
                u * u * start[1] + 2 * u * t * control[1] + t * t * target[1],
                start[2] + (target[2] - start[2]) * t,
            ]
            self._straight(MotionKind.LINEAR, point)

    def _rigid_tap(self, words: dict[str, float]) -> None:
        if "k" not in words or words["k"] <= 0:
            raise self._error("G33.1 rigid tapping needs K<pitch> > 0 (distance per revolution)")
        state = self._state
        if state.spindle_direction == 0 or state.programmed_speed <= 0:
            raise self._error("G33.1 rigid tapping needs the spindle turning (M3/M4 with S)")
        start: Vec3 = (self._pos[0], self._pos[1], self._pos[2])
        end = self._target(words)
        target: Vec3 = (end[0], end[1], end[2])
        pitch_mm = words["k"] * self._factor
        rpm = self._spindle_rpm()
        feed = pitch_mm * rpm
        abc = self._abc
        if math.dist(start, target) > 0:
            reverse = replace(state, spindle_direction=-state.spindle_direction)
            for a, b, st in ((start, target, state), (target, start, reverse)):
                self._emit(
                    Segment(
                        MotionKind.LINEAR,
                        self._line,
                        a,
                        b,
                        feed,
                        rpm,
                        st,
                        start_abc_deg=abc,
                        end_abc_deg=abc,
                        file=self._file,
                    )
                )

    def _dwell(self, words: dict[str, float]) -> None:
        seconds = words.get("p")
        if seconds is None:
            seconds = words.get("x", words.get("u"))
        if seconds is None or seconds < 0:
            raise self._error("G4 dwell needs P<seconds> >= 0 (or X/U seconds)")
        pos = (self._pos[0], self._pos[1], self._pos[2])
        abc = (self._abc[0], self._abc[1], self._abc[2])
        state = self._state
        rpm = self._spindle_rpm() if state.spindle_direction else 0.0
        self._emit(
            Segment(
                MotionKind.DWELL,
                self._line,
                pos,
                pos,
                0.0,
                rpm,
                state,
                None,
                0,
                seconds,
                abc,
                abc,
                self._file,
            )
        )

    def _go_home(self, code: int, words: dict[str, float]) -> None:
        """G28/G30: rapid through the intermediate point (the axis words; the current
        position if none) to the stored reference point, on the named axes (all if none)."""
        home = self._g28 if code == 280 else self._g30
        if self._comp is not None:
            raise self._error("G28/G30 is not allowed while cutter compensation is on")
        axes = [i for i, letter in enumerate("xyzabc") if letter in words] or list(range(6))
        self._straight(MotionKind.RAPID, self._target(words), self._target_abc(words))
        target = list(self._pos)
        abc = list(self._abc)
        for i in axes:
            if i < 3:
                target[i] = home[i]
            else:
                abc[i - 3] = home[i]
        self._straight(MotionKind.RAPID, target, abc)

    def _g10(self, words: dict[str, float]) -> None:
        if "l" not in words:
            raise self._error("G10 needs an L word (L1, L2, L10, L11 or L20)")
        l_word = int(words["l"])
        p = words.get("p")
        f = self._factor
        if l_word in (2, 20):
            if p is None or p != int(p) or not 0 <= p <= 9:
                raise self._error(f"G10 L{l_word} needs P0-P9 (coordinate system); got {p}")
            cs = int(p) or self._cs
            offsets = self._g5x[cs]
            values = self._axis_values(words)
            if l_word == 2:
                for i, v in values.items():
                    offsets[i] = v
            else:
                # L20: the current position becomes the given program coordinates.
                if "r" in words:
                    self._rotation_deg[cs] = words["r"]
                frame = replace(
                    self._state,
                    work_offset_mm=(0.0, 0.0, 0.0),
                    axis_offset_mm=(self._g92[0], self._g92[1], self._g92[2]),
                    xy_rotation_deg=self._rotation_deg[cs],
                )
                prog = list(self._state.to_program(tuple(self._pos)))  # type: ignore[arg-type]
                for i, v in values.items():
                    if i < 3:
                        prog[i] = v
                    else:
                        offsets[i] = self._abc[i - 3] - self._g92[i] - v
                shifted = frame.to_machine((prog[0], prog[1], prog[2]))
                rotated = self._rotation_deg[cs] != 0.0
                for i in range(3):
                    if i in values or rotated:
                        offsets[i] = self._pos[i] - shifted[i]
            if "r" in words:
                self._rotation_deg[cs] = words["r"]
            self._update_offsets()
        elif l_word in (1, 10, 11):
            if p is None or p != int(p) or p < 1:
                raise self._error(f"G10 L{l_word} needs P<tool number>; got {p}")
            number = int(p)
            entry = self._tools.get(number, ToolEntry(number))
            length, xoff, diameter = entry.length_mm, entry.x_offset_mm, entry.diameter_mm
            if "r" in words:
                diameter = 2.0 * words["r"] * f
            if l_word == 1:
                if "z" in words:
                    length = words["z"] * f
                if "x" in words:
                    xoff = words["x"] * f
            else:
                cs = 9 if l_word == 11 else self._cs
                g92 = self._g92 if l_word == 10 else [0.0] * 6
                if "z" in words:
                    length = self._pos[2] - self._g5x[cs][2] - g92[2] - words["z"] * f
                if "x" in words:
                    xoff = self._pos[0] - self._g5x[cs][0] - g92[0] - words["x"] * f
            self._tools[number] = ToolEntry(number, length, xoff, diameter)
        else:
            raise self._error(f"G10 L{l_word} is not supported (use L1, L2, L10, L11 or L20)")

    def _axis_values(self, words: dict[str, float]) -> dict[int, float]:
        """Axis words of a block in mm (degrees for A, B, C), X halved in diameter mode."""
        values: dict[int, float] = {}
        for i, letter in enumerate("xyzabc"):
            if letter in words:
                v = words[letter] * (self._factor if i < 3 else 1.0)
                if i == 0 and self._diameter_mode:
                    v *= 0.5
                values[i] = v
        return values

    def _set_g92(self, code: int, words: dict[str, float]) -> None:
        f = self._factor
        if code == 920:
            if not any(k in words for k in "xyzabc"):
                raise self._error("G92 needs at least one axis word")
            unshifted = replace(self._state, axis_offset_mm=(0.0, 0.0, 0.0))
            here = unshifted.to_program(tuple(self._pos))  # type: ignore[arg-type]
            for i, v in self._axis_values(words).items():
                if i < 3:
                    self._g92[i] = here[i] - v
                else:
                    self._g92[i] = self._abc[i - 3] - self._g5x[self._cs][i] - v
            self._g92_saved = list(self._g92)
        elif code == 520:
            for i, letter in enumerate("xyzabc"):
                if letter in words:
                    self._g92[i] = words[letter] * (f if i < 3 else 1.0)
            self._g92_saved = list(self._g92)
        elif code == 921:
            self._g92 = [0.0] * 6
            self._g92_saved = [0.0] * 6
        elif code == 922:
            self._g92 = [0.0] * 6
        elif code == 923:
            self._g92 = list(self._g92_saved)
        self._g92_enabled = code in (920, 520, 923)
        self._update_offsets()

    # ------------------------------------------------------------------ cutter comp
    def _set_comp(self, code: int, words: dict[str, float]) -> None:
        if code == 400:
            self._finish_comp()
            if self._state.cutter_comp != CutterComp.OFF:
                self._state = replace(self._state, cutter_comp=CutterComp.OFF, comp_radius_mm=0.0)
            return
        if self._comp is not None:
            raise self._error(
                "cutter compensation is already on: turn it off with G40 before G41/G42"
            )
        side = CutterComp.LEFT if code in (410, 411) else CutterComp.RIGHT
        orientation = 0
        if code in (411, 421):
            if "d" not in words:
                raise self._error(f"G{_g(code)} needs D<diameter>")
            radius = words["d"] * self._factor / 2.0
        else:
            number = words.get("d", float(self._state.tool))
            if number != int(number) or number < 0:
                raise self._error(f"D{number:g} must be a tool number")
            entry = self._tool_entry(int(number), "cutter compensation uses radius 0")
            radius = entry.diameter_mm / 2.0
            orientation = entry.orientation
        if radius < 0:
            # A negative diameter compensates on the other side (as LinuxCNC does).
            side = CutterComp.RIGHT if side == CutterComp.LEFT else CutterComp.LEFT
            radius = -radius
        self._state = replace(self._state, cutter_comp=side, comp_radius_mm=radius)
        if radius > 0:
            pos = self._pos
            self._comp = CutterCompensator(
                side, radius, self._state.plane, (pos[0], pos[1], pos[2]), orientation
            )

    def _finish_comp(self) -> None:
        """G40 or program end: flush the compensator.

        The tool stays where compensation left it; the next (exit) move starts there,
        while the axes its block does not name keep their programmed values (LinuxCNC).
        """
        if self._comp is None:
            return
        out = self._comp.finish()
        self._comp = None
        self._out.extend(out)
        if out:
            end = out[-1].end_mm
            self._exit_base = self._pos
            self._pos = [end[0], end[1], end[2]]

    # ------------------------------------------------------------------ canned cycles
    def _cycle(self, code: int, words: dict[str, float]) -> None:
        if self._comp is not None:
            raise self._error(f"canned cycle G{code} is not allowed with cutter compensation on")
        plane = self._state.plane
        if plane != Plane.XY and self._state.xy_rotation_deg:
            raise self._error(
                f"canned cycle G{code} in G18/G19 with a rotated coordinate system is not supported"
            )
        if self._state.feed_mode == FeedMode.INVERSE_TIME:
            raise self._error(
                f"canned cycle G{code} cannot run in G93 inverse time mode: use G94 or G95"
            )
        if self._state.programmed_feed <= 0.0:
            raise self._error(f"canned cycle G{code} with feed rate 0: program F (e.g. F100) first")
        i0, i1, n = PLANE_AXES[plane]
        letter_n = _AXES[n]
        f = self._factor
        repeats = words.get("l", 1.0)
        if not 1 <= repeats <= MAX_CYCLE_REPEATS or repeats != int(repeats):
            raise self._error(
                f"canned cycle repeat L{repeats:g} must be a whole number from 1 to "
                f"{MAX_CYCLE_REPEATS}"
            )
        direction = self._state.spindle_direction
        if code == 84 and direction != 1:
            raise self._error(
                "G84 right-hand tapping needs the spindle turning clockwise (M3) before the cycle"
            )
        if code == 86 and direction == 0:
            raise self._error("G86 boring needs the spindle turning (M3/M4) before the cycle")
        if "r" in words:
            r_word = words["r"] * f
        elif self._cycle_r is not None:
            r_word = self._cycle_r
        else:
            raise self._error(f"canned cycle G{code} needs an R word (retract plane)")
        if letter_n in words:
            bottom_word = words[letter_n] * f
        elif self._cycle_bottom is not None:
            bottom_word = self._cycle_bottom
        else:
            raise self._error(f"canned cycle G{code} needs a {letter_n.upper()} word (hole bottom)")
        self._cycle_r = r_word
        self._cycle_bottom = bottom_word
        if code in (73, 83):
            if "q" in words:
                self._cycle_q = words["q"] * f
            if self._cycle_q <= 0:
                raise self._error(f"G{code} needs Q<peck depth> > 0")
        if "p" in words:
            self._cycle_p = words["p"]
        old = self._pos[n]
        if self._incremental:
            r_mm = old + r_word
            bottom_mm = r_mm + bottom_word
        else:
            r_mm = r_word + self._offset(n)
            bottom_mm = bottom_word + self._offset(n)
        if bottom_mm > r_mm:
            raise self._error(
                f"canned cycle G{code}: hole bottom {letter_n.upper()} is above the R plane"
            )
        if old < r_mm:
            target = list(self._pos)
            target[n] = r_mm
            self._straight(MotionKind.RAPID, target)
            old = r_mm
        clear = r_mm if self._retract_r else old
        state_before = self._state
        spec = CycleSpec(
            code,
            n,
            r_mm,
            bottom_mm,
            clear,
            self._cycle_q,
            self._cycle_p if code in (82, 84, 86, 89) else 0.0,
            state_before.spindle_direction or 1,
        )
        moves = int(repeats) * (3 * peck_count(spec) + 6)
        if moves > MAX_SEGMENTS_PER_BLOCK:
            raise self._error(
                f"canned cycle G{code} L{repeats:g} would make about {moves} moves in one "
                f"block; at most {MAX_SEGMENTS_PER_BLOCK} are allowed (fewer repeats or "
                "larger Q pecks)"
            )
        hole_words = {k: v for k, v in words.items() if k in (_AXES[i0], _AXES[i1], "@", "^")}
        for _ in range(int(repeats)):
            hole = self._target(hole_words)
            for move in expand_cycle(spec, (hole[0], hole[1], hole[2]), tuple(self._pos)):  # type: ignore[arg-type]
                if move.spindle_direction is not None:
                    self._state = replace(state_before, spindle_direction=move.spindle_direction)
                if move.kind == MotionKind.DWELL:
                    pos = (self._pos[0], self._pos[1], self._pos[2])
                    abc = (self._abc[0], self._abc[1], self._abc[2])
                    self._out.append(
                        Segment(
                            MotionKind.DWELL,
                            self._line,
                            pos,
                            pos,
                            0.0,
                            self._state.programmed_speed,
                            self._state,
                            None,
                            0,
                            move.dwell_s,
                            abc,
                            abc,
                            self._file,
                        )
                    )
                else:
                    self._straight(move.kind, list(move.position_mm))
            self._state = state_before


def _arc_words(raw: str, motion: int | None) -> tuple[int, dict[str, float]] | None:
    """``(motion code, words)`` of a raw line that is a plain arc block (see
    :data:`_ARC_LINE`) under the modal ``motion``; ``None`` for any other line, and for
    one whose words need the lexer's checks (a number too long or out of range)."""
    found = _ARC_LINE.fullmatch(raw)
    if found is None:
        return None
    digit = found.group(1)
    code = motion if digit is None else 20 if digit == "2" else 30
    if code != 20 and code != 30:
        return None
    words: dict[str, float] = {}
    for letter, text in zip(_ARC_LETTERS, found.groups()[1:], strict=True):
        if text is not None:
            if len(text) > MAX_NUMBER_CHARS:
                return None
            value = float(text)
            if not -_LENGTH_WORD_LIMIT <= value <= _LENGTH_WORD_LIMIT:
                return None
            words[letter] = value
    return (code, words) if words else None


def _check_target(point: list[float] | tuple[float, float, float]) -> None:
    """Refuse a machine position (mm) beyond the bounds of :mod:`cnctwin.nc.limits`."""
    x, y, z = point[0], point[1], point[2]
    if (
        -MAX_POSITION_MM <= x <= MAX_POSITION_MM
        and -MAX_POSITION_MM <= y <= MAX_POSITION_MM
        and -MAX_POSITION_MM <= z <= MAX_POSITION_MM
    ):
        return  # the common case, without a call per axis (also false for NaN)
    for axis, value in zip("XYZ", point[:3], strict=True):
        check_position(axis, value)


def _g(code: int) -> str:
    """G-code key (ten times the number) back to its text, e.g. 921 -> '92.1'."""
    whole, tenth = divmod(code, 10)
    return f"{whole}.{tenth}" if tenth else f"{whole}"


def interpret_file(path: str | Path, setup: NCSetup | None = None) -> Iterator[Segment]:
    """Interpret an NC file lazily; see :class:`Interpreter`."""
    return Interpreter(setup).run_file(path)


def interpret_text(
    text: str, setup: NCSetup | None = None, name: str = "<string>"
) -> Iterator[Segment]:
    """Interpret NC program text lazily; see :class:`Interpreter`."""
    return Interpreter(setup).run_text(text, name)


def _arc_end_refused(r0_mm: float, r1_mm: float, units: str) -> bool:
    """Whether LinuxCNC refuses an arc whose start and end radii (mm) are ``r0_mm``, ``r1_mm``.

    ``units``: the program's units (``"mm"`` or ``"inch"``), which set the absolute tolerance.
    """
    tolerance = ARC_END_TOLERANCE_INCH * MM_PER_INCH if units == "inch" else ARC_END_TOLERANCE_MM
    error = abs(r1_mm - r0_mm)
    if error > ARC_RADIUS_LIMIT_FACTOR * tolerance:
        return True
    return error > tolerance and error > ARC_RADIUS_TOLERANCE_REL * max(r0_mm, r1_mm)
