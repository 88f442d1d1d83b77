"""Benchmark of the virtual machine: how much faster than real time it runs the packaged demo.

Usage: ``python benchmarks/bench_virtual.py [--quick]``. Prints a Markdown table for
docs/_bench_virtual.md: for the packaged demo (``cnctwin/examples/demo.ngc`` on ``demo.toml``:
10 mm 3-flute end mill and a 6.8 mm drill in AA6060-T6, dexels at 10 /mm), run tick by tick
with :meth:`VirtualMachine.step` and a :meth:`~VirtualMachine.snapshot` per tick (what a
server publishes), at a 5 ms and a 2.5 ms tick, with and without injected faults: machine time,
wall time, CPU time, the real-time factor (machine time over wall time; over CPU time too, which
other processes on a shared machine do not inflate) and the median and 99th percentile of the
time per tick (the budget at speed 1 is the tick itself).

``--quick`` runs the first 5 s of the program at the 5 ms tick only (CI).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from cnctwin.virtual import (
    HoleFault,
    ToolBreakageFault,
    VirtualMachine,
    VirtualMachineConfig,
    WearFault,
)

FAULTS = [
    # Missing material in the pocket's clearing loop (demo G54 origin: X150 Y100 Z-300).
    HoleFault(
        kind="hole", shape="box", min_mm=(190.0, 125.0, -310.0), max_mm=(200.0, 135.0, -299.0)
    ),
    WearFault(kind="wear", growth_per_min=0.5),
    ToolBreakageFault(kind="breakage", at_line=41, lost_length_mm=5.0),
]


def run(tick_s: float, faults: bool, limit_s: float | None) -> str:
    config = VirtualMachineConfig(tick_ms=tick_s * 1e3, faults=FAULTS if faults else [])
    built = time.perf_counter()
    vm = VirtualMachine(config)
    build_s = time.perf_counter() - built
    times = []
    wall0 = time.perf_counter()
    cpu0 = time.process_time()
    while not vm.finished and (limit_s is None or vm.time_s < limit_s):
        begin = time.perf_counter()
        vm.step(tick_s)
        vm.snapshot()
        times.append(time.perf_counter() - begin)
    wall = time.perf_counter() - wall0
    cpu = time.process_time() - cpu0
    us = np.array(times) * 1e6
    label = "hole + wear + breakage" if faults else "none"
    return (
        f"| {tick_s * 1e3:g} | {label} | {vm.time_s:.2f} | {len(times)} | {wall:.2f} | {cpu:.2f} "
        f"| {vm.time_s / wall:.1f} | {vm.time_s / cpu:.1f} | {np.median(us):.0f} "
        f"| {np.percentile(us, 99):.0f} | {build_s:.2f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5 s of the program, 5 ms tick (CI)")
    args = parser.parse_args()
    # Warm-up: numba kernels load from their cache on first use.
    warm = VirtualMachine(VirtualMachineConfig())
    for _ in range(2000):
        warm.step(0.005)
    cases = [(0.005, False)] if args.quick else [(0.005, False), (0.0025, False), (0.005, True)]
    limit = 5.0 if args.quick else None
    print(
        f"Virtual machine on the packaged demo; {platform.processor() or platform.machine()}, "
        f"Python {platform.python_version()}.\n"
    )
    print(
        "| tick ms | faults | machine s | ticks | wall s | CPU s | real-time factor (wall) "
        "| real-time factor (CPU) | tick p50 us | tick p99 us | build s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for tick_s, faults in cases:
        print(run(tick_s, faults, limit), flush=True)


if __name__ == "__main__":
    main()
