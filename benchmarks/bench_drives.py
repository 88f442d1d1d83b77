"""Benchmark of the spindle drive: how many times faster than real time it runs.

Usage: ``python benchmarks/bench_drives.py [--quick]``. Prints a Markdown table (one row per
case) for docs/benchmarks.md. The drive is the "christiand2024" preset at 20,000 rpm running a
slot cycle (spindle on, idle, cut with a 1 mN m cutting torque, idle), at a 10 kHz step:

* ``simulate``: one batch call over the whole cycle;
* ``step``: the live twin's calls, one per 12.5 ms cycle (125 steps of 0.1 ms each), and one per
  0.1 ms step (the per-call overhead dominates).

Each figure is the best of several repetitions, after a warm-up call that compiles (or loads)
the numba kernel. ``--quick`` runs short cycles in a few seconds, to prove the script still runs.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from cnctwin.drives import EventState, MachiningEvents, SpindleDrive, spindle_preset

STEP_S = 1e-4  # 10 kHz
REF_RPM = 20000.0
LOAD_NM = 1e-3


def slot_events(t: np.ndarray, t_end: float) -> MachiningEvents:
    """Spindle on throughout; feed over the middle 60 %, contact over the middle 40 %."""
    return MachiningEvents.from_intervals(
        t,
        spindle_s=[(0.0, t_end)],
        feed_s=[(0.2 * t_end, 0.8 * t_end)],
        contact_s=[(0.3 * t_end, 0.7 * t_end)],
    )


def best_of(repeats: int, fn: object) -> float:
    """Smallest wall time of ``repeats`` calls of ``fn``, s."""
    assert callable(fn)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def bench_simulate(t_end: float, repeats: int) -> tuple[str, float, int, float]:
    drive = SpindleDrive(spindle_preset("christiand2024"), step_s=STEP_S)
    t = np.arange(0.0, t_end, STEP_S)
    events = slot_events(t, t_end)
    drive.simulate(t[:10], REF_RPM, LOAD_NM, slot_events(t[:10], t_end))  # warm-up
    wall = best_of(repeats, lambda: drive.simulate(t, REF_RPM, LOAD_NM, events))
    return "simulate (batch)", t_end, t.size, wall


def bench_step(t_end: float, cycle_s: float, repeats: int) -> tuple[str, float, int, float]:
    drive = SpindleDrive(spindle_preset("christiand2024"), step_s=STEP_S)
    n_calls = round(t_end / cycle_s)
    idle, cutting = EventState(feed_on=False, in_contact=False), EventState()
    schedule = [cutting if 0.3 <= k / n_calls < 0.7 else idle for k in range(n_calls)]
    drive.step(cycle_s, REF_RPM, LOAD_NM, idle)  # warm-up

    def run() -> None:
        drive.reset()
        for events in schedule:
            drive.step(cycle_s, REF_RPM, LOAD_NM, events)

    wall = best_of(repeats, run)
    label = f"step() per {cycle_s * 1e3:g} ms cycle"
    return label, t_end, round(t_end / STEP_S), wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short cycles, a few seconds")
    args = parser.parse_args()
    t_batch, t_live, repeats = (2.0, 0.5, 3) if args.quick else (60.0, 10.0, 7)
    rows = [
        bench_simulate(t_batch, repeats),
        bench_step(t_live, 0.0125, repeats),
        bench_step(t_live, STEP_S, repeats),
    ]
    print(f"Spindle drive, christiand2024 preset, 10 kHz step; {platform.processor() or 'cpu'}, "
          f"Python {platform.python_version()}\n")  # fmt: skip
    print("| case | simulated time (s) | steps | wall time (ms) | ns per step | x real time |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, sim_s, steps, wall in rows:
        print(
            f"| {label} | {sim_s:g} | {steps} | {wall * 1e3:.2f} | {wall / steps * 1e9:.0f} "
            f"| {sim_s / wall:,.0f} |"
        )


if __name__ == "__main__":
    main()
