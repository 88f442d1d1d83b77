"""Decisions only on honest data: new samples vs repeats, stale readings, gaps, invalid values.

The machine here is scripted (:class:`Scripted`): each read is a new sample stamped with a
controllable wall clock unless the test freezes it, and the twin's freshness judge reads the
same clock, so every figure below follows from the script, not from the CPU's speed.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from cnctwin.store.historian import Historian
from cnctwin.thread.connection import MachineConnection, Reading
from cnctwin.thread.signals import SIGNALS, RunState
from cnctwin.twin.config import RunConfig
from cnctwin.twin.freshness import Freshness
from cnctwin.twin.pipeline import Twin, build_twin
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.state import CycleState

DT = 0.0125  # s of machine and wall time per read


class Clock:
    """Wall (POSIX s) and monotonic time, advanced by the scripted machine."""

    def __init__(self) -> None:
        self.wall = 1.7e9
        self.mono = 1000.0

    def tick(self) -> None:
        self.wall += DT
        self.mono += DT


class Scripted(MachineConnection):
    """A machine that produces a new sample per read unless ``frozen``.

    ``age_s`` makes it serve values stamped that much in the past (a gateway's old cache).
    Writes are applied at once.
    """

    def __init__(self, clock: Clock, position: tuple[float, float, float]) -> None:
        super().__init__(timeout_s=1.0)
        self.clock = clock
        self.values = dict.fromkeys(SIGNALS, 0.0)
        self.values.update(
            feed_override_pct=100.0,
            spindle_override_pct=100.0,
            run_state=float(RunState.RUNNING),
            work_offset=1.0,
            tool_number=1.0,
            spindle_rpm=8000.0,
            feed_mm_min=600.0,
        )
        self.move_to(position)
        self.frozen = False
        self.age_s = 0.0
        self.writes: list[tuple[str, float]] = []
        self._source: float | None = None
        self._received = clock.mono

    def move_to(self, position: tuple[float, float, float]) -> None:
        self.values.update(x_mm=position[0], y_mm=position[1], z_mm=position[2])

    async def _open(self) -> None:
        return None

    async def _close(self) -> None:
        return None

    async def _read(self) -> Reading:
        self.clock.tick()
        if not self.frozen or self._source is None:
            self.values["heartbeat"] += 1.0
            self.values["t_s"] += DT
            self._source = self.clock.wall - self.age_s
            self._received = self.clock.mono
        return Reading(dict(self.values), self._received, source_time_s=self._source)

    async def _write(self, name: str, value: float) -> None:
        self.writes.append((name, value))
        self.values[name] = value


def _config(demo: RunConfig, **twin: object) -> RunConfig:
    return RunConfig.from_machining(
        demo,
        control={"enabled": True, "feed_override": {"min_pct": 30.0, "max_pct": 100.0}},
        twin={"cycle_s": DT, "watchdog_s": 60.0, "max_sample_age_s": 1.0, **twin},
        rules=[
            {
                "name": "form_error",
                "condition": "form_error_um > form_error_tolerance_um",
                "action": "feed_override",
                "value": "feed_override_pct * 0.9 * form_error_tolerance_um / form_error_um",
                "cooldown_s": 0.05,
            }
        ],
    )


def _run(twin: Twin, clock: Clock, script: Callable[[int], None], cycles: int) -> list[CycleState]:
    """Run ``cycles`` back-to-back cycles; ``script(k)`` runs before cycle ``k + 1``."""
    read = twin.runtime.stages[0]
    freshness = read.freshness
    assert isinstance(freshness, Freshness)
    freshness.wall_clock = lambda: clock.wall
    freshness.monotonic = lambda: clock.mono
    seen: list[CycleState] = []
    stop = asyncio.Event()

    def on_cycle(state: CycleState) -> None:
        seen.append(state)
        script(state.index)
        if state.index + 1 >= cycles:
            stop.set()

    twin.runtime.on_cycle = on_cycle

    async def main() -> None:
        await twin.actions.connection.connect()
        await twin.runtime.run(stop_event=stop)

    asyncio.run(main())
    return seen


AIR = (200.0, 130.0, -200.0)  # far above the demo's stock (top at z = -300 mm)


def test_a_frozen_machine_records_no_duplicate_frames_and_the_gap_starts_at_its_last_sample(
    demo_config: RunConfig, tmp_path: Path
) -> None:
    clock = Clock()
    conn = Scripted(clock, AIR)
    cfg = _config(demo_config)
    frozen = range(20, 260)  # 240 reads = 3 s without a new sample

    def script(k: int) -> None:
        conn.frozen = k + 1 in frozen

    with Historian.open(tmp_path / "h.db") as historian:
        recorder = Recorder(historian, {"test": "freeze"}, 0.0)
        twin = build_twin(cfg, conn, recorder=recorder, realtime=False)
        states = _run(twin, clock, script, 300)
        historian.flush()
        frames = historian.samples(recorder.run_id, ["heartbeat"])
        run = historian.run(recorder.run_id)
    beats = frames["heartbeat"]
    fresh = [s for s in states if s.new_sample]
    # one frame per new sample, none of the 240 repeats: every heartbeat once
    assert len(beats) == len(fresh) == 300 - len(frozen)
    assert len(np.unique(beats)) == len(beats)
    assert recorder.samples == len(fresh)
    # after 1 s (max_sample_age_s) of repeats the machine is lost; the gap runs from the last
    # fresh sample (cycle 19) to the first after the freeze
    kinds = [e.kind for e in run.events]
    assert kinds.count("connection_lost") == 1 and kinds.count("connection_restored") == 1
    lost = next(e for e in run.events if e.kind == "connection_lost")
    assert "max_sample_age_s" in lost.message
    last_fresh = states[19].received_s
    assert lost.t_s == pytest.approx(last_fresh)
    assert twin.runtime.summary().gaps_s == [pytest.approx((len(frozen) + 1) * DT)]
    # repeats computed nothing: the cut and the rules saw only new samples
    repeat = states[100]
    assert not repeat.new_sample and repeat.stale and "cut" not in _ran(twin, repeat)


def _ran(twin: Twin, state: CycleState) -> set[str]:
    """Stages a repeat would have run (every stage that is not per sample)."""
    if state.new_sample:
        return {stage.name for stage in twin.runtime.stages}
    return {s.name for s in twin.runtime.stages if not getattr(s, "per_sample", False)}


def test_an_hour_old_source_time_stamp_is_stale_not_current(
    demo_config: RunConfig, tmp_path: Path
) -> None:
    clock = Clock()
    conn = Scripted(clock, AIR)
    conn.age_s = 3600.0  # a gateway serving its cache of an hour ago, still counting

    def script(k: int) -> None:
        if k + 1 == 40:
            conn.age_s = 0.0  # the machine itself is back

    with Historian.open(tmp_path / "h.db") as historian:
        recorder = Recorder(historian, {"test": "old"}, 0.0)
        twin = build_twin(
            _config(demo_config), conn, recorder=recorder, realtime=False, clock=lambda: clock.mono
        )
        states = _run(twin, clock, script, 60)
        historian.flush()
        run = historian.run(recorder.run_id)
        beats = historian.samples(recorder.run_id, ["heartbeat"])["heartbeat"]
    old = states[:40]
    assert all(s.stale and not s.new_sample for s in old)
    assert old[5].sample_age_s == pytest.approx(3600.0, abs=1.0)
    # nothing of the old cache was recorded, nor taken as a connected machine
    assert beats.min() > max(s.measured.get("heartbeat", 0.0) for s in old)
    assert len(beats) == 20
    assert [e.kind for e in run.events if e.kind.startswith("conn")] == ["connected"]
    connected = next(e for e in run.events if e.kind == "connected")
    assert connected.t_s >= states[40].received_s - 1e-9


def test_freshness_bases() -> None:
    """Source time first, then a sample counter, then the receive time."""
    wall = [100.0]
    judge = Freshness(1.0, wall_clock=lambda: wall[0], monotonic=lambda: 0.0)
    assert judge.check(Reading({}, 0.0, source_time_s=99.5)).new
    again = judge.check(Reading({}, 0.1, source_time_s=99.5))
    assert not again.new and not again.stale and again.basis == "source time"
    wall[0] = 101.0
    assert judge.check(Reading({}, 0.2, source_time_s=99.5)).stale
    counter = Freshness(1.0)
    assert counter.check(Reading({}, 0.0, sequence=7.0)).new
    assert not counter.check(Reading({}, 0.5, sequence=7.0)).new
    assert counter.check(Reading({}, 0.6, sequence=8.0)).basis == "sample counter"
    received = Freshness(1.0)
    assert received.check(Reading({}, 0.0)).new and received.check(Reading({}, 0.1)).new


class FormError:
    """Stands in for the form-error stage: a predicted error of 50 um (tolerance 40)."""

    name = "form_error"
    per_sample = True

    def process(self, state: CycleState) -> CycleState:
        state.predicted.update(form_error_um=50.0, form_error_tolerance_um=40.0)
        return state


def test_an_override_reading_beyond_the_machine_range_never_raises_the_override(
    demo_config: RunConfig,
) -> None:
    """Reading 150 % on a machine whose dial ends at 120 %: invalid, and the form-error rule
    (whose value is computed from that reading) does not raise the override."""
    clock = Clock()
    conn = Scripted(clock, AIR)
    cfg = _config(demo_config, plausibility={"feed_override_max_pct": 120.0})
    twin = build_twin(cfg, conn, realtime=False)
    stages = twin.runtime.stages
    index = next(k for k, s in enumerate(stages) if s.name == "form_error")
    stages[index] = FormError()
    glitch = range(40, 80)

    def script(k: int) -> None:
        if k + 1 in glitch:
            conn.values["feed_override_pct"] = 150.0  # the dial's reading is garbage
        elif k + 1 == glitch.stop:
            conn.values["feed_override_pct"] = conn.writes[-1][1]

    states = _run(twin, clock, script, 100)
    feed = [value for name, value in conn.writes if name == "feed_override_pct"]
    assert feed and feed[0] < 100.0  # the rule lowered it on valid readings
    assert all(b <= a + 1e-9 for a, b in zip(feed, feed[1:], strict=False))  # never raised
    during = states[glitch.start + 1 : glitch.stop]
    assert all("feed_override_pct" in s.rejected for s in during)
    assert all("feed_override_pct" not in s.measured for s in during)
    events = [e for s in states for e in s.events if e.kind == "signal_invalid"]
    assert [e.data["signal"] for e in events] == ["feed_override_pct"]
    assert "120" in events[0].message


def test_the_safety_filter_never_raises_an_override_it_cannot_see() -> None:
    from cnctwin.control import SafetyFilter
    from cnctwin.control.config import ControlConfig
    from cnctwin.control.rules import Decision

    flt = SafetyFilter(ControlConfig(enabled=True))
    lower = Decision(0.0, "r", "feed_override", 60.0, "lower")
    assert flt.check(lower, 0.0, {"feed_override_pct": 100.0}).send
    raise_ = Decision(5.0, "r", "feed_override", 90.0, "raise")
    blind = flt.check(raise_, 5.0, {"x_mm": 1.0})  # the override's reading is invalid
    assert blind.outcome == "blocked" and "not raised" in blind.note
    assert flt.check(Decision(6.0, "r", "feed_override", 50.0, "lower"), 6.0, {"x_mm": 1.0}).send


def _volume(twin: Twin) -> float:
    return float(twin.physics.stock.volume_mm3())


def test_a_one_metre_jump_removes_no_material_and_is_marked_invalid(
    demo_config: RunConfig,
) -> None:
    """The tool stands left of the stock at cutting depth; one sample puts it 1 m to the
    right, across the stock. The twin holds the last valid position: nothing is cut."""
    clock = Clock()
    cfg = _config(demo_config)
    conn = Scripted(clock, (0.0, 0.0, 0.0))
    twin = build_twin(cfg, conn, realtime=False)
    dx, dy, dz = twin.runtime.stages[1].program.offset_mm(0, 1)
    left = (140.0 + dx, 130.0 + dy, -310.0 + dz)  # tool tip 10 mm left of the stock, 10 deep
    far = (left[0] + 1000.0, left[1], left[2])
    conn.move_to(left)
    before = _volume(twin)

    def script(k: int) -> None:
        conn.move_to(far if k + 1 == 10 else left)

    states = _run(twin, clock, script, 20)
    assert _volume(twin) == pytest.approx(before, abs=1e-6)
    jump = states[10]
    assert {"x_mm", "y_mm", "z_mm"} <= set(jump.rejected)
    assert "jumped 1000.000 mm" in jump.rejected["x_mm"]
    assert jump.position_mm is not None and jump.position_mm[0] == pytest.approx(140.0)
    assert [e.data["signal"] for e in jump.events if e.kind == "signal_invalid"] == [
        "x_mm",
        "y_mm",
        "z_mm",
    ]
    assert math.isclose(states[-1].position_mm[0], 140.0)


def test_a_jump_the_next_sample_confirms_starts_a_new_path_without_cutting_along_it(
    demo_config: RunConfig,
) -> None:
    clock = Clock()
    cfg = _config(demo_config)
    conn = Scripted(clock, (0.0, 0.0, 0.0))
    twin = build_twin(cfg, conn, realtime=False)
    dx, dy, dz = twin.runtime.stages[1].program.offset_mm(0, 1)
    left = (140.0 + dx, 130.0 + dy, -310.0 + dz)
    right = (260.0 + dx, 130.0 + dy, -310.0 + dz)  # across the stock, 120 mm in one sample
    conn.move_to(left)
    before = _volume(twin)

    def script(k: int) -> None:
        conn.move_to(right if k + 1 >= 10 else left)

    states = _run(twin, clock, script, 20)
    assert "x_mm" in states[10].rejected and not states[10].path_break
    assert states[11].path_break and "x_mm" not in states[11].rejected
    assert states[-1].position_mm[0] == pytest.approx(260.0)
    assert _volume(twin) == pytest.approx(before, abs=1e-6)


def test_plausible_reach_is_the_axis_dynamics_times_the_margin(demo_config: RunConfig) -> None:
    """Closed form: margin * (v dt + a dt^2 / 2) + floor, v = max(axis velocity, rapid)."""
    from cnctwin.twin.plausibility import Plausibility
    from cnctwin.twin.settings import PlausibilityConfig

    config = PlausibilityConfig(jump_margin=2.0, jump_floor_mm=0.5)
    judge = Plausibility(demo_config.machine, config)
    # demo: X and Y 12000 mm/min, 2000 mm/s^2; Z 10000 mm/min under a 12000 mm/min rapid
    dt = 0.0125
    expected = 2.0 * (200.0 * dt + 0.5 * np.array([2000.0, 2000.0, 1500.0]) * dt**2) + 0.5
    assert judge.reach_mm(dt) == pytest.approx(expected)
    first = judge.check({"x_mm": 0.0, "y_mm": 0.0, "z_mm": 0.0, "t_s": 1.0}, 0.0)
    assert not first.invalid  # the first sample is the reference
    near = judge.check({"x_mm": expected[0] * 0.99, "y_mm": 0.0, "z_mm": 0.0, "t_s": 1.0 + dt}, dt)
    assert not near.invalid
    ranges = judge.check({"feed_override_pct": 150.1, "spindle_override_pct": 49.0}, 0.1)
    assert set(ranges.invalid) == {"feed_override_pct", "spindle_override_pct"}


@pytest.mark.parametrize(
    ("twin", "key"),
    [
        ({"max_sample_age_s": 0.0}, "max_sample_age_s"),
        ({"plausibility": {"jump_margin": 0.5}}, "jump_margin"),
        ({"plausibility": {"feed_override_max_pct": 200.0}}, "feed_override_max_pct"),
    ],
)
def test_out_of_range_keys_are_refused_naming_the_key(
    demo_config: RunConfig, twin: dict[str, object], key: str
) -> None:
    with pytest.raises(ValueError, match=key):
        RunConfig.from_machining(demo_config, twin=twin)
