"""The runtime: fixed-period cycle with absolute deadlines, stage timing, overruns, watchdog,
and the lost-connection policy (docs/twin.md).

The period and overrun tests run the runtime on virtual time (tests/virtual_time.py), so their
counts are exact on a loaded machine too; the watchdog and outage tests stage their faults by
cycle count, never by wall time. Cycle timing figures are measured in benchmarks/.
"""

from __future__ import annotations

import asyncio

import pytest
from virtual_time import VirtualClock, run

from cnctwin.thread.signals import SIGNALS, RunState
from cnctwin.twin.config import RunConfig
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import build_twin
from cnctwin.twin.state import CycleState


class FakeMachine:
    """A machine that stands still: every signal readable, commands applied at once."""

    def __init__(self) -> None:
        self.values = dict.fromkeys(SIGNALS, 0.0)
        self.values.update(
            feed_override_pct=100.0,
            spindle_override_pct=100.0,
            run_state=float(RunState.RUNNING),
            work_offset=1.0,
        )
        self.beating = True
        self.commands: list[tuple[str, float]] = []

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        self.commands.append((name, value))
        self.values[name] = value
        if name == "stop" and value == 1.0:
            self.values["run_state"] = float(RunState.STOPPED)

    def step(self, dt_s: float) -> None:
        self.values["t_s"] += dt_s
        if self.beating:
            self.values["heartbeat"] += 1


def config(demo: RunConfig, rules: list[dict], **control: object) -> RunConfig:
    return RunConfig.from_machining(
        demo,
        rules=rules,
        control={"enabled": True, **control},
        twin={"watchdog_s": 0.05, "cycle_s": 0.005},
    )


