"""Benchmark of the stability lobes: zero-order approximation and semi-discretization.

Usage: ``python benchmarks/bench_stability.py [--quick]``. Prints the load average and a
Markdown table (one row per case) for docs/benchmarks.md: the wall time of one lobe diagram
after a warm-up (numba kernels compiled or loaded from the cache), and its CPU time.

Targets (issue 5, item 9), measured as stated:

- "a ZOA lobe diagram over 400 speeds in under 0.1 s": ``zoa_lobes`` over 400 speeds,
  5000-25000 rpm, for the Insperger & Stépán slot (../shared/data/stability/NOTES.md
  section 1) and the UBC two-mode tool (section 2, half immersion, 2000-16000 rpm); the
  best of 5 runs.
- "the semi-discretization lobes of the Insperger benchmark over 400 speeds x 0-10 mm at
  0.05 mm resolution in under 10 s": ``sdm_lobes`` over 400 speeds, 5000-25000 rpm,
  m = 40 steps per tooth period, depths 0-10 mm (``max_depth_m=0.01``), for the four
  cases of section 1 (1-DOF and symmetric 2-DOF, slot and a/D = 0.05 down-milling), each
  searched two ways, one run each:

  * ``step 0.05 mm`` (``depth_step_m=5e-5``): the target's grid taken literally. Per speed
    the depths 0, 0.05, 0.10 ... mm are evaluated up to the first unstable one and Brent's
    method then places the crossing inside that step. This is the case the target refers
    to: its "0.05 mm resolution" fixes the depth grid (201 depths, like the 401 x 201 grid of
    the full-discretization GPU run the issue compares with), and only a 0.05 mm step
    guarantees that no unstable band thicker than 0.05 mm is stepped over. Unlike a grid
    method it does not evaluate the depths above the first unstable one, which the lobes do
    not need.
  * ``step 0.25 mm`` (the default, ``max_depth_m / 40``, what ``cnctwin stability lobes``
    uses): the same Brent refinement from a coarser upward search; it can step over an
    unstable band thinner than 0.25 mm.

  Both give the critical depth to the Brent tolerance (1e-8 m), far finer than 0.05 mm.

The UBC tool's SDM lobes (the automatic grid per speed: 30 steps per cycle of the 1449 Hz
mode in the cut) are timed too, for reference; no target applies to them.

The SDM roadmap (issue 16, item 4: "SDM defaults that finish a typical program's roadmap in
seconds"; it ran 25 minutes with 2,001 speeds before): ``program_roadmap(method="sdm")`` with
the defaults (the grid from half the lowest programmed speed, the SDM at 20 of its speeds,
the ZOA's shape between them, interpolated candidates computed before they are scheduled)
on the packaged demo (T1 with the UBC tool's modes, T2 without) and on the KIT notch program
(../shared/data/gcode, skipped without it), one run each.

``--quick`` (CI) runs 20 speeds once and the demo's roadmap at 2 dexels per mm over
7000-9000 rpm with the SDM at 4 speeds only.
"""

from __future__ import annotations

import argparse
import logging
import math
import platform
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

