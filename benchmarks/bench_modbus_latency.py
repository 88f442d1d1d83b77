"""Benchmark of the Modbus TCP write-to-read-back round trip on loopback.

Usage: ``python benchmarks/bench_modbus_latency.py [--quick] [--n N] [--interval-ms MS]``.
Prints a Markdown table for docs/_bench_modbus.md.

The method is Heide 2025's (section 2.5): write a new feed override, then poll the machine's
feedback until it shows the new value; repeat ``n`` times, ``interval-ms`` apart, alternating
between values. The client is :class:`cnctwin.thread.modbus.ModbusConnection` (a write is one
Write Single Register request, a read one Read Input Registers request of all 27 signals); the
server is :class:`cnctwin.virtual.modbus_server.ModbusMachineServer` over the packaged
virtual machine, stepped in real time by :class:`cnctwin.virtual.MachineClock` (5 ms ticks,
publishing after each). Two set-ups:

- ``separate process``: the machine, its clock and the server run in a child process, as a
  real machine would be another host;
- ``same process``: machine, clock, server and client share one event loop (what the tests and
  ``cnctwin demo`` do).

Times are wall-clock (``time.perf_counter``) in ms: ``write`` is the write request,
``read`` every read request, ``round trip`` from the start of the write to the end of the read
that showed the new value. ``--quick`` runs 30 round trips per set-up to prove the script runs.
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing as mp
import platform
import time
from multiprocessing.connection import Connection

import numpy as np

from cnctwin.thread import ConnectionConfig, ModbusConnection
from cnctwin.virtual import MachineClock, ModbusMachineServer, VirtualMachine, VirtualMachineConfig

VALUES_PCT = (80.0, 100.0)


def _child(port_pipe: Connection) -> None:
    """Run the virtual machine, its clock and the server until the parent writes to the pipe."""

    async def main() -> None:
        stop = asyncio.Event()
        asyncio.get_running_loop().add_reader(port_pipe.fileno(), stop.set)
        vm = VirtualMachine(VirtualMachineConfig())
        async with ModbusMachineServer(vm) as server:
            clock = MachineClock(vm, vm.tick_s, speed=1.0)
            clock.add_listener(server.publish)
            async with clock:
                port_pipe.send(server.port)
                await stop.wait()

    asyncio.run(main())


async def _round_trips(endpoint: str, n: int, interval_s: float) -> dict[str, list[float]]:
    config = ConnectionConfig(transport="modbus", endpoint=endpoint, timeout_s=2.0)
    write_ms: list[float] = []
    read_ms: list[float] = []
    trip_ms: list[float] = []
    async with ModbusConnection(config) as connection:
        for i in range(n + 5):  # 5 warm-up trips, not counted
            target = VALUES_PCT[i % 2]
            t0 = time.perf_counter()
            await connection.write("feed_override_pct", target)
            t1 = time.perf_counter()
            reads = []
            while True:
                r0 = time.perf_counter()
                reading = await connection.read()
                reads.append((time.perf_counter() - r0) * 1e3)
                if reading.values.get("feed_override_pct") == target:
                    break
            t2 = time.perf_counter()
            if i >= 5:
                write_ms.append((t1 - t0) * 1e3)
                read_ms.extend(reads)
                trip_ms.append((t2 - t0) * 1e3)
            await asyncio.sleep(interval_s)
    return {"round trip": trip_ms, "write": write_ms, "read": read_ms}


def _row(setup: str, name: str, values: list[float]) -> str:
    a = np.asarray(values)
    return (
        f"| {setup} | {name} | {a.size} | {a.mean():.3f} | {a.std():.3f} | {a.min():.3f} | "
        f"{np.median(a):.3f} | {np.percentile(a, 99):.3f} | {a.max():.3f} |"
    )


async def _same_process(n: int, interval_s: float) -> tuple[dict[str, list[float]], str]:
    vm = VirtualMachine(VirtualMachineConfig())
    async with ModbusMachineServer(vm) as server:
        clock = MachineClock(vm, vm.tick_s, speed=1.0)
        clock.add_listener(server.publish)
        async with clock:
            result = await _round_trips(server.endpoint, n, interval_s)
        stats = clock.stats
    return result, f"{stats.ticks} ticks, {stats.late_ticks} late"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="30 round trips per set-up")
    parser.add_argument("--n", type=int, default=500, help="round trips per set-up")
    parser.add_argument("--interval-ms", type=float, default=20.0, help="pause between trips")
    args = parser.parse_args()
    n = 30 if args.quick else args.n
    interval_s = args.interval_ms / 1e3

    rows = []
    parent_end, child_end = mp.Pipe()
    child = mp.get_context("spawn").Process(target=_child, args=(child_end,), daemon=True)
    child.start()
    if not parent_end.poll(60.0):
        raise SystemExit("the server process did not start within 60 s")
    port = parent_end.recv()
    try:
        separate = asyncio.run(_round_trips(f"modbus://127.0.0.1:{port}", n, interval_s))
    finally:
        parent_end.send("stop")
        child.join(10.0)
    same, clock_note = asyncio.run(_same_process(n, interval_s))
    for setup, result in (("separate process", separate), ("same process", same)):
        rows += [_row(setup, name, values) for name, values in result.items()]

    polls = len(separate["read"]) / n, len(same["read"]) / n
    print(
        f"Modbus TCP write-to-read-back on loopback, {n} round trips {args.interval_ms:g} ms "
        f"apart; Python {platform.python_version()}, {platform.machine()}; reads per trip "
        f"{polls[0]:.2f} (separate), {polls[1]:.2f} (same); same-process clock: {clock_note}"
    )
    print()
    print("| set-up | time (ms) | n | mean | std | min | median | p99 | max |")
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
