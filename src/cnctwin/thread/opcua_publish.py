"""The subscription's publishes read without asyncua's generic decoder (issue 15, item 7).

:class:`~cnctwin.thread.opcua.OpcUaConnection` takes the machine's readings from an OPC UA
subscription: the virtual machine publishes every 5 ms, some 20 data changes each, and
asyncua decodes every PublishResponse with its generic, type-driven decoder, 0.18 ms of the
twin's CPU per publish on this project's sandbox, about half a millisecond of each 12.5 ms
cycle (docs/benchmarks.md).

:func:`lean_publish_response` reads the layout servers commonly send straight into the same
asyncua objects: a PublishResponse (OPC 10000-4, 5.13.5; binary encoding OPC 10000-6, 5.2)
whose header carries a Good result and no diagnostics, string table or additional header,
whose notifications are DataChangeNotifications (OPC 10000-4, 7.25.2), each value a
DataValue (OPC 10000-6, 5.2.2.17) whose Variant is a scalar of a numeric built-in type or
Boolean, and which has no diagnostic infos. Anything else (a status change or events, a
string, an array, diagnostic infos, another header, a truncated or longer message) gives
``None`` and asyncua decodes the message whole, as before. The result equals asyncua's
decoding of the same bytes (tests/thread/test_opcua_publish.py re-encodes both), so the
subscription's sequence numbers, acknowledgements and republishing (asyncua's) are
unchanged.

:func:`use_lean_publish` makes an asyncua session's publish loop decode with it.
"""

from __future__ import annotations

import functools
import struct
from datetime import datetime
from typing import Any, cast

from asyncua import ua
from asyncua.client.ua_session import UaSession
from asyncua.common.utils import Buffer
from asyncua.ua.object_ids import ObjectIds
from asyncua.ua.ua_binary import nodeid_to_binary, struct_from_binary
from asyncua.ua.uaerrors import UaStructParsingError
from asyncua.ua.uatypes import win_epoch_to_datetime

__all__ = ["lean_publish_response", "use_lean_publish"]

#: TypeId, ResponseHeader (Timestamp, RequestHandle, ServiceResult, ServiceDiagnostics mask,
#: StringTable count, AdditionalHeader: null NodeId and no body), then the PublishResult's
#: SubscriptionId and the count of AvailableSequenceNumbers.
_START = struct.Struct("<4sqIIBi3sIi")
_PUBLISH_TYPE = cast(ua.Int32, ObjectIds.PublishResponse_Encoding_DefaultBinary)
_PUBLISH_ID = bytes(nodeid_to_binary(ua.FourByteNodeId(_PUBLISH_TYPE)))
#: MoreNotifications, the NotificationMessage's SequenceNumber and PublishTime, the count of
#: its NotificationData.
_MESSAGE = struct.Struct("<?Iqi")
#: An ExtensionObject holding a DataChangeNotification: its TypeId (FourByte NodeId), the
#: encoding byte (a binary body) and the body's length.
_DATA_CHANGE = struct.Struct("<4sBi")
_DATA_CHANGE_ID = bytes(
    nodeid_to_binary(
        ua.FourByteNodeId(cast(ua.Int32, ObjectIds.DataChangeNotification_Encoding_DefaultBinary))
    )
)
_INT32 = struct.Struct("<i")
#: Namespace 0. asyncua's decoder gives plain ints (and datetimes) where its annotations name
#: its int (datetime) subclasses; this module gives what the decoder gives, cast to match.
_NS0 = cast(ua.Int16, 0)
#: The Variant types read here, by their encoding byte (a scalar), with their struct code.
_SCALARS: dict[int, tuple[str, ua.VariantType]] = {
    vtype.value: (fmt, vtype)
    for vtype, fmt in (
        (ua.VariantType.Boolean, "?"),
        (ua.VariantType.SByte, "b"),
        (ua.VariantType.Byte, "B"),
        (ua.VariantType.Int16, "h"),
        (ua.VariantType.UInt16, "H"),
        (ua.VariantType.Int32, "i"),
        (ua.VariantType.UInt32, "I"),
        (ua.VariantType.Int64, "q"),
        (ua.VariantType.UInt64, "Q"),
        (ua.VariantType.Float, "f"),
        (ua.VariantType.Double, "d"),
    )
}


def lean_publish_response(data: Buffer) -> ua.PublishResponse | None:
    """The PublishResponse in ``data`` (a message body, its TypeId first) as asyncua
    decodes it, or ``None`` when it is not of the layout read here (module notes).

    Parameters
    ----------
    data
        The body of the answer to a Publish request, as the secure channel passes it on.

    Returns
    -------
    asyncua.ua.PublishResponse or None
        Equal to ``struct_from_binary(ua.PublishResponse, data)``; ``None``: decode it so.
    """
    body = bytes(data.copy().read(len(data)))
    try:
        return _read(body)
    except (struct.error, IndexError):  # cut short: asyncua reports it
        return None


