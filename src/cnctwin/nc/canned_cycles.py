"""Drilling canned cycles (G73, G81-G86, G89) expanded into elementary moves.

The expansion follows the RS274NGC/LinuxCNC definition: for each hole, a rapid in the
plane at the clearance level, a rapid along the drilling axis to the R plane, the
cycle's own motion, and a retract to the clearance level (the initial level under G98,
the R plane under G99). Moves that would not move the tool are dropped, as LinuxCNC does.
Positions are machine coordinates in mm; the drilling axis is the plane's normal.
:class:`CycleModes` holds the cycles' sticky words (R, hole bottom, Q, P) and retract mode
and turns a cycle block into a :class:`CycleSpec`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from cnctwin.errors import NCError
from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.limits import MAX_CYCLE_REPEATS, MAX_PECKS, MAX_SEGMENTS_PER_BLOCK
from cnctwin.nc.segments import PLANE_AXES, FeedMode, MachineState, MotionKind, Plane

__all__ = [
    "CycleModes",
    "CycleMove",
    "CycleSpec",
    "expand_cycle",
    "peck_count",
    "PECK_CLEARANCE_MM",
]

#: Retract of G73 chip breaking and the stop short of the previous depth in G83, in mm
#: (LinuxCNC uses 0.010 inch, i.e. 0.254 mm).
PECK_CLEARANCE_MM: Final = 0.254


@dataclass(frozen=True, slots=True)
class CycleMove:
    """One elementary move of an expanded cycle.

    Attributes
    ----------
    kind
        RAPID, LINEAR or DWELL.
    position_mm
        Target (x, y, z) in machine coordinates, mm (unchanged for a dwell).
    dwell_s
        Dwell time in s.
    spindle_direction
        Spindle direction during the move: 1 CW, -1 CCW, 0 stopped, ``None`` unchanged.
    """

    kind: MotionKind
    position_mm: tuple[float, float, float]
    dwell_s: float = 0.0
    spindle_direction: int | None = None


@dataclass(frozen=True, slots=True)
class CycleSpec:
    """What one hole of a cycle needs.

    Attributes
    ----------
    code
        The cycle's G number: 73, 81, 82, 83, 84, 85, 86 or 89.
    normal_axis
        Index (0, 1, 2) of the drilling axis (Z in G17, Y in G18, X in G19).
    r_mm
        R plane level along the drilling axis, machine coordinates, mm.
    bottom_mm
        Hole bottom along the drilling axis, machine coordinates, mm.
    clear_mm
        Retract level after the hole, machine coordinates, mm.
    peck_mm
        Peck increment Q (G73, G83), mm, > 0.
    dwell_s
        Dwell P at the bottom (G82, G86, G89; also G84 when given), s.
    spindle_direction
        Spindle direction before the cycle (G84 reverses it to retract).
    """

    code: int
    normal_axis: int
    r_mm: float
    bottom_mm: float
    clear_mm: float
    peck_mm: float = 0.0
    dwell_s: float = 0.0
    spindle_direction: int = 1


def peck_count(spec: CycleSpec) -> int:
    """Pecks of one hole: 1 for cycles without pecks, ceil(depth / Q) for G73 and G83.

    Raises
    ------
    NCError
        For more than :data:`~cnctwin.nc.limits.MAX_PECKS` pecks, naming their number.
    """
    if spec.code not in (73, 83):
        return 1
    depth_mm = spec.r_mm - spec.bottom_mm
    pecks = max(1, math.ceil(depth_mm / spec.peck_mm)) if spec.peck_mm > 0.0 else math.inf
    if pecks > MAX_PECKS:
        raise NCError(
            f"G{spec.code} with peck Q{spec.peck_mm:.6g} mm over a {depth_mm:.6g} mm deep hole "
            f"needs {pecks} pecks; at most {MAX_PECKS} are allowed: use a larger Q"
        )
    return int(pecks)


def expand_cycle(
    spec: CycleSpec, hole_mm: tuple[float, float, float], current_mm: tuple[float, float, float]
) -> list[CycleMove]:
    """Elementary moves that drill one hole.

    Parameters
    ----------
    spec
        The cycle.
    hole_mm
        Hole position in machine coordinates, mm; its drilling-axis component is ignored.
    current_mm
        Position before the hole, machine coordinates, mm.

    Returns
    -------
    list of CycleMove
        Rapid to the hole at the current level, rapid to R, the cycle motion, retract.

    Raises
    ------
    NCError
        For a G73/G83 hole of more than :data:`~cnctwin.nc.limits.MAX_PECKS` pecks.
    """
    peck_count(spec)
    n = spec.normal_axis
    moves: list[CycleMove] = []
    here = list(current_mm)

    def go(kind: MotionKind, level: float | None = None, direction: int | None = None) -> None:
        target = list(here)
        if level is not None:
            target[n] = level
        if target == here and kind != MotionKind.DWELL:
            return
        here[:] = target
        moves.append(CycleMove(kind, (target[0], target[1], target[2]), 0.0, direction))

    def dwell(seconds: float, direction: int | None = None) -> None:
        moves.append(CycleMove(MotionKind.DWELL, (here[0], here[1], here[2]), seconds, direction))

    # Position over the hole at the current level, then down to R.
    over = list(hole_mm)
    over[n] = here[n]
    if over != here:
        here[:] = over
        moves.append(CycleMove(MotionKind.RAPID, (over[0], over[1], over[2])))
    go(MotionKind.RAPID, spec.r_mm)

    code = spec.code
    r, bottom = spec.r_mm, spec.bottom_mm
    if code in (73, 83):
        depth = r - spec.peck_mm
        while depth > bottom:
            go(MotionKind.LINEAR, depth)
            if code == 73:
                go(MotionKind.RAPID, depth + PECK_CLEARANCE_MM)
            else:
                go(MotionKind.RAPID, r)
                go(MotionKind.RAPID, depth + PECK_CLEARANCE_MM)
            depth -= spec.peck_mm
        go(MotionKind.LINEAR, bottom)
        go(MotionKind.RAPID, spec.clear_mm)
    elif code == 81:
        go(MotionKind.LINEAR, bottom)
        go(MotionKind.RAPID, spec.clear_mm)
    elif code == 82:
        go(MotionKind.LINEAR, bottom)
        if spec.dwell_s > 0.0:
            dwell(spec.dwell_s)
        go(MotionKind.RAPID, spec.clear_mm)
    elif code == 84:
        go(MotionKind.LINEAR, bottom)
        reverse = -spec.spindle_direction
        if spec.dwell_s > 0.0:
            dwell(spec.dwell_s, reverse)
        # The tap feeds out with the spindle reversed, straight to the clearance level.
        go(MotionKind.LINEAR, spec.clear_mm, reverse)
    elif code == 85:
        # Feed out to R, then rapid to the clearance level.
        go(MotionKind.LINEAR, bottom)
        go(MotionKind.LINEAR, r)
        go(MotionKind.RAPID, spec.clear_mm)
    elif code == 89:
        # Dwell at the bottom, then feed straight out to the clearance level.
        go(MotionKind.LINEAR, bottom)
        if spec.dwell_s > 0.0:
            dwell(spec.dwell_s)
        go(MotionKind.LINEAR, spec.clear_mm)
    elif code == 86:
        # Dwell, stop the spindle, rapid out; the spindle restarts after the retract.
        go(MotionKind.LINEAR, bottom)
        if spec.dwell_s > 0.0:
            dwell(spec.dwell_s)
        go(MotionKind.RAPID, spec.clear_mm, 0)
    else:
        raise ValueError(f"not a drilling cycle: G{code}")
    return moves


class CycleModes:
    """The sticky words of the drilling cycles and the retract mode.

    Parameters
    ----------
    where
        Where errors are reported.

    Attributes
    ----------
    retract_to_r
        G99 (retract to the R plane); False under G98 (retract to the initial level).
        LinuxCNC and RS274/NGC start in the R-plane mode until G98.
    r_word_mm, bottom_word_mm
        The last R and hole-bottom words, mm (program frame, or increments under G91);
        ``None`` until given or after G80.
    peck_mm
        The last Q word (G73, G83), mm.
    dwell_s
        The last P word, s.
    """

    __slots__ = ("retract_to_r", "r_word_mm", "bottom_word_mm", "peck_mm", "dwell_s", "_where")

    def __init__(self, where: ProgramCursor) -> None:
        self.retract_to_r = True
        self.r_word_mm: float | None = None
        self.bottom_word_mm: float | None = None
        self.peck_mm = 0.0
        self.dwell_s = 0.0
        self._where = where

    def cancel(self) -> None:
        """G80: forget the R and hole-bottom words."""
        self.r_word_mm = None
        self.bottom_word_mm = None

    def plan(
        self,
        code: int,
        words: dict[str, float],
        state: MachineState,
        factor: float,
        incremental: bool,
        level_mm: float,
        offset_mm: float,
    ) -> tuple[CycleSpec, int]:
        """The hole of cycle G``code`` and its repeat count (L word) for a block's ``words``
        (program units, ``factor`` mm each) under the modal ``state``.

        ``level_mm`` is the tool's machine position along the drilling axis before the
        block and ``offset_mm`` the program-to-machine offset on that axis.

        Raises
        ------
        NCError
            For a cycle the modes forbid (G93, feed 0, G18/G19 rotated, G84/G86 without the
            spindle), a bad L or Q word, a missing R or hole bottom, or a bottom above R.
        """
        self._check_modes(code, state)
        normal = PLANE_AXES[state.plane][2]
        letter = "xyz"[normal]
        repeats = words.get("l", 1.0)
        if not 1 <= repeats <= MAX_CYCLE_REPEATS or repeats != int(repeats):
            raise self._where.error(
                f"canned cycle repeat L{repeats:g} must be a whole number from 1 to "
                f"{MAX_CYCLE_REPEATS}"
            )
        self._check_spindle(code, state.spindle_direction)
        r_word, bottom_word = self._levels(code, words, letter, factor)
        if code in (73, 83):
            if "q" in words:
                self.peck_mm = words["q"] * factor
            if self.peck_mm <= 0:
                raise self._where.error(f"G{code} needs Q<peck depth> > 0")
        if "p" in words:
            self.dwell_s = words["p"]
        if incremental:
            r_mm = level_mm + r_word
            bottom_mm = r_mm + bottom_word
        else:
            r_mm = r_word + offset_mm
            bottom_mm = bottom_word + offset_mm
        if bottom_mm > r_mm:
            raise self._where.error(
                f"canned cycle G{code}: hole bottom {letter.upper()} is above the R plane"
            )
        start = max(level_mm, r_mm)
        spec = CycleSpec(
            code,
            normal,
            r_mm,
            bottom_mm,
            r_mm if self.retract_to_r else start,
            self.peck_mm,
            self.dwell_s if code in (82, 84, 86, 89) else 0.0,
            state.spindle_direction or 1,
        )
        return spec, int(repeats)

    def check_size(self, spec: CycleSpec, repeats: int) -> None:
        """Refuse a cycle block of more than
        :data:`~cnctwin.nc.limits.MAX_SEGMENTS_PER_BLOCK` moves."""
        moves = repeats * (3 * peck_count(spec) + 6)
        if moves > MAX_SEGMENTS_PER_BLOCK:
            raise self._where.error(
                f"canned cycle G{spec.code} L{repeats:g} would make about {moves} moves in one "
                f"block; at most {MAX_SEGMENTS_PER_BLOCK} are allowed (fewer repeats or "
                "larger Q pecks)"
            )

    def _check_modes(self, code: int, state: MachineState) -> None:
        if state.plane != Plane.XY and state.xy_rotation_deg:
            raise self._where.error(
                f"canned cycle G{code} in G18/G19 with a rotated coordinate system is not supported"
            )
        if state.feed_mode == FeedMode.INVERSE_TIME:
            raise self._where.error(
                f"canned cycle G{code} cannot run in G93 inverse time mode: use G94 or G95"
            )
        if state.programmed_feed <= 0.0:
            raise self._where.error(
                f"canned cycle G{code} with feed rate 0: program F (e.g. F100) first"
            )

    def _check_spindle(self, code: int, direction: int) -> None:
        if code == 84 and direction != 1:
            raise self._where.error(
                "G84 right-hand tapping needs the spindle turning clockwise (M3) before the cycle"
            )
        if code == 86 and direction == 0:
            raise self._where.error("G86 boring needs the spindle turning (M3/M4) before the cycle")

    def _levels(
        self, code: int, words: dict[str, float], letter: str, factor: float
    ) -> tuple[float, float]:
        """The R and hole-bottom words in mm, from the block or the sticky ones."""
        if "r" in words:
            r_word = words["r"] * factor
        elif self.r_word_mm is not None:
            r_word = self.r_word_mm
        else:
            raise self._where.error(f"canned cycle G{code} needs an R word (retract plane)")
        if letter in words:
            bottom_word = words[letter] * factor
        elif self.bottom_word_mm is not None:
            bottom_word = self.bottom_word_mm
        else:
            raise self._where.error(
                f"canned cycle G{code} needs a {letter.upper()} word (hole bottom)"
            )
        self.r_word_mm = r_word
        self.bottom_word_mm = bottom_word
        return r_word, bottom_word
