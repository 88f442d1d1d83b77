"""The virtual machine's server answers the common Read and Write itself
(cnctwin.virtual.opcua_lean, issue 17): for every request it takes, its answer must be the one
asyncua's own service path gives (the same bytes but for the ResponseHeader's time stamp and
request handle), with the same effect on the machine, the same refusals and the same
notifications; anything else, and anything malformed, must be left to asyncua without harm.

Each pair sends the same request twice over one asyncua client session: once answered by the
lean path, once with it stepped aside (its ``answer`` patched to decline), which is asyncua's
path as before.
"""

from __future__ import annotations

import asyncio
import functools
import math
import random
import struct
from collections.abc import Awaitable, Callable
from datetime import UTC, datetime
from typing import Any

import pytest
from asyncua import Client, ua
from asyncua.common.connection import SecureConnection
from asyncua.common.utils import Buffer
from asyncua.crypto.permission_rules import User
from asyncua.server.binary_server_asyncio import OPCUAProtocol
from asyncua.server.uaprocessor import UaProcessor
from asyncua.ua.ua_binary import struct_from_binary, struct_to_binary
from opcua_fixtures import TIMEOUT_S, FakeMachine

from cnctwin.thread.opcua import NAMESPACE_URI, NODE_MAP
from cnctwin.virtual.opcua_lean import LeanService, _LeanProtocol, encode_data_value
from cnctwin.virtual.opcua_server import OpcUaMachineServer
from cnctwin.virtual.users import Account, UserTable, hash_password

USERS = UserTable(
    accounts={"twin": Account("operator", hash_password("op-pass"))}, anonymous="read-only"
)

STAMP = datetime(2026, 11, 27, 19, 0, 0, 123456, tzinfo=UTC)

Body = Callable[[OpcUaMachineServer, FakeMachine, LeanService], Awaitable[None]]


def serve(body: Body) -> None:
    async def main() -> None:
        machine = FakeMachine()
        async with OpcUaMachineServer(machine, users=USERS) as server:
            service = server._server.service  # type: ignore[union-attr]
            assert isinstance(service, LeanService)
            await asyncio.wait_for(body(server, machine, service), TIMEOUT_S * 3)

    asyncio.run(main())


async def connect(server: OpcUaMachineServer, user: str | None = "twin") -> tuple[Client, int]:
    client = Client(server.endpoint, timeout=TIMEOUT_S)
    if user is not None:
        client.set_user(user)
        client.set_password("op-pass")
    await client.connect()
    return client, await client.get_namespace_index(NAMESPACE_URI)


async def send(client: Client, request: Any) -> bytes:
    """The answer's body to ``request`` sent on ``client``'s session, undecoded."""
    protocol = client.uaclient.protocol
    assert protocol is not None
    data: Buffer = await protocol.send_request(request)
    return bytes(data.read(len(data)))


async def both(client: Client, service: LeanService, make: Callable[[], Any]) -> bytes:
    """The answer to ``make()`` from the lean path and from asyncua's; they must agree but for
    the answer's time stamp and request handle (bytes 4 to 16). Returns the lean one."""
    before = service.answered
    lean = await send(client, make())
    assert service.answered == before + 1, "the lean path did not answer"
    answer = service.answer
    service.answer = lambda *args: None  # type: ignore[method-assign]
    try:
        generic = await send(client, make())
    finally:
        service.answer = answer  # type: ignore[method-assign]
    assert service.answered == before + 1
    assert lean[:4] + lean[16:] == generic[:4] + generic[16:]
    return lean


def read(node: ua.NodeId, timestamps: ua.TimestampsToReturn = ua.TimestampsToReturn.Both) -> Any:
    request = ua.ReadRequest()
    request.Parameters.TimestampsToReturn = timestamps
    request.Parameters.NodesToRead = [
        ua.ReadValueId(NodeId=node, AttributeId=ua.AttributeIds.Value)
    ]
    return request


def write(node: ua.NodeId, variant: ua.Variant, status: bool = True) -> Any:
    request = ua.WriteRequest()
    value = ua.DataValue(variant) if status else ua.DataValue(variant, StatusCode=None)
    request.Parameters.NodesToWrite = [
        ua.WriteValue(NodeId=node, AttributeId=ua.AttributeIds.Value, Value=value)
    ]
    return request


