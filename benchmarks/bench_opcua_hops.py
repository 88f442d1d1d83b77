"""Where the time of one OPC UA write-to-read-back round trip goes, hop by hop (issue 17).

Usage: ``python benchmarks/bench_opcua_hops.py [--quick] [--n N] [--interval-ms MS]``.

The set-up is ``cnctwin bench latency --transport opcua``'s: the virtual machine and its
server in a child process (:func:`cnctwin.virtual.virtual_machine_server`), the client
:class:`cnctwin.thread.OpcUaConnection` reading by request, and Heide 2025's round trip
(:func:`cnctwin.thread.measure_latency`). Both processes stamp each hop with
``time.perf_counter_ns`` (CLOCK_MONOTONIC on Linux: one clock for both processes):

- client: each request's framing for the secure channel (``SecureConnection.message_to_binary``
  or cnctwin's ``frame_message``, after its encoding), the end of each ``transport.write``
  (one for a Write and the Read sent behind it), the arrival of each answer
  (``data_received``) and the end of the round trip;
- server: the arrival of each request (``data_received`` of cnctwin's lean connection,
  :mod:`cnctwin.virtual.opcua_lean`, which answers the common Read and Write there and whose
  return is stamped as an answer written), the start of asyncua's processing of any other
  (``UaProcessor.process``, after asyncua's per-connection queue) and the sending of its
  answer (``UaProcessor.send_response``, before encoding and after ``transport.write``).

The server's hooks are installed in the spawned child: ``multiprocessing``'s spawn start method
imports this script there as ``__mp_main__`` before it runs the child's target, and the module
installs them then (only then, see the end of the file). The child writes its stamps to the file
named by ``$CNCTWIN_HOPS_FILE`` when the client's connection closes.

The round trips are :func:`~cnctwin.thread.measure_latency`'s own (a round trip's stamps run
from its first request's encoding to its ``progress`` call), so the script measures whatever
code is on the path, old or new. Printed: for the round trips whose stamps come in the
commonest order, the median and p90 of the time from each stamp to the next in µs and the CPU
time (``time.thread_time_ns``) the thread that made the later stamp spent since its own stamp
before; ``measure_latency``'s round-trip median and p99 in ms; the CPU time per round trip of
the client process (``getrusage``) and of the server's event-loop thread while it handles the
round trip's requests (from a batch's arrival to its last answer's ``write``).
``--quick`` (CI) makes 20 round trips.
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import itertools
import json
import math
import os
import resource
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

_ENV = "CNCTWIN_HOPS_FILE"
_clock = time.perf_counter_ns


def _wrap(
    cls: type, name: str, before: Callable[..., None] | None, after: Callable[..., None] | None
) -> None:
    """Stamp ``cls.name``'s calls: ``before(self, *args)`` at entry, ``after(self, result)`` at
    return."""
    original = getattr(cls, name)

    @functools.wraps(original)
    def stamped(self: Any, *args: Any, **kwargs: Any) -> Any:
        if before is not None:
            before(self, *args)
        result = original(self, *args, **kwargs)
        if after is not None:
            after(self, result)
        return result

    setattr(cls, name, stamped)


# Server side (the child) -----------------------------------------------------------------------
def _own(name: str, base: type) -> list[type]:
    """The subclasses of ``base`` that define method ``name`` themselves."""
    return [cls for cls in base.__subclasses__() if name in vars(cls)]


def _install_server_hooks(path: str) -> None:
    from asyncua.server.binary_server_asyncio import OPCUAProtocol
    from asyncua.server.uaprocessor import UaProcessor

    events: list[tuple[str, int, int]] = []  # (hop, perf_counter_ns, thread_time_ns)

    def mark(hop: str) -> Callable[..., None]:
        return lambda *_: events.append((hop, _clock(), time.thread_time_ns()))

    from cnctwin.virtual import OpcUaMachineServer  # noqa: F401  (its lean connections)

    # the virtual machine's connections (cnctwin.virtual.opcua_lean, a subclass) answer the
    # common requests in data_received itself: their answers are written when it returns
    for cls in _own("data_received", OPCUAProtocol):
        _wrap(cls, "data_received", mark("s_recv"), mark("s_sent"))
    process = UaProcessor.process

    async def processed(self: Any, header: Any, body: Any) -> Any:
        events.append(("s_proc", _clock(), time.thread_time_ns()))
        return await process(self, header, body)

    UaProcessor.process = processed  # type: ignore[method-assign]
    _wrap(UaProcessor, "send_response", mark("s_encode"), mark("s_sent"))
    lost = OPCUAProtocol.connection_lost

    def dump(self: Any, ex: BaseException | None) -> None:
        lost(self, ex)
        Path(path).write_text(json.dumps(events))

    OPCUAProtocol.connection_lost = dump  # type: ignore[method-assign]


# Client side -----------------------------------------------------------------------------------
class _ClientHops:
    """The client's stamps: asyncua's send and receive, and the round trip's own."""

    def __init__(self) -> None:
        from asyncio.selector_events import _SelectorSocketTransport

        from asyncua.client.ua_client import UASocketProtocol
        from asyncua.common.connection import SecureConnection

        self.events: list[tuple[str, int, int]] = []
        mark = self.mark
        # every request is framed here: asyncua's _send_request in message_to_binary, cnctwin's
        # own _send in frame_message (which frames a plain message itself, and calls
        # message_to_binary for any other, not in this set-up)
        _wrap(SecureConnection, "message_to_binary", lambda *_: mark("c_encode"), None)
        from cnctwin.thread import OpcUaConnection

        opcua = sys.modules[OpcUaConnection.__module__]  # where its _send finds frame_message
        frame = opcua.frame_message

        def framed(connection: Any, body: bytes, request_id: int) -> bytes:
            mark("c_encode")
            return frame(connection, body, request_id)

        opcua.frame_message = framed  # type: ignore[attr-defined]
        _wrap(_SelectorSocketTransport, "write", None, lambda *_: mark("c_sent"))

        # cnctwin's connection gives its links a subclass that takes the common answers
        for cls in (UASocketProtocol, *_own("data_received", UASocketProtocol)):
            _wrap(cls, "data_received", lambda *_: mark("c_recv"), None)

    def mark(self, hop: str) -> None:
        self.events.append((hop, _clock(), time.thread_time_ns()))


