"""A stop is confirmed by motion, not by a flag; a machine that does not stop is escalated.

The independent side is the virtual machine itself: its axes (read directly, not through
the twin) and its run state. The fake machines below acknowledge a command (the flag reads
back 1) but ignore it, as a control with a broken interlock or a wrong mapping would.
"""

from __future__ import annotations

import asyncio
import sqlite3

import pytest
from twin_helpers import STEP_S

from cnctwin.errors import InputError
from cnctwin.store.historian import Historian
from cnctwin.thread.signals import RunState
from cnctwin.twin.config import RunConfig
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import build_twin
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.settings import StopConfirmationConfig
from cnctwin.twin.state import TwinEvent
from cnctwin.twin.stopping import StopWatch
from cnctwin.virtual import VirtualMachine


class Ignores:
    """A virtual machine whose control acknowledges the ``ignored`` commands but does not
    act on them: the flag reads back 1, the axes go on along the program. With ``claims``
    its run state says STOPPED too while the program runs on."""

    def __init__(self, vm: VirtualMachine, ignored: tuple[str, ...], claims: bool) -> None:
        self.vm = vm
        self.ignored = ignored
        self.claims = claims
        self.flags: dict[str, float] = {}

    def snapshot(self) -> dict[str, float]:
        values = self.vm.snapshot()
        values.update(self.flags)
        running = values["run_state"] == RunState.RUNNING
        if self.claims and self.flags.get("stop") == 1.0 and running:
            values["run_state"] = float(RunState.STOPPED)
        return values

    def command(self, name: str, value: float) -> None:
        if name in self.ignored:
            self.flags[name] = value
            return
        self.vm.command(name, value)

    def step(self, dt_s: float) -> None:
        self.vm.step(dt_s)


def _run(
    config: RunConfig, ignored: tuple[str, ...], db, *, claims: bool = False
) -> tuple[RunSummary, list[TwinEvent], VirtualMachine]:
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    machine = Ignores(vm, ignored, claims)
    conn = LocalConnection(machine, step_s=STEP_S, tick_s=vm.tick_s)

    async def main() -> tuple[RunSummary, list[TwinEvent]]:
        await conn.connect()
        with Historian.open(db) as historian:
            recorder = Recorder(historian, {"test": "stop"}, 0.0)
            twin = build_twin(
                config, conn, recorder=recorder, program=config.virtual.program, realtime=False
            )
            summary = await twin.runtime.run(duration_s=120.0)
        await conn.close()
        return summary, twin.runtime.events

    summary, events = asyncio.run(main())
    return summary, events, vm


def _kinds(events: list[TwinEvent]) -> list[str]:
    return [e.kind for e in events]


def test_a_machine_that_stops_is_confirmed_at_rest(demo_config: RunConfig, tmp_path) -> None:
    summary, events, vm = _run(demo_config, (), tmp_path / "h.sqlite")
    kinds = _kinds(events)
    assert kinds.count("stop_confirmed") == 1
    assert "stop_escalated" not in kinds and "stop_not_confirmed" not in kinds
    confirmed = next(e for e in events if e.kind == "stop_confirmed")
    assert confirmed.data["steps"] == ["stop"]
    assert summary.ended == "stopped" and vm.run_state == RunState.STOPPED
    # the machine's own path follower: at rest (the twin waited for rest, not for the flag)
    assert vm.finished


def test_a_machine_that_ignores_stop_is_escalated_to_the_emergency_stop(
    demo_config: RunConfig, tmp_path
) -> None:
    db = tmp_path / "h.sqlite"
    summary, events, vm = _run(demo_config, ("feed_hold", "stop"), db)
    kinds = _kinds(events)
    # the stop flag read back 1 at once, yet the axes moved on: not confirmed, escalated
    escalation = next(e for e in events if e.kind == "stop_escalated")
    assert escalation.data["from"] == "stop" and escalation.data["to"] == "emergency_stop"
    assert escalation.data["speed_mm_min"] > 100.0
    assert kinds.index("stop_escalated") < kinds.index("stop_confirmed")
    confirmed = next(e for e in events if e.kind == "stop_confirmed")
    assert confirmed.data["steps"] == ["stop", "emergency_stop"]
    # the machine itself is in its emergency stop (FAULT) and the run ended on it
    assert vm.run_state == RunState.FAULT and vm.alarm == "emergency stop"
    assert summary.ended == "stopped"
    with sqlite3.connect(db) as conn:
        rows = conn.execute(
            "SELECT rule, action, value, reason, accepted FROM hist_decisions "
            "WHERE rule = 'stop_escalation'"
        ).fetchall()
    assert len(rows) == 1
    rule, action, value, reason, accepted = rows[0]
    assert (action, value, accepted) == ("emergency_stop", 1.0, 1)
    assert "stop not confirmed: axes still moving" in reason and "timeout_s = 0.5" in reason


def test_a_machine_that_ignores_every_step_is_reported_not_stopped(
    demo_config: RunConfig, tmp_path
) -> None:
    db = tmp_path / "h.sqlite"
    # its run state even says STOPPED: neither that nor the flags make a stop
    ignored = ("feed_hold", "stop", "emergency_stop")
    summary, events, vm = _run(demo_config, ignored, db, claims=True)
    kinds = _kinds(events)
    assert kinds.count("stop_not_confirmed") == 1
    assert "stop_confirmed" not in kinds
    assert summary.stop_reactions_ms == []
    failure = next(e for e in events if e.kind == "stop_not_confirmed")
    assert failure.data["steps"] == ["stop", "emergency_stop"]
    # the machine ran its program to the end: the run did not take the flags for a stop
    assert summary.ended == "finished" and vm.run_state == RunState.FINISHED
    with sqlite3.connect(db) as conn:
        rows = conn.execute(
            "SELECT action, accepted, reason FROM hist_decisions WHERE rule = 'stop_confirmation'"
        ).fetchall()
    assert len(rows) == 1 and rows[0][1] == 0
    assert "no further step" in rows[0][2]


