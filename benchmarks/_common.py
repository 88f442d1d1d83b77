"""What several benchmarks share: the generated CAM-style NC program, a measured child process.

Not a benchmark itself (CI runs ``benchmarks/bench_*.py --quick``); imported by
``bench_interpreter.py``, ``bench_nc_vs_rs274.py`` and ``bench_nc_consumers.py``.
"""

from __future__ import annotations

import os
import random
import subprocess
import sys
from pathlib import Path

__all__ = ["cnctwin_command", "run_measured", "write_program"]


def _reflect(value: float, low: float, high: float) -> float:
    """``value`` folded back into [low, high] at the edge it crossed (a random walk's step
    of at most ``high - low``)."""
    if value < low:
        return 2.0 * low - value
    if value > high:
        return 2.0 * high - value
    return value


def write_program(
    path: Path,
    lines: int,
    seed: int = 1,
    box: tuple[float, float, float, float] | None = None,
) -> None:
    """A CAM-style 3-axis program of ``lines`` lines: modal XY(Z) moves, feed changes, arcs,
    rapids, comments (T1, Z between -1 and -2 mm, feeds 1000-1499 mm/min).

    Without ``box`` the tool walks at random from X0 Y0 (steps of up to 1 mm per axis) with
    no bound, and every twentieth move is a rapid at the cutting depth. With ``box`` =
    ``(x_min, x_max, y_min, y_max)`` (mm, program coordinates) the walk starts at the box's
    centre and folds back at its edges, and the twentieth move is a feed move: the tool stays
    in the box (arcs of radius 5 mm over chords below 3 mm bulge less than 0.3 mm), and no
    rapid moves through material, so a stock holding the box with the tool's radius to spare
    is cut without a collision; the tool's length is compensated (``G43 H1``: Z is the tip).
    """
    rng = random.Random(seed)
    x = y = 0.0
    if box is not None:
        x, y = (box[0] + box[1]) / 2.0, (box[2] + box[3]) / 2.0
    reposition = "G0" if box is None else "G1"
    tool = "T1 M6" if box is None else "T1 M6 G43 H1"
    with path.open("w") as out:
        out.write(f"%\nO1000 (generated benchmark)\nG21 G90 G17 G94\n{tool}\nS12000 M3\n")
        out.write(f"G0 X{x:g} Y{y:g} Z5\nG1 Z-1 F1200\n")
        for i in range(lines - 10):
            x += rng.uniform(-1.0, 1.0)
            y += rng.uniform(-1.0, 1.0)
            if box is not None:
                x, y = _reflect(x, box[0], box[1]), _reflect(y, box[2], box[3])
            kind = i % 20
            if kind < 15:
                out.write(f"X{x:.3f} Y{y:.3f}\n")
            elif kind < 17:
                out.write(f"G1 X{x:.3f} Y{y:.3f} Z{-1.0 - rng.random():.3f} F{1000 + i % 500}\n")
            elif kind < 18:
                out.write(f"N{i} G1 X{x:.3f} Y{y:.3f}\n")
            elif kind < 19:
                out.write(f"G2 X{x:.3f} Y{y:.3f} R5.\n")
            else:
                out.write(f"{reposition} X{x:.3f} Y{y:.3f} (reposition)\n")
        out.write("G0 Z5\nM5\nM30\n%\n")


def run_measured(
    command: list[str],
    cwd: Path,
    env: dict[str, str] | None = None,
    stdout_to: Path | None = None,
    stderr_to: Path | None = None,
) -> tuple[float, float, int]:
    """(CPU seconds, peak RSS MiB, exit code) of one child process (user + system time and
    ``ru_maxrss`` from ``os.wait4`` of that child alone); its output is discarded, or its
    standard output and error written to the files ``stdout_to`` and ``stderr_to``. ``env``:
    the child's environment (default: this one's)."""
    with open(stdout_to or os.devnull, "w") as sink, open(stderr_to or os.devnull, "w") as errs:
        proc = subprocess.Popen(
            command,
            cwd=cwd,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=sink,
            stderr=errs,
        )
        _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0, proc.returncode


def cnctwin_command() -> list[str]:
    """The ``cnctwin`` console script next to this Python, else ``python -m cnctwin``."""
    script = Path(sys.executable).with_name("cnctwin")
    return [str(script)] if script.exists() else [sys.executable, "-m", "cnctwin"]