async def _run(n: int, interval_s: float, hops_file: Path) -> dict[str, Any]:
    from cnctwin.thread import ConnectionConfig, OpcUaConnection, measure_latency
    from cnctwin.virtual import virtual_machine_server

    client = _ClientHops()
    ends: list[int] = []  # index in client.events where each round trip ended
    async with virtual_machine_server("opcua") as url:
        config = ConnectionConfig(transport="opcua", endpoint=url, timeout_s=2.0)
        async with OpcUaConnection(config, subscription_ms=None) as connection:
            await connection.read_signal("feed_override_pct")  # as measure_latency's first read
            client.events.clear()

            def done(_: int) -> None:
                client.mark("c_done")
                ends.append(len(client.events))

            usage0 = resource.getrusage(resource.RUSAGE_SELF)
            result = await measure_latency(connection, n=n, interval_s=interval_s, progress=done)
            usage1 = resource.getrusage(resource.RUSAGE_SELF)
        for _ in range(200):  # the child writes its stamps when the connection closes
            if hops_file.exists() and hops_file.stat().st_size:
                break
            await asyncio.sleep(0.01)
    # a round trip's stamps: from the end of the one before to its own end (the first round
    # trip, behind measure_latency's read of the start value, is left out)
    trips = [client.events[a:b] for a, b in itertools.pairwise(ends)]
    cpu_s = (usage1.ru_utime + usage1.ru_stime) - (usage0.ru_utime + usage0.ru_stime)
    return {
        "trips": trips,
        "server": json.loads(hops_file.read_text()),
        "client_cpu_s": cpu_s,
        "round_trip_ms": result.round_trip_ms,
    }


#: What happens between a stamp and the next, for the table.
_MEANING = {
    "c_encode": "client: a request's encoding framed for the secure channel",
    "c_sent": "client: request(s) written to the socket",
    "s_recv": "server: request bytes arrive (data_received)",
    "s_proc": "server: its processing starts (after asyncua's queue)",
    "s_encode": "server: answer made, being encoded",
    "s_sent": "server: answer written to the socket",
    "c_recv": "client: answer bytes arrive (data_received)",
    "c_done": "client: answers decoded and checked, round trip over",
}


