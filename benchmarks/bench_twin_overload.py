"""Benchmark: the demo's session with busy-loop processes beside it; does the hole stop hold?

The question (issue 11): what cycle load does the twin hold with its protection intact? Each
run is the ``cnctwin demo`` session (the packaged ``demo_twin.toml``: the virtual machine in
a child process serving OPC UA on loopback at 2x real time, the twin in this process with
everything on, a hole in the machine's blank) while ``N`` processes spin in busy loops.
For each ``N`` the run's cycle p50/p99, overruns, the cycles run overloaded, the stages
shed (docs/twin.md, "Overload"), whether the hole stop fired and was confirmed by motion,
and how far from the hole the machine stopped.

Usage::

    python benchmarks/bench_twin_overload.py [--quick] [--loads 0,2,4,8] [--out FILE]

``--quick`` (CI, 2 cores): one run with one busy loop per core, under 60 s (the run stops at
the hole or after 35 s). ``--out``
writes the figures as Markdown. The busy loops are this script's children and are killed
when each run ends (also on an error or Ctrl-C).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import sqlite3
import subprocess
import sys
import tempfile
import time
from collections import Counter
from datetime import UTC, datetime
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

from cnctwin.store import Historian
from cnctwin.thread import RunState
from cnctwin.twin import MachineProcess, RunConfig, load_run_config, run_session
from cnctwin.virtual import HoleFault

#: Longest run, s (wall), quick and full: the demo reaches its hole in about 12 s at 2x real
#: time, later when the machine's own process is starved too (its clock drops ticks).
RUN_LIMIT_S = {"quick": 35.0, "full": 120.0}


def _with_endpoint(config: RunConfig, endpoint: str) -> RunConfig:
    connection = config.connection.model_copy(update={"endpoint": endpoint})
    return config.model_copy(update={"connection": connection})


def _busy_loops(n: int) -> list[subprocess.Popen[bytes]]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def _stop(loops: list[subprocess.Popen[bytes]]) -> None:
    for proc in loops:
        proc.kill()
    for proc in loops:
        proc.wait()


def one_run(config: RunConfig, folder: Path, busy: int, limit_s: float) -> dict[str, Any]:
    """The demo's session beside ``busy`` busy-loop processes."""
    loops: list[subprocess.Popen[bytes]] = []
    machine = MachineProcess(config, "opcua", log=folder / f"machine-{busy}.log")
    db = folder / f"history-{busy}.sqlite"
    try:
        machine.spawn()
        endpoint = machine.wait_ready()
        loops = _busy_loops(busy)
        with Historian.open(db) as historian:
            summary = asyncio.run(
                run_session(
                    _with_endpoint(config, endpoint),
                    historian=historian,
                    duration_s=limit_s,
                    on_start=lambda _twin: machine.go(),
                    meta={"benchmark": "bench_twin_overload", "busy_loops": busy},
                )
            )
        state = machine.state() or {}
    finally:
        _stop(loops)
        machine.stop()
    with sqlite3.connect(db) as conn:
        events = Counter(k for (k,) in conn.execute("SELECT kind FROM hist_events"))
        stops = [
            {"rule": rule, "action": action, "accepted": bool(accepted), "reason": reason}
            for rule, action, accepted, reason in conn.execute(
                "SELECT rule, action, accepted, reason FROM hist_decisions "
                "WHERE action IN ('feed_hold', 'stop', 'emergency_stop') ORDER BY seq"
            )
        ]
    assert config.virtual is not None
    hole = next(f for f in config.virtual.faults if isinstance(f, HoleFault))
    position = state.get("position_mm")
    x = None if position is None else position[0]
    return {
        "busy_loops": busy,
        "ended": summary.ended,
        "cycles": summary.cycles,
        "cycle_p50_ms": summary.cycle_p50_ms,
        "cycle_p99_ms": summary.cycle_p99_ms,
        "overruns": summary.overruns,
        "overrun_pct": 100.0 * summary.overruns / max(summary.cycles, 1),
        "overloaded_cycles": summary.overloaded_cycles,
        "shed": summary.shed,
        "events": dict(events),
        "stop_decisions": stops,
        "stop_fired": bool(summary.stop_reactions_ms),
        "stop_reaction_ms": summary.stop_reaction_ms,
        # the machine's own word (not the twin's): its run state and whether it stands
        "machine_run_state": RunState(state["run_state"]).name if "run_state" in state else None,
        "machine_at_rest": state.get("at_rest"),
        "machine_t_s": state.get("t_s"),
        # how far past the hole's entry the axes came to rest (X, mm; None without a stop)
        "stopped_past_hole_mm": (
            None if x is None or not summary.stop_reactions_ms else x - hole.min_mm[0]
        ),
    }


def _figure(value: float | None, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def markdown(result: dict[str, Any], command: str) -> str:
    rows = "\n".join(
        f"| {r['busy_loops']} | {r['cycles']} | {r['cycle_p50_ms']:.2f} | "
        f"{r['cycle_p99_ms']:.1f} | {r['overrun_pct']:.1f} % | {r['overloaded_cycles']} | "
        f"{', '.join(r['shed']) or '-'} | {'yes' if r['stop_fired'] else 'NO'} | "
        f"{_figure(r['stop_reaction_ms'], '.1f')} | {_figure(r['stopped_past_hole_mm'], '.1f')} | "
        f"{r['machine_run_state']} at {_figure(r['machine_t_s'], '.1f')} s |"
        for r in result["runs"]
    )
    return f"""# Benchmark: the twin under CPU load (bench_twin_overload)

Date: {result["date"]}. Machine: {result["cores"]} cores ({result["platform"]}). Command:
`{command}`.

| busy loops | cycles | p50 (ms) | p99 (ms) | overruns | overloaded cycles | shed | hole stop | reaction (ms) | stopped past hole entry (mm) | machine at the end (its clock) |
|---|---|---|---|---|---|---|---|---|---|---|
{rows}
"""  # noqa: E501


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one run, one busy loop per core (CI)")
    parser.add_argument(
        "--loads", default="0,2,4,8", help="busy-loop counts, comma separated (default 0,2,4,8)"
    )
    parser.add_argument("--out", type=Path, help="write the figures as Markdown here")
    args = parser.parse_args()
    cores = os.cpu_count() or 1
    try:
        loads = [cores] if args.quick else [int(n) for n in args.loads.split(",")]
    except ValueError:
        parser.error(f"--loads {args.loads!r}: give whole numbers separated by commas")
    if any(not 0 <= n <= 64 for n in loads):
        parser.error(f"--loads {args.loads!r}: each count must be 0 to 64")
    with as_file(files("cnctwin.examples")) as examples:
        config = load_run_config(Path(examples) / "demo_twin.toml")
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        limit = RUN_LIMIT_S["quick" if args.quick else "full"]
        runs = [one_run(config, Path(tmp), n, limit) for n in loads]
    result = {
        "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "platform": f"{platform.python_implementation()} {platform.python_version()}, "
        f"{platform.machine()}",
        "cores": cores,
        "wall_s": time.time() - started,
        "runs": runs,
    }
    print(json.dumps(result, indent=2))
    if args.out is not None:
        command = "python benchmarks/bench_twin_overload.py" + (
            " --quick" if args.quick else f" --loads {args.loads}"
        )
        args.out.write_text(markdown(result, command))


if __name__ == "__main__":
    main()
