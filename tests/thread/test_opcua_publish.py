"""The subscription's lean PublishResponse reading (cnctwin.thread.opcua_publish) against
asyncua's own encoder and decoder: whatever it reads must be what asyncua decodes from the
same bytes (both re-encoded by asyncua, byte for byte, and every value of the same Python
type), and what it does not read it must leave to asyncua (``None``), never raise."""

from __future__ import annotations

import asyncio
import struct
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from asyncua import Client, Server, ua
from asyncua.common.utils import Buffer
from asyncua.ua.ua_binary import struct_from_binary, struct_to_binary
from hypothesis import given
from hypothesis import strategies as st

from cnctwin.thread import lean_publish_response, use_lean_publish

STAMP = datetime(2026, 11, 28, 1, 30, 0, 123456, tzinfo=UTC)

#: Scalar values of each type the lean path reads (asyncua's Variant type, a strategy).
NUMERIC = {
    ua.VariantType.Boolean: st.booleans(),
    ua.VariantType.SByte: st.integers(-128, 127),
    ua.VariantType.Byte: st.integers(0, 255),
    ua.VariantType.Int16: st.integers(-(2**15), 2**15 - 1),
    ua.VariantType.UInt16: st.integers(0, 2**16 - 1),
    ua.VariantType.Int32: st.integers(-(2**31), 2**31 - 1),
    ua.VariantType.UInt32: st.integers(0, 2**32 - 1),
    ua.VariantType.Int64: st.integers(-(2**63), 2**63 - 1),
    ua.VariantType.UInt64: st.integers(0, 2**64 - 1),
    ua.VariantType.Float: st.floats(width=32),
    ua.VariantType.Double: st.floats(),
}
#: Values it leaves to asyncua.
OTHER = st.one_of(
    st.text(max_size=8).map(lambda s: ua.Variant(s, ua.VariantType.String)),
    st.lists(st.floats(), max_size=3).map(lambda v: ua.Variant(v, ua.VariantType.Double)),
    st.just(ua.Variant(ua.NodeId(5, 2), ua.VariantType.NodeId)),
)
STAMPS = st.one_of(
    st.none(),
    st.just(STAMP),
    st.datetimes(
        min_value=datetime(1601, 1, 2), max_value=datetime(9999, 1, 1), timezones=st.just(UTC)
    ),
)


@st.composite
def variants(draw: st.DrawFn, lean_only: bool) -> ua.Variant | None:
    if not lean_only and draw(st.integers(0, 9)) == 0:
        return draw(st.one_of(st.none(), OTHER))
    vtype = draw(st.sampled_from(sorted(NUMERIC, key=lambda t: t.value)))
    return ua.Variant(draw(NUMERIC[vtype]), vtype)


@st.composite
def items(draw: st.DrawFn, lean_only: bool) -> ua.MonitoredItemNotification:
    value = draw(variants(lean_only))
    status = draw(st.sampled_from([None, 0, 0x80000000, 0x40000000, 0x80350000]))
    value_ = ua.DataValue(
        Value=value,
        StatusCode=None if status is None else ua.StatusCode(status),
        SourceTimestamp=draw(STAMPS),
        ServerTimestamp=draw(STAMPS),
        SourcePicoseconds=draw(st.one_of(st.none(), st.integers(0, 9999))),
        ServerPicoseconds=draw(st.one_of(st.none(), st.integers(0, 9999))),
    )
    return ua.MonitoredItemNotification(ClientHandle=draw(st.integers(0, 2**32 - 1)), Value=value_)


@st.composite
def responses(draw: st.DrawFn, lean_only: bool) -> ua.PublishResponse:
    data: list[Any] = [
        ua.DataChangeNotification(MonitoredItems=draw(st.lists(items(lean_only), max_size=25)))
        for _ in range(draw(st.integers(0, 2)))
    ]
    if not lean_only and draw(st.integers(0, 4)) == 0:
        data.append(ua.StatusChangeNotification(Status=ua.StatusCode(0x80AB0000)))
    response = ua.PublishResponse()
    response.ResponseHeader.Timestamp = draw(STAMPS) or STAMP
    response.ResponseHeader.RequestHandle = draw(st.integers(0, 2**32 - 1))
    if not lean_only and draw(st.integers(0, 4)) == 0:
        response.ResponseHeader.StringTable = ["a string"]
    parameters = response.Parameters
    parameters.SubscriptionId = draw(st.integers(0, 2**32 - 1))
    parameters.AvailableSequenceNumbers = draw(st.lists(st.integers(0, 2**32 - 1), max_size=4))
    parameters.MoreNotifications = draw(st.booleans())
    parameters.NotificationMessage = ua.NotificationMessage(
        SequenceNumber=draw(st.integers(0, 2**32 - 1)),
        PublishTime=draw(STAMPS) or STAMP,
        NotificationData=data,
    )
    codes = draw(st.lists(st.sampled_from([0, 0x80000000]), max_size=3))
    parameters.Results = [ua.StatusCode(c) for c in codes]
    return response


def asyncua_reads(data: bytes) -> ua.PublishResponse:
    return struct_from_binary(ua.PublishResponse, Buffer(data))


