"""The virtual machine's OPC UA server answers the common Read and Write itself.

asyncua's server decodes every request into objects, queues it for a task of its own,
dispatches it by comparing its type with each service's in turn, calls the attribute service
and encodes the answer generically: about 1,240 Python calls a round trip (docs/latency.md,
issue 17), two to three times dearer on the first request after a pause. A connection of
:class:`LeanServer` answers, right where its bytes arrive, a request that is

- a whole single-chunk message on a channel of policy None that asyncua would accept as is
  (:func:`~cnctwin.thread.opcua_channel.plain_message`),
- of an activated session whose user may call the service (the server's permission ruleset,
  asked as asyncua asks it), on a server with no service callbacks registered,
- a Read of the Value of one of the machine's variables, or a Write of one DataValue (a
  scalar Boolean, Int32 or Double, with or without a StatusCode) to one of them, in the
  usual encoding (OPC 10000-6 5.2, 7.1.2; no diagnostics asked for, no index range or data
  encoding, no additional header),

and only when nothing of the connection waits in asyncua's queue, so the requests of a
channel are still handled in order. The Read answers the DataValue the address space holds
(encoded once per value by asyncua's own encoder); the Write is judged by
:func:`~cnctwin.virtual.opcua_server.write_refusal` and applied by
:meth:`~cnctwin.virtual.opcua_server.OpcUaMachineServer.command_status`, as asyncua's write
service of the server does. Every other message goes to asyncua unchanged (other services,
several nodes, other types, arrays, a signed or encrypted channel, anything malformed:
asyncua's errors then). The answer is framed as asyncua's secure channel frames it, with its
sequence counter (:func:`~cnctwin.thread.opcua_channel.frame_message`).

This reaches into asyncua's private server classes (``Server.bserver``,
``BinaryServer._make_protocol``, ``OPCUAProtocol._buffer``, ``messages`` and
``_process_one_msg``, ``UaProcessor._connection``, ``CallbackService._listeners``):
pyproject.toml pins asyncua, and tests/virtual/test_opcua_lean.py fails if they change.
"""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from asyncua import Server, ua
from asyncua.common.utils import Buffer
from asyncua.crypto.permission_rules import User
from asyncua.server.address_space import AttributeValue
from asyncua.server.binary_server_asyncio import BinaryServer, OPCUAProtocol
from asyncua.server.uaprocessor import UaProcessor
from asyncua.ua.ua_binary import nodeid_to_binary, struct_to_binary

from cnctwin.thread import (
    PlainMessage,
    filetime_now,
    frame_message,
    plain_message,
    take_plain_message,
)

