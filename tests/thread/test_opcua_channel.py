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

from cnctwin.thread.opcua_channel import frame_message, plain_message, take_plain_message

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


# --- framing: frame_message is asyncua's message_to_binary for the plain case ---------------

#: A body that fills one chunk of a 65535-byte send buffer exactly (header 24 bytes).
FULL = 65535 - 24


@pytest.mark.parametrize("size", [1, 17, len(BODY), 4096, FULL])
@pytest.mark.parametrize("sequence", [0, 1, 41, (1 << 32) - 4])  # - 4: the last before the wrap
def test_a_plain_frame_is_asyncua_s_byte_for_byte(size: int, sequence: int) -> None:
    body = bytes(k % 251 for k in range(size))
    ours, theirs = channel(), channel()
    for connection in (ours, theirs):
        connection._sequence_number = sequence
    for request_id in (1, 12, 0xFFFFFFFF):
        with _asyncua_forbidden(ours):
            lean = frame_message(ours, body, request_id)
        assert lean == theirs.message_to_binary(body, request_id=request_id)
        assert ours._sequence_number == theirs._sequence_number


@pytest.mark.parametrize(
    ("body", "change"),
    [
        (BODY, lambda c: setattr(c, "_sequence_number", (1 << 32) - 1)),  # wraps to 1
        (bytes(FULL + 1), None),  # two chunks
        (bytes(4000), lambda c: setattr(c._limits, "max_send_buffer", 1000)),  # five chunks
        (b"", None),  # no chunk at all in asyncua
        (BODY, lambda c: setattr(c, "security_policy", _Signed())),  # signing is asyncua's
    ],
    ids=["wrap", "two-chunks", "small-buffer", "empty", "other-policy"],
)
def test_anything_else_is_framed_by_asyncua(body: bytes, change: Any) -> None:
    ours, theirs = channel(), channel()
    if change is not None:
        change(ours)
        change(theirs)
    calls: list[int] = []
    framed = ours.message_to_binary

    def counted(message: bytes, message_type: Any = None, request_id: int = 0) -> bytes:
        calls.append(request_id)
        return framed(message, request_id=request_id)

    ours.message_to_binary = counted  # type: ignore[method-assign]
    assert frame_message(ours, body, 5) == theirs.message_to_binary(body, request_id=5)
    assert calls == [5]
    assert ours._sequence_number == theirs._sequence_number


def test_lean_and_asyncua_frames_share_one_sequence_counter() -> None:
    """Lean, asyncua's, lean, asyncua's in chunks, lean: asyncua's receive (which closes the
    channel on any gap in the sequence numbers) takes every one, in order."""
    sender, receiver = channel(), channel()
    sender._limits.max_send_buffer = 1000
    big = bytes(range(256)) * 10  # three chunks of asyncua's
    sent = [
        (frame_message(sender, BODY, 1), BODY, 1),
        (sender.message_to_binary(BODY[:9], request_id=2), BODY[:9], 2),
        (frame_message(sender, BODY[:50], 3), BODY[:50], 3),
        (sender.message_to_binary(big, request_id=4), big, 4),
        (frame_message(sender, BODY, 5), BODY, 5),
    ]
    assert sender._sequence_number == 7
    buffer = Buffer(b"".join(data for data, _, _ in sent))
    got = []
    while len(buffer):
        header = header_from_binary(buffer)
        message = receiver.receive_from_header_and_body(header, buffer)
        if isinstance(message, ua.Message):
            body = message.body()
            got.append((message.request_id(), bytes(body.read(len(body)))))
    assert got == [(request_id, body) for _, body, request_id in sent]
    assert receiver._peer_sequence_number == 7


def test_the_asyncua_channel_state_framing_relies_on_is_there() -> None:
    """frame_message reads and advances asyncua's own counter (``_sequence_number``) and
    assumes asyncua's chunk size rule and wrap-around: fail loudly if any of that changes
    (asyncua is pinned to 2.1.x in pyproject.toml)."""
    import asyncua
    from asyncua.common.connection import MessageChunk

    assert asyncua.__version__.startswith("2.1."), asyncua.__version__
    connection = channel()
    assert connection._sequence_number == 0
    connection._sequence_number = 99
    connection.message_to_binary(BODY, request_id=1)
    assert connection._sequence_number == 100, "asyncua's counter is not _sequence_number"
    crypto = SecurityPolicyNone().symmetric_cryptography
    for chunk in (100, 8192, 65535):
        assert MessageChunk.max_body_size(crypto, chunk) == chunk - 24
    connection._sequence_number = (1 << 32) - 1
    data = connection.message_to_binary(BODY, request_id=1)
    assert connection._sequence_number == 1 and data[16:20] == b"\1\0\0\0"
    assert isinstance(connection._limits.max_send_buffer, int)


class _Signed(SecurityPolicyNone):  # stands for any policy but None
    pass


class _asyncua_forbidden:
    """Within it, ``connection.message_to_binary`` fails: the frame must be made here."""

    def __init__(self, connection: SecureConnection) -> None:
        self.connection = connection

    def __enter__(self) -> None:
        def refuse(*args: Any, **kwargs: Any) -> bytes:
            raise AssertionError("framed by asyncua")

        self.connection.message_to_binary = refuse  # type: ignore[method-assign]

    def __exit__(self, *exc: object) -> None:
        del self.connection.message_to_binary
