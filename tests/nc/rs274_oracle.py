"""Run LinuxCNC's standalone interpreter ``rs274`` and compare its canonical calls with ours.

``rs274`` (Debian package ``linuxcnc-uspace``) prints one canonical machining call a line,
lengths in the program's units (after ``USE_LENGTH_UNITS``) and in the program frame, which
is what :func:`cnctwin.nc.trace.canonical_moves` produces. Two ``rs274`` processes at once
corrupt each other's tool table in shared memory, so every run holds an exclusive lock on
one file in the temporary directory (pytest-xdist runs workers in parallel).
"""

from __future__ import annotations

import fcntl
import re
import shutil
import subprocess
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from skips import missing

from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.segments import FeedMode
from cnctwin.nc.setup import NCSetup
from cnctwin.nc.tool_table import parse_tool_table
from cnctwin.nc.trace import canonical_moves

#: Canonical calls compared number by number.
MOVES = ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED")
#: rs274 prints 4 decimals: half a printed digit plus float noise, in program units.
TOLERANCE = 1.5e-4
#: A whole run of rs274 on the largest sample takes well under a second; generous for a
#: machine oversubscribed by parallel test workers.
TIMEOUT_S = 120.0

_CALL = re.compile(r"^\s*\d+\s+N[\d.]*\s+([A-Z_0-9]+)\((.*)\)\s*$")
_LOCK = Path(tempfile.gettempdir()) / "cnctwin-rs274.lock"

#: The tool table both interpreters use unless a test gives its own: T1-T99 in pockets
#: 1-99, zero length and diameter (rs274 refuses a T word missing from its table).
DEFAULT_TOOLS = "".join(f"T{n} P{n} D0 Z0\n" for n in range(1, 100))


@pytest.fixture(scope="session", name="rs274")
def rs274_fixture() -> str:
    """Path of LinuxCNC's ``rs274``; skip (fail in CI) when it is not installed."""
    found = shutil.which("rs274")
    if found is None:
        missing(
            "LinuxCNC's rs274 is not installed (apt-get install linuxcnc-uspace)",
            "CNCTWIN_REQUIRE_SERVICES",
        )
    return str(found)


@dataclass
class Run:
    """What one interpreter did with a program, in the program's units.

    ``moves``: (call, values, feed) of every traverse, feed and arc that moves the tool
    (LinuxCNC also prints zero-length traverses, e.g. a canned cycle's rapid to the R plane
    it is already at; cnctwin makes no segment for them, so both lists leave them out);
    ``feed`` is the rate in units/min of a feed move, ``None`` for a traverse or outside
    units-per-minute mode;
    ``error``: the message that stopped the program, empty if none.
    """

    moves: list[tuple[str, tuple[float, ...], float | None]] = field(default_factory=list)
    error: str = ""

    def add(self, name: str, values: tuple[float, ...], feed: float | None) -> None:
        """Append a move unless it is a traverse that ends where the straight move before did.

        Only traverses: CAM programs hold feed moves shorter than the 4 printed decimals.
        """
        rapid = name == "STRAIGHT_TRAVERSE" and self.moves and self.moves[-1][0] != "ARC_FEED"
        if rapid and _printed(values) == _printed(self.moves[-1][1]):
            return
        self.moves.append((name, values, None if name == "STRAIGHT_TRAVERSE" else feed))


def run_rs274(executable: str, program: Path, tools: str = DEFAULT_TOOLS) -> Run:
    """Interpret ``program`` with LinuxCNC's ``rs274`` (inch tool table text ``tools``)."""
    with tempfile.TemporaryDirectory() as work:
        table = Path(work) / "tools.tbl"
        table.write_text(tools)
        with _LOCK.open("w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            done = subprocess.run(
                [executable, "-g", "-t", str(table), str(program)],
                capture_output=True,
                text=True,
                stdin=subprocess.DEVNULL,
                cwd=work,
                timeout=TIMEOUT_S,
                check=False,
            )
    result = Run()
    feed: float | None = 0.0
    per_minute = True
    errors = [line.strip() for line in done.stderr.splitlines() if line.strip() != "executing"]
    for raw in done.stdout.splitlines():
        found = _CALL.match(raw)
        if not found:
            if raw.strip() and raw.strip() != "executing":
                errors.append(raw.strip())
            continue
        name, args = found.groups()
        if name == "SET_FEED_MODE":
            per_minute = args.split(",")[0].strip() == "0"
        elif name == "SET_FEED_RATE":
            feed = float(args)
        elif name == "RIGID_TAP" and result.moves:
            # G33.1: in to (x, y, z) and back out along the same line, spindle-synchronised.
            start = result.moves[-1][1][:6]
            bottom = (*(float(v) for v in args.split(",")), *start[3:])
            result.add("STRAIGHT_FEED", bottom, None)
            result.add("STRAIGHT_FEED", start, None)
        elif name in MOVES:
            result.add(name, tuple(float(v) for v in args.split(",")), feed if per_minute else None)
    if done.returncode != 0:
        result.error = " | ".join(errors[:2]) or f"exit code {done.returncode}"
    return result


def run_cnctwin(program: Path, tools: str = DEFAULT_TOOLS) -> Run:
    """Interpret ``program`` with cnctwin's interpreter and the same tool table."""
    setup = NCSetup(tools=parse_tool_table(tools, units="inch", source="tools.tbl"))
    result = Run()
    segments = []
    try:
        for segment in Interpreter(setup).run_file(program):
            segments.append(segment)
    except Exception as err:  # noqa: BLE001 - the test reports it next to rs274's
        result.error = str(err)
    for segment, move in zip(segments, canonical_moves(segments), strict=True):
        if move.name not in MOVES:
            continue
        state = segment.state
        per_minute = state.feed_mode == FeedMode.UNITS_PER_MINUTE
        result.add(move.name, move.values, state.programmed_feed if per_minute else None)
    return result


def first_difference(ours: Run, theirs: Run) -> str:
    """A description of the first move or feed that differs, or ``""`` if all agree."""
    for index, ((name, values, feed), (name_l, values_l, feed_l)) in enumerate(
        zip(ours.moves, theirs.moves, strict=False)
    ):
        if name != name_l or len(values) != len(values_l) or _far(values, values_l):
            return (
                f"move {index + 1}: cnctwin {name}{_fmt(values)}, LinuxCNC {name_l}{_fmt(values_l)}"
            )
        if feed is not None and feed_l is not None and abs(feed - feed_l) > TOLERANCE:
            return f"move {index + 1}: cnctwin F{feed:.4f}, LinuxCNC F{feed_l:.4f}"
    if len(ours.moves) != len(theirs.moves):
        return f"cnctwin made {len(ours.moves)} moves, LinuxCNC {len(theirs.moves)}"
    return ""


def _far(a: Iterable[float], b: Iterable[float]) -> bool:
    return any(abs(x - y) > TOLERANCE for x, y in zip(a, b, strict=True))


def _printed(values: Iterable[float]) -> tuple[str, ...]:
    """Values as rs274 prints them (4 decimals)."""
    return tuple(f"{round(v, 4) + 0.0:.4f}" for v in values)


def _fmt(values: Iterable[float]) -> str:
    return "(" + ", ".join(f"{v:.4f}" for v in values) + ")"