def results(body: bytes, kind: type) -> list[Any]:
    response = struct_from_binary(kind, Buffer(body))
    assert response.ResponseHeader.ServiceResult.is_good()
    return list(response.Results)


def test_reads_answer_as_asyncua_does() -> None:
    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        machine.values["program_line"] = math.nan  # published as BadOutOfRange, no value
        machine.values["x_mm"] = math.inf
        machine.values["feed_hold"] = 1.0
        server.publish()
        client, ns = await connect(server)
        try:
            for name, identifier in NODE_MAP.items():
                node = ua.NodeId(identifier, ns)
                for stamps in ua.TimestampsToReturn:
                    if stamps is ua.TimestampsToReturn.Invalid:
                        continue
                    (value,) = results(
                        await both(client, service, functools.partial(read, node, stamps)),
                        ua.ReadResponse,
                    )
                    if name == "program_line":
                        assert value.StatusCode.value == ua.StatusCodes.BadOutOfRange
                    elif name == "x_mm":
                        assert value.Value.Value == math.inf
                    else:
                        assert value.Value.Value == pytest.approx(machine.values[name]), name
        finally:
            await client.disconnect()

    serve(body)


def test_writes_answer_and_act_as_asyncua_does() -> None:
    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        client, ns = await connect(server)
        feed = ua.NodeId(NODE_MAP["feed_override_pct"], ns)
        cases = [
            (feed, ua.Variant(42.5, ua.VariantType.Double), ua.StatusCodes.Good),
            (feed, ua.Variant(55, ua.VariantType.Int32), ua.StatusCodes.Good),
            (feed, ua.Variant(151.0, ua.VariantType.Double), ua.StatusCodes.BadOutOfRange),
            (feed, ua.Variant(math.nan, ua.VariantType.Double), ua.StatusCodes.BadOutOfRange),
            (feed, ua.Variant(-math.inf, ua.VariantType.Double), ua.StatusCodes.BadOutOfRange),
            (feed, ua.Variant(True, ua.VariantType.Boolean), ua.StatusCodes.BadTypeMismatch),
            (
                ua.NodeId(NODE_MAP["feed_hold"], ns),
                ua.Variant(True, ua.VariantType.Boolean),
                ua.StatusCodes.Good,
            ),
            (
                ua.NodeId(NODE_MAP["x_mm"], ns),
                ua.Variant(1.0, ua.VariantType.Double),
                ua.StatusCodes.BadNotWritable,
            ),
        ]
        try:
            for node, variant, expected in cases:
                for status in (True, False):  # with and without the DataValue's StatusCode
                    machine.commands.clear()
                    answer = await both(
                        client, service, functools.partial(write, node, variant, status)
                    )
                    (code,) = results(answer, ua.WriteResponse)
                    assert code.value == expected, (node, variant)
                    applied = machine.commands
                    if expected == ua.StatusCodes.Good:  # once by each path, the same
                        assert len(applied) == 2 and applied[0] == applied[1]
                        assert applied[0][1] == float(variant.Value)
                    else:
                        assert applied == []
        finally:
            await client.disconnect()

    serve(body)


def test_an_unauthorised_write_is_refused_on_the_lean_path() -> None:
    """A read-only session's write of a command node: BadUserAccessDenied, nothing applied,
    answered by the lean path (and asyncua's agrees)."""

    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        client, ns = await connect(server, user=None)  # anonymous: read-only
        feed = ua.NodeId(NODE_MAP["feed_override_pct"], ns)
        try:
            answer = await both(
                client, service, lambda: write(feed, ua.Variant(42.0, ua.VariantType.Double))
            )
            (code,) = results(answer, ua.WriteResponse)
            assert code.value == ua.StatusCodes.BadUserAccessDenied
            assert machine.commands == []
            # reading stays allowed
            (value,) = results(await both(client, service, lambda: read(feed)), ua.ReadResponse)
            assert value.StatusCode.is_good()
        finally:
            await client.disconnect()

    serve(body)


