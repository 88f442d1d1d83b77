"""The bench's machine steps in a thread beside its OPC UA server (cnctwin.virtual.spawned).

Proven with a step held open on purpose, against a real asyncua client session: the server
answers a Read while the step runs (it used to wait for the step), and a Write, which changes
the machine, waits until the step has ended. Nothing here is timed except lower bounds that
cannot be undercut: the write cannot finish before the step is released.
"""

from __future__ import annotations

import asyncio
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from timeouts import BODY_S

from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.opcua import OpcUaConnection
from cnctwin.thread.signals import SIGNALS
from cnctwin.virtual.clock import MachineClock
from cnctwin.virtual.opcua_server import OpcUaMachineServer
from cnctwin.virtual.spawned import _SteppedOffLoop
from cnctwin.virtual.users import UserTable

HELD_S = 0.3


class HeldMachine:
    """A machine whose step waits until the test releases it."""

    tick_s = 0.005

    def __init__(self) -> None:
        self.values = {name: 0.0 for name in SIGNALS}
        self.values.update(feed_override_pct=100.0, spindle_override_pct=100.0, work_offset=1.0)
        self.entered = threading.Event()
        self.release = threading.Event()
        self.steps = 0

    def step(self, dt_s: float) -> None:
        self.entered.set()
        self.release.wait(BODY_S)
        self.steps += 1

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        self.values[name] = value


def test_a_read_is_answered_during_a_step_and_a_write_waits_for_its_end() -> None:
    async def body() -> None:
        machine = HeldMachine()
        loop = asyncio.get_running_loop()
        with ThreadPoolExecutor(1) as pool:
            stepped = _SteppedOffLoop(machine, pool)  # type: ignore[arg-type]
            users = UserTable(anonymous="operator")
            async with OpcUaMachineServer(stepped, users=users) as server:
                config = ConnectionConfig(endpoint=server.endpoint, timeout_s=BODY_S)
                async with OpcUaConnection(config, subscription_ms=None) as conn:
                    step = asyncio.ensure_future(stepped.step(machine.tick_s))
                    assert await loop.run_in_executor(None, machine.entered.wait, BODY_S)
                    # the step is held: the server still answers a read
                    assert await conn.read_signal("feed_override_pct") == 100.0
                    assert not step.done() and machine.steps == 0
                    # a write changes the machine: it waits for the step (the loop blocks on
                    # the machine's lock, so the step is released from another thread)
                    threading.Timer(HELD_S, machine.release.set).start()
                    t0 = time.monotonic()
                    await conn.write("feed_override_pct", 90.0)
                    assert time.monotonic() - t0 >= HELD_S * 0.9
                    await step
                    assert machine.steps == 1
                    assert await conn.read_signal("feed_override_pct") == 90.0

    asyncio.run(asyncio.wait_for(body(), BODY_S))


def test_the_clock_awaits_a_step_run_in_a_thread() -> None:
    async def body() -> None:
        machine = HeldMachine()
        machine.release.set()
        with ThreadPoolExecutor(1) as pool:
            stepped = _SteppedOffLoop(machine, pool)  # type: ignore[arg-type]
            clock = MachineClock(stepped, machine.tick_s, speed=1e6)
            stats = await clock.run(duration_s=20 * machine.tick_s)
        assert stats.ticks == 20 and machine.steps == 20

    asyncio.run(asyncio.wait_for(body(), BODY_S))
