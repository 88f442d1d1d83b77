"""An overloaded twin says so, sheds optional work, and still stops the machine at the hole.

The overload is injected, not produced by CPU load: the runtime runs on a fake clock whose
``sleep`` advances it, and a wrapped stage advances it by a fixed cost per cycle (a slow cut).
The virtual machine moves with the fake clock (twice real time, as in the demo), so a slow
twin sees the machine move several of its periods between two readings, as it would on a
loaded computer. The independent side is the virtual machine's own run state and the
hole's position in its configuration.
"""

from __future__ import annotations

import asyncio
import sqlite3

import pytest
from twin_helpers import load_demo_config

from cnctwin.control.config import RuleConfig
from cnctwin.errors import InputError
from cnctwin.store.historian import Historian
from cnctwin.thread.signals import RunState
from cnctwin.twin.config import RunConfig
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import SHED_ORDER, build_twin, shed_order
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.state import CycleState, TwinEvent
from cnctwin.twin.timing import OverloadMonitor
from cnctwin.virtual import VirtualMachine
from cnctwin.virtual.config import HoleFault


class FakeClock:
    """Fake time, s; the machine runs ``speed`` machine seconds per fake second."""

    def __init__(self, vm: VirtualMachine, speed: float) -> None:
        self.t = 1000.0
        self.vm = vm
        self.speed = speed
        self._owed = 0.0

    def now(self) -> float:
        return self.t

    def advance(self, dt_s: float) -> None:
        self.t += dt_s
        self._owed += dt_s * self.speed
        tick = self.vm.tick_s
        while self._owed >= tick:
            self.vm.step(tick)
            self._owed -= tick

    async def sleep(self, dt_s: float) -> None:
        self.advance(dt_s)
        await asyncio.sleep(0)


class Slow:
    """A stage that costs ``cost_s`` of fake time every cycle."""

    def __init__(self, stage, clock: FakeClock, cost_s: float) -> None:
        self.stage = stage
        self.name = stage.name
        self.clock = clock
        self.cost_s = cost_s

    def process(self, state: CycleState) -> CycleState:
        self.clock.advance(self.cost_s)
        return self.stage.process(state)


def _run(
    config: RunConfig, cost_s: float, db
) -> tuple[RunSummary, list[TwinEvent], VirtualMachine, list[CycleState]]:
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    clock = FakeClock(vm, config.virtual.speed)
    conn = LocalConnection(vm)
    seen: list[CycleState] = []

    async def main() -> tuple[RunSummary, list[TwinEvent]]:
        await conn.connect()
        with Historian.open(db) as historian:
            recorder = Recorder(historian, {"test": "overload"}, 0.0)
            twin = build_twin(
                config,
                conn,
                recorder=recorder,
                program=config.virtual.program,
                clock=clock.now,
                sleep=clock.sleep,
            )
            runtime = twin.runtime
            runtime.stages = [
                Slow(s, clock, cost_s) if s.name == "cut" else s for s in runtime.stages
            ]
            runtime.on_cycle = seen.append
            summary = await runtime.run(duration_s=60.0)
        await conn.close()
        return summary, runtime.events

    summary, events = asyncio.run(main())
    return summary, events, vm, seen


def test_overloaded_twin_reports_sheds_and_still_stops_at_the_hole(tmp_path) -> None:
    config = load_demo_config()
    db = tmp_path / "h.sqlite"
    # a cut that takes 40 ms in a 12.5 ms period: every cycle overruns; the machine moves
    # 80 ms of machine time between two readings
    summary, events, vm, seen = _run(config, 0.040, db)
    kinds = [e.kind for e in events]
    assert "overload" in kinds
    overload = next(e for e in events if e.kind == "overload")
    assert overload.data["overrun_fraction"] >= config.twin.overload.enter_fraction
    assert "protection" in overload.message and "shedding historian_detail" in overload.message
    # the live view (on_cycle) sees it with the cycle it belongs to
    assert any(e.kind == "overload" for state in seen for e in state.events)
    # optional stages went, in the documented order; the protective chain never did
    assert summary.shed == list(shed_order(config))
    assert summary.overload_episodes == 1 and summary.overloaded_cycles > 40
    last = seen[-1]
    assert "form_error_um" not in last.predicted  # shed
    assert "force_band_armed" in last.predicted  # kept
    # ...and the hole stop fired: the machine itself stopped where the tool meets the hole
    assert "stop_confirmed" in kinds
    assert vm.run_state == RunState.STOPPED and summary.ended == "stopped"
    hole = next(f for f in config.virtual.faults if isinstance(f, HoleFault))
    radius = config.tools[0].diameter_mm / 2
    x, y = vm.snapshot()["x_mm"], vm.snapshot()["y_mm"]
    assert hole.min_mm[0] - radius <= x <= hole.max_mm[0] + radius + 5.0  # 80 ms of feed
    assert hole.min_mm[1] - radius <= y <= hole.max_mm[1] + radius
    # the overload is in the historian with its reason; the samples were thinned
    with sqlite3.connect(db) as conn:
        rows = conn.execute(
            "SELECT kind, message FROM hist_events WHERE kind LIKE 'overload%'"
        ).fetchall()
        kept = [k for (k,) in conn.execute("SELECT kind FROM hist_events")]
    assert rows and rows[0][0] == "overload" and "overruns in" in rows[0][1]
    # thinning drops samples only: every event is in the historian
    assert kept.count("stop_confirmed") == 1 and kept.count("overload_shed") == 2
    assert summary.samples_recorded < summary.cycles


def test_a_twin_that_keeps_its_period_reports_no_overload(tmp_path) -> None:
    config = load_demo_config()
    summary, events, vm, _ = _run(config, 0.002, tmp_path / "h.sqlite")
    assert summary.overruns == 0
    assert not any(e.kind.startswith("overload") for e in events)
    assert summary.shed == [] and summary.overloaded_cycles == 0
    assert vm.run_state == RunState.STOPPED  # the hole stop, of course


def test_overload_needs_a_full_window_and_clears_with_hysteresis() -> None:
    monitor = OverloadMonitor(window=4, enter_fraction=0.5, exit_fraction=0.25, levels=2)
    assert [monitor.update(True) for _ in range(3)] == [None, None, None]  # window not full
    assert monitor.update(False) == "entered" and monitor.level == 1
    # 2 of 4 overran: between the thresholds, stays overloaded
    assert monitor.update(False) is None and monitor.overloaded
    assert monitor.update(True) is None
    assert monitor.update(True) is None
    assert monitor.update(True) == "shed" and monitor.level == 2  # a window more, still over
    # 3 of 4, 2 of 4 overran: still overloaded; 1 of 4 is at exit_fraction: cleared
    assert [monitor.update(False) for _ in range(3)] == [None, None, "cleared"]
    assert monitor.level == 0 and not monitor.overloaded
    assert monitor.episodes == 1
    with pytest.raises(InputError, match="exit < enter"):
        OverloadMonitor(window=4, enter_fraction=0.2, exit_fraction=0.3)


def test_a_stage_a_protective_rule_reads_is_never_shed() -> None:
    config = load_demo_config()
    # the demo's form-error rule only lowers the feed; its roughness stage is off
    assert shed_order(config) == SHED_ORDER[:3] == ("historian_detail", "features", "form_error")
    bent = RuleConfig(name="bent", condition="form_error_um > 200", action="stop")
    guarded = config.model_copy(update={"rules": [*config.rules, bent]})
    assert shed_order(guarded) == ("historian_detail", "features")
