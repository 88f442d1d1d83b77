"""The plain secure-channel message read without asyncua's chunk objects
(cnctwin.thread.opcua_channel, issue 17): it must find what asyncua's receive finds, with
the same checks, and leave everything else (other policies, chunking, a wrong channel, token
or sequence number, a cut message) to asyncua, changing nothing."""

from __future__ import annotations

from typing import Any

import pytest
from asyncua import ua
from asyncua.common.connection import SecureConnection, TransportLimits
from asyncua.common.utils import Buffer
from asyncua.crypto.security_policies import SecurityPolicyNone
from asyncua.ua.ua_binary import header_from_binary

from cnctwin.thread.opcua_channel import plain_message, take_plain_message

BODY = bytes(range(40)) * 3


def channel(policy: Any = None) -> SecureConnection:
    connection = SecureConnection(policy or SecurityPolicyNone(), TransportLimits(65535, 65535))
    connection.security_token.ChannelId = 7
    connection.security_token.TokenId = 3
    return connection


def test_a_plain_message_is_what_asyncua_receives() -> None:
    sender, ours, theirs = channel(), channel(), channel()
    data = b"".join(sender.message_to_binary(BODY, request_id=r) for r in (11, 12))
    at = 0
    for request_id in (11, 12):
        message = plain_message(ours, data, at)
        assert message is not None
        assert message.request_id == request_id
        assert data[message.start : message.end] == BODY
        take_plain_message(ours, message)
        buffer = Buffer(data[at:])
        header = header_from_binary(buffer)
        got = theirs.receive_from_header_and_body(header, buffer)
        assert isinstance(got, ua.Message)
        assert got.request_id() == request_id and bytes(got.body().read(len(BODY))) == BODY
        assert ours._peer_sequence_number == theirs._peer_sequence_number
        at = message.end
    assert at == len(data)


def test_every_cut_is_left_to_asyncua() -> None:
    data = channel().message_to_binary(BODY, request_id=1)
    receiver = channel()
    for k in range(len(data)):
        assert plain_message(receiver, data[:k], 0) is None
    assert receiver._peer_sequence_number is None  # nothing taken


@pytest.mark.parametrize(
    "change",
    [
        lambda c: setattr(c.security_token, "ChannelId", 8),  # another channel
        lambda c: setattr(c.security_token, "TokenId", 4),  # a renewed token: asyncua's
        lambda c: setattr(c, "_peer_sequence_number", 5),  # a gap in the sequence
        lambda c: c._incoming_parts.append(object()),  # a chunked message in progress
        lambda c: setattr(c._limits, "max_recv_buffer", 100),  # over the limit
    ],
)
def test_what_asyncua_must_judge_is_left_to_it(change: Any) -> None:
    data = channel().message_to_binary(BODY, request_id=1)
    receiver = channel()
    change(receiver)
    before = receiver._peer_sequence_number
    assert plain_message(receiver, data, 0) is None
    assert receiver._peer_sequence_number == before


def test_other_message_types_chunks_and_policies_are_left_to_asyncua() -> None:
    data = bytearray(channel().message_to_binary(BODY, request_id=1))
    receiver = channel()
    assert plain_message(receiver, bytes(data), 0) is not None
    for at, byte in ((3, b"C"), (3, b"A"), (0, b"C")):  # intermediate, abort, "CSG"
        changed = bytearray(data)
        changed[at : at + 1] = byte
        assert plain_message(receiver, bytes(changed), 0) is None

    class Signed(SecurityPolicyNone):  # any policy but None: signatures are asyncua's
        pass

    assert plain_message(channel(Signed()), bytes(data), 0) is None
