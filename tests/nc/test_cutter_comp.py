"""Tests of cutter radius compensation (cnctwin.nc.cutter_comp).

Three kinds of checks:

1. closed forms on hand-built paths (squares offset outward and inward, arcs, tangent
   junctions, the errors);
2. LinuxCNC oracles driven by paths taken from the oracle itself: the programmed path
   is the uncompensated (or zero-radius) run of the same trace, or built by hand for the
   short ccomp programs; the compensated run of the trace is the expectation;
3. the same oracles end to end through the lead's interpreter, once
   ``cnctwin.nc.interpreter`` exists (skipped until then).

The traces print 4 decimals in program units, so positions are compared to 1e-4
program units (the printing error is 5e-5) unless a test says why it needs more.
"""

from __future__ import annotations

import importlib.util
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from cnctwin.errors import NCError
from cnctwin.nc.cutter_comp import CutterCompensator
from cnctwin.nc.segments import (
    PLANE_AXES,
    CutterComp,
    MachineState,
    MotionKind,
    Plane,
    Segment,
    Vec3,
)

MM_PER_INCH = 25.4


# --------------------------------------------------------------------------- data


def _data_dir() -> Path | None:
    env = os.environ.get("CNCTWIN_DATA")
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[3] / "shared" / "data")
    candidates.append(Path(__file__).resolve().parents[2] / ".." / "shared" / "data")
    for cand in candidates:
        if (cand / "gcode_golden").is_dir():
            return cand
    return None


def _golden(*parts: str) -> Path:
    base = _data_dir()
    if base is None:
        if os.environ.get("CNCTWIN_REQUIRE_DATA") == "1":
            pytest.fail("shared data folder not found (CNCTWIN_REQUIRE_DATA=1)")
        pytest.skip("shared data folder (../shared/data or $CNCTWIN_DATA) not found")
    return base.joinpath("gcode_golden", "linuxcnc", *parts)


# --------------------------------------------------------------------------- canonical traces


@dataclass(frozen=True)
class Move:
    """One motion of a LinuxCNC canonical trace, in machine coordinates and mm."""

    kind: str  # "traverse", "feed" or "arc"
    start: Vec3
    end: Vec3
    centre: Vec3 | None
    turns: int
    plane: Plane
    tol_mm: float  # 1e-4 program units, in mm


@dataclass
class Trace:
    """Motions of a trace, with the compensation comments as markers."""

    items: list[Move | str] = field(default_factory=list)


_CALL = re.compile(r"^\s*N\.+\s+([A-Z_]+)\((.*)\)\s*$")
_PLANES = {"CANON_PLANE_XY": Plane.XY, "CANON_PLANE_XZ": Plane.ZX, "CANON_PLANE_YZ": Plane.YZ}


def read_trace(path: Path) -> Trace:
    """Parse a LinuxCNC canonical-call trace into moves in machine mm.

    Tracks USE_LENGTH_UNITS, SET_G5X_OFFSET, SET_G92_OFFSET, USE_TOOL_LENGTH_OFFSET and
    SELECT_PLANE; the positions a trace prints are in program units in the program frame.
    Compensation comments ``"on left"``, ``"on right"`` and ``"off"`` are kept as markers.
    """
    trace = Trace()
    scale = 1.0
    g5x = g92 = tlo = (0.0, 0.0, 0.0)
    plane = Plane.XY
    pos: Vec3 = (0.0, 0.0, 0.0)
    for line in path.read_text().splitlines():
        m = _CALL.match(line)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            scale = MM_PER_INCH if "INCHES" in args else 1.0
        elif name == "SELECT_PLANE":
            plane = _PLANES[args.strip()]
        elif name == "COMMENT" and "cutter radius compensation" in args:
            trace.items.append(args.strip('"').rsplit(" ", 1)[-1])
        elif name in ("SET_G5X_OFFSET", "SET_G92_OFFSET", "USE_TOOL_LENGTH_OFFSET"):
            nums = [float(v) for v in re.split(r"[,\s]+", args.strip()) if v]
            xyz = nums[1:4] if name == "SET_G5X_OFFSET" else nums[0:3]
            off = (xyz[0] * scale, xyz[1] * scale, xyz[2] * scale)
            if name == "SET_G5X_OFFSET":
                g5x = off
            elif name == "SET_G92_OFFSET":
                g92 = off
            else:
                tlo = off
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED"):
            v = [float(x) for x in args.split(",")]
            shift = tuple(g5x[i] + g92[i] + tlo[i] for i in range(3))

            def machine(p: list[float], shift: tuple[float, ...] = shift) -> Vec3:
                return (p[0] * scale + shift[0], p[1] * scale + shift[1], p[2] * scale + shift[2])

            if name == "ARC_FEED":
                i0, i1, i2 = PLANE_AXES[plane]
                e = [0.0, 0.0, 0.0]
                c = [0.0, 0.0, 0.0]
                e[i0], e[i1], e[i2] = v[0], v[1], v[5]
                c[i0], c[i1] = v[2], v[3]
                end = machine(e)
                cm = list(machine(c))
                cm[i2] = pos[i2]
                move = Move("arc", pos, end, (cm[0], cm[1], cm[2]), int(v[4]), plane, 1e-4 * scale)
            else:
                kind = "traverse" if name == "STRAIGHT_TRAVERSE" else "feed"
                end = machine(v[0:3])
                move = Move(kind, pos, end, None, 0, plane, 1e-4 * scale)
            trace.items.append(move)
            pos = end
    return trace


