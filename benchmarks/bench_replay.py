"""Benchmark of the recorded machine: the UMich experiment files served over OPC UA at 10x.

Usage: ``python benchmarks/bench_replay.py [--quick] [--speed X]``. Prints a Markdown table for
docs/benchmarks.md: for each file of ``umich_cnc_mill_tool_wear`` (the shared data,
``$CNCTWIN_DATA`` or ``../shared/data``), read through examples/replay/umich.toml, then served
the way ``cnctwin virtual serve --replay`` serves it (``cnctwin.twin.MachineServer``: the
machine clock publishing every 100 ms row into the OPC UA server's address space) at ``--speed``
(default 10) x real time: the time to read and map the file, the recorded time served, the wall
time, the CPU time of the process, and the clock's counters (ticks, late ticks: started more
than half a tick after their deadline, dropped ticks, the largest lag). A replay keeps up when
no tick is dropped and the wall time is the recorded time over the speed.

``--quick`` serves the first 20 s of recorded time of experiment_05 only (CI).
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import platform
import sys
import time
from pathlib import Path

from cnctwin.twin import MachineServer
from cnctwin.virtual import ReplayMachine, load_replay_map, read_replay_log

REPO = Path(__file__).resolve().parents[1]
MAP = REPO / "examples" / "replay" / "umich.toml"


def data_folder() -> Path | None:
    root = Path(os.environ.get("CNCTWIN_DATA") or REPO.parent / "shared" / "data")
    folder = root / "umich_cnc_mill_tool_wear"
    return folder if folder.is_dir() else None


async def serve(path: Path, speed: float, limit_s: float | None) -> str:
    began = time.perf_counter()
    log = read_replay_log(path, load_replay_map(MAP))
    read_ms = (time.perf_counter() - began) * 1e3
    replay = ReplayMachine(log)
    machine = MachineServer(None, "opcua", speed, replay=replay)
    await machine.start()
    try:
        duration = log.duration_s if limit_s is None else min(limit_s, log.duration_s)
        wall0 = time.perf_counter()
        cpu0 = time.process_time()
        stats = await machine.clock.run(duration)
        wall = time.perf_counter() - wall0
        cpu = time.process_time() - cpu0
    finally:
        await machine.stop()
    return (
        f"| {path.name} | {log.rows_read} | {sum(log.glitch_rows.values())} | {read_ms:.0f} "
        f"| {stats.machine_time_s:.1f} | {wall:.2f} | {stats.machine_time_s / wall:.2f} "
        f"| {cpu:.2f} | {stats.ticks} | {stats.late_ticks} | {stats.dropped_ticks} "
        f"| {stats.max_lag_s * 1e3:.1f} |"
    )


async def main(quick: bool, speed: float) -> int:
    folder = data_folder()
    if folder is None:
        message = "bench_replay: the UMich data (umich_cnc_mill_tool_wear) is absent"
        print(message, file=sys.stderr)
        return 1 if os.environ.get("CNCTWIN_REQUIRE_DATA") == "1" else 0
    files = [folder / "experiment_05.csv"] if quick else sorted(folder.glob("experiment_*.csv"))
    print(f"replay over OPC UA at {speed:g}x real time; {platform.processor() or 'cpu'}, "
          f"Python {platform.python_version()}; load {os.getloadavg()[0]:.2f}")  # fmt: skip
    print()
    print(
        "| file | rows | glitch rows | read ms | recorded s | wall s | x real time | CPU s "
        "| ticks | late | dropped | max lag ms |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for path in files:
        print(await serve(path, speed, 20.0 if quick else None), flush=True)
    return 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20 s of one file (CI)")
    parser.add_argument("--speed", type=float, default=10.0, help="x real time (default 10)")
    args = parser.parse_args()
    logging.getLogger("asyncua").setLevel(logging.ERROR)
    sys.exit(asyncio.run(main(args.quick, args.speed)))
