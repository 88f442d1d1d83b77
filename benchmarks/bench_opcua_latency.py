"""Benchmark of the OPC UA write-to-read-back round trip on loopback (issue 7, item 10).

Usage: ``python benchmarks/bench_opcua_latency.py [--quick] [--n N] [--interval-ms MS]``.
Prints a Markdown table for docs/_bench_opcua.md. Targets: round trip p50 < 1 ms and
p99 < 3 ms without jitter.

The method is Heide 2025's (section 2.5), as ``cnctwin bench latency`` runs it
(:func:`cnctwin.thread.latency.measure_latency`): write a new feed override, poll the
feedback node until it shows the new value; ``n`` round trips, ``interval-ms`` apart. The
client is :class:`cnctwin.thread.opcua.OpcUaConnection`; the server
:class:`cnctwin.virtual.opcua_server.OpcUaMachineServer` over the packaged virtual machine on
its real-time :class:`~cnctwin.virtual.MachineClock` (5 ms ticks, publishing after each).
Set-ups:

- ``separate process``: machine, clock and server in a child process (the default of
  ``cnctwin bench latency``), read-back by a one-node Read request;
- ``separate, jitter J``: the same through :class:`~cnctwin.thread.latency.JitterProxy`,
  J = 5, 10, 20 ms (each request held U(0, 2 J) ms);
- ``same process``: machine, clock, server and client on one event loop;
- ``subscription``: separate process, the read-back seen through a subscription
  (publishing interval 0, the server's fastest) instead of a Read: what a subscription
  cache would give;

plus the duration of the twin's cycle read of all 27 signals, every 12.5 ms: one Read request,
or the subscription cache of ``OpcUaConnection`` (publishing interval 5 ms, the default).
``--quick`` runs 20 round trips per set-up and no jitter (CI).
"""

from __future__ import annotations

import argparse
import asyncio
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.thread import (
    DEFAULT_SUBSCRIPTION_MS,
    NODE_MAP,
    ConnectionConfig,
    JitterProxy,
    LatencyResult,
    LatencyStats,
    OpcUaConnection,
    OpcUaSecurityConfig,
    measure_latency,
)
from cnctwin.virtual import (
    MachineClock,
    OpcUaMachineServer,
    OpcUaServerSecurity,
    SecurityMode,
    UserTable,
    VirtualMachine,
    VirtualMachineConfig,
    application_certificate,
    virtual_machine_server,
)


def _row(setup: str, name: str, n: int, s: LatencyStats) -> str:
    return (
        f"| {setup} | {name} | {n} | {s.mean:.3f} | {s.std:.3f} | {s.min:.3f} | "
        f"{s.median:.3f} | {s.p99:.3f} | {s.max:.3f} |"
    )


def _rows(setup: str, result: LatencyResult) -> list[str]:
    return [
        _row(setup, "round trip", result.n, result.round_trip_ms),
        _row(setup, "write", result.n, result.write_ms),
        _row(setup, "read", result.n, result.read_ms),
    ]


async def _measure(
    endpoint: str,
    n: int,
    interval_s: float,
    jitter_ms: float,
    security: OpcUaSecurityConfig | None = None,
) -> LatencyResult:
    config = ConnectionConfig(
        endpoint=endpoint, timeout_s=5.0, security=security or OpcUaSecurityConfig()
    )
    async with OpcUaConnection(config, subscription_ms=None) as conn:
        await measure_latency(conn, n=5, interval_s=interval_s)  # warm-up, not counted
        return await measure_latency(
            conn, n=n, interval_s=interval_s, timeout_s=5.0, jitter_ms=jitter_ms
        )


async def _cycle_read(endpoint: str, n: int, subscription_ms: float | None) -> LatencyStats:
    """Duration of the twin's cycle read, one read every 12.5 ms."""
    config = ConnectionConfig(endpoint=endpoint)
    async with OpcUaConnection(config, subscription_ms=subscription_ms) as conn:
        samples = []
        for _ in range(n):
            t0 = time.perf_counter()
            await conn.read()
            samples.append(time.perf_counter() - t0)
            await asyncio.sleep(0.0125)
    return LatencyStats.of(samples)


async def _subscription(endpoint: str, n: int, interval_s: float) -> LatencyStats:
    """Round trip with the read-back taken from a data-change subscription."""
    config = ConnectionConfig(endpoint=endpoint)
    async with OpcUaConnection(config, subscription_ms=None) as conn:
        client = conn._client
        assert client is not None
        seen: asyncio.Queue[float] = asyncio.Queue()

        class Handler:
            def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
                seen.put_nowait(float(value))

        ns = await client.get_namespace_index("urn:cnctwin:virtual-machine")
        subscription = await client.create_subscription(0, Handler())
        node = client.get_node(f"ns={ns};s={NODE_MAP['feed_override_pct']}")
        await subscription.subscribe_data_change(node, queuesize=10)
        await seen.get()  # the initial value
        samples = []
        for i in range(n):
            target = 90.0 + (i % 10)
            t0 = time.perf_counter()
            await conn.write("feed_override_pct", target)
            while await seen.get() != target:
                pass
            samples.append(time.perf_counter() - t0)
            await asyncio.sleep(interval_s)
        await subscription.delete()
        await conn.write("feed_override_pct", 100.0)
    return LatencyStats.of(samples)


