"""Decoding a subscription's PublishResponse: asyncua's generic decoder against
:mod:`cnctwin.thread.opcua_publish` (issue 15, item 7).

Usage: ``python benchmarks/bench_opcua_publish.py [--quick] [--items N]``.

The message is one the twin's subscription receives from the virtual machine: a publish with
one DataChangeNotification of ``--items`` (default 20, what the machine changes per 5 ms
tick) data changes, each a Double or a Boolean with its status and both time stamps, encoded
by asyncua. Each decoder reads it in turn, ``--repeat`` times, best of 5 rounds
(``time.perf_counter``), after a check that both give the same objects. Printed: µs per
publish for each, and the ratio.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from typing import Any

from asyncua import ua
from asyncua.common.utils import Buffer
from asyncua.ua.ua_binary import struct_from_binary, struct_to_binary

from cnctwin.thread import lean_publish_response


def publish(items: int) -> bytes:
    """A PublishResponse of ``items`` data changes, as asyncua encodes it."""
    stamp = datetime.now(UTC)
    changes = []
    for n in range(items):
        if n % 5 == 4:
            value = ua.Variant(n % 2 == 0, ua.VariantType.Boolean)
        else:
            value = ua.Variant(n * 1.25 + 0.1, ua.VariantType.Double)
        changes.append(
            ua.MonitoredItemNotification(
                ClientHandle=n + 1,
                Value=ua.DataValue(
                    Value=value,
                    StatusCode=ua.StatusCode(0),
                    SourceTimestamp=stamp,
                    ServerTimestamp=stamp + timedelta(microseconds=30),
                ),
            )
        )
    response = ua.PublishResponse()
    response.Parameters.SubscriptionId = 1
    response.Parameters.AvailableSequenceNumbers = [4711]
    response.Parameters.NotificationMessage = ua.NotificationMessage(
        SequenceNumber=4711,
        PublishTime=stamp,
        NotificationData=[ua.DataChangeNotification(MonitoredItems=changes)],
    )
    return bytes(struct_to_binary(response))


def best_us(decode: Callable[[Buffer], Any], data: bytes, repeat: int) -> float:
    """Lowest mean µs per call over 5 rounds of ``repeat`` calls."""
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(repeat):
            decode(Buffer(data))
        best = min(best, (time.perf_counter() - t0) / repeat * 1e6)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="200 calls per round")
    parser.add_argument("--items", type=int, default=20, help="data changes per publish")
    parser.add_argument("--repeat", type=int, default=2000, help="calls per round")
    args = parser.parse_args()
    repeat = 200 if args.quick else args.repeat
    data = publish(args.items)

    def asyncua_decode(buffer: Buffer) -> ua.PublishResponse:
        return struct_from_binary(ua.PublishResponse, buffer)

    lean = lean_publish_response(Buffer(data))
    assert lean is not None and lean == asyncua_decode(Buffer(data))
    theirs = best_us(asyncua_decode, data, repeat)
    ours = best_us(lean_publish_response, data, repeat)
    print(
        f"{platform.python_implementation()} {platform.python_version()}, "
        f"load {' '.join(f'{x:.1f}' for x in os.getloadavg())}; a publish of {args.items} "
        f"data changes, {len(data)} bytes, best of 5 x {repeat}:"
    )
    print(f"  asyncua struct_from_binary: {theirs:.1f} us")
    print(f"  cnctwin lean_publish_response: {ours:.1f} us ({theirs / ours:.1f}x faster)")


if __name__ == "__main__":
    main()