def test_cycles_keep_the_period_and_time_every_stage(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    conn = LocalConnection(machine, step_s=0.005)
    cfg = config(demo_config, [])
    clock = VirtualClock()

    async def main() -> tuple[int, float]:
        await conn.connect()
        twin = build_twin(cfg, conn, clock=clock.monotonic)
        started = clock.monotonic()
        summary = await twin.runtime.run(duration_s=0.4975)  # half a period short of 0.5 s
        return summary.cycles, clock.monotonic() - started

    cycles, elapsed = run(main(), clock)
    twin_stages = {"read", "kinematics", "cut", "forces", "rules", "actions"}
    # absolute deadlines: the first cycle at 0 and one every 5 ms up to the first at or past
    # the duration, 0.5 s: 101 cycles
    assert elapsed == pytest.approx(0.5)
    assert cycles == 101
    assert twin_stages <= set(build_twin(cfg, conn).runtime.timings)


def test_overruns_are_counted_and_missed_deadlines_skipped(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    conn = LocalConnection(machine, step_s=0.01)
    cfg = config(demo_config, [])
    clock = VirtualClock()

    class Slow:
        name = "slow"

        def __init__(self) -> None:
            self.slow_cycles = 0

        def process(self, state: CycleState) -> CycleState:
            if state.index % 10 == 5:
                clock.sleep(0.025)  # 2.5 periods
                self.slow_cycles += 1
            return state

    slow = Slow()

    async def main():
        await conn.connect()
        twin = build_twin(cfg, conn, clock=clock.monotonic)
        twin.runtime.cycle_s = 0.01
        twin.runtime.stages.append(slow)
        twin.runtime.timings["slow"] = type(twin.runtime.cycle_times)()
        return await twin.runtime.run(duration_s=0.955)

    summary = run(main(), clock)
    # every slow cycle, and only those, overruns: the run ends at the 96th period (0.96 s, the
    # first at or past 0.955 s), between two slow cycles (every 12th period from the 5th), and
    # each slow cycle skips two deadlines (it ends 25 ms after its start, past the next two)
    assert slow.slow_cycles == 8
    assert summary.overruns == slow.slow_cycles
    assert summary.cycles == 97 - 2 * slow.slow_cycles
    assert summary.stages_ms["slow"]["max_ms"] == pytest.approx(25.0)
    assert summary.cycle_max_ms == pytest.approx(25.0)


def test_stale_heartbeat_is_a_lost_machine_and_its_return_a_gap(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    conn = LocalConnection(machine, step_s=0.005)
    cfg = config(demo_config, [])

    async def main():
        await conn.connect()
        twin = build_twin(cfg, conn)
        events = []
        stop = asyncio.Event()

        def watch(state: CycleState) -> None:
            events.extend(state.events)
            if state.index == 20:
                machine.beating = False  # frozen control: answers, but nothing moves
            if state.index == 60:
                machine.beating = True
            if state.index == 120:
                stop.set()

        twin.runtime.on_cycle = watch
        summary = await twin.runtime.run(stop_event=stop)
        return summary, events

    summary, events = asyncio.run(main())
    assert events[0].kind == "reached"  # the first answered read, before any fresh sample
    events = events[1:]
    kinds = [e.kind for e in events]
    assert kinds[:3] == ["connected", "connection_lost", "connection_restored"]
    assert "heartbeat stale" in events[1].message
    # frozen from cycle 20 to 60, 40 periods of 5 ms apart at least (a loaded machine only
    # stretches them): the watchdog (50 ms) trips, and the gap is at least the frozen time
    # less one watchdog period and the slack of a late cycle 20
    assert summary.gaps_s[0] >= 0.2 - 0.05 - 0.01
    assert summary.reconnects == 1


def _run_with_gap(cfg: RunConfig, machine: FakeMachine, during_gap) -> tuple[list, list]:
    conn = LocalConnection(machine, step_s=0.005)

    async def main():
        await conn.connect()
        twin = build_twin(cfg, conn)
        events = []
        stop = asyncio.Event()

        def outage(state: CycleState) -> None:
            # by cycle count, so every run sees the same outage however loaded the machine
            events.extend(state.events)
            if state.index == 40:
                conn.drop()
            if state.index == 60:
                during_gap(machine)
                conn.restore()
            if state.index == 160:
                stop.set()

        twin.runtime.on_cycle = outage
        await twin.runtime.run(stop_event=stop)
        return events, twin.actions.results

    return asyncio.run(main())


def test_lowered_feed_override_stays_lowered_after_a_lost_connection(
    demo_config: RunConfig,
) -> None:
    machine = FakeMachine()
    cfg = config(
        demo_config,
        [
            {
                "name": "slow_down",
                "condition": "t_s > 0.05",
                "action": "feed_override",
                "value": 60.0,
                "cooldown_s": 100.0,
            }
        ],
    )

    def restart_control(m: FakeMachine) -> None:
        m.values["feed_override_pct"] = 100.0  # a restarted control comes back at 100 %

    events, results = _run_with_gap(cfg, machine, restart_control)
    kinds = [e.kind for e in events]
    assert "connection_lost" in kinds and "connection_restored" in kinds
    assert machine.values["feed_override_pct"] == 60.0
    assert machine.commands.count(("feed_override_pct", 60.0)) == 2  # rule, then the policy
    policy = [r for r in results if r.verdict.decision.rule == "reconnect"]
    assert policy and policy[0].confirmed
    assert any(e.kind == "reconnect_policy" for e in events)


def test_raised_feed_override_does_not_survive_a_lost_connection(
    demo_config: RunConfig,
) -> None:
    machine = FakeMachine()
    cfg = config(
        demo_config,
        [
            {
                "name": "speed_up",
                "condition": "t_s > 0.05",
                "action": "feed_override",
                "value": 120.0,
                "cooldown_s": 100.0,
            }
        ],
        feed_override={"min_pct": 10.0, "max_pct": 130.0},
    )
    events, _ = _run_with_gap(cfg, machine, lambda m: None)
    assert ("feed_override_pct", 120.0) in machine.commands
    assert machine.values["feed_override_pct"] == 100.0  # capped at the programmed feed


def test_stop_set_by_the_twin_stays_and_is_never_released(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    cfg = config(
        demo_config,
        [{"name": "halt", "condition": "t_s > 0.05", "action": "stop"}],
    )

    async def main():
        conn = LocalConnection(machine, step_s=0.005)
        await conn.connect()
        twin = build_twin(cfg, conn)
        summary = await twin.runtime.run(duration_s=1.0)
        return summary

    summary = asyncio.run(main())
    assert summary.ended == "stopped"
    assert machine.values["stop"] == 1.0
    assert ("stop", 0.0) not in machine.commands
    assert len(summary.stop_reactions_ms) == 1


def test_control_disabled_writes_nothing_but_records_decisions(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    cfg = RunConfig.from_machining(
        demo_config,
        rules=[{"name": "halt", "condition": "t_s > 0.02", "action": "stop", "cooldown_s": 0.05}],
    )

    async def main():
        conn = LocalConnection(machine, step_s=0.005)
        await conn.connect()
        twin = build_twin(cfg, conn)
        await twin.runtime.run(duration_s=0.3)
        return twin.actions.results

    results = asyncio.run(main())
    assert machine.commands == []
    assert results and all(r.verdict.outcome == "blocked" for r in results)
