"""OPC UA: time stamps in every reading, and the session kept across a dropped link.

Both sides run on one event loop here: cnctwin's virtual OPC UA server (asyncua's server) and
the twin's client. The time stamps the client reports are compared with the DataValues the
server holds; the reconnection is compared with what OPC UA Part 4, 6.7 asks: the same
session re-activated on a new secure channel, its subscription transferred and the
notifications missed during the gap republished.
"""

from __future__ import annotations

import asyncio
import time

from opcua_fixtures import TIMEOUT_S, FakeMachine

from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import ConnectionLost, Reading
from cnctwin.thread.opcua import OpcUaConnection, _posix_s
from cnctwin.twin.freshness import Freshness
from cnctwin.virtual.opcua_server import OpcUaMachineServer


async def _read_until(conn: OpcUaConnection, done, timeout_s: float = TIMEOUT_S) -> Reading:
    """Read until ``done(reading)``; reconnection may be under way (generous timeout: the
    suite runs on loaded machines)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            reading = await conn.read()
            if done(reading):
                return reading
        except ConnectionLost:
            pass
        assert time.monotonic() < deadline, "no such reading in time"
        await asyncio.sleep(0.01)


def _config(server: OpcUaMachineServer) -> ConnectionConfig:
    return ConnectionConfig(
        endpoint=server.endpoint, timeout_s=2.0, reconnect_initial_s=0.05, reconnect_max_s=0.5
    )


def test_readings_carry_the_servers_time_stamps_and_a_frozen_machine_gives_no_new_sample() -> None:
    machine = FakeMachine()

    async def main() -> None:
        async with OpcUaMachineServer(machine) as server:
            for subscription_ms in (5.0, None):
                async with OpcUaConnection(
                    _config(server), subscription_ms=subscription_ms
                ) as conn:
                    judge = Freshness(60.0)
                    machine.values["heartbeat"] += 1.0
                    server.publish()
                    beat = machine.values["heartbeat"]
                    reading = await _read_until(conn, lambda r, b=beat: r.values["heartbeat"] == b)
                    held = server._slots["heartbeat"].value
                    # the newest value's stamps are the server's, to the microsecond
                    assert reading.source_time_s == _posix_s(held.SourceTimestamp)
                    assert reading.server_time_s == _posix_s(held.ServerTimestamp)
                    assert abs(time.time() - reading.source_time_s) < TIMEOUT_S
                    assert judge.check(reading).new
                    # frozen: nothing published, the same stamp, no new sample
                    again = await conn.read()
                    assert again.source_time_s == reading.source_time_s
                    assert not judge.check(again).new

    asyncio.run(asyncio.wait_for(main(), 3 * TIMEOUT_S))


def test_a_dropped_link_keeps_the_session_and_republishes_what_was_missed() -> None:
    machine = FakeMachine()

    async def main() -> tuple[str, str, float, float]:
        async with OpcUaMachineServer(machine) as server:
            async with OpcUaConnection(_config(server), subscription_ms=5.0) as conn:
                await _read_until(conn, lambda r: "heartbeat" in r.values)
                client = conn._client
                assert client is not None
                client.uaclient.protocol.transport.abort()  # the network drops the link
                # the machine goes on while the twin is cut off
                machine.values["heartbeat"] += 5.0
                machine.values["x_mm"] = 123.5
                server.publish()
                beat = machine.values["heartbeat"]
                back = await _read_until(conn, lambda r: r.values.get("heartbeat") == beat)
                kept = conn.last_reconnect
                # the server goes away for good; a new one (a restarted control) answers
                await server.stop()
                fresh = OpcUaMachineServer(machine, port=server.port)
                await fresh.start()
                try:
                    machine.values["heartbeat"] += 1.0
                    fresh.publish()
                    beat = machine.values["heartbeat"]
                    await _read_until(conn, lambda r: r.values.get("heartbeat") == beat)
                    renewed = conn.last_reconnect
                finally:
                    await fresh.stop()
                return kept, renewed, back.values["x_mm"], float(conn.reconnects)

    kept, renewed, x_mm, reconnects = asyncio.run(asyncio.wait_for(main(), 4 * TIMEOUT_S))
    assert kept.startswith("session re-activated; subscription transferred"), kept
    assert "republished" in kept
    assert x_mm == 123.5  # the value published during the gap arrived
    assert renewed.startswith("new session"), renewed
    assert "subscription created anew" in renewed
    assert reconnects == 2
