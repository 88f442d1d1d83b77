"""The OPC UA client's own encoding of its requests and its lean decoding of one-value answers
(cnctwin.thread.opcua, issue 17) against asyncua's encoder and decoder, byte for byte: the
request built once and filled in must be what asyncua would send, and a lean decoding must
agree with asyncua's or step aside (``None``) for asyncua to decode the answer whole."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import pytest
from asyncua import ua
from asyncua.common.utils import Buffer
from asyncua.ua.ua_binary import struct_from_binary, struct_to_binary
from asyncua.ua.uatypes import datetime_to_win_epoch

from cnctwin.thread.opcua import (
    _encode_value,
    _lean_read_result,
    _lean_write_result,
    _read_request,
    _write_request,
)

NODE = ua.NodeId(ua.String("Machine.Monitoring.Channel1.FeedOverride"), ua.Int16(2))
TOKEN = ua.NodeId(ua.ByteString(bytes(range(32))), ua.Int16(0))
STAMP = datetime(2026, 11, 27, 16, 30, 0, 123400, tzinfo=UTC)


def body(response: ua.ReadResponse | ua.WriteResponse) -> Buffer:
    return Buffer(struct_to_binary(response))


@pytest.mark.parametrize(("kind", "value"), [("float", 37.5), ("float", -0.015), ("bool", 1.0)])
def test_a_write_built_once_encodes_as_asyncua_would(kind: str, value: float) -> None:
    request = _write_request(NODE, kind)
    body_bytes = request.encode(TOKEN, 2000, 41, _encode_value(kind, value))
    expected = ua.WriteRequest()
    header = expected.RequestHeader
    header.AuthenticationToken, header.TimeoutHint, header.RequestHandle = TOKEN, 2000, 41
    variant = (
        ua.Variant(bool(value), ua.VariantType.Boolean)
        if kind == "bool"
        else ua.Variant(value, ua.VariantType.Double)
    )
    expected.Parameters.NodesToWrite = [
        ua.WriteValue(NodeId=NODE, AttributeId=ua.AttributeIds.Value, Value=ua.DataValue(variant))
    ]
    header.Timestamp = STAMP
    wanted = struct_to_binary(expected)
    stamp = 4 + 39  # the TypeId and the token before it; its 8 bytes stamped at the send
    assert len(body_bytes) == len(wanted)
    assert body_bytes[:stamp] + body_bytes[stamp + 8 :] == wanted[:stamp] + wanted[stamp + 8 :]
    decoded = struct_from_binary(ua.WriteRequest, Buffer(body_bytes))
    assert abs(decoded.RequestHeader.Timestamp - datetime.now(UTC)).total_seconds() < 5.0


def test_a_read_built_once_follows_a_new_token_and_timeout() -> None:
    request = _read_request([NODE])
    first = struct_from_binary(ua.ReadRequest, Buffer(request.encode(TOKEN, 2000, 7, b"")))
    other = ua.NodeId(ua.ByteString(b"\x01" * 32), ua.Int16(0))
    second = struct_from_binary(ua.ReadRequest, Buffer(request.encode(other, 500, 8, b"")))
    assert first.RequestHeader.AuthenticationToken == TOKEN
    assert (first.RequestHeader.RequestHandle, first.RequestHeader.TimeoutHint) == (7, 2000)
    assert second.RequestHeader.AuthenticationToken == other
    assert (second.RequestHeader.RequestHandle, second.RequestHeader.TimeoutHint) == (8, 500)
    assert second.Parameters.NodesToRead[0].NodeId == NODE
    assert second.Parameters.TimestampsToReturn == ua.TimestampsToReturn.Both


def read_response(value: ua.DataValue) -> ua.ReadResponse:
    response = ua.ReadResponse()
    response.ResponseHeader.Timestamp = STAMP
    response.Results = [value]
    return response


@pytest.mark.parametrize(
    "value",
    [
        ua.DataValue(ua.Variant(37.5, ua.VariantType.Double), SourceTimestamp=STAMP),
        ua.DataValue(
            ua.Variant(math.nan, ua.VariantType.Double),
            SourceTimestamp=STAMP,
            ServerTimestamp=STAMP,
        ),
        ua.DataValue(ua.Variant(math.inf, ua.VariantType.Double)),
        ua.DataValue(ua.Variant(True, ua.VariantType.Boolean), ServerTimestamp=STAMP),
        ua.DataValue(ua.Variant(-3, ua.VariantType.Int32)),
        ua.DataValue(
            ua.Variant(1.0, ua.VariantType.Double),
            StatusCode=ua.StatusCode(ua.StatusCodes.BadOutOfRange),
        ),
        ua.DataValue(
            ua.Variant(1.0, ua.VariantType.Double),
            StatusCode=ua.StatusCode(ua.StatusCodes.UncertainLastUsableValue),
        ),
    ],
)
def test_a_one_value_read_answer_decodes_as_asyncua_decodes_it(value: ua.DataValue) -> None:
    data = body(read_response(value))
    lean = _lean_read_result(data)
    assert lean is not None
    whole = struct_from_binary(ua.ReadResponse, data).Results[0]  # the buffer is untouched
    assert lean.StatusCode == whole.StatusCode
    assert lean.Value is not None and whole.Value is not None
    assert lean.Value.VariantType == whole.Value.VariantType
    got, expected = lean.Value.Value, whole.Value.Value
    assert got == expected or (math.isnan(got) and math.isnan(expected))
    assert type(got) is type(expected)


@pytest.mark.parametrize(
    "response",
    [
        read_response(ua.DataValue(ua.Variant("37.5", ua.VariantType.String))),
        read_response(ua.DataValue(ua.Variant([1.0, 2.0], ua.VariantType.Double))),
        read_response(ua.DataValue(ua.Variant(1.0, ua.VariantType.Float))),
        read_response(ua.DataValue(StatusCode=ua.StatusCode(ua.StatusCodes.BadNodeIdUnknown))),
        read_response(
            ua.DataValue(ua.Variant(1.0, ua.VariantType.Double), SourcePicoseconds=ua.UInt16(5))
        ),
    ],
    ids=["string", "array", "float32", "no value", "picoseconds"],
)
def test_other_read_answers_are_left_to_asyncua(response: ua.ReadResponse) -> None:
    assert _lean_read_result(body(response)) is None


def unusual_headers() -> list[ua.ReadResponse]:
    bad = read_response(ua.DataValue(ua.Variant(1.0, ua.VariantType.Double)))
    bad.ResponseHeader.ServiceResult = ua.StatusCode(ua.StatusCodes.BadTooManyOperations)
    strings = read_response(ua.DataValue(ua.Variant(1.0, ua.VariantType.Double)))
    strings.ResponseHeader.StringTable = ["x"]
    diagnostics = read_response(ua.DataValue(ua.Variant(1.0, ua.VariantType.Double)))
    diagnostics.ResponseHeader.ServiceDiagnostics = ua.DiagnosticInfo(SymbolicId=3)
    two = read_response(ua.DataValue(ua.Variant(1.0, ua.VariantType.Double)))
    two.Results = two.Results * 2
    trailing = read_response(ua.DataValue(ua.Variant(1.0, ua.VariantType.Double)))
    trailing.DiagnosticInfos = [ua.DiagnosticInfo(SymbolicId=1)]
    return [bad, strings, diagnostics, two, trailing]


@pytest.mark.parametrize("response", unusual_headers())
def test_an_unusual_read_answer_is_left_to_asyncua(response: ua.ReadResponse) -> None:
    assert _lean_read_result(body(response)) is None
    assert _lean_write_result(body(response)) is None  # and is no WriteResponse


def test_a_truncated_or_padded_answer_is_left_to_asyncua() -> None:
    whole = struct_to_binary(read_response(ua.DataValue(ua.Variant(2.0, ua.VariantType.Double))))
    for end in range(len(whole)):
        assert _lean_read_result(Buffer(whole[:end])) is None
    assert _lean_read_result(Buffer(whole + b"\x00")) is None
    write = ua.WriteResponse()
    write.Results = [ua.StatusCode()]
    encoded = struct_to_binary(write)
    for end in range(len(encoded)):
        assert _lean_write_result(Buffer(encoded[:end])) is None
    assert _lean_read_result(Buffer(encoded)) is None  # a WriteResponse is no ReadResponse


@pytest.mark.parametrize(
    "code", [ua.StatusCodes.Good, ua.StatusCodes.BadOutOfRange, ua.StatusCodes.BadTypeMismatch]
)
def test_a_write_answer_decodes_as_asyncua_decodes_it(code: int) -> None:
    response = ua.WriteResponse()
    response.ResponseHeader.Timestamp = STAMP
    response.Results = [ua.StatusCode(code)]
    lean = _lean_write_result(body(response))
    assert (
        lean is not None and lean == struct_from_binary(ua.WriteResponse, body(response)).Results[0]
    )
    assert lean.value == code


def test_the_stamp_is_asyncuas_tick_count() -> None:
    request = _read_request([NODE])
    before = datetime_to_win_epoch(datetime.now(UTC))
    decoded = struct_from_binary(ua.ReadRequest, Buffer(request.encode(TOKEN, 2000, 1, b"")))
    after = datetime_to_win_epoch(datetime.now(UTC))
    assert before - 10 <= datetime_to_win_epoch(decoded.RequestHeader.Timestamp) <= after + 10
