"""Benchmark of tri-dexel material removal with engagement: real-time factor and memory.

Usage: ``python benchmarks/bench_dexel.py [--quick]``. Prints Markdown tables for
docs/benchmarks.md:

1. the 60 s slotting program (Heide 2025's 6 mm flat end mill, full slots 3 mm deep at
   1440 mm/min, zig-zag along x in a 100 x 100 x 30 mm block) at 10 /mm and 12.5 ms and at
   20 /mm and 6.25 ms, timed as a simulation loop (removal and engagement, the positions
   generated beforehand with numpy) two ways: one :func:`cnctwin.geometry.cut` per sampled
   position (the twin's cycle), and :func:`cnctwin.geometry.engagement.cut_path` per chunk of
   the positions of 1 s of process (an offline simulation: the trajectory sampler yields
   chunks);
2. the cost per simulated second over dexel densities and cycle times, with Heide 2025's
   scaling metric ``T* = rho^2 / t_cycle`` (their Eq. 1) for comparison;
3. the memory of a 200 x 200 x 50 mm stock at 10 /mm (computed and traced);
4. the accuracy table of docs/dexel.md: a 4 mm deep side-milling pass (up milling, ae = 1.8 mm)
   along the wall of a slot cut before with 0.05 mm steps, both at 30 degrees to the x axis, 6 mm
   flat end mill, over the steady part: mean |ae - 1.8 mm|, mean error of the contact's exit
   angle arccos(1 - 2 ae / D) over the slices, error of the mean MRR against feed x ae x ap.

Times are wall-clock seconds and CPU seconds of this process (one core: the loop is serial), the
best of three runs of the program (the machine is shared; other loads only slow a run down).
The sweep (with ``cut_path``) fits ``cost ~ rho^a t_cycle^b`` by least squares, to compare with
T*'s a = 2, b = -1. The warm-up runs every kernel once (loading numba's cache is a one-off cost
of a process, not of a simulated second).
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

from cnctwin.geometry import Cutter, DexelStock, cut, cut_path

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


def simulate(
    density_per_mm: float, cycle_s: float, duration_s: float, batched: bool = True
) -> tuple[float, float, int]:
    """(wall s, CPU s, steps) of the slotting program through a fresh block: ``cut_path`` per
    second of process, or (``batched`` false) ``cut`` per position."""
    positions = slotting_positions(duration_s, cycle_s)
    stock = DexelStock.box(BLOCK_MIN_MM, BLOCK_MAX_MM, density_per_mm)
    chunk = max(1, round(1.0 / cycle_s))
    gc.collect()
    wall = time.perf_counter()
    cpu = time.process_time()
    previous = None
    if batched:
        for first in range(0, len(positions), chunk):
            part = positions[first : first + chunk]
            cut_path(stock, CUTTER, part, previous, FEED_PER_TOOTH_MM, cycle_s)
            previous = part[-1]
    else:
        for position in positions:
            cut(stock, CUTTER, position, previous, FEED_PER_TOOTH_MM, cycle_s)
            previous = position
    return time.perf_counter() - wall, time.process_time() - cpu, len(positions)


def warm_up() -> None:
    """Run every kernel once: both loops, and a heap growth."""
    simulate(5.0, 0.05, 1.0)
    simulate(5.0, 0.05, 1.0, batched=False)
    stock = DexelStock.box(BLOCK_MIN_MM, BLOCK_MAX_MM, 2.0)
    for axis in ("x", "y", "z"):
        stock.grow_heap(axis)


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


def accuracy_row(density_per_mm: float, step_mm: float) -> tuple[float, float, float]:
    """(mean |ae - 1.8| mm, mean exit angle error deg, MRR error %) of the side-milling pass."""
    ae, depth, length, angle = 1.8, 4.0, 40.0, math.radians(30.0)
    feed = np.array([math.cos(angle), math.sin(angle)])
    normal = np.array([-feed[1], feed[0]])
    origin = np.array([10.0, 10.0])
    stock = DexelStock.box((0.0, 0.0, -10.0), (60.0, 60.0, 0.0), density_per_mm)

    def line(offset: np.ndarray, step: float) -> np.ndarray:
        t = np.arange(0.0, length + 1e-9, step)
        xy = offset + t[:, None] * feed
        return np.column_stack([xy, np.full(len(t), -depth)])

    cut_path(stock, CUTTER, line(origin, 0.05), None, 0.05, 0.0125)
    side = cut_path(stock, CUTTER, line(origin + ae * normal, step_mm), None, 0.05, 0.0125)
    t = np.arange(0.0, length + 1e-9, step_mm)
    steady = np.flatnonzero((t > 8.0) & (t < length - 8.0))
    exit_rad = math.acos(1.0 - 2.0 * ae / CUTTER.diameter_mm)
    errors = []
    for i in steady:
        e = side.engagement(int(i))
        ends = [
            max(b for a, b in e.slice_intervals(k) if a < math.pi)
            for k in range(len(e.slice_height_mm))
        ]
        errors.append(np.mean(np.abs(np.array(ends) - exit_rad)))
    mrr = float(np.mean(side.mrr_mm3_s[steady]))
    nominal = ae * depth * step_mm / 0.0125
    return (
        float(np.mean(np.abs(side.ae_mm[steady] - ae))),
        math.degrees(float(np.mean(errors))),
        abs(mrr / nominal - 1.0) * 100.0,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 s of process, a few seconds")
    args = parser.parse_args()
    duration = 2.0 if args.quick else 60.0
    warm_up()
    cpu = platform.processor() or platform.machine()
    print(f"Tri-dexel removal and engagement, {cpu}, Python {platform.python_version()}")
    print()
    print(
        f"Slotting program: {duration:g} s, 6 mm flat end mill, slots {DEPTH_MM:g} mm deep at "
        f"{FEED_MM_MIN:g} mm/min, 100 x 100 x 30 mm block."
    )
    print()
    print(
        "| density /mm | cycle ms | loop | steps | wall s | CPU s | real-time factor | required |"
    )
    print("|---:|---:|---|---:|---:|---:|---:|---:|")
    repeats = 1 if args.quick else 3
    for density, cycle_s, required in ((10.0, 0.0125, 200), (20.0, 0.00625, 50)):
        for batched, loop in ((False, "cut per position"), (True, "cut_path per second")):
            wall, cpu_s, steps = min(
                simulate(density, cycle_s, duration, batched) for _ in range(repeats)
            )
            print(
                f"| {density:g} | {cycle_s * 1e3:g} | {loop} | {steps} | {wall:.3f} | "
                f"{cpu_s:.3f} | {duration / wall:.0f}x | {required}x |"
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
    print()
    print("Accuracy: 4 mm deep side milling, ae = 1.8 mm, along a slot's wall at 30 deg to x:")
    print()
    print("| density /mm | step mm | mean \\|ae - 1.8\\| mm | exit angle error deg | MRR error % |")
    print("|---:|---:|---:|---:|---:|")
    for density in (10.0,) if args.quick else (5.0, 10.0, 20.0):
        for step_mm in (0.3,) if args.quick else (0.1, 0.3, 1.0):
            ae_err, angle_err, mrr_err = accuracy_row(density, step_mm)
            print(f"| {density:g} | {step_mm:g} | {ae_err:.3f} | {angle_err:.2f} | {mrr_err:.2f} |")


if __name__ == "__main__":
    main()
