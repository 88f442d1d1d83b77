"""The virtual machine's child process: Ctrl-C while it starts ends the start as Ctrl-C does;
its server steps the machine in its own thread."""

from __future__ import annotations

import asyncio
import signal
import threading
from pathlib import Path

import pytest
from timeouts import BODY_S

from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.opcua import OpcUaConnection
from cnctwin.twin import MachineServer, RunConfig
from cnctwin.twin.host import MachineProcess
from cnctwin.virtual import SteppedOffLoop


def test_ctrl_c_that_ends_the_starting_child_is_a_keyboard_interrupt(
    demo_config: RunConfig, tmp_path: Path
) -> None:
    # Ctrl-C at a terminal reaches the whole process group; the parent's own interrupt can be
    # swallowed while numba compiles (a ctypes callback), so the child's end must tell
    machine = MachineProcess(demo_config, "opcua", log=tmp_path / "machine.log")
    machine.spawn()
    child = machine._process
    assert child is not None
    child.send_signal(signal.SIGINT)  # before it can answer: it is still importing
    with pytest.raises(KeyboardInterrupt):
        machine.wait_ready()
    assert child.poll() is not None


def test_a_child_that_dies_otherwise_is_a_one_line_error(
    demo_config: RunConfig, tmp_path: Path
) -> None:
    from cnctwin.errors import CnctwinError

    machine = MachineProcess(demo_config, "opcua", log=tmp_path / "machine.log")
    machine.spawn()
    assert machine._process is not None
    machine._process.send_signal(signal.SIGTERM)
    with pytest.raises(CnctwinError, match="did not start"):
        machine.wait_ready()


def test_a_threaded_machine_server_steps_in_its_own_thread_and_restarts_between_steps(
    demo_config: RunConfig,
) -> None:
    """The child's server (``threaded``): the ticks run in the machine's thread, not the
    loop's; a write and its read-back go through it; a restart waits for the tick."""

    async def body() -> None:
        async with MachineServer(demo_config, "opcua", speed=1.0, threaded=True) as machine:
            assert isinstance(machine.source, SteppedOffLoop)
            vm = machine.vm
            step = vm.step
            threads: set[int] = set()

            def recorded(dt_s: float) -> None:
                threads.add(threading.get_ident())
                step(dt_s)

            vm.step = recorded  # type: ignore[method-assign]
            machine.go()
            config = ConnectionConfig(endpoint=machine.endpoint, timeout_s=BODY_S)
            async with OpcUaConnection(config, subscription_ms=None) as conn:
                await conn.write("feed_override_pct", 80.0)
                assert await conn.read_signal("feed_override_pct") == 80.0
                while machine.clock.stats.ticks < 20:
                    await asyncio.sleep(0.01)
            assert machine.between_steps(vm.restart) is None
            assert machine.between_steps(lambda: vm.time_s) < 1.0
        assert threads and threading.get_ident() not in threads

    asyncio.run(asyncio.wait_for(body(), BODY_S))
