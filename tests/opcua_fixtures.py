"""A fake machine and one shared OPC UA server for the OPC UA tests of both sides.

asyncua's server takes about a second to build its standard address space, so a test module
shares one, on its own event loop in a thread; each test starts from a fresh FakeMachine state,
published before it runs.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Awaitable, Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from asyncua import ua
from asyncua.client.ua_client import UASocketProtocol
from asyncua.common.utils import Buffer
from asyncua.ua.ua_binary import nodeid_from_binary, struct_from_binary
from timeouts import BODY_S, SERVER_START_S

from cnctwin.errors import ConfigError
from cnctwin.thread import opcua as opcua_client
from cnctwin.thread.signals import SIGNALS
from cnctwin.virtual.opcua_server import OpcUaMachineServer
from cnctwin.virtual.users import UserTable

#: Limit of a test's body and of each wait on the shared server, s (tests/timeouts.py: why).
TIMEOUT_S = BODY_S


class FakeMachine:
    """Stands in for the VirtualMachine: a distinct, in-range value for every signal.

    Parameters
    ----------
    quantised
        Act like a control: round an override to whole percent (a read-back equal to the
        rounded value, not the written one, proves a node shows the machine's state) and keep
        a stop latched.
    """

    def __init__(self, quantised: bool = False) -> None:
        self.quantised = quantised
        self.reset()

    def reset(self) -> None:
        self.values: dict[str, float] = {}
        for i, (name, spec) in enumerate(SIGNALS.items()):
            if spec.kind == "bool":
                self.values[name] = 0.0
            elif spec.high is not None:
                self.values[name] = float(spec.high if spec.low is None else spec.low + 1.0)
            else:
                self.values[name] = 10.0 * i + (0.25 if spec.kind == "float" else 0.0)
        self.commands: list[tuple[str, float]] = []

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        if not self.quantised:
            self.commands.append((name, value))
            self.values[name] = value
            return
        if name == "stop" and value == 0.0 and self.values["stop"] == 1.0:
            raise ConfigError("stop is latched; valid: reset the program")
        self.commands.append((name, value))
        self.values[name] = float(round(value)) if name.endswith("_pct") else value


class Shared:
    """One server for a module, on its own event loop in a thread; reset before each test."""

    def __init__(self, machine: FakeMachine) -> None:
        self.machine = machine
        self.loop = asyncio.new_event_loop()
        # the tests write commands anonymously (docs/security.md: anonymous operator)
        self.server = OpcUaMachineServer(self.machine, users=UserTable(anonymous="operator"))
        self.endpoint = self.server.endpoint
        self._stop = asyncio.Event()
        started = threading.Event()

        async def serve() -> None:
            async with self.server:
                started.set()
                await self._stop.wait()

        self.thread = threading.Thread(
            target=self.loop.run_until_complete, args=(serve(),), daemon=True
        )
        self.thread.start()
        assert started.wait(SERVER_START_S), f"OPC UA server not started in {SERVER_START_S} s"

    def publish(self) -> None:
        """Publish the machine's snapshot from the server's own loop and wait for it."""

        async def publish() -> None:
            self.server.publish()

        asyncio.run_coroutine_threadsafe(publish(), self.loop).result(TIMEOUT_S)

    def run(self, body: Callable[[Shared, FakeMachine], Awaitable[None]]) -> None:
        """Reset the machine, then run ``body`` in this thread's own loop, with a timeout."""
        self.machine.reset()
        self.publish()

        async def main() -> None:
            await asyncio.wait_for(body(self, self.machine), TIMEOUT_S)

        asyncio.run(main())

    def close(self) -> None:
        self.loop.call_soon_threadsafe(self._stop.set)
        self.thread.join(TIMEOUT_S)
        self.loop.close()


@dataclass
class Traffic:
    """What a client's secure channel sent and got while :func:`watched` watched it.

    Attributes
    ----------
    sent
        Every request, decoded from the bytes that went out, with its request id, in order.
    events
        ``"Write"`` / ``"Read"`` at each such request's sending and ``"Write answered"`` /
        ``"Read answered"`` at its answer's arrival, in order (the subscription's Publish and
        other services left out).
    writes
        Socket writes, each as the number of messages it carried.
    """

    sent: list[tuple[int, Any]] = field(default_factory=list)
    events: list[str] = field(default_factory=list)
    writes: list[int] = field(default_factory=list)


@contextlib.contextmanager
def watched(protocol: UASocketProtocol) -> Iterator[Traffic]:
    """Watch ``protocol``'s requests where every one passes, asyncua's or
    :class:`~cnctwin.thread.OpcUaConnection`'s: framing (asyncua's ``message_to_binary``,
    the connection's ``frame_message``, which frames a plain message itself), the socket
    write and the answer's hand-over (``_call_callback``)."""
    traffic = Traffic()
    connection = protocol._connection
    frame, answer = connection.message_to_binary, protocol._call_callback
    lean_frame = opcua_client.frame_message
    in_lean_frame: list[bool] = []  # asyncua's framing inside frame_message is noted there
    transport = protocol.transport
    assert transport is not None
    write = transport.write
    kinds: dict[int, str] = {}
    framed: list[int] = []  # requests framed since the last socket write

    def note(message: bytes, request_id: int) -> None:
        typeid = nodeid_from_binary(Buffer(message))
        request: Any = struct_from_binary(ua.extension_objects_by_typeid[typeid], Buffer(message))
        traffic.sent.append((request_id, request))
        kind = kinds[request_id] = type(request).__name__.removesuffix("Request")
        if kind in ("Write", "Read"):
            traffic.events.append(kind)
        framed.append(request_id)

    def framing(message: bytes, *args: Any, **kwargs: Any) -> bytes:
        if not in_lean_frame:
            note(message, kwargs.get("request_id", args[1] if len(args) > 1 else 0))
        return frame(message, *args, **kwargs)

    def lean_framing(on: Any, message: bytes, request_id: int) -> bytes:
        if on is not connection:  # another client's channel in this process
            return lean_frame(on, message, request_id)
        note(message, request_id)
        in_lean_frame.append(True)
        try:
            return lean_frame(on, message, request_id)
        finally:
            in_lean_frame.pop()

    def writing(data: Any) -> None:
        traffic.writes.append(len(framed))
        framed.clear()
        write(data)

    def answered(request_id: int, body: Any) -> None:
        if kinds.get(request_id) in ("Write", "Read"):
            traffic.events.append(f"{kinds[request_id]} answered")
        answer(request_id, body)

    connection.message_to_binary = framing  # type: ignore[method-assign]
    opcua_client.frame_message = lean_framing  # type: ignore[attr-defined]
    transport.write = writing  # type: ignore[method-assign]
    protocol._call_callback = answered  # type: ignore[method-assign]
    try:
        yield traffic
    finally:
        connection.message_to_binary = frame  # type: ignore[method-assign]
        opcua_client.frame_message = lean_frame  # type: ignore[attr-defined]
        transport.write = write  # type: ignore[method-assign]
        protocol._call_callback = answer  # type: ignore[method-assign]
