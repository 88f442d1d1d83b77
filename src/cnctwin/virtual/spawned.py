"""The virtual machine and its server in a child process, as a separate machine would be.

:func:`virtual_machine_server` starts the virtual machine (the packaged demo program, in real
time on its :class:`~cnctwin.virtual.MachineClock`, stepped in a thread beside the server's
event loop) behind an OPC UA, Modbus TCP, MTConnect or ADS server in a spawned child process and
yields the server's endpoint on loopback; leaving the context stops the child. Used to measure
the digital thread (``cnctwin bench latency``, benchmarks/bench_opcua_latency.py) without the
client and the machine sharing a process.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING

from cnctwin.errors import CnctwinError, InputError

if TYPE_CHECKING:
    from cnctwin.virtual.machine import VirtualMachine

__all__ = ["TRANSPORTS", "virtual_machine_server"]

#: The protocols the virtual machine serves.
TRANSPORTS = ("opcua", "modbus", "mtconnect", "ads")
#: Longest wait for the child to report ready, s: on a cold numba cache the warm-up compiles the
#: cutting kernels, which took 179 s on the 2-core sandbox at load 20-40 (17 s at load 1.5).
_START_TIMEOUT_S = 300.0
#: Machine time a throwaway machine runs before the server starts, s: past the demo program's
#: first cut (4.1 s), so every kernel the measurement meets is compiled.
_WARM_UP_S = 6.0


def _serve_child(transport: str, pipe: Connection) -> None:
    """Child process: the virtual machine on its clock behind a server, until told to stop."""
    try:
        asyncio.run(_serve(transport, pipe))
    except Exception as err:  # reported to the parent in one line
        pipe.send(("error", f"virtual machine server failed: {type(err).__name__}: {err}"))


async def _serve(transport: str, pipe: Connection) -> None:
    from cnctwin.virtual import (
        SWITCH_S,
        AdsMachineServer,
        MachineClock,
        ModbusMachineServer,
        MTConnectAgent,
        SteppedOffLoop,
        VirtualMachine,
    )
    from cnctwin.virtual.config import VirtualMachineConfig
    from cnctwin.virtual.opcua_server import OpcUaMachineServer
    from cnctwin.virtual.users import UserTable

    logging.getLogger("asyncua").setLevel(logging.ERROR)  # policy-None notices
    _warm_up(VirtualMachine(VirtualMachineConfig()))
    vm = VirtualMachine(VirtualMachineConfig())
    vm.step(vm.tick_s)
    # a thread that waits for the GIL gets it after 0.1 ms, not CPython's 5 ms: a request
    # arriving during a step of the machine's thread is not held up for the step
    sys.setswitchinterval(SWITCH_S)
    with SteppedOffLoop(vm) as machine:
        server: OpcUaMachineServer | ModbusMachineServer | MTConnectAgent | AdsMachineServer
        if transport == "opcua":  # on loopback; the bench writes the feed override anonymously
            server = OpcUaMachineServer(machine, users=UserTable(anonymous="operator"))
        elif transport == "mtconnect":
            server = MTConnectAgent(machine)
        elif transport == "ads":
            server = AdsMachineServer(machine)
        else:
            server = ModbusMachineServer(machine)
        async with server:
            clock = MachineClock(machine, vm.tick_s)
            clock.add_listener(server.publish)
            async with clock:
                pipe.send(("ready", server.endpoint))
                await asyncio.get_running_loop().run_in_executor(None, _wait_for_parent, pipe)


def _warm_up(vm: VirtualMachine) -> None:
    """Run a throwaway machine through the demo program's first :data:`_WARM_UP_S` s, off the
    clock: numba compiles (or loads from its cache) the cutting kernels at the first cut, which
    on a cold cache took 17 s on the loaded 2-core sandbox and stalled the server mid-run (the
    bench's writes timed out)."""
    for _ in range(round(_WARM_UP_S / vm.tick_s)):
        vm.step(vm.tick_s)


def _wait_for_parent(pipe: Connection) -> None:
    try:
        pipe.recv()
    except EOFError:  # the parent is gone
        pass


@asynccontextmanager
async def virtual_machine_server(transport: str) -> AsyncIterator[str]:
    """Run the virtual machine (demo program, real time) and its server in a child process.

    Parameters
    ----------
    transport
        ``"opcua"``, ``"modbus"``, ``"mtconnect"`` or ``"ads"``.

    Yields
    ------
    str
        The server's endpoint on 127.0.0.1.

    Raises
    ------
    InputError
        For a transport other than those of :data:`TRANSPORTS`.
    CnctwinError
        When the server does not start within 300 s, or fails.
    """
    if transport not in TRANSPORTS:
        raise InputError(f"transport {transport!r}; valid: {', '.join(TRANSPORTS)}")
    context = multiprocessing.get_context("spawn")
    parent, child = context.Pipe()
    process = context.Process(
        target=_serve_child, args=(transport, child), name=f"cnctwin-vm-{transport}", daemon=True
    )
    process.start()
    child.close()
    loop = asyncio.get_running_loop()
    try:
        ready = await loop.run_in_executor(None, parent.poll, _START_TIMEOUT_S)
        if not ready:
            raise CnctwinError(
                f"virtual machine {transport} server did not start within {_START_TIMEOUT_S} s"
            )
        kind, text = parent.recv()
        if kind != "ready":
            raise CnctwinError(text)
        yield text
    finally:
        try:
            parent.send("stop")
        except OSError:
            pass
        await loop.run_in_executor(None, process.join, 10.0)
        if process.is_alive():
            process.terminate()
            process.join(5.0)
        parent.close()