from cnctwin.dynamics import (
    MillingProcess,
    StabilityLobes,
    ToolDynamics,
    ToolMode,
    load_stability_config,
    program_roadmap,
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
MAX_DEPTH_M = 0.01
GRID_STEP_M = 5e-5

Case = tuple[str, str, int, int, Callable[[], StabilityLobes]]


def best_seconds(
    call: Callable[[], StabilityLobes], repeats: int
) -> tuple[float, float, StabilityLobes]:
    """Shortest of ``repeats`` wall times of ``call`` in s, that run's CPU time in s, the result.

    The CPU time (this process, all threads) is what the run costs on an otherwise idle
    core; on the shared sandbox the wall time exceeds it by the share other jobs take.
    """
    best = (math.inf, math.inf)
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        result = call()
        best = min(best, (time.perf_counter() - wall, time.process_time() - cpu))
    return best[0], best[1], result


def load_average() -> str:
    """The 1, 5 and 15 min load averages from /proc/loadavg, or "n/a" elsewhere."""
    path = Path("/proc/loadavg")
    return " ".join(path.read_text().split()[:3]) if path.exists() else "n/a"


def slot(immersion: float) -> MillingProcess:
    """Insperger & Stépán down-milling cut at radial immersion ``immersion`` (a/D)."""
    return MillingProcess.from_immersion(2, INSPERGER, immersion)


def build_cases(speeds: int, quick: bool) -> list[Case]:
    """(method, case, speeds, repeats, call) of every benchmark case."""
    zoa_repeats, sdm_repeats = (1, 1) if quick else (5, 1)
    insperger = np.linspace(5000.0, 25000.0, speeds) * RPM
    ubc = np.linspace(2000.0, 16000.0, speeds) * RPM
    cases: list[Case] = [
        ("zoa", "Insperger 1-DOF slot", speeds, zoa_repeats,
         lambda: zoa_lobes(ONE_DOF, slot(1.0), insperger)),
        ("zoa", "UBC two modes per axis, ae = D/2", speeds, zoa_repeats,
         lambda: zoa_lobes(UBC, UBC_CUT, ubc)),
    ]  # fmt: skip
    for label, tool in (("1-DOF", ONE_DOF), ("2-DOF", TWO_DOF)):
        for imm, where in ((1.0, "slot"), (0.05, "a/D = 0.05")):
            for step_m in (GRID_STEP_M, None):
                shown = f"{(MAX_DEPTH_M / 40 if step_m is None else step_m) * 1e3:.2f} mm"
                cases.append(
                    (
                        f"sdm, m = 40, step {shown}",
                        f"Insperger {label} {where}, 0-10 mm",
                        speeds,
                        sdm_repeats,
                        partial(
                            sdm_lobes, tool, slot(imm), insperger, max_depth_m=MAX_DEPTH_M,
                            steps=40, depth_step_m=step_m,
                        ),
                    )
                )  # fmt: skip
    cases.append(
        ("sdm, m = auto, step 0.15 mm", "UBC two modes per axis, ae = D/2, 0-6 mm", speeds,
         sdm_repeats, lambda: sdm_lobes(UBC, UBC_CUT, ubc, max_depth_m=0.006)),
    )  # fmt: skip
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="20 speeds, one run (CI)")
    args = parser.parse_args()
    speeds = 20 if args.quick else 400
    # The Insperger cases keep m = 40 at 5000 rpm on purpose: no warning about it.
    logging.getLogger("cnctwin").setLevel(logging.ERROR)
    # Warm-up: load or compile the numba kernels.
    zoa_lobes(ONE_DOF, slot(1.0), [1000.0])
    sdm_lobes(ONE_DOF, slot(1.0), [10000.0], max_depth_m=1e-3, steps=40)
    print(f"Python {platform.python_version()}, {platform.machine()}; "
          f"load average before: {load_average()}")  # fmt: skip
    print()
    print("| method | case | speeds | runs | wall (s) | CPU (s) | per speed (ms, wall) "
          "| lowest critical depth (mm) |")  # fmt: skip
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for method, case, count, repeats, call in build_cases(speeds, args.quick):
        seconds, cpu, result = best_seconds(call, repeats)
        print(
            f"| {method} | {case} | {count} | {repeats} | {seconds:.3f} | {cpu:.3f} "
            f"| {seconds / count * 1e3:.3f} | {result.min_critical_depth_m * 1e3:.4f} |",
            flush=True,
        )
    print()
    roadmaps(args.quick)
    print()
    print(f"load average after: {load_average()}")


def roadmaps(quick: bool) -> None:
    """The SDM roadmap of the demo and of the KIT notch program with the default settings."""
    from cnctwin.config import load_config

    root = Path(__file__).resolve().parents[1]
    examples = root / "src" / "cnctwin" / "examples"
    ubc = load_stability_config(root / "examples" / "stability" / "ubc_two_mode.toml")
    notch = root.parent / "shared/data/gcode/siemens_kit_dmc60h/AL_2007_T4_Notch_Normal.mpf"
    runs = [("demo.ngc (T1 modes: UBC; T2 none)", examples / "demo.ngc",
             examples / "demo.toml", {1: ubc}, 5.0)]  # fmt: skip
    if notch.exists() and not quick:
        runs.append(("KIT notch (UBC modes)", notch, root / "examples/kit_dmc60h_al2007.toml",
                     ubc, 5.0))  # fmt: skip
    print("| SDM roadmap | segments | lobe diagrams | grid speeds | SDM speeds | wall (s) "
          "| CPU (s) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, program, config_path, stability, density in runs:
        config = load_config(config_path)
        grid = np.linspace(7000.0, 9000.0, 201) if quick else None
        wall, cpu = time.perf_counter(), time.process_time()
        points = {"sdm_points": 4} if quick else {}
        density = 2.0 if quick else density
        road = program_roadmap(program, config, stability, grid, density_per_mm=density,
                               method="sdm", **points)  # type: ignore[arg-type]  # fmt: skip
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        computed = sum(
            road.spindle_rpm.size if lobe.exact is None else int(lobe.exact.sum())
            for lobe in road.lobes
        )
        print(f"| {name} | {len(road.segments)} | {len(road.lobes)} | {road.spindle_rpm.size} "
              f"| {computed} | {wall:.1f} | {cpu:.1f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
