"""Benchmark: ``cnctwin nc inspect --json`` and ``cnctwin nc trace`` against LinuxCNC's
``rs274``, end to end.

The interpreters run as whole processes on the same generated programs, one after the
other in one run: ``cnctwin nc inspect --json FILE`` (start-up, imports, interpretation,
summary, JSON), ``cnctwin nc trace FILE`` (start-up, interpretation, one printed canonical
call per move, as rs274 prints them) and ``rs274 -g -t TOOLTABLE FILE`` (start-up,
interpretation, one printed canonical call per move); printed output goes to
``/dev/null``. For each, the CPU time (user + system, from ``os.wait4`` of that child
alone) and its peak RSS are reported, with lines per CPU second and the ratios cnctwin /
rs274 of lines/s (above 1: cnctwin is faster).
CPU time, not wall time, because the benchmark machine is shared and loaded.

Programs (lines are lines of the file; a loop body counts once):
``lines`` (G1 X Y moves), ``arcs`` (G2/G3 with I J centres), ``mixed`` (two G1 lines, a G3
and a G2 in turn, as CAM output alternates them), ``expressions`` (``#``
parameters, functions, an O-word ``if`` and a ``repeat`` loop in every block of 10 lines)
and, when the shared data folder is present, ``3D_Chips.ngc``.

cnctwin's bytecode is compiled first, as an installation does. When the NC interpreter is
installed compiled (``CNCTWIN_COMPILE=1``, docs/nc.md), cnctwin also runs on its sources
(``CNCTWIN_PURE_PYTHON=1``) in the same run, and the report gives both.
When ``rs274`` is not installed, cnctwin is measured alone and the report says so.
Like the test suite, ``rs274`` runs hold an exclusive lock so that two never run at once
(two at once corrupt each other's tool table in shared memory).

Usage::

    python benchmarks/bench_nc_vs_rs274.py [--quick] [--lines N] [--repeat K]
"""

from __future__ import annotations

import argparse
import compileall
import fcntl
import os
import platform
import random
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from _common import cnctwin_command, run_measured

import cnctwin as cnctwin_package
from cnctwin.nc import compiled_modules

REPO = Path(__file__).resolve().parents[1]
LOCK = Path(tempfile.gettempdir()) / "cnctwin-rs274.lock"
#: T1-T9 in pockets 1-9, zero length and diameter (rs274 refuses a T word not in its table).
TOOLS = "".join(f"T{n} P{n} D0 Z0\n" for n in range(1, 10))
HEADER = "%\nG21 G90 G17 G94\nT1 M6\nS12000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F1200\n"
FOOTER = "G0 Z5\nM5\nM30\n%\n"


def write_lines(path: Path, lines: int, seed: int = 1) -> None:
    """Straight feed moves: ``G1 X.. Y..`` (every tenth with a new F)."""
    rng = random.Random(seed)
    x = y = 0.0
    with path.open("w") as out:
        out.write(HEADER)
        for i in range(lines - 10):
            x += rng.uniform(-1.0, 1.0)
            y += rng.uniform(-1.0, 1.0)
            feed = f" F{1000 + i % 500}" if i % 10 == 0 else ""
            out.write(f"G1 X{x:.3f} Y{y:.3f}{feed}\n")
        out.write(FOOTER)


def write_arcs(path: Path, lines: int, seed: int = 2) -> None:
    """Half circles of radius 1-3 mm, centres given by I J: a G3 out along X and a G2
    back to the start, so that the program stays in a few mm whatever its length."""
    rng = random.Random(seed)
    with path.open("w") as out:
        out.write(HEADER)
        r = 1.0
        for i in range(lines - 10):
            if i % 2 == 0:
                r = 1.0 + 2.0 * rng.random()
                out.write(f"G3 X{2 * r:.4f} Y0 I{r:.4f} J0\n")
            else:
                out.write(f"G2 X0 Y0 I{-r:.4f} J0\n")
        out.write(FOOTER)


def write_mixed(path: Path, lines: int, seed: int = 3) -> None:
    """CAM output alternating straight moves and arcs: two ``G1 X.. Y..`` lines, then a half
    circle out along X (``G3 ... I J``) and back (``G2 ... I J``): no run of one kind of line
    is longer than two lines (bulk runs take both kinds together)."""
    rng = random.Random(seed)
    x = y = r = 0.0
    with path.open("w") as out:
        out.write(HEADER)
        for i in range(lines - 10):
            kind = i % 4
            if kind < 2:
                x = round(x + rng.uniform(-1.0, 1.0), 3)
                y = round(y + rng.uniform(-1.0, 1.0), 3)
                out.write(f"G1 X{x:.3f} Y{y:.3f}\n")
            elif kind == 2:
                r = round(1.0 + 2.0 * rng.random(), 3)
                out.write(f"G3 X{x + 2 * r:.3f} Y{y:.3f} I{r:.3f} J0\n")
            else:
                out.write(f"G2 X{x:.3f} Y{y:.3f} I{-r:.3f} J0\n")
        out.write(FOOTER)


