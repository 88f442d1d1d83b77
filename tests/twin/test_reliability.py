"""Reliability of the running twin: a machine server that goes away and comes back, garbage
values, a twin killed with SIGKILL (the historian afterwards), and a flood of rule firings.

The machine is the virtual machine behind the real OPC UA server on a free loopback port.
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from timeouts import BODY_S, CHILD_START_S
from twin_helpers import ServerOutage, served, without_faults

from cnctwin.store.historian import Historian
from cnctwin.thread.signals import SIGNALS, RunState
from cnctwin.twin.config import RunConfig
from cnctwin.twin.host import MachineServer
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import build_twin
from cnctwin.twin.session import run_session
from cnctwin.twin.state import CycleState

REPO = Path(__file__).resolve().parents[2]


def test_server_restart_mid_run_reconnects_and_records_the_gap(
    demo_config: RunConfig, tmp_path: Path
) -> None:
    clean = without_faults(demo_config)
    db = tmp_path / "h.sqlite"

    async def main():
        async with MachineServer(clean, "opcua", speed=1.0) as machine:
            config = served(clean, machine.endpoint)
            outage = ServerOutage(machine, after_s=1.5)
            with Historian.open(db) as historian:
                stop = asyncio.Event()

                def watch(state: CycleState) -> None:
                    # end 80 cycles after the reconnection that follows the restart (a count,
                    # not a time: a server restart takes about 1 s on a quiet machine, many
                    # more on a loaded one, where the heartbeat watchdog may also trip and
                    # recover before)
                    outage.watch(state)
                    if outage.restored and state.index >= outage.restored[0][0] + 80:
                        stop.set()

                summary = await run_session(
                    config,
                    historian=historian,
                    duration_s=BODY_S,
                    stop_event=stop,
                    on_cycle=watch,
                    on_start=outage.on_start,
                )
                await outage.finished()
            return summary, machine.vm.run_state, outage.restored[0][1]

    summary, run_state, gap_s = asyncio.run(asyncio.wait_for(main(), 2 * BODY_S))
    assert summary.reconnects >= 1
    # the server was away 1 s; its restart and the backoff come on top (how much depends on load)
    assert gap_s >= 0.9
    assert summary.ended == "interrupted"  # went on after the gap, and did not stop the machine
    assert run_state == RunState.RUNNING
    with sqlite3.connect(db) as conn:
        kinds = [k for (k,) in conn.execute("SELECT kind FROM hist_events ORDER BY seq")]
        gap = conn.execute(
            "SELECT data FROM hist_events WHERE kind = 'connection_restored'"
        ).fetchone()
        (samples,) = conn.execute("SELECT COUNT(*) FROM hist_frames WHERE kind = 0").fetchone()
    # (an 'overload' event of a loaded machine may come between them: not what is tested here)
    order = [k for k in kinds if not k.startswith("overload")]
    assert order[:4] == ["reached", "connected", "connection_lost", "connection_restored"]
    assert json.loads(gap[0])["gap_s"] == pytest.approx(summary.gaps_s[0])
    # a cycle records only a new sample; an overloaded twin keeps fewer (docs/twin.md)
    assert 0 < samples == summary.samples_recorded <= summary.cycles


class GarbageMachine:
    """A machine whose readings are partly garbage: NaN, infinities, absurd magnitudes, text,
    None and out-of-range states, changing every step."""

    BAD = (math.nan, math.inf, -1e300, "12,5", None, b"\x00", 7.0 + 1j)

    def __init__(self) -> None:
        self.values: dict[str, object] = dict.fromkeys(SIGNALS, 0.0)
        self.values.update(feed_override_pct=100.0, run_state=1.0, work_offset=1.0)
        self.k = 0

    def snapshot(self) -> dict[str, object]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        self.values[name] = value

    def step(self, dt_s: float) -> None:
        self.k += 1
        self.values["heartbeat"] = float(self.k)
        self.values["t_s"] = self.k * dt_s
        for i, name in enumerate(("force_x_n", "x_mm", "spindle_rpm", "run_state", "t_s")):
            self.values[name] = self.BAD[(self.k + i) % len(self.BAD)]
        self.values["feed_override_pct"] = 400.0 if self.k % 3 else 100.0  # out of range
        self.values["force_y_n"] = 1e9 if self.k % 5 == 0 else 10.0


def test_garbage_values_are_rejected_without_a_crash_or_a_decision(
    demo_config: RunConfig,
) -> None:
    machine = GarbageMachine()
    config = RunConfig.from_machining(
        demo_config,
        rules=[{"name": "halt", "condition": "force_out_of_band > 0.5", "action": "stop"}],
        control={"enabled": True},
        twin={"watchdog_s": 5.0},
    )
    rejected: dict[str, int] = {}

    def count(state: CycleState) -> None:
        for name in state.rejected:
            rejected[name] = rejected.get(name, 0) + 1
        # a garbage value never reaches the stages
        assert all(math.isfinite(v) and abs(v) < 1e8 for v in state.measured.values())

    async def main():
        conn = LocalConnection(machine, step_s=0.0125)  # type: ignore[arg-type]
        await conn.connect()
        twin = build_twin(config, conn, realtime=False)
        twin.runtime.on_cycle = count
        summary = await twin.runtime.run(duration_s=1.0)
        return summary, twin

    summary, twin = asyncio.run(main())
    assert summary.cycles > 50
    assert twin.actions.results == []  # nothing decided on garbage
    assert machine.values["stop"] == 0.0
    for name in ("force_x_n", "x_mm", "spindle_rpm", "run_state", "feed_override_pct"):
        assert rejected.get(name, 0) > 10, name
    assert rejected["force_y_n"] >= summary.cycles // 5 - 1


def test_garbage_over_opc_ua_is_rejected(demo_config: RunConfig) -> None:
    """NaN and out-of-range values published by a real OPC UA server."""

    class Source:
        def __init__(self) -> None:
            self.k = 0

        def snapshot(self) -> dict[str, float]:
            self.k += 1
            values = dict.fromkeys(SIGNALS, 1.0)
            values.update(heartbeat=float(self.k), t_s=0.01 * self.k)
            if self.k == 1:
                return values  # the server builds its address space from a sane first one
            values.update(
                force_x_n=math.nan,
                run_state=math.nan,  # an integer node: BadOutOfRange
                feed_override_pct=1e9,
                x_mm=-math.inf,
            )
            return values

        def command(self, name: str, value: float) -> None:
            pass

    from cnctwin.virtual.opcua_server import OpcUaMachineServer

    async def main():
        source = Source()
        async with OpcUaMachineServer(source) as server:
            config = served(RunConfig.from_machining(demo_config), server.endpoint)
            seen: list[CycleState] = []

            async def publish() -> None:
                while True:
                    server.publish(source.snapshot())
                    await asyncio.sleep(0.01)

            pub = asyncio.get_running_loop().create_task(publish())
            try:
                summary = await run_session(config, duration_s=0.6, on_cycle=seen.append)
            finally:
                pub.cancel()
            return summary, seen

    summary, seen = asyncio.run(asyncio.wait_for(main(), 30))
    assert summary.cycles > 10
    last = seen[-1]
    assert {"force_x_n", "run_state", "feed_override_pct", "x_mm"} <= set(last.rejected)
    assert "force_y_n" in last.measured


def test_flood_of_rule_firings_is_bounded_by_the_safety_filter(demo_config: RunConfig) -> None:
    """Rules that fire every cycle with ever-changing values: the machine sees at most
    ``1 + T / min_interval_s`` writes per override and ``max_commands_per_s * (1 + T)`` in all
    over ``T`` s of twin time (the bound of :mod:`cnctwin.control.safety`)."""
    from test_twin_runtime import FakeMachine

    machine = FakeMachine()
    config = RunConfig.from_machining(
        demo_config,
        rules=[
            {
                "name": "feed_flood",
                "condition": "heartbeat > 0",
                "action": "feed_override",
                "value": "50 + heartbeat - 7 * (heartbeat / 7 - heartbeat / 7)",
                "cooldown_s": 0.0,
            },
            {
                "name": "feed_flood_2",
                "condition": "heartbeat > 0",
                "action": "feed_override",
                "value": "heartbeat / 10",
                "cooldown_s": 0.0,
            },
            {
                "name": "spindle_flood",
                "condition": "heartbeat > 0",
                "action": "spindle_override",
                "value": "80 + heartbeat / 20",
                "cooldown_s": 0.0,
            },
        ],
        control={
            "enabled": True,
            "min_interval_s": 0.1,
            "max_commands_per_s": 5.0,
            "spindle_override": {"min_pct": 80.0, "max_pct": 120.0},
        },
    )
    cycles = 800  # 10 s of twin time at 12.5 ms

    async def main():
        conn = LocalConnection(machine, step_s=0.0125)
        await conn.connect()
        twin = build_twin(config, conn, realtime=False)
        twin.runtime.on_cycle = lambda s: None
        await twin.runtime.run(duration_s=None, stop_event=_stop_after(twin, cycles))
        return twin

    twin = asyncio.run(main())
    span_s = cycles * config.twin.cycle_s
    feed = [v for n, v in machine.commands if n == "feed_override_pct"]
    spindle = [v for n, v in machine.commands if n == "spindle_override_pct"]
    assert len(twin.actions.results) > 2 * cycles  # the flood reached the filter
    assert 0 < len(feed) <= 1 + span_s / 0.1
    assert 0 < len(spindle) <= 1 + span_s / 0.1
    assert len(feed) + len(spindle) <= 5.0 * (1 + span_s)
    assert all(10.0 <= v <= 100.0 for v in feed)  # the default feed bounds
    assert all(80.0 <= v <= 120.0 for v in spindle)


def _stop_after(twin, cycles: int) -> asyncio.Event:
    event = asyncio.Event()
    previous = twin.runtime.on_cycle

    def check(state: CycleState) -> None:
        if previous is not None:
            previous(state)
        if state.index + 1 >= cycles:
            event.set()

    twin.runtime.on_cycle = check
    return event


def test_sigkill_leaves_a_sound_database_missing_at_most_the_last_second(
    tmp_path: Path,
) -> None:
    db = tmp_path / "killed.sqlite"
    command = [
        sys.executable,
        "-m",
        "cnctwin",
        "demo",
        "--db",
        str(db),
        "--speed",
        "1",
        "--duration",
        "60",
        "--json",
    ]
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=REPO
    )
    try:
        deadline = time.monotonic() + CHILD_START_S
        recorded = 0.0
        while time.monotonic() < deadline and recorded < 4.0:
            time.sleep(0.25)
            recorded = _last_sample_s(db)
        assert recorded >= 4.0, f"the demo did not record 4 s of samples in {CHILD_START_S} s"
        time.sleep(1.3)
        os.kill(process.pid, signal.SIGKILL)
        killed_at = time.time()
        process.wait(10)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(10)
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        started_at, status = conn.execute("SELECT started_at, status FROM hist_runs").fetchone()
        (last,) = conn.execute("SELECT MAX(t_s) FROM hist_frames WHERE kind = 0").fetchone()
    assert status == "running"  # never ended: killed
    lost_s = (killed_at - started_at) - last
    assert lost_s <= 1.0 + 0.3  # flush interval 0.25 s; 0.3 s slack for the kill's timing


def _last_sample_s(db: Path) -> float:
    if not db.exists():
        return 0.0
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0) as conn:
            row = conn.execute("SELECT MAX(t_s) FROM hist_frames WHERE kind = 0").fetchone()
    except sqlite3.Error:
        return 0.0
    return float(row[0]) if row and row[0] is not None else 0.0
