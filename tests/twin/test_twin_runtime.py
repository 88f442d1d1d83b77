"""The runtime: fixed-period cycle with absolute deadlines, stage timing, overruns, watchdog,
and the lost-connection policy (docs/twin.md)."""

from __future__ import annotations

import asyncio
import time

import pytest

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
    return RunConfig.from_physics(
        demo,
        rules=rules,
        control={"enabled": True, **control},
        twin={"watchdog_s": 0.05, "cycle_s": 0.005},
    )


def test_cycles_keep_the_period_and_time_every_stage(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    conn = LocalConnection(machine, step_s=0.005)
    cfg = config(demo_config, [])

    async def main() -> tuple[int, float]:
        await conn.connect()
        twin = build_twin(cfg, conn)
        started = time.monotonic()
        summary = await twin.runtime.run(duration_s=0.5)
        return summary.cycles, time.monotonic() - started

    cycles, elapsed = asyncio.run(main())
    twin_stages = {"read", "kinematics", "cut", "process", "rules", "actions"}
    # absolute deadlines: the count follows the wall clock (0.5 s / 5 ms = 100), a late wake-up
    # does not push later cycles back; a loaded 2-core box may drop a few
    assert 0.5 <= elapsed < 0.7
    assert 80 <= cycles <= 101
    assert twin_stages <= set(build_twin(cfg, conn).runtime.timings)


def test_overruns_are_counted_and_missed_deadlines_skipped(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    conn = LocalConnection(machine, step_s=0.01)
    cfg = config(demo_config, [])

    class Slow:
        name = "slow"

        def __init__(self) -> None:
            self.slow_cycles = 0

        def process(self, state: CycleState) -> CycleState:
            if state.index % 10 == 5:
                time.sleep(0.025)  # 2.5 periods
                self.slow_cycles += 1
            return state

    slow = Slow()

    async def main():
        await conn.connect()
        twin = build_twin(cfg, conn)
        twin.runtime.cycle_s = 0.01
        twin.runtime.stages.append(slow)
        twin.runtime.timings["slow"] = type(twin.runtime.cycle_times)()
        return await twin.runtime.run(duration_s=1.0)

    summary = asyncio.run(main())
    assert summary.overruns >= slow.slow_cycles >= 5
    assert summary.overruns <= slow.slow_cycles + 10  # a loaded machine adds a few
    # skipped deadlines: 1 s at 10 ms is 100 deadlines; each slow cycle eats about 3
    assert summary.cycles <= 100 - 2 * slow.slow_cycles + 5
    assert summary.stages_ms["slow"]["max_ms"] >= 25.0
    assert summary.cycle_max_ms >= 25.0


def test_stale_heartbeat_is_a_lost_machine_and_its_return_a_gap(demo_config: RunConfig) -> None:
    machine = FakeMachine()
    conn = LocalConnection(machine, step_s=0.005)
    cfg = config(demo_config, [])

    async def main():
        await conn.connect()
        twin = build_twin(cfg, conn)
        events = []

        def watch(state: CycleState) -> None:
            events.extend(state.events)
            if state.index == 20:
                machine.beating = False  # frozen control: answers, but nothing moves
            if state.index == 60:
                machine.beating = True

        twin.runtime.on_cycle = watch
        summary = await twin.runtime.run(duration_s=0.6)
        return summary, events

    summary, events = asyncio.run(main())
    kinds = [e.kind for e in events]
    assert kinds[:3] == ["connected", "connection_lost", "connection_restored"]
    assert "heartbeat stale" in events[1].message
    # frozen from cycle 20 to 60 at 5 ms: lost after 50 ms of staleness, back at cycle 60;
    # the gap runs from the last moving heartbeat (cycle 20), not from the detection
    assert summary.gaps_s[0] == pytest.approx(0.2, abs=0.08)
    assert summary.reconnects == 1


def _run_with_gap(cfg: RunConfig, machine: FakeMachine, during_gap) -> tuple[list, list]:
    conn = LocalConnection(machine, step_s=0.005)

    async def main():
        await conn.connect()
        twin = build_twin(cfg, conn)
        events = []

        async def outage() -> None:
            await asyncio.sleep(0.2)
            conn.drop()
            await asyncio.sleep(0.1)
            during_gap(machine)
            conn.restore()

        task = asyncio.get_running_loop().create_task(outage())
        twin.runtime.on_cycle = lambda s: events.extend(s.events)
        await twin.runtime.run(duration_s=0.8)
        await task
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
    cfg = RunConfig.from_physics(
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