@dataclass
class Block:
    """A run of a trace between two ``off`` markers."""

    side: str | None  # "left", "right" or None (no "on" marker: compensation was never on)
    before: Vec3  # position when compensation went on
    comp: list[Move]  # moves while compensation is on
    exit: Move | None  # the first move after ``off``


def comp_blocks(trace: Trace) -> list[Block]:
    """Split a trace at its ``off`` markers; blocks without moves are dropped.

    A block's compensated moves follow its ``on`` marker; a block without one (a run
    where the program skipped G41.1 for a zero diameter) starts after its last rapid.
    """
    blocks: list[Block] = []
    items = trace.items
    off_idx = [i for i, it in enumerate(items) if it == "off"]
    prev = -1
    for k in off_idx:
        seg = items[prev + 1 : k]
        on = [i for i, it in enumerate(seg) if it in ("left", "right")]
        if on:
            side: str | None = str(seg[on[-1]])
            body = seg[on[-1] + 1 :]
        else:
            side = None
            trav = [i for i, it in enumerate(seg) if isinstance(it, Move) and it.kind == "traverse"]
            body = seg[trav[-1] + 1 :] if trav else []
        moves = [m for m in body if isinstance(m, Move)]
        nxt = next((it for it in items[k + 1 :] if isinstance(it, Move)), None)
        if moves:
            blocks.append(Block(side, moves[0].start, moves, nxt))
        prev = k
    return blocks


# --------------------------------------------------------------------------- building segments


def _state(plane: Plane = Plane.XY, units: str = "mm") -> MachineState:
    return MachineState(units=units, plane=plane)  # type: ignore[arg-type]


def seg_from_move(move: Move, line: int = 0, feed: float = 100.0) -> Segment:
    """The Segment a trace move describes (its start is the previous end)."""
    kind = {"traverse": MotionKind.RAPID, "feed": MotionKind.LINEAR, "arc": MotionKind.ARC}[move.kind]
    return Segment(
        kind=kind,
        line=line,
        start_mm=move.start,
        end_mm=move.end,
        feed_mm_min=0.0 if kind == MotionKind.RAPID else feed,
        spindle_rpm=0.0,
        state=_state(move.plane),
        center_mm=move.centre,
        turns=move.turns,
    )


