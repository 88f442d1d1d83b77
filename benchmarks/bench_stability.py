"""Benchmark of the stability lobes: zero-order approximation and semi-discretization.

Usage: ``python benchmarks/bench_stability.py [--quick]``. Prints a Markdown table (one row per
case) for docs/benchmarks.md: the wall time of one lobe diagram after a warm-up (numba kernels
compiled and cached), the best of ``repeats`` runs. Cases: the Insperger & Stépán benchmark
(../shared/data/stability/NOTES.md section 1: 1-DOF and symmetric 2-DOF, slot and a/D = 0.05
down-milling, 5000-25000 rpm, 40 steps per tooth period, depths searched up to 10 mm) and the
UBC two-mode tool (section 2, half immersion). Targets (issue 5): ZOA over 400 speeds under
0.1 s; SDM of the Insperger benchmark over 400 speeds x 0-10 mm under 10 s. ``--quick`` runs
20 speeds once.
"""

from __future__ import annotations

import argparse
import logging
import math
import platform
import time
from collections.abc import Callable

import numpy as np

from cnctwin.dynamics.stability import (
    MillingProcess,
    StabilityLobes,
    ToolDynamics,
    ToolMode,
    sdm_lobes,
    zoa_lobes,
)
from cnctwin.mechanics import CuttingCoefficients

RPM = math.pi / 30.0
MODE = ToolMode.from_hz(922.0, 0.011, stiffness_n_m=1340049.648)
ONE_DOF = ToolDynamics.from_xy(x=[MODE])
TWO_DOF = ToolDynamics.from_xy(x=[MODE], y=[MODE])
INSPERGER = CuttingCoefficients(6e8, 2e8)
UBC = ToolDynamics.from_xy(
    x=[
        ToolMode.from_hz(456.780, 0.111705, stiffness_n_m=7933097.2),
        ToolMode.from_hz(1448.889, 0.017037, stiffness_n_m=14691778.4),
    ],
    y=[
        ToolMode.from_hz(516.518, 0.024580, stiffness_n_m=9374613.8),
        ToolMode.from_hz(1408.448, 0.031358, stiffness_n_m=12406389.7),
    ],
)
UBC_CUT = MillingProcess.from_immersion(2, CuttingCoefficients(1319.4e6, 788.8e6), 0.5)


def best_seconds(call: Callable[[], StabilityLobes], repeats: int) -> tuple[float, StabilityLobes]:
    """Shortest of ``repeats`` wall times of ``call`` in s, and its result."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = call()
        times.append(time.perf_counter() - start)
    return min(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="20 speeds, one run (CI)")
    args = parser.parse_args()
    zoa_speeds, sdm_speeds = (20, 20) if args.quick else (400, 200)
    repeats = 1 if args.quick else 3
    insperger = np.linspace(5000.0, 25000.0, sdm_speeds) * RPM
    ubc = np.linspace(2000.0, 16000.0, sdm_speeds) * RPM

    def slot(imm: float) -> MillingProcess:
        return MillingProcess.from_immersion(2, INSPERGER, imm)

    cases: list[tuple[str, str, int, Callable[[], StabilityLobes]]] = [
        ("zoa", "Insperger 1-DOF slot", zoa_speeds,
         lambda: zoa_lobes(ONE_DOF, slot(1.0), np.linspace(5000, 25000, zoa_speeds) * RPM)),
        ("zoa", "UBC two modes per axis, ae = D/2", zoa_speeds,
         lambda: zoa_lobes(UBC, UBC_CUT, np.linspace(2000, 16000, zoa_speeds) * RPM)),
    ]  # fmt: skip
    for label, tool in (("1-DOF", ONE_DOF), ("2-DOF", TWO_DOF)):
        for imm, where in ((1.0, "slot"), (0.05, "a/D = 0.05")):
            cases.append(
                (
                    "sdm, m = 40",
                    f"Insperger {label} {where}",
                    sdm_speeds,
                    lambda t=tool, i=imm: sdm_lobes(
                        t, slot(i), insperger, max_depth_m=0.01, steps=40
                    ),
                )
            )
    cases.append(
        ("sdm, m = auto", "UBC two modes per axis, ae = D/2", sdm_speeds,
         lambda: sdm_lobes(UBC, UBC_CUT, ubc, max_depth_m=0.006)),
    )  # fmt: skip
    # The Insperger cases keep m = 40 at 5000 rpm on purpose: no warning about it.
    logging.getLogger("cnctwin").setLevel(logging.ERROR)
    # Warm-up: load or compile the numba kernels.
    zoa_lobes(ONE_DOF, slot(1.0), [1000.0])
    sdm_lobes(ONE_DOF, slot(1.0), [10000.0], max_depth_m=1e-3, steps=40)
    print(f"Python {platform.python_version()}, {platform.machine()}, best of {repeats}")
    print()
    print("| method | case | speeds | time (s) | per speed (ms) | lowest critical depth (mm) |")
    print("|---|---|---:|---:|---:|---:|")
    for method, case, count, call in cases:
        seconds, result = best_seconds(call, repeats)
        print(
            f"| {method} | {case} | {count} | {seconds:.3f} | {seconds / count * 1e3:.3f} "
            f"| {result.min_critical_depth_m * 1e3:.4f} |"
        )


if __name__ == "__main__":
    main()
