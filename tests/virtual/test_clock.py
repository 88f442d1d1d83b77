"""The machine clock: real time without drift, scaled time, late ticks, listeners.

Reference: the event loop's monotonic clock. Tolerances allow for a shared 2-core machine:
asyncio wakes up to ~1 ms late (epoll's millisecond timeout), never early.
"""

from __future__ import annotations

import asyncio
import time

import pytest

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


async def _run_for(clock: MachineClock, wall_s: float) -> float:
    started = time.monotonic()
    async with clock:
        await asyncio.sleep(wall_s)
    return time.monotonic() - started


def test_real_time_without_drift() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=0.005, speed=1.0)
    seen: list[float] = []
    clock.add_listener(lambda snapshot: seen.append(snapshot["t_s"]))
    wall = asyncio.run(_run_for(clock, 1.0))
    stats = clock.stats
    # Machine time tracks wall time to within two ticks (plus the stop's last tick).
    assert vm.t_s == pytest.approx(wall, abs=0.015)
    assert stats.ticks == vm.steps == len(seen)
    assert seen == sorted(seen) and seen[-1] == pytest.approx(vm.t_s)
    assert stats.machine_time_s == pytest.approx(vm.t_s)
    assert stats.dropped_ticks == 0
    assert stats.late_ticks <= stats.ticks // 10  # a loaded machine may wake a few late


def test_scaled_time() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=0.005, speed=4.0)
    wall = asyncio.run(_run_for(clock, 0.5))
    assert vm.t_s == pytest.approx(4.0 * wall, abs=0.03)


def test_late_ticks_are_counted_and_caught_up() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=0.005, speed=1.0)
    blocked = []

    def stall(snapshot: dict[str, float]) -> None:
        if not blocked and snapshot["t_s"] >= 0.2:
            blocked.append(snapshot["t_s"])
            time.sleep(0.1)  # blocks the loop: 20 ticks' worth

    clock.add_listener(stall)
    wall = asyncio.run(_run_for(clock, 0.6))
    stats = clock.stats
    assert stats.late_ticks >= 15
    assert stats.max_lag_s >= 0.09
    assert stats.dropped_ticks == 0
    assert vm.t_s == pytest.approx(wall, abs=0.015)  # caught up: no drift


def test_lag_beyond_the_limit_drops_ticks() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=0.005, speed=1.0, max_lag_s=0.05)
    once = []

    def stall(snapshot: dict[str, float]) -> None:
        if not once:
            once.append(True)
            time.sleep(0.2)

    clock.add_listener(stall)
    wall = asyncio.run(_run_for(clock, 0.5))
    stats = clock.stats
    assert stats.dropped_ticks >= 30
    assert vm.t_s == pytest.approx(wall - 0.2, abs=0.03)


def test_async_listener_and_failing_listener() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=0.005)
    published: list[float] = []

    async def publish(snapshot: dict[str, float]) -> None:
        await asyncio.sleep(0)
        published.append(snapshot["t_s"])

    def broken(snapshot: dict[str, float]) -> None:
        raise RuntimeError("listener bug")

    clock.add_listener(broken)
    clock.add_listener(publish)
    asyncio.run(_run_for(clock, 0.1))
    assert len(published) == clock.stats.ticks > 0
    assert clock.stats.listener_errors == clock.stats.ticks


def test_run_for_a_duration() -> None:
    vm = _Counter()
    clock = MachineClock(vm, tick_s=0.01, speed=50.0)
    stats = asyncio.run(clock.run(duration_s=1.0))
    assert stats.ticks == 100 and vm.t_s == pytest.approx(1.0)
    assert stats.wall_time_s == pytest.approx(0.02, abs=0.02)


@pytest.mark.parametrize(("tick_s", "speed"), [(0.0, 1.0), (0.005, 0.0), (float("nan"), 1.0)])
def test_invalid_clock(tick_s: float, speed: float) -> None:
    with pytest.raises(ConfigError, match="give a finite number > 0"):
        MachineClock(_Counter(), tick_s, speed)