class PathBuilder:
    """Hand-built programmed path in one plane, in program units (scaled to mm).

    ``line(end)`` and ``arc(end, centre, turns)`` take (x, y, z) of the program frame;
    the frame origin ``origin`` (work offset) is in program units too.
    """

    def __init__(self, start: Vec3, units: str = "mm", plane: Plane = Plane.XY, origin: Vec3 = (0, 0, 0)):
        self.k = MM_PER_INCH if units == "inch" else 1.0
        self.units = units
        self.plane = plane
        self.origin = origin
        self.pos = self.mm(start)
        self.segs: list[Segment] = []

    def mm(self, p: Vec3) -> Vec3:
        return ((p[0] + self.origin[0]) * self.k, (p[1] + self.origin[1]) * self.k, (p[2] + self.origin[2]) * self.k)

    def _add(self, kind: MotionKind, end: Vec3, centre: Vec3 | None = None, turns: int = 0) -> None:
        e = self.mm(end)
        c = None
        if centre is not None:
            c3 = list(self.mm(centre))
            c3[PLANE_AXES[self.plane][2]] = self.pos[PLANE_AXES[self.plane][2]]
            c = (c3[0], c3[1], c3[2])
        self.segs.append(
            Segment(
                kind=kind,
                line=len(self.segs) + 1,
                start_mm=self.pos,
                end_mm=e,
                feed_mm_min=0.0 if kind == MotionKind.RAPID else 100.0 + len(self.segs),
                spindle_rpm=1000.0,
                state=_state(self.plane, self.units),
                center_mm=c,
                turns=turns,
            )
        )
        self.pos = e

    def rapid(self, end: Vec3) -> PathBuilder:
        self._add(MotionKind.RAPID, end)
        return self

    def line(self, end: Vec3) -> PathBuilder:
        self._add(MotionKind.LINEAR, end)
        return self

    def arc(self, end: Vec3, centre: Vec3, turns: int) -> PathBuilder:
        self._add(MotionKind.ARC, end, centre, turns)
        return self


def run_comp(
    segs: list[Segment],
    side: CutterComp,
    radius_mm: float,
    plane: Plane = Plane.XY,
    start: Vec3 | None = None,
    orientation: int = 0,
) -> list[Segment]:
    """Push ``segs`` through a compensator and finish it."""
    comp = CutterCompensator(side, radius_mm, plane, start if start is not None else segs[0].start_mm, orientation)
    out: list[Segment] = []
    for s in segs:
        out.extend(comp.push(s))
    out.extend(comp.finish())
    return out


def exit_move(after: list[Segment], programmed: Segment) -> Segment:
    """The exit move after G40: from the last compensated point to the programmed end."""
    start = after[-1].end_mm
    return Segment(
        kind=programmed.kind,
        line=programmed.line,
        start_mm=start,
        end_mm=programmed.end_mm,
        feed_mm_min=programmed.feed_mm_min,
        spindle_rpm=programmed.spindle_rpm,
        state=programmed.state,
        center_mm=programmed.center_mm,
        turns=programmed.turns,
    )


# --------------------------------------------------------------------------- comparing


def _close(a: Vec3, b: Vec3, tol: float) -> bool:
    return all(abs(a[i] - b[i]) <= tol for i in range(3))


def mismatch(got: list[Segment], expected: list[Move]) -> str | None:
    """Why ``got`` differs from ``expected`` (None when they agree)."""
    kinds = {MotionKind.RAPID: "traverse", MotionKind.LINEAR: "feed", MotionKind.ARC: "arc"}
    lines = []
    for i in range(max(len(got), len(expected))):
        g = got[i] if i < len(got) else None
        e = expected[i] if i < len(expected) else None
        if g is None or e is None:
            lines.append(f"#{i}: got {g and (kinds[g.kind], g.end_mm)} expected {e and (e.kind, e.end)}")
            break
        tol = e.tol_mm + 1e-9
        ok = kinds[g.kind] == e.kind and _close(g.end_mm, e.end, tol) and _close(g.start_mm, e.start, tol)
        if ok and e.kind == "arc":
            assert g.center_mm is not None and e.centre is not None
            ok = g.turns == e.turns and _close(g.center_mm, e.centre, tol)
        if not ok:
            lines.append(
                f"#{i}: got {kinds[g.kind]} {_fmt(g.start_mm)}->{_fmt(g.end_mm)} c={g.center_mm and _fmt(g.center_mm)} "
                f"t={g.turns}; expected {e.kind} {_fmt(e.start)}->{_fmt(e.end)} c={e.centre and _fmt(e.centre)} t={e.turns}"
            )
            break
    return "\n".join(lines) or None


def _fmt(p: Vec3) -> str:
    return "(" + ", ".join(f"{v:.4f}" for v in p) + ")"
