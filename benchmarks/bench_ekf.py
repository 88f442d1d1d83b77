"""Benchmark: one step of the wear EKF (target: under 10 microseconds).

Usage::

    python benchmarks/bench_ekf.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import platform
import time

from cnctwin.wear import CHRISTIAND2024, WearEKF


def _per_step_us(ekf: WearEKF, steps: int, measured: bool) -> float:
    torque = 3.0e-3 if measured else math.nan
    start = time.perf_counter()
    for _ in range(steps):
        ekf.step(4e-4, torque, 1.26e-3)
    return (time.perf_counter() - start) / steps * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps")
    args = parser.parse_args()
    steps = 20_000 if args.quick else 500_000
    print(f"machine: {platform.machine()}, Python {platform.python_version()}, {steps} steps")
    print("| step | us per step | tools per core at 100 samples/s |")
    print("|---|---:|---:|")
    for measured in (True, False):
        ekf = CHRISTIAND2024.filter(vb0_mm=0.02)
        us = min(_per_step_us(ekf, steps, measured) for _ in range(3))
        label = "predict + update" if measured else "predict only (missed sample)"
        print(f"| {label} | {us:.2f} | {1e6 / us / 100:,.0f} |")


if __name__ == "__main__":
    main()
