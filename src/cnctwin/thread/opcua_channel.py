"""The plain secure-channel message of OPC UA, read and framed without asyncua's chunk objects.

A service request or answer on a secure channel with security policy None travels, in the
common case, as one final chunk (OPC 10000-6 6.7.2): the MessageHeader (``MSG``, chunk type
``F``, MessageSize), the SecureChannelId, the SymmetricAlgorithmHeader (TokenId), the
SequenceHeader (SequenceNumber, RequestId) and the body, with no signature or padding.
:func:`plain_message` finds such a message and checks it as asyncua's
``SecureConnection.receive_from_header_and_body`` does (channel, token, size limits,
sequence number); everything else (another policy, a message type other than ``MSG``, an
intermediate or aborting chunk, a token or sequence number asyncua must judge: renewal,
wrap-around, an error) is left to asyncua, so signing, encryption and their checks stay
asyncua's. Used by the twin's client (:mod:`cnctwin.thread.opcua`) and the virtual machine's
server (:mod:`cnctwin.virtual.opcua_lean`) for their common answers and requests.
:func:`frame_message` is the other way: it frames such a message as asyncua's
``SecureConnection.message_to_binary`` does, byte for byte, with the channel's own sequence
counter, and leaves every other message to asyncua.

This reads asyncua's private channel state (``_peer_sequence_number``, ``_sequence_number``,
``_incoming_parts``, ``_limits``): pyproject.toml pins asyncua to the versions it was
written for, and tests/thread/test_opcua_channel.py fails if that state changes shape.
"""

from __future__ import annotations

import struct
import time
from typing import NamedTuple

from asyncua.common.connection import SecureConnection
from asyncua.crypto.security_policies import SecurityPolicyNone
from asyncua.ua.uatypes import EPOCH_AS_FILETIME

__all__ = ["PlainMessage", "filetime_now", "frame_message", "plain_message", "take_plain_message"]

#: MessageHeader (type, chunk type, size), SecureChannelId, TokenId, SequenceNumber, RequestId.
_HEAD = struct.Struct("<3scIIIII")
_HEAD_SIZE = _HEAD.size
#: Sequence numbers are UInt32; asyncua's counter wraps (to 1) when it reaches this.
_SEQUENCE_WRAP = 1 << 32


class PlainMessage(NamedTuple):
    """A complete single-chunk ``MSG`` of policy None: the body is ``data[start:end]``."""

    start: int
    end: int
    sequence_number: int
    request_id: int


def plain_message(connection: SecureConnection, data: bytes, at: int) -> PlainMessage | None:
    """The message that starts at ``data[at]`` if it is a whole single-chunk ``MSG`` on
    ``connection``'s channel with policy None that asyncua would accept as is; ``None``
    otherwise (incomplete, another type or policy, anything asyncua must judge or refuse).

    Nothing is changed: :func:`take_plain_message` takes the message's sequence number once
    the caller has decided to handle it, so a message left to asyncua meets the channel as it
    was.
    """
    if type(connection.security_policy) is not SecurityPolicyNone:
        return None
    if len(data) - at < _HEAD_SIZE:
        return None
    kind, chunk, size, channel, token, sequence, request = _HEAD.unpack_from(data, at)
    end = at + size
    if kind != b"MSG" or chunk != b"F" or size < _HEAD_SIZE or end > len(data):
        return None
    limits = connection._limits
    if size > limits.max_recv_buffer or not limits.is_msg_size_within_limit(size - _HEAD_SIZE):
        return None
    if connection._incoming_parts:  # a message in chunks is being put together
        return None
    current = connection.security_token
    if channel != current.ChannelId or token != current.TokenId:
        return None
    peer = connection._peer_sequence_number
    if peer is not None and sequence != peer + 1:  # wrap-around or an error: asyncua's
        return None
    return PlainMessage(at + _HEAD_SIZE, end, sequence, request)


def take_plain_message(connection: SecureConnection, message: PlainMessage) -> None:
    """Take ``message`` (of :func:`plain_message`) as received on ``connection``: its
    sequence number becomes the channel's last, as asyncua's receive makes it."""
    connection._peer_sequence_number = message.sequence_number


def frame_message(connection: SecureConnection, body: bytes, request_id: int) -> bytes:
    """``connection.message_to_binary(body, request_id=request_id)``, byte for byte: the
    service message ``body`` framed for request ``request_id`` on ``connection``'s channel,
    the channel's sequence number advanced.

    Framed here when asyncua would make one plain final chunk of it (policy None, a body
    not empty that fits the chunk size the peer receives, ``max_send_buffer``; OPC 10000-6
    6.7.2) and the sequence number does not wrap: the header of :func:`plain_message`, with
    the channel's current ChannelId and TokenId and the next number of asyncua's own counter
    (``SecureConnection._sequence_number``, which asyncua's frames on the same channel
    advance too). Anything else (signing, encryption, several chunks, the wrap to 1) is
    asyncua's ``message_to_binary``.
    """
    if type(connection.security_policy) is SecurityPolicyNone:
        size = len(body) + _HEAD_SIZE
        sequence = connection._sequence_number + 1
        if _HEAD_SIZE < size <= connection._limits.max_send_buffer and sequence < _SEQUENCE_WRAP:
            current = connection.security_token
            head = _HEAD.pack(
                b"MSG", b"F", size, current.ChannelId, current.TokenId, sequence, request_id
            )
            connection._sequence_number = sequence
            return head + body
    return connection.message_to_binary(body, request_id=request_id)


def filetime_now() -> int:
    """Now as an OPC UA DateTime: 100 ns ticks since 1601-01-01 UTC (OPC 10000-6 5.2.2.5)."""
    return time.time_ns() // 100 + EPOCH_AS_FILETIME
