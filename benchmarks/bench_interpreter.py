"""Benchmark: NC interpretation speed and memory.

Measures lines per second (CPU time of this process) and peak resident memory for
(1) a generated CAM-style program of N lines (default 1,000,000; --quick: 20,000) and
(2) the real program 3D_Chips.ngc when the shared data folder is present.
Memory is measured in child processes so that the two sizes can be compared: a flat
profile means the peak does not grow with the program's length.

Usage::

    python benchmarks/bench_interpreter.py [--quick] [--lines N]
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import write_program

REPO = Path(__file__).resolve().parents[1]


def _interpret(path: str) -> tuple[int, int, float]:
    from cnctwin.nc import Interpreter

    interp = Interpreter()
    start = time.process_time()
    segments = sum(1 for _ in interp.run_file(path))
    return interp.lines_read, segments, time.process_time() - start


def _child(path: str) -> None:
    lines, segments, seconds = _interpret(path)
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(f"{lines} {segments} {seconds} {peak_kib}")


def measure(path: Path) -> tuple[int, int, float, float]:
    """(lines, segments, cpu seconds, peak RSS MiB) in a fresh process."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    out = subprocess.run(
        [sys.executable, __file__, "--child", str(path)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    ).stdout.split()
    return int(out[0]), int(out[1]), float(out[2]), int(out[3]) / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, a few seconds")
    parser.add_argument("--lines", type=int, default=None, help="lines of the large program")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.child)
        return
    large = args.lines or (20_000 if args.quick else 1_000_000)
    small = max(large // 10, 1000)
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}"
    )
    print("| program | lines | segments | lines/s | peak RSS (MiB) |")
    print("|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in (small, large):
            path = Path(tmp) / f"generated_{n}.ngc"
            write_program(path, n)
            lines, segments, seconds, peak = measure(path)
            print(
                f"| generated CAM-style | {lines} | {segments} | {lines / seconds:,.0f} | "
                f"{peak:.1f} |"
            )
    data = Path(os.environ.get("CNCTWIN_DATA") or REPO.parent / "shared" / "data")
    chips = data / "gcode" / "linuxcnc" / "3D_Chips.ngc"
    if chips.exists():
        lines, segments, seconds, peak = measure(chips)
        print(f"| 3D_Chips.ngc | {lines} | {segments} | {lines / seconds:,.0f} | {peak:.1f} |")
    else:
        print(f"(3D_Chips.ngc not found under {data}: skipped)")


if __name__ == "__main__":
    main()
