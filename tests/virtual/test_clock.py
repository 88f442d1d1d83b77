"""The machine clock: real time without drift, scaled time, late ticks, listeners.

The clock runs on a virtual-time event loop (tests/virtual_time.py): every timer fires exactly
at its deadline and a stall is virtual time spent, so the counts below are exact and the same
on a quiet or a loaded machine. Reference: the loop's own clock.
"""

from __future__ import annotations

import asyncio

import pytest
from virtual_time import VirtualClock, run

from cnctwin.errors import ConfigError
from cnctwin.virtual import MachineClock


class _Counter:
    """A stand-in machine that records its steps."""

    def __init__(self) -> None:
        self.t_s = 0.0
        self.steps = 0

    def step(self, dt_s: float) -> None:
        self.t_s += dt_s
        self.steps += 1

    def snapshot(self) -> dict[str, float]:
        return {"t_s": self.t_s}


TICK_S = 0.005


async def _run_for(clock: MachineClock, wall_s: float) -> float:
    loop = asyncio.get_running_loop()
    started = loop.time()
    async with clock:
        await asyncio.sleep(wall_s)
    return loop.time() - started


def test_real_time_without_drift() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=TICK_S, speed=1.0)
    seen: list[float] = []
    clock.add_listener(lambda snapshot: seen.append(snapshot["t_s"]))
    wall = run(_run_for(clock, 1.0), VirtualClock())
    stats = clock.stats
    # 1 s at 5 ms: 200 ticks on time; the stop may come before or after the tick due with it
    assert wall == pytest.approx(1.0)
    assert vm.t_s == pytest.approx(wall, abs=TICK_S + 1e-9)
    assert stats.ticks == vm.steps == len(seen) in (199, 200)
    assert seen == sorted(seen) and seen[-1] == pytest.approx(vm.t_s)
    assert stats.machine_time_s == pytest.approx(vm.t_s)
    assert stats.dropped_ticks == stats.late_ticks == 0
    assert stats.max_lag_s == pytest.approx(0.0, abs=1e-9)


def test_scaled_time() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=TICK_S, speed=4.0)
    wall = run(_run_for(clock, 0.5), VirtualClock())
    assert vm.t_s == pytest.approx(4.0 * wall, abs=TICK_S + 1e-9)  # within the last tick


def test_late_ticks_are_counted_and_caught_up() -> None:
    vm = _Counter()
    time = VirtualClock()
    clock = MachineClock(vm, tick_s=TICK_S, speed=1.0)
    blocked = []

    def stall(snapshot: dict[str, float]) -> None:
        if not blocked and snapshot["t_s"] >= 0.2:
            blocked.append(snapshot["t_s"])
            time.sleep(0.1)  # blocks the loop: 20 ticks' worth

    clock.add_listener(stall)
    wall = run(_run_for(clock, 0.6), time)
    stats = clock.stats
    # the 19 ticks due during the stall start 95, 90, ... 5 ms late (late: > 2.5 ms), back to
    # back; the 20th is due as the stall ends
    assert stats.late_ticks == 19
    assert stats.max_lag_s == pytest.approx(0.1 - TICK_S)
    assert stats.dropped_ticks == 0
    assert vm.t_s == pytest.approx(wall, abs=TICK_S + 1e-9)  # caught up: no drift


def test_lag_beyond_the_limit_drops_ticks() -> None:
    vm = _Counter()
    time = VirtualClock()
    clock = MachineClock(vm, tick_s=TICK_S, speed=1.0, max_lag_s=0.05)
    once = []

    def stall(snapshot: dict[str, float]) -> None:
        if not once:
            once.append(True)
            time.sleep(0.2)

    clock.add_listener(stall)
    wall = run(_run_for(clock, 0.5), time)
    stats = clock.stats
    # the tick after the stall is 195 ms late, beyond 50 ms: its 39 ticks are dropped (38 where
    # 0.195 / 0.005 rounds below 39) and the machine loses the stall's 0.2 s for good
    assert stats.dropped_ticks in (38, 39)
    assert stats.late_ticks == 0
    assert vm.t_s == pytest.approx(wall - 0.2, abs=TICK_S + 1e-9)


def test_async_listener_and_failing_listener() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=TICK_S)
    published: list[float] = []

    async def publish(snapshot: dict[str, float]) -> None:
        await asyncio.sleep(0)
        published.append(snapshot["t_s"])

    def broken(snapshot: dict[str, float]) -> None:
        raise RuntimeError("listener bug")

    clock.add_listener(broken)
    clock.add_listener(publish)
    run(_run_for(clock, 0.1), VirtualClock())
    assert len(published) == clock.stats.ticks > 0
    assert clock.stats.listener_errors == clock.stats.ticks


def test_run_for_a_duration() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=0.01, speed=50.0)
    stats = run(clock.run(duration_s=1.0), VirtualClock())
    # 100 ticks of 10 ms machine time, 0.2 ms wall time apart at 50x
    assert stats.ticks == 100 and vm.t_s == pytest.approx(1.0)
    assert stats.wall_time_s == pytest.approx(0.02)


@pytest.mark.parametrize(("tick_s", "speed"), [(0.0, 1.0), (0.005, 0.0), (float("nan"), 1.0)])
def test_invalid_clock(tick_s: float, speed: float) -> None:
    with pytest.raises(ConfigError, match="give a finite number > 0"):
        MachineClock(_Counter(), tick_s, speed)
