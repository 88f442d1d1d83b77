"""Benchmark of chatter detection and of the stability roadmap (issue 5, items 6 and 7).

Usage: ``python benchmarks/bench_chatter_detection.py [--quick]``. Prints a Markdown table
for docs/_bench_chatter_detection.md:

- the streaming detector in the twin's 12.5 ms cycle: per cycle, push the cycle's samples of
  an accelerometer sampled at 25.6 kHz (320 samples), a 0.1 s window (2560 samples, 10 Hz
  resolution) analysed every cycle; the median and the 99th percentile of the time per push
  (the cycle's budget is 12.5 ms);
- the batch detector over a 10 s record with the same windows;
- the roadmap of a synthetic four-pass program (map at 0.2 mm, ZOA on 1901 speeds).

``--quick`` runs 1 s of signal and skips the roadmap (CI).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from cnctwin.dynamics import (
    DetectorSettings,
    StreamingChatterDetector,
    detect_chatter,
)

FS = 25_600.0
CYCLE_S = 0.0125
PROGRAM = """G21 G90 G17 G94
T1 M6
S10000 M3
G0 X-10 Y10 Z5
G0 Z-0.5
G1 X70 F1000
G0 Z5
G0 X-10 Y30
G0 Z-2.0
G1 X70 F1000
G0 Z5
G0 X-10 Y17.5
G0 Z-0.5
G1 X70 F1000
G0 Z5
S13500
G0 X-10 Y45
G0 Z-2.0
G1 X70 F1000
M30
"""


def signal(seconds: float) -> np.ndarray:
    """Tooth-passing harmonics at 10000 rpm, 2 teeth, and a growing 931 Hz component."""
    t = np.arange(int(seconds * FS)) / FS
    rng = np.random.default_rng(1)
    harmonics = sum(np.sin(2 * np.pi * k * 333.333 * t) / k for k in range(1, 6))
    chatter = 0.5 * np.sin(2 * np.pi * 931.0 * t) * np.exp(3.0 * (t - seconds))
    return harmonics + chatter + 0.01 * rng.normal(size=t.size)


def bench_detection(seconds: float) -> list[str]:
    x = signal(seconds)
    settings = DetectorSettings(FS, 10000.0, 2, window_s=0.1, hop_s=CYCLE_S)
    per_cycle = int(round(CYCLE_S * FS))
    detector = StreamingChatterDetector(settings)
    detector.push(x[: settings.window_samples])  # warm-up: first window
    times = []
    for start in range(settings.window_samples, x.size - per_cycle + 1, per_cycle):
        begin = time.perf_counter()
        detector.push(x[start : start + per_cycle])
        times.append(time.perf_counter() - begin)
    begin = time.perf_counter()
    batch = detect_chatter(x, settings)
    batch_s = time.perf_counter() - begin
    us = np.array(times) * 1e6
    return [
        f"| streaming, {per_cycle} samples per 12.5 ms push, window {settings.window_samples} "
        f"| {len(times)} pushes | median {np.median(us):.0f} us, p99 "
        f"{np.percentile(us, 99):.0f} us, max {us.max():.0f} us |",
        f"| batch, {seconds:g} s record, {len(batch)} windows | {x.size} samples "
        f"| {batch_s:.3f} s ({batch_s / len(batch) * 1e6:.0f} us per window) |",
    ]


def bench_roadmap() -> str:
    from cnctwin.config import ToolConfig
    from cnctwin.dynamics import ToolDynamics, ToolMode, stability_roadmap
    from cnctwin.geometry import Cutter, DexelStock, EngagementMap
    from cnctwin.mechanics import CuttingCoefficients
    from cnctwin.nc import Interpreter, NCSetup

    tool = ToolConfig(number=1, diameter_mm=10.0, flutes=2, helix_deg=0.0, flute_length_mm=20.0)
    speeds: dict[int, float] = {}

    def recording():  # type: ignore[no-untyped-def]
        for segment in Interpreter(NCSetup()).run_text(PROGRAM):
            speeds[segment.line] = segment.spindle_rpm
            yield segment

    begin = time.perf_counter()
    stock = DexelStock.box((0.0, 0.0, -10.0), (60.0, 55.0, 0.0), 5.0)
    emap = EngagementMap.build(recording(), stock, {1: Cutter.from_tool_config(tool)}, step_mm=0.2)
    built = time.perf_counter() - begin
    dynamics = ToolDynamics.from_xy(x=[ToolMode.from_hz(922.0, 0.011, stiffness_n_m=1340049.648)])
    grid = np.arange(5000.0, 24001.0, 10.0)
    begin = time.perf_counter()
    road = stability_roadmap(emap, speeds, dynamics, CuttingCoefficients(6e8, 2e8), {1: 2}, grid)
    solved = time.perf_counter() - begin
    return (
        f"| roadmap, 4 passes, {len(emap)} map locations, {len(road.segments)} segments, "
        f"{len(road.lobes)} lobe diagrams x {grid.size} speeds (ZOA) | map {built:.2f} s "
        f"| roadmap {solved:.3f} s |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="1 s of signal, no roadmap (CI)")
    args = parser.parse_args()
    print(f"Python {platform.python_version()}, {platform.machine()}, numpy {np.__version__}")
    print()
    print("| case | size | time |")
    print("|---|---|---|")
    for row in bench_detection(1.0 if args.quick else 10.0):
        print(row)
    if not args.quick:
        print(bench_roadmap())


if __name__ == "__main__":
    main()
