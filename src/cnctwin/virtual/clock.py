"""Running a virtual machine in real (or scaled) time on an asyncio event loop.

The clock steps the machine by ``tick_s`` of machine time per tick and schedules tick ``k`` at
the absolute wall-clock deadline ``t0 + k tick_s / speed`` (``loop.time()``, monotonic), so
sleep inaccuracy never accumulates: machine time stays locked to wall time. A tick that starts
more than half a tick after its deadline counts as late; a loop that falls behind runs the
missed ticks back to back, and one more than ``max_lag_s`` behind drops them (counted) and
starts a new time base. After each tick the listeners are called with the machine's snapshot
(a server publishes it); a listener may be a coroutine function, which is awaited.

:class:`SteppedOffLoop` steps the machine in a worker thread instead, as a machine's controller
runs beside its server: the loop answers the server's clients while a step runs.
"""

from __future__ import annotations

import asyncio
import inspect
import logging
import math
import threading
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, TypeVar

from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.thread import SampleBlock

__all__ = [
    "LATCHED",
    "SWITCH_S",
    "ClockStats",
    "Listener",
    "MachineClock",
    "Steppable",
    "SteppedOffLoop",
]

logger = logging.getLogger(__name__)

#: Called after every tick with the snapshot; may return an awaitable.
Listener = Callable[[dict[str, float]], Awaitable[None] | None]


class Steppable(Protocol):
    """What the clock drives: a :class:`~cnctwin.virtual.machine.VirtualMachine`."""

    def step(self, dt_s: float) -> Awaitable[None] | None:
        """Advance by ``dt_s`` seconds of machine time; a machine stepped in a worker thread
        returns an awaitable that the clock awaits before the next tick."""

    def snapshot(self) -> dict[str, float]:
        """Every signal's current value."""


class _Machine(Protocol):
    """What :class:`SteppedOffLoop` steps: a :class:`~cnctwin.virtual.machine.VirtualMachine`
    or a :class:`~cnctwin.virtual.replay.ReplayMachine`."""

    @property
    def tick_s(self) -> float:
        """The machine's simulation step, s."""

    def step(self, dt_s: float) -> None:
        """Advance by ``dt_s`` seconds of machine time."""

    def snapshot(self) -> dict[str, float]:
        """Every signal's current value."""

    def command(self, name: str, value: float) -> None:
        """Apply a command."""


#: GIL switch interval, s, for a process that serves a :class:`SteppedOffLoop` (CPython's
#: default: 5 ms). The server's loop gives the GIL up at every send, recv and epoll; while a
#: step runs it waits up to this long to get it back, several times a request (docs/latency.md,
#: "OPC UA: where the time goes"). Set it with ``sys.setswitchinterval`` in that process only.
SWITCH_S = 0.0001
#: Commands that set a register the machine reads once, at the start of each step (the
#: interpolator takes the override at its next cycle, as a controller's NCK takes the PLC's
#: override byte): written at once, without waiting for a step in progress to end.
LATCHED = frozenset({"feed_override_pct", "spindle_override_pct"})

_T = TypeVar("_T")