def test_a_stop_the_machine_does_not_offer_is_not_escalated_to(demo_config: RunConfig) -> None:
    watch = StopWatch("stop", 0.0, StopConfirmationConfig(timeout_s=0.1))
    moving = {"t_s": 0.0, "x_mm": 0.0, "y_mm": 0.0, "z_mm": 0.0, "feed_mm_min": 1500.0}
    assert watch.update(moving, 0.0).verdict == "watching"
    later = dict(moving, t_s=0.2, x_mm=5.0)
    status = watch.update(later, 0.2)
    assert status.verdict == "failed"  # no emergency_stop in the reading: nothing to write
    assert status.speed_mm_min == pytest.approx(1500.0)
    offered = dict(later, t_s=0.4, x_mm=10.0, emergency_stop=0.0)
    status = watch.update(offered, 0.4)
    assert (status.verdict, status.next_step) == ("escalate", "emergency_stop")


def test_rest_is_judged_from_positions_and_feed_not_from_a_repeated_sample() -> None:
    config = StopConfirmationConfig(rest_speed_mm_min=6.0, rest_readings=2, timeout_s=1.0)
    watch = StopWatch("feed_hold", 0.0, config)
    rest = {"t_s": 1.0, "x_mm": 10.0, "y_mm": 20.0, "z_mm": -5.0, "feed_mm_min": 0.3}
    assert watch.update(rest, 0.0).verdict == "watching"  # one reading at rest
    # the same machine sample read again is no second reading at rest
    assert watch.update(rest, 0.01).verdict == "watching"
    # a creeping axis (0.01 mm in 25 ms = 24 mm/min) with a feed signal that reads 0
    creep = dict(rest, t_s=1.025, x_mm=10.01, feed_mm_min=0.0)
    status = watch.update(creep, 0.02)
    assert status.verdict == "watching" and status.speed_mm_min == pytest.approx(24.0)
    # sensor noise of half a micrometre is rest; two such readings confirm
    still = dict(creep, t_s=1.05, x_mm=10.0105)
    assert watch.update(still, 0.03).verdict == "watching"
    still2 = dict(still, t_s=1.075, x_mm=10.0100)
    assert watch.update(still2, 0.04).verdict == "confirmed"


def test_axes_last_seen_at_rest_get_twice_the_timeout_for_their_confirming_samples() -> None:
    config = StopConfirmationConfig(rest_speed_mm_min=6.0, rest_readings=2, timeout_s=0.5)
    offered = {"emergency_stop": 0.0, "y_mm": 0.0, "z_mm": 0.0, "feed_mm_min": 0.0}
    watch = StopWatch("stop", 0.0, config)
    assert watch.update({**offered, "t_s": 1.0, "x_mm": 0.0}, 0.0).verdict == "watching"
    # the machine publishes nothing new (starved): the same sample until past the timeout
    assert watch.update({**offered, "t_s": 1.0, "x_mm": 0.0}, 0.6).verdict == "watching"
    assert watch.update({**offered, "t_s": 1.0, "x_mm": 0.0}, 1.0).verdict == "escalate"
    # axes last seen moving: the plain timeout
    moving = StopWatch("stop", 0.0, config)
    moving.update({**offered, "t_s": 1.0, "x_mm": 0.0}, 0.0)
    status = moving.update({**offered, "t_s": 1.1, "x_mm": 1.0, "feed_mm_min": 600.0}, 0.6)
    assert (status.verdict, status.next_step) == ("escalate", "emergency_stop")


def test_emergency_stop_latches_a_fault_and_brings_the_axes_to_rest(
    demo_config: RunConfig,
) -> None:
    assert demo_config.virtual is not None
    vm = VirtualMachine(demo_config.virtual.model_copy(update={"faults": []}), demo_config)
    while vm.time_s < 5.0:  # in the first pass, feeding
        vm.step(vm.tick_s)
    assert vm.snapshot()["feed_mm_min"] > 100.0
    vm.command("emergency_stop", 1.0)
    assert vm.run_state == RunState.FAULT and vm.alarm == "emergency stop"
    for _ in range(50):
        vm.step(vm.tick_s)
    values = vm.snapshot()
    assert values["feed_mm_min"] == pytest.approx(0.0, abs=5.0)
    assert values["emergency_stop"] == 1.0 and values["stop"] == 1.0
    vm.command("emergency_stop", 0.0)  # an emergency stop is not released by a command
    assert vm.snapshot()["emergency_stop"] == 1.0 and vm.run_state == RunState.FAULT
    vm.restart()
    assert vm.snapshot()["emergency_stop"] == 0.0 and vm.run_state == RunState.RUNNING


def test_an_unknown_stop_step_is_an_input_error_naming_it() -> None:
    with pytest.raises(InputError, match="stop step 'halt'; valid: feed_hold"):
        StopWatch("halt", 0.0, StopConfirmationConfig())
