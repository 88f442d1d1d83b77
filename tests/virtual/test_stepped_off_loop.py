"""A served machine steps in a thread beside its OPC UA server (cnctwin.virtual.SteppedOffLoop).

Proven with a step held open on purpose, against a real asyncua client session: the server
answers a Read while the step runs, and a Write of the feed override (a register the machine
reads at the start of each step) too, with its read-back; a Write of any other command, which
changes the machine's state, waits until the step has ended. Nothing here is timed except
lower bounds that cannot be undercut: that write cannot finish before the step is released.
"""

from __future__ import annotations

import asyncio
import threading
import time

from timeouts import BODY_S

from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.opcua import OpcUaConnection
from cnctwin.thread.signals import SIGNALS
from cnctwin.virtual.clock import MachineClock, SteppedOffLoop
from cnctwin.virtual.config import VirtualMachineConfig
from cnctwin.virtual.machine import VirtualMachine
from cnctwin.virtual.opcua_server import OpcUaMachineServer
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


def test_during_a_step_a_read_and_an_override_are_answered_and_other_commands_wait() -> None:
    async def body() -> None:
        machine = HeldMachine()
        loop = asyncio.get_running_loop()
        with SteppedOffLoop(machine) as stepped:
            users = UserTable(anonymous="operator")
            async with OpcUaMachineServer(stepped, users=users) as server:
                config = ConnectionConfig(endpoint=server.endpoint, timeout_s=BODY_S)
                async with OpcUaConnection(config, subscription_ms=None) as conn:
                    step = asyncio.ensure_future(stepped.step(machine.tick_s))
                    assert await loop.run_in_executor(None, machine.entered.wait, BODY_S)
                    # the step is held: the server still answers a read
                    assert await conn.read_signal("feed_override_pct") == 100.0
                    # the override is a register: written and read back during the step
                    await conn.write("feed_override_pct", 90.0)
                    assert await conn.read_signal("feed_override_pct") == 90.0
                    assert stepped.snapshot()["feed_override_pct"] == 90.0
                    assert not step.done() and machine.steps == 0
                    # feed hold changes the machine's state: it waits for the step (the loop
                    # blocks on the machine's lock, so the step is released from another
                    # thread)
                    threading.Timer(HELD_S, machine.release.set).start()
                    t0 = time.monotonic()
                    await conn.write("feed_hold", 1.0)
                    assert time.monotonic() - t0 >= HELD_S * 0.9
                    await step
                    assert machine.steps == 1
                    assert await conn.read_signal("feed_hold") == 1.0
                    assert await conn.read_signal("feed_override_pct") == 90.0

    asyncio.run(asyncio.wait_for(body(), BODY_S))


def test_an_override_written_during_a_step_moves_the_real_machine_from_its_next_step() -> None:
    """The latched register's meaning, on the virtual machine itself: the step in progress
    has taken the override at its start and keeps it; the next step moves at the new one."""

    async def body() -> None:
        vm = VirtualMachine(VirtualMachineConfig())
        follower = vm._follower
        advance = follower.advance
        factors: list[float] = []
        entered, release = threading.Event(), threading.Event()

        def held_advance(dt_s: float, feed_factor: float, hold: bool) -> None:
            factors.append(feed_factor)
            entered.set()
            release.wait(BODY_S)
            advance(dt_s, feed_factor, hold)

        follower.advance = held_advance  # type: ignore[method-assign]
        loop = asyncio.get_running_loop()
        with SteppedOffLoop(vm) as stepped:
            step = asyncio.ensure_future(stepped.step(vm.tick_s))
            assert await loop.run_in_executor(None, entered.wait, BODY_S)
            stepped.command("feed_override_pct", 50.0)  # returns while the step is held
            assert not step.done()
            assert stepped.snapshot()["feed_override_pct"] == 50.0  # the read-back
            release.set()
            await step
            assert stepped.snapshot()["feed_override_pct"] == 50.0  # the step kept it
            await stepped.step(vm.tick_s)
        assert factors == [1.0, 0.5]  # the step under way at 100 %, the next at 50 %

    asyncio.run(asyncio.wait_for(body(), BODY_S))


def test_the_clock_awaits_a_step_run_in_a_thread() -> None:
    async def body() -> None:
        machine = HeldMachine()
        machine.release.set()
        with SteppedOffLoop(machine) as stepped:
            clock = MachineClock(stepped, machine.tick_s, speed=1e6)
            stats = await clock.run(duration_s=20 * machine.tick_s)
        assert stats.ticks == 20 and machine.steps == 20

    asyncio.run(asyncio.wait_for(body(), BODY_S))


def test_between_steps_waits_for_the_step_in_progress_and_the_snapshot_shows_its_effect() -> None:
    async def body() -> None:
        machine = HeldMachine()
        loop = asyncio.get_running_loop()
        with SteppedOffLoop(machine) as stepped:  # type: ignore[arg-type]
            step = asyncio.ensure_future(stepped.step(machine.tick_s))
            assert await loop.run_in_executor(None, machine.entered.wait, BODY_S)
            threading.Timer(HELD_S, machine.release.set).start()
            t0 = time.monotonic()

            def offset() -> int:
                machine.values["work_offset"] = 2.0
                return machine.steps

            assert stepped.between_steps(offset) == 1  # after the held step, not during it
            assert time.monotonic() - t0 >= HELD_S * 0.9
            assert stepped.snapshot()["work_offset"] == 2.0
            await step

    asyncio.run(asyncio.wait_for(body(), BODY_S))


def test_the_machine_s_block_is_served_as_is_where_the_machine_has_one() -> None:
    class WithBlock(HeldMachine):
        def block(self, name: str, since: int) -> tuple[str, int]:
            return name, since

    with SteppedOffLoop(HeldMachine()) as plain:  # type: ignore[arg-type]
        assert getattr(plain, "block", None) is None  # the OPC UA server serves no block node
    with SteppedOffLoop(WithBlock()) as stepped:  # type: ignore[arg-type]
        assert stepped.block("vibration", 3) == ("vibration", 3)
