"""Serving a virtual machine on loopback for the twin: in this process or in a child process.

``cnctwin demo``, the reliability tests and the cycle benchmark need a machine the twin can
reach over a real protocol. :class:`MachineServer` runs a
:class:`~cnctwin.virtual.VirtualMachine` with its :class:`~cnctwin.virtual.MachineClock` and
an OPC UA or Modbus TCP server in the running event loop; :class:`MachineProcess` runs the
same in a child process, so the machine's simulation and server do not share the twin's
event loop and CPU time slices (the twin then measures its own cycle, as it would next to a
real control). In the child the machine steps in its own thread
(:class:`~cnctwin.virtual.SteppedOffLoop`), so its server answers the twin while a tick runs.

The clock starts *paused* until :meth:`MachineServer.go` (or :meth:`MachineProcess.go`), so
the twin can connect before the machine moves and sees the whole program.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import logging
import select
import signal
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol, TypeVar

from cnctwin import finite_json
from cnctwin.errors import CnctwinError, ConfigError
from cnctwin.twin.config import RunConfig
from cnctwin.virtual import (
    SWITCH_S,
    MachineClock,
    ReplayMachine,
    SteppedOffLoop,
    UserTable,
    VirtualMachine,
)

if TYPE_CHECKING:
    from cnctwin.virtual import OpcUaServerSecurity

__all__ = ["MachineProcess", "MachineServer", "Transport", "serve"]

logger = logging.getLogger(__name__)

Transport = Literal["opcua", "modbus", "mtconnect", "ads"]
_T = TypeVar("_T")


class _Server(Protocol):
    @property
    def endpoint(self) -> str: ...

    def publish(self, snapshot: dict[str, float]) -> Any: ...

    async def start(self) -> None: ...

    async def stop(self) -> None: ...


@dataclass
class MachineServer:
    """A virtual machine served in the running event loop. Use as ``async with``.

    Parameters
    ----------
    config
        The run configuration; its ``[virtual]`` table (required without ``replay``) and
        physics describe the machine.
    transport
        ``"opcua"``, ``"modbus"``, ``"mtconnect"`` or ``"ads"``.
    speed
        Machine seconds per wall second; ``None`` takes ``[virtual].speed``.
    host, port
        Where to listen; port 0 picks a free one.
    security, users, insecure
        OPC UA endpoint security, users and roles, and leave to serve without security on a
        non-loopback host (docs/security.md). Default: policy None, and an anonymous session
        may command the machine (the twin of ``cnctwin demo``, on loopback).
    replay
        A recorded machine to serve instead of the simulated one (``config`` is then unused;
        ``speed`` ``None`` is real time): the same clock and servers.
    machine_tool_model
        OPC UA: also serve the OPC 40501 MachineTool object (``cnctwin virtual serve`` does;
        docs/opcua.md).
    threaded
        Step the machine in its own thread (:class:`~cnctwin.virtual.SteppedOffLoop`), not on
        the event loop: the server answers while a tick runs. For a process that serves the
        machine alone (:class:`MachineProcess`'s child); beside a twin in the same process
        the two threads would contend for the GIL.
    """

    config: RunConfig | None
    transport: Transport = "opcua"
    speed: float | None = None
    host: str = "127.0.0.1"
    port: int = 0
    security: OpcUaServerSecurity | None = None
    users: UserTable = field(default_factory=lambda: UserTable(anonymous="operator"))
    insecure: bool = False
    replay: ReplayMachine | None = None
    machine_tool_model: bool = False
    threaded: bool = False

    def __post_init__(self) -> None:
        self.vm: VirtualMachine | ReplayMachine
        if self.replay is not None:
            self.vm = self.replay
            speed = self.speed if self.speed is not None else 1.0
        elif self.config is None or self.config.virtual is None:
            raise ConfigError(
                "the configuration has no [virtual] table; add one to describe the virtual "
                "machine (program, speed, faults)"
            )
        else:
            self.vm = VirtualMachine(self.config.virtual, self.config)
            speed = self.speed if self.speed is not None else self.config.virtual.speed
        #: What the clock steps and the server serves: the machine, or it in its own thread.
        self.source: VirtualMachine | ReplayMachine | SteppedOffLoop = (
            SteppedOffLoop(self.vm) if self.threaded else self.vm
        )
        self.clock = MachineClock(self.source, self.vm.tick_s, speed)
        self.server: _Server = self._make_server(self.port)
        self.clock.add_listener(self._publish)

    def _make_server(self, port: int) -> _Server:
        if self.transport == "opcua":
            from cnctwin.virtual import OpcUaMachineServer

            return OpcUaMachineServer(
                self.source,
                self.host,
                port,
                self.security,
                self.users,
                self.insecure,
                machine_tool_model=self.machine_tool_model,
            )
        if self.transport == "modbus":
            from cnctwin.virtual import ModbusMachineServer

            return ModbusMachineServer(self.source, self.host, port, insecure=self.insecure)
        if self.transport == "mtconnect":
            from cnctwin.virtual import MTConnectAgent

            return MTConnectAgent(self.source, self.host, port, insecure=self.insecure)
        if self.transport == "ads":
            from cnctwin.virtual import AdsMachineServer

            return AdsMachineServer(self.source, self.host, port, insecure=self.insecure)
        raise ConfigError(
            f"transport {self.transport!r}; valid: 'opcua', 'modbus', 'mtconnect', 'ads'"
        )

    async def _publish(self, snapshot: dict[str, float]) -> None:
        result = self.server.publish(snapshot)
        if asyncio.iscoroutine(result):
            await result

    @property
    def endpoint(self) -> str:
        """The server's address (``opc.tcp://...``, ``modbus://...``, ``http://...`` or
        ``ads://...``)."""
        return self.server.endpoint

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the machine's kernels before it listens, so
        that its clock does not stall on them once a twin watches (on a first run after
        installing the compilation takes tens of seconds): a throw-away machine runs its first
        ticks, the cut and force kernels run on a copy of the blank and the vibration sensor
        integrates a few steps. A replay has nothing to compile.
        """
        if self.config is None or self.config.virtual is None or self.replay is not None:
            return
        from cnctwin.twin.physics import TwinPhysics

        vm = VirtualMachine(self.config.virtual, self.config)
        for _ in range(20):
            vm.step(vm.tick_s)
        vm.warm_up()
        TwinPhysics(self.config, density_per_mm=self.config.virtual.density_per_mm).warm_up()

    @property
    def clients(self) -> int | None:
        """OPC UA clients connected now; ``None`` for the other transports, whose clients
        poll (MTConnect) or are not counted."""
        from cnctwin.virtual import OpcUaMachineServer

        return self.server.clients if isinstance(self.server, OpcUaMachineServer) else None

    async def start(self) -> None:
        """Listen (the clock stays paused until :meth:`go`)."""
        await self.server.start()
        self.port = int(self.endpoint.rsplit(":", 1)[1].split("/", 1)[0])

    def go(self) -> None:
        """Start the machine's clock."""
        self.clock.start()

    async def stop_server(self) -> None:
        """Stop listening; the machine keeps running (a network outage, for tests)."""
        await self.server.stop()

    async def restart_server(self) -> None:
        """Listen again on the same port after :meth:`stop_server`."""
        self.server = self._make_server(self.port)
        await self.server.start()

    def between_steps(self, action: Callable[[], _T]) -> _T:
        """Run ``action`` (on :attr:`vm`) between two ticks, the server then publishing its
        effect at the next tick (threaded: once the step in progress has ended; on the loop,
        no tick runs meanwhile). Returns what ``action`` returns."""
        if isinstance(self.source, SteppedOffLoop):
            return self.source.between_steps(action)
        return action()

    async def stop(self) -> None:
        """Stop the clock and the server (and the machine's thread)."""
        if self.clock.running:
            await self.clock.stop()
        await self.server.stop()
        if isinstance(self.source, SteppedOffLoop):
            self.source.close()

    async def __aenter__(self) -> MachineServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()


async def serve(
    config: RunConfig, transport: Transport, speed: float | None, host: str, port: int
) -> None:
    """Child process: serve the machine; commands on stdin, answers on stdout (JSON lines).

    Commands: ``go`` starts the clock, ``restart`` starts the program again on a fresh blank
    (answered when done), ``state`` answers the machine's state, ``stop`` (or the end of
    stdin) ends.
    """
    loop = asyncio.get_running_loop()
    try:
        machine = MachineServer(config, transport, speed, host, port, threaded=True)
        machine.warm_up()
        # the loop gets the GIL back within 0.1 ms of the machine's thread taking it
        sys.setswitchinterval(SWITCH_S)
        await machine.start()
    except (CnctwinError, OSError) as err:
        _answer({"error": str(err)})
        return
    _answer({"endpoint": machine.endpoint})
    try:
        while True:
            line = await loop.run_in_executor(None, sys.stdin.readline)
            command = line.strip()
            if command == "go":
                machine.go()
            elif command == "restart":
                machine.between_steps(machine.vm.restart)
                _answer({"restarted": True})
            elif command == "state":
                _answer(machine.between_steps(lambda: _state(machine)))
            elif command == "stop" or not line:
                break
    finally:
        await machine.stop()


def _state(machine: MachineServer) -> dict[str, Any]:
    """The answer to ``state``: the machine's state as a whole tick left it."""
    vm = machine.vm
    values = vm.snapshot()
    return {
        "t_s": vm.time_s,
        "run_state": int(vm.run_state),
        "at_rest": vm.finished,
        "position_mm": [values["x_mm"], values["y_mm"], values["z_mm"]],
        "faults": [repr(e) for e in vm.fault_events],
        "tool_wear_mm": vm.tool_wear_mm if isinstance(vm, VirtualMachine) else None,
        "clock": dataclasses.asdict(machine.clock.stats),
    }


def _answer(message: dict[str, Any]) -> None:
    sys.stdout.write(finite_json.dumps(message) + "\n")
    sys.stdout.flush()


class MachineProcess:
    """A virtual machine served from a child process. Use as a context manager.

    Parameters
    ----------
    config
        The run configuration (its ``[virtual]`` table describes the machine).
    transport
        ``"opcua"``, ``"modbus"``, ``"mtconnect"`` or ``"ads"``.
    speed
        Machine seconds per wall second; ``None`` takes ``[virtual].speed``.
    host, port
        Where to listen; port 0 picks a free one.
    start_timeout_s
        How long the child may take to start listening, s. It imports numba, compiles or
        loads the machine's kernels and starts the server: 5-10 s on a quiet 2-core computer,
        10-20x that on an oversubscribed one, hence the generous default; a child that exits
        is reported at once.
    log
        File for the child's log (its stderr); ``None`` shares this process's stderr.
    """

    def __init__(
        self,
        config: RunConfig,
        transport: Transport = "opcua",
        speed: float | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        start_timeout_s: float = 300.0,
        log: Path | None = None,
    ) -> None:
        if config.virtual is None:
            raise ConfigError(
                "the configuration has no [virtual] table; add one to describe the virtual "
                "machine (program, speed, faults)"
            )
        self.config = config
        self.transport = transport
        self.speed = speed
        self.host = host
        self.port = port
        self.start_timeout_s = start_timeout_s
        self.log = log
        self.endpoint = ""
        self._process: subprocess.Popen[str] | None = None

    @property
    def pid(self) -> int | None:
        """The child's process id; ``None`` before :meth:`spawn`."""
        return None if self._process is None else self._process.pid

    @property
    def speed_factor(self) -> float:
        """Machine seconds per wall second the machine runs at."""
        if self.speed is not None:
            return self.speed
        return self.config.virtual.speed if self.config.virtual is not None else 1.0

    def start(self) -> str:
        """Start the child and wait until it listens; returns the endpoint.

        Raises
        ------
        CnctwinError
            If the child fails to start or does not answer within ``start_timeout_s``.
        """
        self.spawn()
        return self.wait_ready()

    def spawn(self) -> None:
        """Start the child without waiting (prepare something else, then :meth:`wait_ready`)."""
        args = [
            sys.executable,
            "-m",
            "cnctwin.twin.serve",
            self.transport,
            self.host,
            str(self.port),
            "" if self.speed is None else repr(self.speed),
        ]
        with contextlib.ExitStack() as stack:
            stderr = None if self.log is None else stack.enter_context(self.log.open("a"))
            process = subprocess.Popen(
                args,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=stderr,
                text=True,
                bufsize=1,
            )
        self._process = process
        assert process.stdin is not None
        process.stdin.write(self.config.model_dump_json(by_alias=True) + "\n")
        process.stdin.flush()

    def wait_ready(self) -> str:
        """Wait until the child listens (it compiles the machine's kernels first); returns the
        endpoint.

        Raises
        ------
        CnctwinError
            If the child fails to start or does not answer within ``start_timeout_s``.
        """
        answer = self._receive(self.start_timeout_s)
        if answer is None and self._interrupted():
            # Ctrl-C reached the child too (one process group); the parent's own interrupt can
            # be lost while numba compiles (a ctypes callback swallows it): end as Ctrl-C does
            self.stop()
            raise KeyboardInterrupt
        if answer is None or "endpoint" not in answer:
            self.stop()
            why = "no answer" if answer is None else answer.get("error", answer)
            where = f" (its log: {self.log})" if self.log is not None else ""
            raise CnctwinError(
                f"the virtual machine did not start within {self.start_timeout_s:g} s: {why}{where}"
            )
        self.endpoint = str(answer["endpoint"])
        return self.endpoint

    def _interrupted(self, timeout_s: float = 2.0) -> bool:
        """Whether the child ended by SIGINT (Ctrl-C at the terminal); waits ``timeout_s`` s."""
        process = self._process
        if process is None:
            return False
        try:
            code = process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            return False
        return code in (-signal.SIGINT, 128 + signal.SIGINT)

    def _send(self, command: str) -> bool:
        process = self._process
        if process is None or process.stdin is None:
            return False
        try:
            process.stdin.write(command + "\n")
            process.stdin.flush()
        except (OSError, ValueError):
            return False
        return True

    def _receive(self, timeout_s: float) -> dict[str, Any] | None:
        process = self._process
        if process is None or process.stdout is None:
            return None
        ready, _, _ = select.select([process.stdout], [], [], timeout_s)
        if not ready:
            return None
        line = process.stdout.readline()
        if not line:
            return None
        try:
            answer = json.loads(line)
        except json.JSONDecodeError:
            return None
        return answer if isinstance(answer, dict) else None

    def go(self) -> None:
        """Start the machine's clock."""
        self._send("go")

    def restart(self, timeout_s: float = 10.0) -> bool:
        """Start the program again on a fresh blank (a latched stop is released); whether the
        machine confirmed it."""
        if not self._send("restart"):
            return False
        answer = self._receive(timeout_s)
        return bool(answer and answer.get("restarted"))

    def state(self, timeout_s: float = 5.0) -> dict[str, Any] | None:
        """The machine's time, run state, whether its axes are at rest after the program, its
        axes' position (machine frame, mm), started faults, the tool's true flank wear (mm, 0
        without a wear fault, ``None`` for a replay) and clock counters (or ``None``)."""
        if not self._send("state"):
            return None
        return self._receive(timeout_s)

    def kill(self) -> None:
        """Kill the child at once (SIGKILL): the machine's server vanishes."""
        if self._process is not None:
            self._process.kill()
            self._process.wait()

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the machine and end the child (killed if it does not end in ``timeout_s``)."""
        process, self._process = self._process, None
        if process is None:
            return
        try:
            if process.stdin is not None:
                process.stdin.write("stop\n")
                process.stdin.close()
        except (OSError, ValueError):
            pass
        try:
            process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout_s)
        if process.stdout is not None:
            process.stdout.close()

    def __enter__(self) -> MachineProcess:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
