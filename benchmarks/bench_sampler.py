"""Benchmark of the trajectory sampler: samples per second and peak memory.

Usage: ``python benchmarks/bench_sampler.py [--quick]``. Prints a Markdown table (one row per
case) for docs/benchmarks.md. Throughput is timed on segments built beforehand (the sampler
alone, reading a list lazily); peak memory is traced (tracemalloc) on a generator of fresh
segments, as the interpreter would deliver them. ``--quick`` runs small programs in a few
seconds, to prove the script still runs.
"""

from __future__ import annotations

import argparse
import gc
import math
import platform
import time
import tracemalloc
from collections.abc import Callable, Iterator

from cnctwin.nc import AxisLimits, MachineState, MotionKind, Segment, TrajectorySampler

STATE = MachineState()
RAPID_MM_MIN = 15000.0
LIMITS = AxisLimits((2000.0, 2000.0, 1000.0), velocity_mm_s=(250.0, 250.0, 250.0))


def short_lines(n: int) -> Iterator[Segment]:
    """Zig-zag of 0.1 mm lines at 1000 mm/min (6 ms each, shorter than a 12.5 ms cycle)."""
    for i in range(n):
        y = 0.1 * i
        x0 = 0.0 if i % 2 == 0 else 0.05
        yield Segment(
            MotionKind.LINEAR, i + 1, (x0, y, 0.0), (0.05 - x0, y + 0.1, 0.0), 1000.0, 8000.0, STATE
        )


def short_arcs(n: int) -> Iterator[Segment]:
    """Quarter arcs of radius 0.1 mm (0.16 mm, 9.4 ms each at 1000 mm/min), round a circle."""
    r = 0.1
    for i in range(n):
        a0 = 0.5 * math.pi * (i % 4)
        a1 = a0 + 0.5 * math.pi
        p0 = (r * math.cos(a0), r * math.sin(a0), 0.0)
        p1 = (r * math.cos(a1), r * math.sin(a1), 0.0)
        yield Segment(
            MotionKind.ARC, i + 1, p0, p1, 1000.0, 8000.0, STATE, center_mm=(0.0, 0.0, 0.0), turns=1
        )


def long_lines(n: int) -> Iterator[Segment]:
    """Back-and-forth 100 mm lines at 3000 mm/min (2 s each)."""
    for i in range(n):
        x0 = 0.0 if i % 2 == 0 else 100.0
        yield Segment(
            MotionKind.LINEAR, i + 1, (x0, 0.0, 0.0), (100.0 - x0, 0.0, 0.0), 3000.0, 8000.0, STATE
        )


def long_arcs(n: int) -> Iterator[Segment]:
    """Full circles of radius 20 mm at 3000 mm/min (2.5 s each)."""
    p = (20.0, 0.0, 0.0)
    for i in range(n):
        yield Segment(
            MotionKind.ARC, i + 1, p, p, 3000.0, 8000.0, STATE, center_mm=(0.0, 0.0, 0.0), turns=1
        )


def run_case(
    make: Callable[[int], Iterator[Segment]], n: int, cycle_s: float, limits: AxisLimits | None
) -> tuple[int, float, int]:
    """(samples, seconds, peak traced bytes) of one case."""
    segments = list(make(n))
    gc.collect()
    start = time.perf_counter()
    samples = 0
    for chunk in TrajectorySampler(
        iter(segments), rapid_mm_min=RAPID_MM_MIN, cycle_s=cycle_s, limits=limits
    ):
        samples += len(chunk.t_s)
    seconds = time.perf_counter() - start
    del segments
    tracemalloc.start()
    try:
        for _ in TrajectorySampler(
            make(n), rapid_mm_min=RAPID_MM_MIN, cycle_s=cycle_s, limits=limits
        ):
            pass
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return samples, seconds, peak


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small programs, a few seconds")
    args = parser.parse_args()
    scale = 10 if args.quick else 1
    cases = [
        ("short lines 0.1 mm", short_lines, 100_000 // scale),
        ("short arcs r 0.1 mm", short_arcs, 100_000 // scale),
        ("long lines 100 mm", long_lines, 1_000 // scale),
        ("full circles r 20 mm", long_arcs, 1_000 // scale),
    ]
    run_case(short_arcs, 50, 0.0125, LIMITS)  # load the compiled kernels before timing
    cpu = platform.processor() or platform.machine()
    print(f"Trajectory sampler, {cpu}, Python {platform.python_version()}")
    print()
    print(
        "| program | segments | cycle ms | limits | samples | time s | samples/s | segments/s "
        "| peak MiB |"
    )
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|")
    for name, make, n in cases:
        for cycle_s in (0.0125, 0.001):
            for limits in (None, LIMITS):
                samples, seconds, peak = run_case(make, n, cycle_s, limits)
                cells = [
                    name,
                    str(n),
                    f"{cycle_s * 1e3:g}",
                    "axis" if limits else "none",
                    str(samples),
                    f"{seconds:.3f}",
                    f"{samples / seconds:,.0f}",
                    f"{n / seconds:,.0f}",
                    f"{peak / 2**20:.1f}",
                ]
                print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