__all__ = ["LeanServer", "LeanService", "MachineNode", "encode_data_value"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class MachineNode:
    """A variable of the machine: its signal's name, NodeId and Value attribute."""

    name: str
    node_id: ua.NodeId
    slot: AttributeValue


#: ``(user, name, node_id, attribute_id) -> refusal or None`` (opcua_server.write_refusal).
Refusal = Callable[[User | None, str | None, ua.NodeId, int], ua.StatusCode | None]
#: ``(name, value) -> status``: apply a command (OpcUaMachineServer.command_status).
Command = Callable[[str, object], ua.StatusCode]

_READ = ua.NodeId(ua.ObjectIds.ReadRequest_Encoding_DefaultBinary)
_WRITE = ua.NodeId(ua.ObjectIds.WriteRequest_Encoding_DefaultBinary)
_READ_ID = bytes(
    nodeid_to_binary(ua.FourByteNodeId(ua.ObjectIds.ReadRequest_Encoding_DefaultBinary))
)
_WRITE_ID = bytes(
    nodeid_to_binary(ua.FourByteNodeId(ua.ObjectIds.WriteRequest_Encoding_DefaultBinary))
)
#: RequestHeader after the AuthenticationToken: Timestamp, RequestHandle, ReturnDiagnostics,
#: AuditEntryId's length.
_HEADER = struct.Struct("<qIIi")
#: TimeoutHint and a null AdditionalHeader (null NodeId, no body).
_HEADER_END = struct.Struct("<I3s")
_NO_EXTENSION = b"\0\0\0"
#: ReadParameters up to the first node: MaxAge, TimestampsToReturn, NodesToRead's length.
_READ_PARAMS = struct.Struct("<dIi")
#: After a node: AttributeId, a null IndexRange, a null DataEncoding (namespace 0, null name).
_READ_ITEM = struct.Struct("<IiHi")
_WRITE_ITEM = struct.Struct("<Ii")
_INT32 = struct.Struct("<i")
_UINT32 = struct.Struct("<I")
_STAMP = struct.Struct("<qI")
_VALUE_ATTRIBUTE = int(ua.AttributeIds.Value)
#: Variant types a Write is taken with: encoding byte -> how the value is packed.
_WRITE_SCALARS = {
    ua.VariantType.Boolean.value: struct.Struct("<?"),
    ua.VariantType.Int32.value: struct.Struct("<i"),
    ua.VariantType.Double.value: struct.Struct("<d"),
}


def _template(response: ua.ReadResponse | ua.WriteResponse) -> tuple[bytes, bytes, bytes]:
    """asyncua's encoding of an answer without results, cut around the ResponseHeader's
    Timestamp and RequestHandle and before the Results: (TypeId, the rest of the header,
    the empty DiagnosticInfos)."""
    whole = bytes(struct_to_binary(response))
    type_id = len(nodeid_to_binary(response.TypeId))
    return whole[:type_id], whole[type_id + _STAMP.size : -8], whole[-4:]


_READ_ANSWER = _template(ua.ReadResponse())
_WRITE_ANSWER = _template(ua.WriteResponse())


#: Variant types :func:`encode_data_value` packs itself: type -> (encoding byte, packer).
_ENCODED_SCALARS = {
    ua.VariantType.Boolean: (ua.VariantType.Boolean.value, struct.Struct("<B?")),
    ua.VariantType.Int32: (ua.VariantType.Int32.value, struct.Struct("<Bi")),
    ua.VariantType.Double: (ua.VariantType.Double.value, struct.Struct("<Bd")),
}
_TICKS = struct.Struct("<q")


def encode_data_value(value: ua.DataValue) -> bytes:
    """The binary encoding of ``value`` (OPC 10000-6 5.2.2.17), byte for byte asyncua's.

    Packed here for what the machine's variables hold: a scalar Boolean, Int32 or Double (or
    a null value), a StatusCode and the two time stamps (each optional), no picoseconds;
    anything else is asyncua's ``struct_to_binary`` (test_opcua_lean.py compares both).
    """
    variant = value.Value
    status = value.StatusCode
    source, server = value.SourceTimestamp, value.ServerTimestamp
    if value.SourcePicoseconds is not None or value.ServerPicoseconds is not None:
        return bytes(struct_to_binary(value))
    parts: list[bytes] = []
    mask = 0
    if variant is not None:
        if variant.is_array or variant.Dimensions is not None:
            return bytes(struct_to_binary(value))
        if variant.VariantType is ua.VariantType.Null:
            if variant.Value is not None:
                return bytes(struct_to_binary(value))
            parts.append(b"\0")
        else:
            scalar = _ENCODED_SCALARS.get(variant.VariantType)
            if scalar is None or type(variant.Value) not in (bool, int, float):
                return bytes(struct_to_binary(value))
            kind, packer = scalar
            parts.append(packer.pack(kind, variant.Value))
        mask |= 0x01
    if status is not None:
        parts.append(_UINT32.pack(status.value))
        mask |= 0x02
    if source is not None:
        parts.append(_TICKS.pack(ua.datetime_to_win_epoch(source)))
        mask |= 0x04
    if server is not None:
        parts.append(_TICKS.pack(ua.datetime_to_win_epoch(server)))
        mask |= 0x08
    return bytes((mask,)) + b"".join(parts)


def _node_end(data: bytes, at: int, end: int) -> int:
    """Where the NodeId encoded at ``data[at]`` ends (OPC 10000-6 5.2.2.9); ``-1`` for a
    NodeId with a namespace URI or server index, an unknown encoding or one past ``end``."""
    if at >= end:
        return -1
    kind = data[at]
    if kind == 0:  # TwoByte
        stop = at + 2
    elif kind == 1:  # FourByte
        stop = at + 4
    elif kind == 2:  # Numeric
        stop = at + 7
    elif kind == 4:  # Guid
        stop = at + 19
    elif kind in (3, 5):  # String, ByteString: namespace, length, bytes
        if at + 7 > end:
            return -1
        (length,) = _INT32.unpack_from(data, at + 3)
        stop = at + 7 + max(length, 0)
    else:
        return -1
    return stop if stop <= end else -1


class LeanService:
    """Answers the common Read and Write of a machine's variables (module docstring).

    Parameters
    ----------
    nodes
        The machine's variables.
    refusal
        Why a write is refused, or ``None`` (the server's own rule).
    command
        Applies a command and says its status (never raises).
    """

    def __init__(self, nodes: list[MachineNode], refusal: Refusal, command: Command) -> None:
        self._nodes = {bytes(nodeid_to_binary(node.node_id)): node for node in nodes}
        self._refusal = refusal
        self._command = command
        #: The last DataValue of each variable read and asyncua's encoding of it.
        self._encoded: dict[str, tuple[ua.DataValue, bytes]] = {}
        #: Requests answered here (tests/virtual/test_opcua_lean.py counts them).
        self.answered = 0

    def answer(self, processor: UaProcessor, data: bytes, message: PlainMessage) -> bytes | None:
        """The body of the answer to the request ``message`` of ``data``, the request handled
        (a Write applied); ``None``, with nothing done, for a request asyncua must handle."""
        session = processor.session
        if session is None or not session.is_activated():
            return None
        iserver = processor.iserver
        if iserver.callback_service._listeners:  # someone hooks reads or writes: asyncua's
            return None
        start, end = message.start, message.end
        kind = data[start : start + 4]
        if kind == _READ_ID:
            service = _READ
        elif kind == _WRITE_ID:
            service = _WRITE
        else:
            return None
        at = _node_end(data, start + 4, end)  # the AuthenticationToken, which asyncua ignores
        if at < 0 or at + _HEADER.size > end:
            return None
        _, handle, diagnostics, audit = _HEADER.unpack_from(data, at)
        at += _HEADER.size + max(audit, 0)
        if diagnostics or at + _HEADER_END.size > end:
            return None
        if _HEADER_END.unpack_from(data, at)[1] != _NO_EXTENSION:
            return None
        at += _HEADER_END.size
        user = session.user
        permissions = processor._connection.security_policy.permissions
        if permissions is not None:
            body = Buffer(data, at, end - at)
            if permissions.check_validity(user, service, body) is False:
                return None  # asyncua refuses it with a ServiceFault
        if service is _READ:
            result = self._read(data, at, end)
            answer = _READ_ANSWER
        else:
            writer = user if user is not None else User()
            if writer is iserver.isession.user:
                return None
            result = self._write(writer, data, at, end)
            answer = _WRITE_ANSWER
        if result is None:
            return None
        processor.session_last_activity = time.monotonic()
        session.touch()
        self.answered += 1
        head, rest, tail = answer
        stamp = _STAMP.pack(filetime_now(), handle)
        return b"".join((head, stamp, rest, b"\x01\0\0\0", result, tail))

    def _node(self, data: bytes, at: int, end: int) -> tuple[MachineNode, int] | None:
        """The one node of a request's parameters at ``at`` (after the count, which must be
        1) if it is one of the machine's, and where it ends."""
        if at + 4 > end or _INT32.unpack_from(data, at)[0] != 1:
            return None
        stop = _node_end(data, at + 4, end)
        if stop < 0:
            return None
        node = self._nodes.get(data[at + 4 : stop])
        return None if node is None else (node, stop)

    def _read(self, data: bytes, at: int, end: int) -> bytes | None:
        """The encoded DataValue of a one-node Read of a Value, else ``None``."""
        if at + _READ_PARAMS.size > end:
            return None
        _, timestamps, _ = _READ_PARAMS.unpack_from(data, at)
        if timestamps > ua.TimestampsToReturn.Neither:
            return None
        found = self._node(data, at + _READ_PARAMS.size - 4, end)
        if found is None:
            return None
        node, at = found
        if at + _READ_ITEM.size != end:
            return None
        attribute, index_range, encoding_ns, encoding_name = _READ_ITEM.unpack_from(data, at)
        if (attribute, index_range, encoding_ns, encoding_name) != (_VALUE_ATTRIBUTE, -1, 0, -1):
            return None
        slot = node.slot
        value = slot.value
        if slot.value_callback is not None or value is None:
            return None
        held = self._encoded.get(node.name)
        if held is None or held[0] is not value:
            held = (value, encode_data_value(value))
            self._encoded[node.name] = held
        return held[1]

    def _write(self, user: User, data: bytes, at: int, end: int) -> bytes | None:
        """The encoded status of a one-node Write of a scalar, the Write applied; else
        ``None``."""
        found = self._node(data, at, end)
        if found is None:
            return None
        node, at = found
        if at + _WRITE_ITEM.size + 2 > end:
            return None
        attribute, index_range = _WRITE_ITEM.unpack_from(data, at)
        at += _WRITE_ITEM.size
        mask, variant = data[at], data[at + 1]
        packer = _WRITE_SCALARS.get(variant)
        if index_range != -1 or mask not in (0x01, 0x03) or packer is None:
            return None
        at += 2
        stop = at + packer.size + (4 if mask & 0x02 else 0)
        if stop != end:
            return None
        (raw,) = packer.unpack_from(data, at)
        status = self._refusal(user, node.name, node.node_id, attribute)
        if status is None:
            status = self._command(node.name, raw)
        return _UINT32.pack(status.value)


class _LeanProtocol(OPCUAProtocol):
    """asyncua's connection, which answers the common requests itself (:class:`LeanService`)
    while nothing of the connection is queued for or being handled by asyncua."""

    service: LeanService
    _handling = False

    def data_received(self, data: bytes) -> None:
        at = 0
        processor = self.processor
        if processor is not None and not (self._buffer or self._handling) and self.messages.empty():
            connection = processor._connection
            answers: list[bytes] = []
            while at < len(data):
                message = plain_message(connection, data, at)
                if message is None:
                    break
                try:
                    body = self.service.answer(processor, data, message)
                except Exception:  # a fault of this path must not end the connection
                    logger.exception("OPC UA request left to asyncua after an error")
                    body = None
                if body is None:
                    break
                take_plain_message(connection, message)
                answers.append(frame_message(connection, body, message.request_id))
                at = message.end
            if answers and self.transport is not None:
                self.transport.write(b"".join(answers))
        if at < len(data):
            super().data_received(data[at:] if at else data)

    async def _process_one_msg(self, header: Any, buf: Buffer) -> bool:
        self._handling = True
        try:
            return await super()._process_one_msg(header, buf)
        finally:
            self._handling = False


class _LeanBinaryServer(BinaryServer):
    """asyncua's listening server, whose connections are :class:`_LeanProtocol`."""

    service: LeanService | None = None

    def _make_protocol(self) -> OPCUAProtocol:
        protocol = super()._make_protocol()
        if self.service is not None:
            protocol.__class__ = _LeanProtocol
            assert isinstance(protocol, _LeanProtocol)
            protocol.service = self.service
        return protocol


class LeanServer(Server):
    """asyncua's :class:`~asyncua.Server`, whose connections answer the common Read and
    Write with :attr:`service` (set it before :meth:`start`; ``None``: asyncua answers all)."""

    service: LeanService | None = None

    @property  # type: ignore[override]
    def bserver(self) -> BinaryServer | None:
        """asyncua's listening server (made by :meth:`start`), given lean connections."""
        made: BinaryServer | None = self.__dict__.get("_bserver")
        return made

    @bserver.setter
    def bserver(self, made: BinaryServer | None) -> None:
        if made is not None and type(made) is BinaryServer:
            made.__class__ = _LeanBinaryServer
            assert isinstance(made, _LeanBinaryServer)
            made.service = self.service
        self.__dict__["_bserver"] = made