def _read(body: bytes) -> ua.PublishResponse | None:
    (kind, stamp, handle, service, diagnostics, strings, extra, subscription, n_available) = (
        _START.unpack_from(body)
    )
    if (
        kind != _PUBLISH_ID
        or service != 0
        or diagnostics != 0
        or strings != 0
        or extra != b"\0\0\0"
        or n_available < 0
    ):
        return None
    at = _START.size
    available = list(struct.unpack_from(f"<{n_available}I", body, at))
    at += 4 * len(available)
    more, sequence, published, n_data = _MESSAGE.unpack_from(body, at)
    at += _MESSAGE.size
    if n_data < 0:
        return None
    stamps: dict[int, datetime] = {}
    notifications: list[Any] = []
    for _ in range(n_data):
        type_id, encoding, length = _DATA_CHANGE.unpack_from(body, at)
        at += _DATA_CHANGE.size
        if type_id != _DATA_CHANGE_ID or encoding != 1 or length < 8:
            return None
        end = at + length
        read = _data_change(body, at, end, stamps)
        if read is None:
            return None
        notifications.append(read)
        at = end
    (n_results,) = _INT32.unpack_from(body, at)
    at += 4
    if n_results < 0:
        return None
    results = [ua.StatusCode(code) for code in struct.unpack_from(f"<{n_results}I", body, at)]
    at += 4 * n_results
    (n_diagnostics,) = _INT32.unpack_from(body, at)
    if n_diagnostics != 0 or at + 4 != len(body):
        return None
    return ua.PublishResponse(
        TypeId=ua.NodeId(_PUBLISH_TYPE, _NS0, ua.NodeIdType.FourByte),  # a NodeId, as asyncua's
        ResponseHeader=ua.ResponseHeader(
            Timestamp=_stamp(stamp, stamps),
            RequestHandle=handle,
            ServiceResult=ua.StatusCode(service),
            ServiceDiagnostics=ua.DiagnosticInfo(),
            StringTable=[],
            AdditionalHeader=ua.ExtensionObject(),
        ),
        Parameters=ua.PublishResult(
            SubscriptionId=subscription,
            AvailableSequenceNumbers=available,
            MoreNotifications=more,
            NotificationMessage=ua.NotificationMessage(
                SequenceNumber=sequence,
                PublishTime=_stamp(published, stamps),
                NotificationData=notifications,
            ),
            Results=results,
            DiagnosticInfos=[],
        ),
    )


def _data_change(
    body: bytes, at: int, end: int, stamps: dict[int, datetime]
) -> ua.DataChangeNotification | None:
    """The DataChangeNotification in ``body[at:end]``; ``None`` if not of the layout."""
    (n_items,) = _INT32.unpack_from(body, at)
    at += 4
    if n_items < 0:
        return None
    items: list[ua.MonitoredItemNotification] = []
    for _ in range(n_items):
        mask = body[at + 4]
        layout = _item_layout(mask, body[at + 5] if mask & 0x01 else -1)
        if layout is None:  # an array, another type, an unknown field: asyncua reads it
            return None
        packer, vtype = layout
        fields = iter(packer.unpack_from(body, at))
        handle = next(fields)
        next(fields)  # the mask
        value = status = source = server = source_ps = server_ps = None
        if vtype is not None:
            next(fields)  # the Variant's encoding byte
            value = ua.Variant(next(fields), vtype, None, False)
        status = ua.StatusCode(cast(ua.UInt32, next(fields) if mask & 0x02 else 0))
        if mask & 0x04:
            source = _stamp(next(fields), stamps)
        if mask & 0x08:
            server = _stamp(next(fields), stamps)
        if mask & 0x10:
            source_ps = next(fields)
        if mask & 0x20:
            server_ps = next(fields)
        at += packer.size
        items.append(
            ua.MonitoredItemNotification(
                ClientHandle=handle,
                Value=ua.DataValue(value, status, source, server, source_ps, server_ps),
            )
        )
    (n_diagnostics,) = _INT32.unpack_from(body, at)
    if n_diagnostics != 0 or at + 4 != end:
        return None
    return ua.DataChangeNotification(MonitoredItems=items, DiagnosticInfos=[])


@functools.cache
def _item_layout(mask: int, variant: int) -> tuple[struct.Struct, ua.VariantType | None] | None:
    """How a MonitoredItemNotification with this DataValue mask and Variant encoding byte
    (-1: no value) is packed: ClientHandle, the mask, the Variant's encoding byte and value,
    StatusCode, the two time stamps and the two picosecond counts, each where the mask has
    it; ``None`` for a layout not read here. At most 64 x 257 of them."""
    if mask & ~0x3F:
        return None
    fmt = "<IB"
    vtype = None
    if mask & 0x01:
        scalar = _SCALARS.get(variant)
        if scalar is None:
            return None
        fmt += "B" + scalar[0]
        vtype = scalar[1]
    fmt += "I" * bool(mask & 0x02) + "q" * bool(mask & 0x04) + "q" * bool(mask & 0x08)
    fmt += "H" * bool(mask & 0x10) + "H" * bool(mask & 0x20)
    return struct.Struct(fmt), vtype


def _stamp(raw: int, stamps: dict[int, datetime]) -> ua.DateTime:
    """A DateTime as asyncua decodes it, each distinct value of a message converted once."""
    held = stamps.get(raw)
    if held is None:
        held = stamps[raw] = win_epoch_to_datetime(raw)
    return cast(ua.DateTime, held)


def use_lean_publish(session: UaSession) -> None:
    """Make ``session``'s publish loop decode its answers with :func:`lean_publish_response`
    (asyncua's decoder for the rest); the request is asyncua's, as before."""

    async def publish(acks: list[ua.SubscriptionAcknowledgement]) -> ua.PublishResponse:
        request = ua.PublishRequest()
        request.Parameters.SubscriptionAcknowledgements = acks if acks else []
        data = await session._send_request(request, timeout=0)
        response = lean_publish_response(data)
        if response is not None:
            return response
        try:
            return struct_from_binary(ua.PublishResponse, data)
        except Exception as err:  # as asyncua's publish: the loop goes on
            raise UaStructParsingError from err

    session.publish = publish  # type: ignore[method-assign]
