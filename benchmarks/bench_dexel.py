"""Benchmark of tri-dexel material removal with engagement: real-time factor and memory.

Usage: ``python benchmarks/bench_dexel.py [--quick]``. Prints Markdown tables for
docs/benchmarks.md:

1. the 60 s slotting program (Heide 2025's 6 mm flat end mill, full slots 3 mm deep at
   1440 mm/min, zig-zag along x in a 100 x 100 x 30 mm block) at 10 /mm and 12.5 ms and at
   20 /mm and 6.25 ms, timed as a simulation loop: one :func:`cnctwin.geometry.cut` per sampled
   position (removal and engagement), the positions generated beforehand with numpy;
2. the cost per simulated second over dexel densities and cycle times, with Heide 2025's
   scaling metric ``T* = rho^2 / t_cycle`` (their Eq. 1) for comparison;
3. the memory of a 200 x 200 x 50 mm stock at 10 /mm (computed and traced).

Times are wall-clock seconds and CPU seconds of this process (one core: the loop is serial), the
best of three runs of the program (the machine is shared; other loads only slow a run down).
The sweep fits ``cost ~ rho^a t_cycle^b`` by least squares, to compare with T*'s a = 2, b = -1.
``--quick`` simulates 2 s of the program once instead of 60 s three times, to prove the script
still runs.
"""

from __future__ import annotations

import argparse
import gc
import math
import platform
import time
import tracemalloc

import numpy as np

from cnctwin.geometry import Cutter, DexelStock, cut

BLOCK_MIN_MM = (0.0, 0.0, -30.0)
BLOCK_MAX_MM = (100.0, 100.0, 0.0)
CUTTER = Cutter.flat(6.0, 20.0, flutes=3)
DEPTH_MM = 3.0
FEED_MM_MIN = 1440.0
SPINDLE_RPM = 9600.0
FEED_PER_TOOTH_MM = FEED_MM_MIN / (SPINDLE_RPM * CUTTER.flutes)


def slotting_positions(duration_s: float, cycle_s: float) -> np.ndarray:
    """Tool-tip positions (n, 3) in mm every ``cycle_s`` for ``duration_s`` of slotting.

    Zig-zag full slots along x from x = -5 to 105 mm at y = 8, 15, ... 92 mm, 3 mm deep, joined
    by 7 mm slots along y, at a constant feed of 1440 mm/min.
    """
    ys = np.arange(8.0, 92.1, 7.0)
    corners = []
    for i, y in enumerate(ys):
        xa, xb = (-5.0, 105.0) if i % 2 == 0 else (105.0, -5.0)
        corners += [(xa, y), (xb, y)]
    path = np.array(corners)
    lengths = np.hypot(*np.diff(path, axis=0).T)
    s_at = np.concatenate([[0.0], np.cumsum(lengths)])
    s = np.arange(0.0, duration_s, cycle_s) * FEED_MM_MIN / 60.0
    if s[-1] > s_at[-1]:
        raise ValueError(f"path of {s_at[-1]:.0f} mm is too short for {duration_s} s")
    xy = np.column_stack([np.interp(s, s_at, path[:, 0]), np.interp(s, s_at, path[:, 1])])
    return np.column_stack([xy, np.full(len(s), -DEPTH_MM)])


def simulate(density_per_mm: float, cycle_s: float, duration_s: float) -> tuple[float, float, int]:
    """(wall s, CPU s, steps) of the slotting program through a fresh block."""
    positions = slotting_positions(duration_s, cycle_s)
    stock = DexelStock.box(BLOCK_MIN_MM, BLOCK_MAX_MM, density_per_mm)
    gc.collect()
    wall = time.perf_counter()
    cpu = time.process_time()
    previous = None
    for position in positions:
        cut(stock, CUTTER, position, previous, FEED_PER_TOOTH_MM, cycle_s)
        previous = position
    return time.perf_counter() - wall, time.process_time() - cpu, len(positions)


def memory_case() -> tuple[int, int, int]:
    """(estimated bytes, array bytes, traced peak bytes) of a 200 x 200 x 50 mm stock at 10 /mm."""
    low, high = (0.0, 0.0, -50.0), (200.0, 200.0, 0.0)
    estimate = DexelStock.estimate_nbytes(low, high, 10.0)
    gc.collect()
    tracemalloc.start()
    try:
        stock = DexelStock.box(low, high, 10.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return estimate, stock.nbytes, peak


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 s of process, a few seconds")
    args = parser.parse_args()
    duration = 2.0 if args.quick else 60.0
    simulate(5.0, 0.05, 1.0)  # load the compiled kernels before timing
    cpu = platform.processor() or platform.machine()
    print(f"Tri-dexel removal and engagement, {cpu}, Python {platform.python_version()}")
    print()
    print(
        f"Slotting program: {duration:g} s, 6 mm flat end mill, slots {DEPTH_MM:g} mm deep at "
        f"{FEED_MM_MIN:g} mm/min, 100 x 100 x 30 mm block."
    )
    print()
    print("| density /mm | cycle ms | steps | wall s | CPU s | real-time factor | required |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    repeats = 1 if args.quick else 3
    for density, cycle_s, required in ((10.0, 0.0125, 200), (20.0, 0.00625, 50)):
        wall, cpu_s, steps = min(simulate(density, cycle_s, duration) for _ in range(repeats))
        print(
            f"| {density:g} | {cycle_s * 1e3:g} | {steps} | {wall:.3f} | {cpu_s:.3f} "
            f"| {duration / wall:.0f}x | {required}x |"
        )
    print()
    print("Cost per simulated second over density and cycle time (T* = rho^2 / t_cycle):")
    print()
    print("| density /mm | cycle ms | T* | steps/s of process | CPU s per process s | us/step |")
    print("|---:|---:|---:|---:|---:|---:|")
    densities = (5.0, 10.0, 20.0) if args.quick else (5.0, 10.0, 13.0, 16.0, 20.0)
    cycles = (0.0125, 0.05) if args.quick else (0.00625, 0.0125, 0.025, 0.05, 0.1)
    sweep_s = 1.0 if args.quick else 10.0
    fit = []
    for density in densities:
        for cycle_s in cycles:
            _, cpu_s, steps = min(simulate(density, cycle_s, sweep_s) for _ in range(repeats))
            fit.append((math.log(density), math.log(cycle_s), math.log(cpu_s / sweep_s)))
            print(
                f"| {density:g} | {cycle_s * 1e3:g} | {density**2 / cycle_s:,.0f} "
                f"| {steps / sweep_s:g} | {cpu_s / sweep_s:.4f} | {cpu_s / steps * 1e6:.0f} |"
            )
    logs = np.array(fit)
    design = np.column_stack([logs[:, 0], logs[:, 1], np.ones(len(logs))])
    (a, b, _), *_ = np.linalg.lstsq(design, logs[:, 2], rcond=None)
    print()
    print(f"Fit: CPU s per process s ~ rho^{a:.2f} t_cycle^{b:.2f} (T* = rho^2 t_cycle^-1).")
    print()
    estimate, nbytes, peak = memory_case()
    print("| stock | density /mm | estimated MiB | arrays MiB | traced peak MiB | limit MiB |")
    print("|---|---:|---:|---:|---:|---:|")
    print(
        f"| 200 x 200 x 50 mm | 10 | {estimate / 2**20:.0f} | {nbytes / 2**20:.0f} "
        f"| {peak / 2**20:.0f} | 1024 |"
    )


if __name__ == "__main__":
    main()