class SteppedOffLoop:
    """A machine stepped in its own worker thread, as a machine's controller runs beside its
    server: the event loop answers requests while a step runs (it waits for the GIL at most,
    never for the step; the vibration's time-domain kernels release the GIL). Give it to a
    :class:`MachineClock` and to the server in place of the machine; use as ``with`` (or call
    :meth:`close`) to end the thread.

    :meth:`snapshot` returns the signals as the last whole step left them (the server shows
    the controller's last cycle; the clock publishes one such snapshot per tick), with the
    latched registers (:data:`LATCHED`) as last written. A command of :data:`LATCHED` sets its
    register at once, also during a step: the step in progress has read the register already
    and keeps the old value, the next step moves at the new one, and the read-back is the
    register (what the machine will use from its next step on). Any other command, and any
    :meth:`between_steps` call (a restart, a read of the machine's state), waits for the step
    in progress to end (a lock): the machine never changes in the middle of a step, and the
    steps run one after the other in the clock's order, as on the loop.

    A machine's ``block`` (the vibration samples, :meth:`VirtualMachine.block
    <cnctwin.virtual.machine.VirtualMachine.block>`) is served as is: its ring buffer has its
    own lock, so a read during a step gets the samples stored so far.
    """

    block: Callable[[str, int], SampleBlock]

    def __init__(self, vm: _Machine) -> None:
        self.vm = vm
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="cnctwin-vm-step")
        self._lock = threading.Lock()  # held for a whole step
        self._held_lock = threading.Lock()  # held for a dict copy
        self._held = vm.snapshot()
        block = getattr(vm, "block", None)
        if callable(block):  # served as the machine's (the OPC UA server looks for it)
            self.block = block

    @property
    def tick_s(self) -> float:
        """The machine's simulation step, s."""
        return self.vm.tick_s

    def step(self, dt_s: float) -> asyncio.Future[None]:
        """Advance by ``dt_s`` s of machine time in the worker thread (await the result)."""
        return asyncio.get_running_loop().run_in_executor(self._pool, self._step, dt_s)

    def _step(self, dt_s: float) -> None:
        with self._lock:
            self.vm.step(dt_s)
            with self._held_lock:  # a register written meanwhile is in this copy
                self._held = self.vm.snapshot()

    def snapshot(self) -> dict[str, float]:
        """The machine's signals after the last whole step, the latched registers as written."""
        return dict(self._held)

    def command(self, name: str, value: float) -> None:
        """Apply a command: a latched register at once, any other between two steps."""
        if name in LATCHED:
            with self._held_lock:
                self.vm.command(name, value)
                self._held = {**self._held, name: self.vm.snapshot()[name]}
            return
        self.between_steps(lambda: self.vm.command(name, value))

    def between_steps(self, action: Callable[[], _T]) -> _T:
        """Run ``action`` (on :attr:`vm`) once the step in progress has ended, before the next
        one; :meth:`snapshot` then shows its effect. Returns what ``action`` returns."""
        with self._lock:
            result = action()
            with self._held_lock:
                self._held = self.vm.snapshot()
        return result

    def close(self) -> None:
        """End the worker thread (after the step in progress)."""
        self._pool.shutdown(wait=True)

    def __enter__(self) -> SteppedOffLoop:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True, slots=True)
class ClockStats:
    """How well the clock kept time.

    Attributes
    ----------
    ticks
        Ticks run.
    late_ticks
        Ticks that started more than half a tick (wall time) after their deadline.
    dropped_ticks
        Ticks skipped after falling more than ``max_lag_s`` behind.
    max_lag_s
        Largest delay of a tick's start after its deadline, wall-clock s.
    machine_time_s
        Machine time run by the clock, s.
    wall_time_s
        Wall time since the clock started, s.
    listener_errors
        Exceptions raised by listeners (logged, not propagated).
    """

    ticks: int
    late_ticks: int
    dropped_ticks: int
    max_lag_s: float
    machine_time_s: float
    wall_time_s: float
    listener_errors: int