def test_a_lean_write_reaches_a_subscription() -> None:
    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        client, ns = await connect(server)
        feed = ua.NodeId(NODE_MAP["feed_override_pct"], ns)
        seen: asyncio.Queue[float] = asyncio.Queue()

        class Handler:
            def datachange_notification(self, node: Any, value: float, data: Any) -> None:
                seen.put_nowait(value)

        try:
            subscription = await client.create_subscription(5, Handler())
            await subscription.subscribe_data_change(client.get_node(feed))
            await asyncio.wait_for(seen.get(), TIMEOUT_S)  # the initial value
            before = service.answered
            await send(client, write(feed, ua.Variant(63.0, ua.VariantType.Double)))
            assert service.answered == before + 1
            while (value := await asyncio.wait_for(seen.get(), TIMEOUT_S)) != 63.0:
                pass
            assert value == 63.0
        finally:
            await client.disconnect()

    serve(body)


def test_other_requests_are_left_to_asyncua() -> None:
    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        client, ns = await connect(server)
        feed = ua.NodeId(NODE_MAP["feed_override_pct"], ns)
        x = ua.NodeId(NODE_MAP["x_mm"], ns)
        two = read(feed)
        two.Parameters.NodesToRead.append(
            ua.ReadValueId(NodeId=x, AttributeId=ua.AttributeIds.Value)
        )
        name = read(feed)
        name.Parameters.NodesToRead[0].AttributeId = ua.AttributeIds.DisplayName
        ranged = read(feed)
        ranged.Parameters.NodesToRead[0].IndexRange = "0"
        float_write = write(feed, ua.Variant(41.0, ua.VariantType.Float))
        array_write = write(feed, ua.Variant([41.0], ua.VariantType.Double))
        other = read(ua.NodeId("Machine.Identification.Manufacturer", ns))
        try:
            before = service.answered
            for request in (two, name, ranged, float_write, array_write, other):
                await send(client, request)
            assert service.answered == before
            assert await client.get_node(feed).read_value() == 41.0  # the Float write, asyncua's
        finally:
            await client.disconnect()

    serve(body)


def _plain_write_message(client: Client, body: bytes) -> bytes:
    """``body`` framed as the client's next message on its channel (policy None)."""
    protocol = client.uaclient.protocol
    assert protocol is not None
    protocol._request_id += 1
    framed: bytes = protocol._connection.message_to_binary(body, request_id=protocol._request_id)
    return framed


def test_truncated_and_garbage_requests_do_no_harm() -> None:
    """Every cut of a Write's body, and random bytes, sent as whole messages: the lean path
    declines each (asyncua answers or closes the channel), the machine is never commanded,
    and the server still serves a new session."""

    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        client, ns = await connect(server)
        feed = ua.NodeId(NODE_MAP["feed_override_pct"], ns)
        request = write(feed, ua.Variant(44.0, ua.VariantType.Double))
        protocol = client.uaclient.protocol
        assert protocol is not None
        protocol._setup_request_header(request.RequestHeader)
        whole = bytes(struct_to_binary(request))
        rng = random.Random(17)
        garbage = [
            bytes(rng.randrange(256) for _ in range(rng.randrange(1, 80))) for _ in range(50)
        ]
        garbage += [whole[:4] + bytes(rng.randrange(256) for _ in range(60)) for _ in range(50)]
        try:
            for cut in [*(whole[:k] for k in range(len(whole))), *garbage]:
                before = service.answered
                transport = protocol.transport
                if transport is None:  # asyncua closed the channel: a new session
                    await client.disconnect()
                    client, ns = await connect(server)
                    protocol = client.uaclient.protocol
                    assert protocol is not None
                    transport = protocol.transport
                    assert transport is not None
                transport.write(_plain_write_message(client, cut))
                await asyncio.sleep(0.002)
                assert service.answered == before, cut
            assert machine.commands == []
        finally:
            await client.disconnect()
        client, ns = await connect(server)
        try:
            await send(client, write(feed, ua.Variant(45.0, ua.VariantType.Double)))
            assert machine.commands == [("feed_override_pct", 45.0)]
        finally:
            await client.disconnect()

    serve(body)


