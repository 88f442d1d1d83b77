"""Benchmark of engagement maps: build time per metre of path and lookup time per call.

Usage: ``python benchmarks/bench_engagement_map.py [--quick]``. Prints Markdown tables for
docs/benchmarks.md:

1. building the map of a slotting program (Heide 2025's 6 mm flat end mill, full slots 3 mm
   deep, zig-zag along x in a 100 x 100 x 30 mm block at 10 dexels/mm) at path steps of 0.05,
   0.1 and 0.2 mm: wall time per metre of path and per location, and the map's memory;
2. looking it up at every 12.5 ms cycle along the program sampled at 1440 mm/min (the twin's
   positions): time per :meth:`MapCursor.lookup` call (mean, median, 99th percentile, maximum)
   for lookahead windows of 25 and 100 mm, and a global search (no hint) at random points of
   the path. The cycle's budget is 12.5 ms; the target for a lookup is well under 50 us.

Times are wall-clock, best of three builds (one with ``--quick``); the machine is shared, so
other loads only slow a run down. ``--quick`` maps two slots instead of thirteen.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from cnctwin.geometry import Cutter, DexelStock, EngagementMap, MapCursor
from cnctwin.nc import interpret_text, sample_program

BLOCK_MIN_MM = (0.0, 0.0, -30.0)
BLOCK_MAX_MM = (100.0, 100.0, 0.0)
CUTTER = Cutter.flat(6.0, 20.0, flutes=3)
DENSITY_PER_MM = 10.0
DEPTH_MM = 3.0
FEED_MM_MIN = 1440.0
CYCLE_S = 0.0125


def slotting_program(rows: int) -> str:
    """G-code: ``rows`` full slots along x at y = 8, 15, ... joined by 7 mm slots along y."""
    lines = ["G21 G90 G94 S9600 M3", "G0 X-5 Y8 Z5", f"G1 Z{-DEPTH_MM:g} F{FEED_MM_MIN:g}"]
    for i in range(rows):
        y = 8.0 + 7.0 * i
        if i:
            lines.append(f"G1 Y{y:g}")
        lines.append(f"G1 X{105.0 if i % 2 == 0 else -5.0:g}")
    lines += ["G0 Z5", "M2"]
    return "\n".join(lines) + "\n"


def build(program: str, step_mm: float) -> tuple[float, EngagementMap]:
    stock = DexelStock.box(BLOCK_MIN_MM, BLOCK_MAX_MM, DENSITY_PER_MM)
    started = time.perf_counter()
    emap = EngagementMap.build(interpret_text(program), stock, {0: CUTTER}, step_mm=step_mm)
    return time.perf_counter() - started, emap


def map_nbytes(emap: EngagementMap) -> int:
    names = ("s_mm", "tcp_mm", "table", "band_ptr", "band_lo_mm", "band_hi_mm", "interval_ptr",
             "interval_start_rad", "interval_end_rad")  # fmt: skip
    return sum(getattr(emap, name).nbytes for name in names)


def lookup_times_us(emap: EngagementMap, positions: np.ndarray, lookahead_mm: float) -> np.ndarray:
    """Time of each cursor lookup along the positions, us (after a warm-up pass)."""
    for _ in range(2):
        cursor = MapCursor(emap, lookahead_mm=lookahead_mm)
        times = np.empty(len(positions))
        clock = time.perf_counter_ns
        for k, position in enumerate(positions):
            t0 = clock()
            cursor.lookup(position)
            times[k] = clock() - t0
    return times[1:] * 1e-3  # the first lookup is a global search


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two slots, a few seconds")
    args = parser.parse_args()
    program = slotting_program(2 if args.quick else 13)
    repeats = 1 if args.quick else 3
    build(slotting_program(1), 0.5)  # load the compiled kernels before timing
    cpu = platform.processor() or platform.machine()
    print(f"Engagement maps, {cpu}, Python {platform.python_version()}")
    print()
    print(
        f"Slotting program: 6 mm flat end mill, slots {DEPTH_MM:g} mm deep, 100 x 100 x 30 mm "
        f"block at {DENSITY_PER_MM:g} dexels/mm."
    )
    print()
    print("| step mm | locations | path m | build s | s per m | us per location | map MiB "
          "| MiB per m |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    maps = {}
    for step in (0.05, 0.1, 0.2):
        wall, emap = min((build(program, step) for _ in range(repeats)), key=lambda r: r[0])
        maps[step] = emap
        metres = emap.length_mm / 1e3
        mib = map_nbytes(emap) / 2**20
        print(
            f"| {step:g} | {len(emap)} | {metres:.3f} | {wall:.3f} | {wall / metres:.3f} "
            f"| {wall / len(emap) * 1e6:.0f} | {mib:.1f} | {mib / metres:.1f} |"
        )
    emap = maps[0.1]
    chunk, duration = sample_program(interpret_text(program), rapid_mm_min=15000.0, cycle_s=CYCLE_S)
    print()
    print(
        f"Lookups on the 0.1 mm map: the program sampled every {CYCLE_S * 1e3:g} ms at "
        f"{FEED_MM_MIN:g} mm/min ({len(chunk.t_s)} positions, {duration:.1f} s of process)."
    )
    print()
    print("| search | calls | mean us | median us | p99 us | max us | share of 12.5 ms |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for lookahead in (25.0, 100.0):
        times = lookup_times_us(emap, chunk.tcp_mm, lookahead)
        print(
            f"| window {lookahead:g} mm | {times.size} | {times.mean():.1f} "
            f"| {np.median(times):.1f} | {np.percentile(times, 99):.1f} | {times.max():.1f} "
            f"| {times.mean() / (CYCLE_S * 1e6):.2%} |"
        )
    rng = np.random.default_rng(1)
    probes = emap.tcp_mm[rng.integers(0, len(emap), 200 if args.quick else 2000)]
    emap.lookup(probes[0])  # builds the k-d tree
    times = np.empty(len(probes))
    for k, position in enumerate(probes):
        t0 = time.perf_counter_ns()
        emap.lookup(position)
        times[k] = (time.perf_counter_ns() - t0) * 1e-3
    print(
        f"| global (resync) | {times.size} | {times.mean():.1f} | {np.median(times):.1f} "
        f"| {np.percentile(times, 99):.1f} | {times.max():.1f} "
        f"| {times.mean() / (CYCLE_S * 1e6):.2%} |"
    )


if __name__ == "__main__":
    main()
