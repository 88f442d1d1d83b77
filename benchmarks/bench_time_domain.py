"""Benchmark of the time-domain milling simulation (cnctwin.dynamics.time_domain).

Usage: ``python benchmarks/bench_time_domain.py [--quick]``. Prints a Markdown table for
docs/benchmarks.md: per case the simulated seconds per wall-clock second and the steps per
second at 200 steps per tooth period (the best of ``repeats`` runs after a warm-up that
compiles or loads the numba kernel), then the wall time of a process-damping calibration of
one cut. Cases: the Insperger & Stépán slot (../shared/data/stability/NOTES.md section 1:
1-DOF, 2 teeth, straight flutes), the UBC tool (section 2: four modes, half immersion) and
Royandi 2026's slot (2-DOF, 4 teeth, 30 deg helix in 11 slices, edge forces, process
damping). Target (issue 5): more than 1 million steps per second. ``--quick`` simulates
0.05 s once.
"""

from __future__ import annotations

import argparse
import logging
import math
import platform
import time
from collections.abc import Callable

from cnctwin.dynamics import (
    CalibrationSetup,
    MillingProcess,
    MillingVibration,
    ProcessDamping,
    ToolDynamics,
    ToolMode,
    calibrate_cpd,
    simulate_milling,
)
from cnctwin.geometry import Cutter
from cnctwin.mechanics import CuttingCoefficients

RPM = math.pi / 30.0
STEPS = 200
INSPERGER = ToolMode.from_hz(922.0, 0.011, stiffness_n_m=1340049.648)
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
ROYANDI_MODE = ToolMode(math.sqrt(8028e3 / 0.241), 118.0 / (2 * math.sqrt(8028e3 * 0.241)), 8028e3)
ROYANDI = ToolDynamics.from_xy(x=[ROYANDI_MODE], y=[ROYANDI_MODE])
ROYANDI_SLOT = MillingProcess.from_immersion(4, CuttingCoefficients(745.1e6, 360.98e6), 1.0)
ROYANDI_CUTTER = Cutter.flat(12.0, 30.0, flutes=4, helix_rad=math.radians(30.0))


def cases(seconds: float) -> list[tuple[str, Callable[[], MillingVibration]]]:
    """Name and call of each benchmark case."""
    slot = MillingProcess.from_immersion(2, CuttingCoefficients(6e8, 2e8), 1.0)
    ubc_cut = MillingProcess.from_immersion(2, CuttingCoefficients(1319.4e6, 788.8e6), 0.5)
    return [
        (
            "Insperger slot, 1 mode, 2 teeth, 1 slice, 10000 rpm, 0.3 mm",
            lambda: simulate_milling(
                ToolDynamics.from_xy(x=[INSPERGER]), slot, spindle_rad_s=10000 * RPM,
                depth_m=3e-4, feed_per_tooth_m=1e-4, duration_s=seconds, steps_per_tooth=STEPS,
            ),
        ),
        (
            "UBC, 4 modes, 2 teeth, ae = D/2, 1 slice, 6000 rpm, 1.5 mm",
            lambda: simulate_milling(
                UBC, ubc_cut, spindle_rad_s=6000 * RPM, depth_m=1.5e-3, feed_per_tooth_m=1e-4,
                duration_s=seconds, steps_per_tooth=STEPS,
            ),
        ),
        (
            "Royandi slot, 2 modes, 4 teeth, 11 slices, edge + process damping, 5500 rpm, 3.5 mm",
            lambda: simulate_milling(
                ROYANDI, ROYANDI_SLOT, spindle_rad_s=5500 * RPM, depth_m=3.5e-3,
                feed_per_tooth_m=1e-4, duration_s=seconds, cutter=ROYANDI_CUTTER,
                edge_tangential_n_m=31.49e3, edge_radial_n_m=21.85e3, helical_edge=True,
                damping=ProcessDamping(5e10, 1e-4, 0.012), steps_per_tooth=STEPS, slices=11,
            ),
        ),
    ]  # fmt: skip


def best(call: Callable[[], object], repeats: int) -> float:
    """Shortest wall time of ``repeats`` calls in s."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="0.05 s simulated, one run (CI)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    # 200 steps per tooth are 28 per cycle of the UBC tool's 1449 Hz mode at 6000 rpm, which
    # the simulation warns about; the benchmark asks for this resolution on purpose.
    logging.getLogger("cnctwin.dynamics.time_domain").setLevel(logging.ERROR)
    seconds = 0.05 if args.quick else 1.0
    repeats = 1 if args.quick else 3
    machine = platform.processor() or platform.machine()
    print(f"Time-domain milling, {STEPS} steps per tooth period, {seconds:g} s simulated; "
          f"{machine}, Python {platform.python_version()}")  # fmt: skip
    print()
    print("| case | steps | wall s | simulated s per wall s | million steps per s |")
    print("|---|---:|---:|---:|---:|")
    for name, call in cases(seconds):
        warm = call()  # compiles, or loads the cached kernel
        wall = best(call, repeats)
        steps = warm.time_s.size
        simulated = steps * warm.tooth_period_s / warm.steps_per_tooth
        print(f"| {name} | {steps} | {wall:.4f} | {simulated / wall:.1f} | "
              f"{steps / wall / 1e6:.2f} |")  # fmt: skip
    setup = CalibrationSetup(ROYANDI, ROYANDI_SLOT, ROYANDI_CUTTER, 31.49e3, 21.85e3, True,
                             duration_s=0.05 if args.quick else 0.2)  # fmt: skip
    start = time.perf_counter()
    found = calibrate_cpd(setup, spindle_rad_s=7500 * RPM, depth_m=2.5e-3, feed_per_tooth_m=1e-4,
                          measured_rms_m_s2=3.487 * 9.80665)  # fmt: skip
    wall = time.perf_counter() - start
    print()
    print(f"C_pd calibration of one cut (Royandi 2026 Table 3: 7500 rpm, 2.5 mm, 0.1 mm/tooth, "
          f"{setup.duration_s:g} s per run at the default resolution): {found.evaluations} runs "
          f"in {wall:.3f} s, C_pd = {found.cpd_pa:.3g} N/m^2 ({found.status})")  # fmt: skip


if __name__ == "__main__":
    main()
