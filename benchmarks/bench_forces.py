"""Benchmark of the milling force model: mean forces and per-revolution waveforms.

Usage: ``python benchmarks/bench_forces.py [--quick]``. Prints a Markdown table (one row per
case) for docs/benchmarks.md: the median time of one call, over repeated calls, after a warm-up
(numba kernels compiled and cached, the cutter's slice geometry cached as a running twin has
it). Targets (issue 4): mean forces of one engagement state under 20 us; a waveform over one
revolution at 1 degree with 50 axial slices under 200 us. ``--quick`` repeats less.
"""

from __future__ import annotations

import argparse
import math
import platform
import statistics
import time
from collections.abc import Callable

from cnctwin.geometry import Cutter
from cnctwin.mechanics import (
    CuttingCoefficients,
    ImmersionIntervals,
    flat_end_mill_mean_forces,
    mean_forces,
    milling_forces,
)

K = CuttingCoefficients.from_n_mm(958.8, 251.1, -146.4, 15.75, 19.42, -18.21)
OMEGA = 6000.0 * math.pi / 30.0
FZ = 0.05e-3


def median_us(call: Callable[[], object], repeats: int, batch: int) -> float:
    """Median over ``repeats`` batches of the time of one call, in microseconds."""
    call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(batch):
            call()
        times.append((time.perf_counter() - start) / batch * 1e6)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="few repetitions (CI)")
    args = parser.parse_args()
    repeats, batch = (5, 20) if args.quick else (31, 200)

    slot_cutter = Cutter.flat(25.0, 30.0, flutes=2, helix_rad=math.radians(30))
    slot = ImmersionIntervals.from_depths(slot_cutter, 0.025, 0.003, slices=50)
    four = Cutter.flat(12.0, 30.0, flutes=4, helix_rad=math.radians(35))
    half = ImmersionIntervals.from_depths(four, 0.006, 0.012, down_milling=True, slices=50)
    runout = Cutter("flat", 25.0, 30.0, flutes=2, helix_rad=math.radians(30), runout_mm=0.01)
    ball = Cutter.ball(10.0, 20.0, flutes=2, helix_rad=math.radians(30))
    ball_cut = ImmersionIntervals.from_depths(ball, 0.004, 0.003, slices=50)

    cases: list[tuple[str, str, Callable[[], object]]] = [
        (
            "mean, flat closed form (Altintas)",
            "slot, 2 teeth",
            lambda: flat_end_mill_mean_forces(K, 2, 0.0125, 0.0, math.pi, 0.003, FZ, OMEGA),
        ),
        (
            "mean, per-slice closed form",
            "slot, 2 teeth, 50 slices",
            lambda: mean_forces(slot_cutter, K, slot, FZ, OMEGA),
        ),
        (
            "waveform 360 steps",
            "slot, 2 teeth, 50 slices",
            lambda: milling_forces(slot_cutter, K, slot, FZ, OMEGA),
        ),
        (
            "waveform 360 steps",
            "slot, 2 teeth, 50 slices, runout",
            lambda: milling_forces(runout, K, slot, FZ, OMEGA),
        ),
        (
            "waveform 360 steps",
            "ae = D/2 down, 4 teeth, 50 slices",
            lambda: milling_forces(four, K, half, FZ, OMEGA),
        ),
        (
            "waveform 360 steps",
            "ball nose, 2 teeth, 50 slices",
            lambda: milling_forces(ball, K, ball_cut, FZ, OMEGA),
        ),
    ]
    print(
        f"Python {platform.python_version()}, {platform.machine()}, median of {repeats} x {batch}"
    )
    print()
    print("| computation | case | time per call (us) |")
    print("|---|---|---:|")
    for name, case, call in cases:
        print(f"| {name} | {case} | {median_us(call, repeats, batch):.1f} |")


if __name__ == "__main__":
    main()