def same(lean: ua.PublishResponse, theirs: ua.PublishResponse) -> None:
    """Equal as asyncua encodes them, and every field of the same type."""
    assert bytes(struct_to_binary(lean)) == bytes(struct_to_binary(theirs))
    same_types(lean, theirs)


def same_types(lean: Any, theirs: Any) -> None:
    assert type(lean) is type(theirs), (lean, theirs)
    if isinstance(theirs, list):
        assert len(lean) == len(theirs)
        for a, b in zip(lean, theirs, strict=True):
            same_types(a, b)
    elif hasattr(theirs, "__dataclass_fields__"):
        for name in theirs.__dataclass_fields__:
            same_types(getattr(lean, name), getattr(theirs, name))


@given(responses(lean_only=True))
def test_the_common_layout_is_read_as_asyncua_reads_it(response: ua.PublishResponse) -> None:
    data = bytes(struct_to_binary(response))
    lean = lean_publish_response(Buffer(data))
    assert lean is not None, "the common layout was left to asyncua"
    same(lean, asyncua_reads(data))


@given(responses(lean_only=False))
def test_anything_it_reads_is_asyncua_s_reading(response: ua.PublishResponse) -> None:
    data = bytes(struct_to_binary(response))
    lean = lean_publish_response(Buffer(data))
    if lean is not None:
        same(lean, asyncua_reads(data))


def common() -> bytes:
    notification = ua.DataChangeNotification(
        MonitoredItems=[
            ua.MonitoredItemNotification(
                ClientHandle=n,
                Value=ua.DataValue(
                    Value=ua.Variant(n * 1.5, ua.VariantType.Double),
                    SourceTimestamp=STAMP,
                    ServerTimestamp=STAMP + timedelta(microseconds=n),
                ),
            )
            for n in range(20)
        ]
    )
    response = ua.PublishResponse()
    response.ResponseHeader.Timestamp = STAMP
    response.Parameters.SubscriptionId = 7
    response.Parameters.AvailableSequenceNumbers = [41, 42]
    response.Parameters.NotificationMessage = ua.NotificationMessage(
        SequenceNumber=42, PublishTime=STAMP, NotificationData=[notification]
    )
    return bytes(struct_to_binary(response))


def test_what_it_does_not_read_is_left_to_asyncua() -> None:
    data = common()
    assert lean_publish_response(Buffer(data)) is not None
    for cut in range(len(data)):  # every truncation
        assert lean_publish_response(Buffer(data[:cut])) is None
    assert lean_publish_response(Buffer(data + b"\0")) is None  # a longer message
    header = struct.calcsize("<4sqI")
    bad = data[:header] + struct.pack("<I", 0x80010000) + data[header + 4 :]
    assert lean_publish_response(Buffer(bad)) is None  # a bad service result
    read = ua.ReadResponse()
    assert lean_publish_response(Buffer(bytes(struct_to_binary(read)))) is None


@given(st.binary(max_size=300), st.integers(0, 800), st.integers(0, 255))
def test_garbage_never_raises(garbage: bytes, where: int, byte: int) -> None:
    """A peer's bytes, mutated or random: a reading or ``None``, never an exception, and
    counts as large as 2**31 allocate nothing."""
    data = bytearray(common())
    data[where % len(data)] = byte
    for body in (bytes(data), garbage, common()[:20] + b"\xff\xff\xff\x7f" + garbage):
        lean = lean_publish_response(Buffer(body))
        if lean is not None:
            same(lean, asyncua_reads(body))


def test_a_session_decodes_its_publishes_with_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """Against asyncua's server: a subscription's data changes arrive through the lean
    reading (counted), and with the same values as asyncua's own publish."""
    import cnctwin.thread.opcua_publish as module

    read: list[bool] = []
    original = module.lean_publish_response

    def counted(data: Buffer) -> ua.PublishResponse | None:
        result = original(data)
        read.append(result is not None)
        return result

    monkeypatch.setattr(module, "lean_publish_response", counted)

    async def scenario() -> list[float]:
        server = Server()
        await server.init()
        server.set_endpoint("opc.tcp://127.0.0.1:0/cnctwin-test")
        ns = await server.register_namespace("urn:cnctwin:test")
        variable = await server.nodes.objects.add_variable(ns, "X", 0.0)
        async with server:
            port = server.bserver._server.sockets[0].getsockname()[1]
            client = Client(f"opc.tcp://127.0.0.1:{port}/cnctwin-test")
            async with client:
                use_lean_publish(client.uaclient.session)
                subscription = await client.create_subscription(5, None, queue_maxsize=0)
                await subscription.subscribe_data_change(client.get_node(variable.nodeid))
                seen: list[float] = []
                events = aiter(subscription)
                for step in range(1, 6):
                    await variable.write_value(step * 0.5)
                    while not seen or seen[-1] != step * 0.5:
                        event = await asyncio.wait_for(anext(events), 10.0)
                        seen.append(event.value)
                await subscription.delete()
                return seen

    seen = asyncio.run(scenario())
    assert seen[-5:] == [0.5, 1.0, 1.5, 2.0, 2.5]
    assert read and all(read), read
