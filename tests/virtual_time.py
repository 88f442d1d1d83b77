"""A controllable clock for tests of timing logic: an asyncio event loop on virtual time.

The loop never waits for the wall clock. When nothing is ready it moves its clock straight to
the next timer's deadline, so deadlines, periods, lags and overruns come out exactly as the
code under test scheduled them, however loaded the machine is. Work that takes time (a stall
in a listener or stage) is :meth:`VirtualClock.sleep`, which moves the clock on, not the CPU.

Only for code that waits on timers: a real socket or thread would see its timeouts expire at
once. Code that reads ``time.monotonic()`` / ``time.perf_counter()`` itself gets the clock
through ``monkeypatch.setattr(module, "time", clock)``.
"""

from __future__ import annotations

import asyncio
import selectors
from collections.abc import Coroutine
from typing import Any, TypeVar

T = TypeVar("T")


class VirtualClock:
    """Time that moves only when told to, s (stands in for the ``time`` module).

    Parameters
    ----------
    start_s
        The clock's reading at the start, s (not zero, like a monotonic clock).
    """

    def __init__(self, start_s: float = 1000.0) -> None:
        self.now_s = start_s

    def monotonic(self) -> float:
        """The clock's reading, s."""
        return self.now_s

    perf_counter = monotonic
    time = monotonic

    def sleep(self, seconds: float) -> None:
        """Spend ``seconds`` (s) at once, as a blocking call that stalls the loop would."""
        self.now_s += seconds


class _Selector(selectors.DefaultSelector):
    """Polls without blocking; where the loop would wait for a timer, moves the clock on."""

    def __init__(self, clock: VirtualClock) -> None:
        super().__init__()
        self._clock = clock

    def select(self, timeout: float | None = None) -> list[Any]:
        if timeout is None:  # no timer pending: only I/O can wake the loop
            return super().select(None)
        events = super().select(0)
        if not events and timeout > 0:
            self._clock.now_s += timeout  # asyncio's timeout ends at the next timer
        return events


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """An event loop whose ``time()`` is ``clock``, advanced to each timer as it comes due."""

    def __init__(self, clock: VirtualClock) -> None:
        super().__init__(_Selector(clock))
        self.clock = clock

    def time(self) -> float:
        return self.clock.now_s


def run(main: Coroutine[Any, Any, T], clock: VirtualClock) -> T:
    """Run ``main`` to the end on a :class:`VirtualTimeLoop` of ``clock`` (like ``asyncio.run``)."""
    loop = VirtualTimeLoop(clock)
    try:
        return loop.run_until_complete(main)
    finally:
        loop.run_until_complete(loop.shutdown_asyncgens())
        loop.close()