async def _separate(n: int, interval_s: float, jitters: list[float]) -> list[str]:
    rows: list[str] = []
    async with virtual_machine_server("opcua") as endpoint:
        rows += _rows("separate process", await _measure(endpoint, n, interval_s, 0.0))
        modes = (("Read request", None), ("subscription cache", DEFAULT_SUBSCRIPTION_MS))
        for label, mode in modes:
            stats = await _cycle_read(endpoint, n, mode)
            rows.append(_row("separate process", f"cycle read, {label}", n, stats))
        rows.append(
            _row("subscription", "round trip", n, await _subscription(endpoint, n, interval_s))
        )
        host_port = endpoint.split("//")[1].split("/")[0]
        port = int(host_port.rsplit(":", 1)[1])
        for jitter in jitters:
            async with JitterProxy("127.0.0.1", port, jitter, seed=1) as proxy:
                url = f"opc.tcp://127.0.0.1:{proxy.port}/cnctwin"
                result = await _measure(url, n, interval_s, jitter)
            rows += _rows(f"separate, jitter {jitter:g} ms", result)
    return rows


async def _same_process(
    n: int, interval_s: float, mode: SecurityMode = "None", pki: Path | None = None
) -> tuple[list[str], str]:
    vm = VirtualMachine(VirtualMachineConfig())
    vm.step(vm.tick_s)  # load the compiled kernels before the clock runs
    server_security, client_security = None, None
    if mode != "None":
        assert pki is not None
        server_security = OpcUaServerSecurity(
            mode, pki / "server-cert.pem", pki / "server-key.pem", pki / "trusted"
        )
        client_security = OpcUaSecurityConfig(
            policy="Basic256Sha256",
            mode=mode,
            certificate=str(pki / "trusted" / "client-cert.pem"),
            private_key=str(pki / "client-key.pem"),
            server_certificate=str(pki / "server-cert.pem"),
        )
    # the bench writes the feed override anonymously, on loopback
    async with OpcUaMachineServer(
        vm, users=UserTable(anonymous="operator"), security=server_security
    ) as server:
        clock = MachineClock(vm, vm.tick_s, speed=1.0)
        clock.add_listener(server.publish)
        async with clock:
            result = await _measure(server.endpoint, n, interval_s, 0.0, client_security)
        stats = clock.stats
    setup = "same process" if mode == "None" else f"same process, Basic256Sha256 {mode}"
    return _rows(setup, result), f"{stats.ticks} ticks, {stats.late_ticks} late"


def _security(n: int, interval_s: float, repeats: int) -> list[str]:
    """The same-process set-up with message security None, Sign and SignAndEncrypt
    (Basic256Sha256), interleaved ``repeats`` times; self-signed application certificates."""
    rows: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        pki = Path(tmp)
        (pki / "trusted").mkdir()
        application_certificate(pki, "server", "server")
        cert, key = application_certificate(pki, "client", "client")
        cert.rename(pki / "trusted" / cert.name)
        key.rename(pki / key.name)
        modes: tuple[SecurityMode, ...] = ("None", "Sign", "SignAndEncrypt")
        for _ in range(repeats):
            for mode in modes:
                rows += asyncio.run(_same_process(n, interval_s, mode, pki))[0]
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20 round trips, no jitter")
    parser.add_argument("--n", type=int, default=500, help="round trips per set-up")
    parser.add_argument("--interval-ms", type=float, default=20.0, help="pause between trips")
    parser.add_argument(
        "--security",
        type=int,
        default=0,
        metavar="REPEATS",
        help="only compare message security None, Sign, SignAndEncrypt (same process), "
        "interleaved REPEATS times",
    )
    args = parser.parse_args()
    n = 20 if args.quick else args.n
    interval_s = args.interval_ms / 1e3
    jitters = [] if args.quick else [5.0, 10.0, 20.0]
    header = "| set-up | time (ms) | n | mean | std | min | median | p99 | max |"
    if args.security:
        print(f"OPC UA message security, {n} round trips {args.interval_ms:g} ms apart")
        print()
        print(header)
        print("|---|---|---|---|---|---|---|---|---|")
        print("\n".join(_security(n, interval_s, args.security)))
        return

    rows = asyncio.run(_separate(n, interval_s, jitters))
    same, clock_note = asyncio.run(_same_process(n, interval_s))
    rows += same
    print(
        f"OPC UA write-to-read-back on loopback, {n} round trips {args.interval_ms:g} ms apart; "
        f"Python {platform.python_version()}, {platform.machine()}, "
        f"numpy {np.__version__}; same-process clock: {clock_note}"
    )
    print()
    print(header)
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
