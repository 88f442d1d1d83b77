"""Benchmark of the signal prediction (``cnctwin signals``): cost per cycle and real-time factor.

Usage: ``python benchmarks/bench_signals.py [--quick]``. Prints a Markdown table for
docs/benchmarks.md. The program is the KIT notch cut in miniature: a 10 mm 4-flute end mill,
S3800 F350, a full slot then a contour (three sides of a square) in passes of 6 mm depth,
through a block at 10 dexels/mm and 12.5 ms cycles (AA6060-T6 coefficients, the
machining-centre spindle preset). Rows:

* ``immersion intervals``: converting one step's dexel engagement (60 slices) for the force model;
* ``step forces``: that plus the mean forces and the 360-angle peak force of the step;
* ``cut only`` and ``cut + signals``: the whole program, as simulated seconds per wall second.

Each figure is the best of several repetitions after a warm-up (numba compiles or loads its
kernels). ``--quick`` runs one short pass in a few seconds, to prove the script still runs.
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Callable

from cnctwin.drives import spindle_preset
from cnctwin.geometry import Cutter, DexelStock
from cnctwin.mechanics import milling_material
from cnctwin.nc import Interpreter, NCSetup
from cnctwin.simulation import (
    CutStep,
    immersion_intervals,
    simulate_cut,
    simulate_signals,
    step_forces,
)

CUTTER = Cutter.flat(diameter_mm=10.0, flute_length_mm=22.0, flutes=4, helix_rad=0.5236)
COEFFICIENTS = milling_material("AA6060-T6").coefficients
DRIVE = spindle_preset("machining-centre-15kw")


def program(passes: int) -> str:
    """Slot along y = 40 from x = -10 to 60, then around three sides of a square, per pass."""
    lines = ["G21 G90 G17", "T1 M6", "S3800 M3", "G0 X-10 Y40 Z5"]
    for k in range(1, passes + 1):
        lines += [f"G0 Z{-6 * k}", "G1 X60 F350", "G1 Y10", "G1 X20", "G1 X-10 Y40"]
    return "\n".join([*lines, "G0 Z5", "M5", "M30", ""])


def stock() -> DexelStock:
    return DexelStock.box((0.0, 0.0, -30.0), (50.0, 80.0, 0.0), density_per_mm=10.0)


def best_of(repeats: int, fn: Callable[[], object]) -> float:
    """Smallest wall time of ``repeats`` calls of ``fn``, s."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def slot_step() -> CutStep:
    """A step in the middle of the first pass's slot (6 mm deep, 60 slices)."""
    found: list[CutStep] = []

    def keep(step: CutStep) -> None:
        if not found and step.tcp_mm[0] > 25.0:
            found.append(step)

    for _ in simulate_cut(
        Interpreter(NCSetup()).run_text(program(1)), stock(), {1: CUTTER},
        rapid_mm_min=10_000.0, on_step=keep,
    ):  # fmt: skip
        if found:
            break
    return found[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a short run, to check it runs")
    args = parser.parse_args()
    passes, repeats, calls = (1, 1, 200) if args.quick else (3, 3, 2000)
    pitch = stock().grid.pitch_mm[2]
    step = slot_step()
    step_forces(step, COEFFICIENTS, pitch)  # warm-up
    rows = []
    wall = best_of(
        repeats, lambda: [immersion_intervals(step.engagement, pitch) for _ in range(calls)]
    )
    rows.append(("immersion intervals (60 slices)", f"{wall / calls * 1e6:.1f} us per step"))
    wall = best_of(repeats, lambda: [step_forces(step, COEFFICIENTS, pitch) for _ in range(calls)])
    rows.append(("step forces (means + 360-angle peak)", f"{wall / calls * 1e6:.0f} us per step"))
    text = program(passes)
    simulated = 0.0

    def cut_only() -> None:
        nonlocal simulated
        for rows_ in simulate_cut(
            Interpreter(NCSetup()).run_text(text), stock(), {1: CUTTER}, rapid_mm_min=10_000.0
        ):
            simulated = float(rows_[-1, 0]) + 0.0125

    def signals() -> None:
        simulate_signals(
            Interpreter(NCSetup()).run_text(text), stock(), {1: CUTTER}, COEFFICIENTS, DRIVE,
            rapid_mm_min=10_000.0,
        )  # fmt: skip

    wall = best_of(repeats, cut_only)
    rows.append((f"cut only ({simulated:.0f} s program)", f"{simulated / wall:.0f}x real time"))
    wall = best_of(repeats, signals)
    rows.append(
        (f"cut + signals ({simulated:.0f} s program)", f"{simulated / wall:.0f}x real time")
    )
    print(f"Signal prediction, {platform.processor() or platform.machine()}, "
          f"Python {platform.python_version()}{' (quick)' if args.quick else ''}\n")  # fmt: skip
    print("| case | figure |")
    print("|---|---|")
    for case, figure in rows:
        print(f"| {case} | {figure} |")


if __name__ == "__main__":
    main()