def write_expressions(path: Path, lines: int) -> None:
    """Blocks of 10 lines: parameter assignments, functions, an O-word if and a repeat
    (labels unique: LinuxCNC refuses a label defined twice)."""
    with path.open("w") as out:
        out.write(HEADER + "#1 = 0\n#3 = 0\n")
        for n in range((lines - 12) // 10):
            out.write(
                "#1 = [#1 + 0.25]\n"
                "#2 = [SIN[#1 * 3] * 10 + COS[#1] * 2]\n"
                "G1 X[#1] Y[#2] F[1000 + #3 * 10]\n"
                f"o{2 * n + 100} if [#2 GT 5]\n"
                "  #3 = [#3 + 1]\n"
                f"o{2 * n + 100} endif\n"
                f"o{2 * n + 101} repeat [2]\n"
                "  G1 Y[#2 - ABS[#1 MOD 3]]\n"
                f"o{2 * n + 101} endrepeat\n"
                "G0 X[#1 + 0.1] Y[ROUND[#2 * 100] / 100]\n"
            )
        out.write(FOOTER)


PROGRAMS: dict[str, Callable[[Path, int], None]] = {
    "lines": write_lines,
    "arcs": write_arcs,
    "mixed": write_mixed,
    "expressions": write_expressions,
}


def best_of(
    repeat: int, command: list[str], cwd: Path, lock: bool, env: dict[str, str] | None = None
) -> tuple[float, float]:
    """Lowest CPU seconds and peak RSS MiB of ``repeat`` runs (``env``: the children's
    environment, default this one's); raises if one fails."""
    best = (float("inf"), 0.0)
    for _ in range(repeat):
        if lock:
            with LOCK.open("w") as held:
                fcntl.flock(held, fcntl.LOCK_EX)
                seconds, peak, code = run_measured(command, cwd, env)
        else:
            seconds, peak, code = run_measured(command, cwd, env)
        if code != 0:
            raise SystemExit(f"{' '.join(command)} exited with {code}")
        best = min(best, (seconds, peak))
    return best


def count_lines(path: Path) -> int:
    with path.open("rb") as stream:
        return sum(1 for _ in stream)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20,000-line programs, one run")
    parser.add_argument("--lines", type=int, default=None, help="lines of each generated program")
    parser.add_argument("--repeat", type=int, default=None, help="runs of each, best kept")
    args = parser.parse_args()
    lines = args.lines or (20_000 if args.quick else 300_000)
    repeat = args.repeat or (1 if args.quick else 3)
    rs274 = shutil.which("rs274")
    # As installed (pip writes the bytecode): under PYTHONDONTWRITEBYTECODE a package without
    # it would be compiled from source at every start (0.05-0.08 s CPU for `nc inspect`).
    compileall.compile_dir(Path(cnctwin_package.__file__).parent, quiet=1)
    cnctwin = cnctwin_command()
    load = os.getloadavg()
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, load average {load[0]:.2f} {load[1]:.2f} "
        f"{load[2]:.2f}; CPU time, best of {repeat}"
    )
    compiled = compiled_modules()
    print(
        f"cnctwin's NC interpreter: {len(compiled)} modules compiled with mypyc, also run on "
        "its sources (CNCTWIN_PURE_PYTHON=1)"
        if compiled
        else "cnctwin's NC interpreter: pure Python"
    )
    if rs274 is None:
        print("rs274 was not found (apt-get install linuxcnc-uspace): cnctwin measured alone")
    sources = ["| sources inspect CPU s | sources ratio "] if compiled else []
    print(
        "| program | lines | inspect CPU s | inspect lines/s | inspect peak MiB "
        "| trace CPU s | trace peak MiB | rs274 CPU s | rs274 lines/s | rs274 peak MiB "
        f"| inspect ratio | trace ratio {''.join(sources)}|"
    )
    print("|---|" + "---:|" * (11 + (2 if compiled else 0)))
    pure_env = {**os.environ, "CNCTWIN_PURE_PYTHON": "1"}  # docs/nc.md
    data = Path(os.environ.get("CNCTWIN_DATA") or REPO.parent / "shared" / "data")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "tools.tbl").write_text(TOOLS)
        files: list[tuple[str, Path]] = []
        for name, write in PROGRAMS.items():
            path = work / f"{name}.ngc"
            write(path, lines)
            files.append((name, path))
        chips = data / "gcode" / "linuxcnc" / "3D_Chips.ngc"
        if chips.exists():
            files.append(("3D_Chips.ngc", chips))
        for name, path in files:
            n = count_lines(path)
            ours, ours_mib = best_of(
                repeat, [*cnctwin, "nc", "inspect", "--json", str(path)], work, False
            )
            traced, traced_mib = best_of(repeat, [*cnctwin, "nc", "trace", str(path)], work, False)
            row = (
                f"| {name} | {n:,} | {ours:.2f} | {n / ours:,.0f} | {ours_mib:.0f} "
                f"| {traced:.2f} | {traced_mib:.0f} "
            )
            if rs274 is None:
                row += "| - | - | - | - | - |"
            else:
                theirs, theirs_mib = best_of(
                    repeat, [rs274, "-g", "-t", "tools.tbl", str(path)], work, True
                )
                row += (
                    f"| {theirs:.2f} | {n / theirs:,.0f} | {theirs_mib:.0f} "
                    f"| {theirs / ours:.2f} | {theirs / traced:.2f} |"
                )
            if compiled:
                pure, _ = best_of(
                    repeat, [*cnctwin, "nc", "inspect", "--json", str(path)], work, False, pure_env
                )
                row += f" {pure:.2f} | {theirs / pure:.2f} |" if rs274 else f" {pure:.2f} | - |"
            print(row, flush=True)


if __name__ == "__main__":
    main()
