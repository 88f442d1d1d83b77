"""Heide 2025 section 2.5's round-trip method, its statistics and the jitter proxy.

The statistics are checked against closed forms; the method against a real OPC UA server
whose machine answers at once, or only on its next clock tick (then the poll has to wait);
the proxy's delays against the uniform distribution it draws from.
"""

from __future__ import annotations

import asyncio
import math
import random
import time

import pytest
from asyncua import ua
from opcua_fixtures import watched
from timeouts import BODY_S

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.latency import JitterProxy, LatencyStats, measure_latency
from cnctwin.thread.opcua import NODE_MAP, OpcUaConnection
from cnctwin.thread.signals import SIGNALS
from cnctwin.virtual.opcua_server import OpcUaMachineServer
from cnctwin.virtual.users import UserTable


class Machine:
    """A source whose commands take effect at once, or at the next ``tick()`` if ``lagging``."""

    def __init__(self, lagging: bool = False) -> None:
        self.values = {name: 0.0 for name in SIGNALS}
        self.values.update(feed_override_pct=100.0, spindle_override_pct=100.0, work_offset=1.0)
        self.lagging = lagging
        self.pending: dict[str, float] = {}
        self.commands: list[tuple[str, float]] = []

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        self.commands.append((name, value))
        if self.lagging:
            self.pending[name] = value
        else:
            self.values[name] = value

    def tick(self) -> None:
        self.values.update(self.pending)
        self.pending.clear()


def run(coro: object) -> None:
    asyncio.run(asyncio.wait_for(coro, BODY_S))  # type: ignore[arg-type]


def test_stats_match_closed_forms() -> None:
    samples_s = [k / 1e3 for k in range(1, 101)]  # 1, 2, ..., 100 ms
    stats = LatencyStats.of(samples_s)
    assert stats.mean == pytest.approx(50.5)
    assert stats.median == pytest.approx(50.5)
    assert (stats.min, stats.max) == (pytest.approx(1.0), pytest.approx(100.0))
    # Sample standard deviation of 1..N: sqrt(N (N + 1) / 12)
    assert stats.std == pytest.approx(math.sqrt(100 * 101 / 12))
    # Linear interpolation at rank 0.99 * 99 = 98.01 between 99 and 100 ms
    assert stats.p99 == pytest.approx(99.01)
    assert LatencyStats.of([0.002]).std == 0.0
    with pytest.raises(DataError):
        LatencyStats.of([])


def test_round_trips_against_a_real_server_restore_the_override() -> None:
    async def body() -> None:
        machine = Machine()
        async with OpcUaMachineServer(machine, users=UserTable(anonymous="operator")) as server:
            cfg = ConnectionConfig(endpoint=server.endpoint)
            async with OpcUaConnection(cfg) as conn:
                done: list[int] = []
                result = await measure_latency(conn, n=20, interval_s=0.001, progress=done.append)
        assert result.n == 20 and done == list(range(1, 21))
        assert result.polls_mean == 1.0  # the read-back is immediate
        writes = [v for _, v in machine.commands]
        assert len(writes) == 21 and writes[-1] == 100.0  # 20 setpoints, then restored
        assert all(a != b for a, b in zip([100.0, *writes], writes, strict=False))
        assert all(0.0 <= v <= 150.0 for v in writes)
        rt, w, r = result.round_trip_ms, result.write_ms, result.read_ms
        assert 0 < rt.min <= rt.median <= rt.p99 <= rt.max
        assert rt.mean == pytest.approx(w.mean + r.mean, rel=0.5)
        assert rt.min >= w.min

    run(body())


def test_a_round_trip_is_one_write_and_one_read_request() -> None:
    """The cost guard of docs/latency.md: node ids are resolved once at connect, so a round
    trip sends exactly one Write and one one-node Read of the feed override and nothing that
    looks a node up (Browse, TranslateBrowsePaths, RegisterNodes). Counted, not timed."""

    async def body() -> None:
        machine = Machine()
        async with OpcUaMachineServer(machine, users=UserTable(anonymous="operator")) as server:
            cfg = ConnectionConfig(endpoint=server.endpoint)
            async with OpcUaConnection(cfg, subscription_ms=None) as conn:
                assert conn._client is not None
                protocol = conn._client.uaclient.protocol
                assert protocol is not None
                with watched(protocol) as traffic:  # every request of the channel
                    await measure_latency(conn, n=5, interval_s=0.0)
        sent: list[tuple[str, list[str]]] = []
        for _, request in traffic.sent:
            params = getattr(request, "Parameters", None)
            items = getattr(params, "NodesToRead", None) or getattr(params, "NodesToWrite", None)
            sent.append((type(request).__name__, [item.NodeId.Identifier for item in items or ()]))
        override = NODE_MAP["feed_override_pct"]
        on_override = [kind for kind, nodes in sent if nodes == [override]]
        assert on_override == [
            "ReadRequest",
            *["WriteRequest", "ReadRequest"] * 5,
            "WriteRequest",  # the override set back
        ]
        lookups = {"BrowseRequest", "TranslateBrowsePathsToNodeIdsRequest", "RegisterNodesRequest"}
        assert not lookups & {kind for kind, _ in sent}
        # asyncua's watchdog may read the server status on a slow machine; nothing else passes
        status = {
            ua.ObjectIds.Server_ServerStatus,
            ua.ObjectIds.Server_ServerStatus_CurrentTime,
            ua.ObjectIds.Server_ServerStatus_State,
        }
        assert all(
            nodes == [override] or (kind == "ReadRequest" and set(nodes) <= status)
            for kind, nodes in sent
        )

    run(body())