def test_the_parsers_decline_every_cut_without_raising() -> None:
    """The lean service's parsers on every prefix and on random bytes: ``None`` or an
    answer, never an exception (anything from a peer is untrusted)."""

    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        ns = server.namespace_index
        feed = ua.NodeId(NODE_MAP["feed_override_pct"], ns)
        params = [
            bytes(struct_to_binary(read(feed).Parameters)),
            bytes(struct_to_binary(write(feed, ua.Variant(1.0, ua.VariantType.Double)).Parameters)),
        ]
        rng = random.Random(5)
        for whole in params:
            assert (
                service._read(whole, 0, len(whole)) is not None
                or service._write(User(), whole, 0, len(whole)) is not None
            )
            for k in range(len(whole)):
                assert service._read(whole[:k], 0, k) is None
                assert service._write(User(), whole[:k], 0, k) is None
            for _ in range(300):
                noisy = bytearray(whole)
                noisy[rng.randrange(len(noisy))] = rng.randrange(256)
                service._read(bytes(noisy), 0, len(noisy))
                service._write(User(), bytes(noisy), 0, len(noisy))
        assert machine.commands == []  # User() is no operator: refused, never applied

    serve(body)


@pytest.mark.parametrize(
    "value",
    [
        ua.DataValue(ua.Variant(1.5, ua.VariantType.Double)),
        ua.DataValue(ua.Variant(math.nan, ua.VariantType.Double), StatusCode=None),
        ua.DataValue(ua.Variant(-math.inf, ua.VariantType.Double)),
        ua.DataValue(ua.Variant(True, ua.VariantType.Boolean)),
        ua.DataValue(ua.Variant(-(2**31), ua.VariantType.Int32)),
        ua.DataValue(StatusCode=ua.StatusCode(ua.StatusCodes.BadOutOfRange)),
        ua.DataValue(ua.Variant(2.0, ua.VariantType.Double), SourcePicoseconds=7),
        ua.DataValue(ua.Variant([1.0, 2.0], ua.VariantType.Double)),
        ua.DataValue(ua.Variant("text", ua.VariantType.String)),
        ua.DataValue(ua.Variant(3, ua.VariantType.Int64)),
    ],
)
@pytest.mark.parametrize("stamped", [False, True])
def test_encode_data_value_is_asyncua_s(value: ua.DataValue, stamped: bool) -> None:
    if stamped:
        value.SourceTimestamp = value.ServerTimestamp = STAMP
    assert encode_data_value(value) == bytes(struct_to_binary(value))


def test_asyncua_internals_the_lean_path_relies_on_are_there() -> None:
    """Fails loudly when an asyncua upgrade moves what opcua_lean and opcua_channel use."""
    for owner, names in (
        (OPCUAProtocol, ("_process_one_msg", "data_received")),
        (UaProcessor, ("process",)),
    ):
        for name in names:
            assert callable(getattr(owner, name)), (owner, name)
    channel = SecureConnection(None, None)  # type: ignore[arg-type]
    for name in ("_peer_sequence_number", "_incoming_parts", "_limits", "security_token"):
        assert hasattr(channel, name), name
    assert issubclass(_LeanProtocol, OPCUAProtocol)
    assert struct.calcsize("<3scIIIII") == 24


def test_a_fault_of_the_lean_path_leaves_the_request_to_asyncua() -> None:
    async def body(server: OpcUaMachineServer, machine: FakeMachine, service: LeanService) -> None:
        client, ns = await connect(server)
        feed = ua.NodeId(NODE_MAP["feed_override_pct"], ns)

        def broken(name: str, value: object) -> ua.StatusCode:
            raise RuntimeError("a bug")

        service._command = broken
        try:
            before = service.answered
            answer = await send(client, write(feed, ua.Variant(47.0, ua.VariantType.Double)))
            (code,) = results(answer, ua.WriteResponse)
            assert code.is_good() and machine.commands == [("feed_override_pct", 47.0)]
            assert service.answered == before
        finally:
            await client.disconnect()

    serve(body)