class MachineClock:
    """Steps a machine in real or scaled time on the running event loop.

    Parameters
    ----------
    vm
        The machine.
    tick_s
        Machine time per tick, s (> 0), e.g. ``vm.tick_s``.
    speed
        Machine seconds per wall-clock second (> 0; 1 is real time).
    max_lag_s
        Wall time the clock may fall behind before it drops the missed ticks, s (> 0).

    Examples
    --------
    ::

        clock = MachineClock(vm, tick_s=0.005)
        clock.add_listener(server.publish)
        async with clock:            # starts a task; stops it on exit
            await asyncio.sleep(10)
    """

    def __init__(
        self, vm: Steppable, tick_s: float, speed: float = 1.0, *, max_lag_s: float = 1.0
    ) -> None:
        for name, value in (("tick_s", tick_s), ("speed", speed), ("max_lag_s", max_lag_s)):
            if isinstance(value, bool) or not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"clock {name}={value!r}; give a finite number > 0")
        self.vm = vm
        self.tick_s = float(tick_s)
        self.speed = float(speed)
        self.max_lag_s = float(max_lag_s)
        self._listeners: list[Listener] = []
        self._task: asyncio.Task[None] | None = None
        self._running = False
        self._ticks = 0
        self._late = 0
        self._dropped = 0
        self._max_lag = 0.0
        self._errors = 0
        self._t0: float | None = None
        self._loop_time = 0.0

    def add_listener(self, listener: Listener) -> None:
        """Call ``listener(snapshot)`` after every tick (awaited if it returns an awaitable)."""
        self._listeners.append(listener)

    def remove_listener(self, listener: Listener) -> None:
        """Stop calling ``listener``."""
        self._listeners.remove(listener)

    @property
    def stats(self) -> ClockStats:
        """Counters so far."""
        wall = (self._loop_time - self._t0) if self._t0 is not None else 0.0
        return ClockStats(
            self._ticks,
            self._late,
            self._dropped,
            self._max_lag,
            self._ticks * self.tick_s,
            wall,
            self._errors,
        )

    @property
    def running(self) -> bool:
        """Whether the clock is ticking."""
        return self._running

    async def run(self, duration_s: float | None = None) -> ClockStats:
        """Tick until :meth:`stop` (or for ``duration_s`` of machine time, s).

        Returns
        -------
        ClockStats
            The counters at the end.
        """
        loop = asyncio.get_running_loop()
        wall_tick = self.tick_s / self.speed
        max_ticks = None if duration_s is None else round(duration_s / self.tick_s)
        self._running = True
        t0 = loop.time()
        self._t0 = t0
        k = 0  # ticks run on this time base
        try:
            while self._running and (max_ticks is None or self._ticks < max_ticks):
                deadline = t0 + (k + 1) * wall_tick
                now = loop.time()
                if now < deadline:
                    self._sleeping = True
                    try:
                        await asyncio.sleep(deadline - now)
                    except asyncio.CancelledError:
                        if self._running:
                            raise
                        break  # stop() woke the sleep
                    finally:
                        self._sleeping = False
                    now = loop.time()
                    if not self._running:
                        break
                lag = now - deadline
                if lag > self.max_lag_s:
                    missed = int(lag / wall_tick)
                    self._dropped += missed
                    logger.warning("machine clock %.3f s behind: %d ticks dropped", lag, missed)
                    t0 = now - wall_tick
                    k = 0
                    deadline = now
                    lag = 0.0
                self._max_lag = max(self._max_lag, lag)
                if lag > 0.5 * wall_tick:
                    self._late += 1
                stepped = self.vm.step(self.tick_s)
                if stepped is not None:
                    await stepped
                self._ticks += 1
                k += 1
                self._loop_time = now
                if self._listeners:
                    await self._notify(self.vm.snapshot())
                if lag > wall_tick:
                    await asyncio.sleep(0)  # catching up: let other tasks run between ticks
        finally:
            self._running = False
            self._loop_time = loop.time()
        return self.stats

    async def _notify(self, snapshot: dict[str, float]) -> None:
        for listener in list(self._listeners):
            try:
                result = listener(snapshot)
                if inspect.isawaitable(result):
                    await result
            except Exception:  # a listener's bug must not stop the machine
                self._errors += 1
                logger.exception("machine clock listener %r failed", listener)

    def start(self) -> asyncio.Task[None]:
        """Start ticking in a task of the running loop; returns it."""
        if self._task is not None and not self._task.done():
            return self._task

        async def _run() -> None:
            await self.run()

        self._task = asyncio.get_running_loop().create_task(_run(), name="machine-clock")
        return self._task

    async def stop(self) -> ClockStats:
        """Stop ticking (after the current tick) and wait for the task; returns the counters."""
        self._running = False
        task = self._task
        if task is not None:
            self._task = None
            if self._sleeping:
                task.cancel()
            try:
                await task
            except asyncio.CancelledError:
                if not task.cancelled():
                    raise
        return self.stats

    async def __aenter__(self) -> MachineClock:
        self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()