def test_poll_waits_for_the_feedback_to_change() -> None:
    async def body() -> None:
        machine = Machine(lagging=True)
        async with OpcUaMachineServer(machine, users=UserTable(anonymous="operator")) as server:
            async with OpcUaConnection(ConnectionConfig(endpoint=server.endpoint)) as conn:
                polled = 0
                read_signal = conn.read_signal

                async def counted(name: str) -> float:
                    nonlocal polled
                    polled += 1
                    return await read_signal(name)

                conn.read_signal = counted  # type: ignore[method-assign]

                async def clock() -> None:
                    # the machine applies a command on its tick, which comes after the poll has
                    # read the old value twice, however slow the machine running the test
                    while True:
                        while not machine.pending:
                            await asyncio.sleep(0.001)
                        seen = polled
                        while polled < seen + 2:
                            await asyncio.sleep(0.001)
                        machine.tick()
                        server.publish()

                ticking = asyncio.get_running_loop().create_task(clock())
                try:
                    # timeout: a feedback that never changes, not speed (that is benchmarked)
                    result = await measure_latency(
                        conn, n=8, interval_s=0.0, signal="spindle_override_pct", timeout_s=60.0
                    )
                finally:
                    ticking.cancel()
        # two reads of the old value, then at least one of the new: the poll waited every time
        assert result.polls_mean >= 3.0
        assert result.round_trip_ms.min >= result.write_ms.min + result.read_ms.min
        assert all(50.0 <= v <= 120.0 for _, v in machine.commands)

    run(body())


def test_feedback_that_never_changes_times_out() -> None:
    async def body() -> None:
        machine = Machine(lagging=True)  # nothing ticks: the write is never applied
        async with OpcUaMachineServer(machine, users=UserTable(anonymous="operator")) as server:
            async with OpcUaConnection(ConnectionConfig(endpoint=server.endpoint)) as conn:
                with pytest.raises(DataError, match="stayed 100"):
                    await measure_latency(conn, n=3, interval_s=0.0, timeout_s=0.1)
                with pytest.raises(ConfigError):
                    await measure_latency(conn, n=0)
                with pytest.raises(ConfigError, match="x_mm"):
                    await measure_latency(conn, n=1, signal="x_mm")

    run(body())


async def _echo(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    while data := await reader.read(4096):
        writer.write(data)
        await writer.drain()
    writer.close()


def test_jitter_proxy_delays_one_way_uniformly_and_keeps_order() -> None:
    jitter_ms = 10.0

    async def body() -> None:
        echo = await asyncio.start_server(_echo, "127.0.0.1", 0)
        port = echo.sockets[0].getsockname()[1]
        async with JitterProxy("127.0.0.1", port, jitter_ms, seed=1) as proxy:
            reader, writer = await asyncio.open_connection("127.0.0.1", proxy.port)
            delays = []
            for k in range(60):
                message = f"{k:04d}".encode()
                t0 = time.perf_counter()
                writer.write(message)
                await writer.drain()
                assert await reader.readexactly(4) == message
                delays.append((time.perf_counter() - t0) * 1e3)
            # Back-to-back messages arrive in order although each draws its own delay.
            burst = b"".join(f"{k:04d}".encode() for k in range(50))
            for k in range(50):
                writer.write(burst[4 * k : 4 * k + 4])
                await asyncio.sleep(0)
            assert await reader.readexactly(len(burst)) == burst
            writer.close()
        echo.close()
        await echo.wait_closed()
        # Each message draws its own delay, U(0, 2J) from the proxy's seed, in order: every round
        # trip waits at least its draw (a loaded machine only adds, so no upper bound here; how
        # closely the delays follow the draws is benchmarked in bench_opcua_latency.py).
        draws = random.Random(1)
        drawn = [draws.uniform(0.0, 2.0 * jitter_ms) for _ in delays]
        assert all(d >= e - 1e-3 for d, e in zip(delays, drawn, strict=True))
        assert min(drawn) < 0.5 * jitter_ms and max(drawn) > 1.5 * jitter_ms

    run(body())
    with pytest.raises(ConfigError):
        JitterProxy("127.0.0.1", 1, -1.0)