def _analyse(
    data: dict[str, Any],
) -> tuple[list[str], np.ndarray, np.ndarray, list[float], list[float]]:
    """The commonest order of the stamps in a round trip; in the round trips of that order
    (rows), the time (µs) from each stamp to the next, and the CPU time (µs) of the thread
    that made the next stamp since its own stamp before (NaN for its first); all round trips
    (ms); the server's CPU per round trip (µs)."""
    server = sorted((t, hop, cpu) for hop, t, cpu in data["server"])
    times = np.array([t for t, _, _ in server])
    timelines: list[list[tuple[str, int, int]]] = []
    rtts: list[float] = []
    server_cpu: list[float] = []
    trips = data["trips"]
    for k, trip in enumerate(trips):
        start, end = trip[0][1], trip[-1][1]
        rtts.append((end - start) / 1e6)
        # the server's stamps up to the next round trip: its last may come after the client's
        after = trips[k + 1][0][1] if k + 1 < len(trips) else end + 10**7
        lo, hi = np.searchsorted(times, [start, after])
        theirs = server[lo:hi]
        line = sorted(trip + [(hop, t, cpu) for t, hop, cpu in theirs], key=lambda e: e[1])
        timelines.append(line)
        server_cpu.append(_batches_cpu([(hop, cpu) for _, hop, cpu in theirs]))
    orders = Counter(tuple(hop for hop, _, _ in line) for line in timelines)
    order = list(orders.most_common(1)[0][0])
    chosen = [line for line in timelines if [h for h, _, _ in line] == order]
    rows = np.array([np.diff([t for _, t, _ in line]) / 1e3 for line in chosen])
    cpus = np.array([_cpu_steps(line) for line in chosen])
    return order, rows, cpus, rtts, server_cpu


def _batches_cpu(stamps: list[tuple[str, int]]) -> float:
    """The server's CPU (µs) from each batch of requests' arrival to its last answer's write."""
    spent, begin, sent = 0, None, None
    for hop, cpu in stamps:
        if hop == "s_recv" and sent is not None and begin is not None:  # the next batch
            spent += sent - begin
            begin = sent = None
        if hop == "s_recv" and begin is None:
            begin = cpu
        elif hop == "s_sent":
            sent = cpu
    if begin is not None and sent is not None:
        spent += sent - begin
    return spent / 1e3


def _cpu_steps(line: list[tuple[str, int, int]]) -> list[float]:
    """For each stamp after the first: the CPU (µs) its thread spent since its previous stamp."""
    last: dict[str, int] = {}
    steps: list[float] = []
    for k, (hop, _, cpu) in enumerate(line):
        side = hop[0]
        if k:
            steps.append((cpu - last[side]) / 1e3 if side in last else math.nan)
        last[side] = cpu
    return steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="20 round trips (CI)")
    parser.add_argument("--n", type=int, default=200)
    parser.add_argument("--interval-ms", type=float, default=20.0)
    args = parser.parse_args()
    n = 20 if args.quick else args.n
    with tempfile.TemporaryDirectory() as folder:
        hops_file = Path(folder) / "server-hops.json"
        os.environ[_ENV] = str(hops_file)
        data = asyncio.run(_run(n, args.interval_ms / 1e3, hops_file))
    order, rows, cpus, rtts, server_cpu = _analyse(data)
    print(
        f"load average {os.getloadavg()[0]:.2f}; {len(rows)} of {n} round trips in the "
        "commonest order of stamps:"
    )
    print("| from | to | median µs | p90 µs | CPU median µs |")
    print("|---|---|---|---|---|")
    for k, (a, b) in enumerate(itertools.pairwise(order)):
        cpu = "" if np.isnan(cpus[0, k]) else f"{np.median(cpus[:, k]):.0f}"
        print(
            f"| {_MEANING[a]} | {_MEANING[b]} | {np.median(rows[:, k]):.0f} | "
            f"{np.percentile(rows[:, k], 90):.0f} | {cpu} |"
        )
    stats = data["round_trip_ms"]
    print(
        f"round trip (measure_latency): median {stats.median:.3f} ms, p99 {stats.p99:.3f} ms; "
        f"first stamp to last: median {np.median(rtts):.3f} ms; CPU per round trip: client "
        f"process {1e6 * data['client_cpu_s'] / n:.0f} µs, server event-loop thread "
        f"{np.median(server_cpu):.0f} µs (median)"
    )


if __name__ == "__main__":
    main()
elif __name__ == "__mp_main__" and os.environ.get(_ENV):
    _install_server_hooks(os.environ[_ENV])
