"""OPC UA client against the virtual machine's server, both real, on a loopback port.

What the client reads is compared with what the server side publishes (the fake machine's
snapshot), for every mapped signal; writes are checked by the machine's record of commands.
Security runs with self-signed certificates generated here into ``tmp_path``.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from asyncua import ua
from opcua_fixtures import TIMEOUT_S, FakeMachine, Shared, Traffic, watched
from pki import certificate

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.config import ConnectionConfig, OpcUaSecurityConfig
from cnctwin.thread.connection import (
    CommandRejected,
    ConnectionLost,
    ConnectionState,
    Reading,
)
from cnctwin.thread.opcua import (
    DEFAULT_SUBSCRIPTION_MS,
    NODE_MAP,
    OpcUaConnection,
)
from cnctwin.thread.signals import SIGNALS
from cnctwin.virtual.opcua_server import (
    OpcUaMachineServer,
    OpcUaServerSecurity,
)
from cnctwin.virtual.users import Account, UserTable, hash_password


def run(coro: Callable[[], Awaitable[None]]) -> None:
    async def main() -> None:
        await asyncio.wait_for(coro(), TIMEOUT_S)

    asyncio.run(main())


@pytest.fixture(scope="module")
def shared() -> Iterator[Shared]:
    server = Shared(FakeMachine())
    yield server
    server.close()


def config(server: OpcUaMachineServer | Shared, **kwargs: Any) -> ConnectionConfig:
    return ConnectionConfig(endpoint=server.endpoint, timeout_s=2.0, **kwargs)


async def eventually(conn: OpcUaConnection, check: Callable[[Reading], bool]) -> Reading:
    """Read until ``check`` holds (a subscription's cache follows the server within ms)."""
    for _ in range(300):
        reading = await conn.read()
        if check(reading):
            return reading
        await asyncio.sleep(0.01)
    raise AssertionError(f"never held; last reading {reading}")


#: Both ways of reading: one Read request per cycle, and the subscription cache (default).
MODES = pytest.mark.parametrize("subscription_ms", [None, DEFAULT_SUBSCRIPTION_MS])


@MODES
def test_every_mapped_signal_reads_what_the_server_publishes(
    shared: Shared, subscription_ms: float | None
) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        service = server.server._server.iserver.attribute_service  # type: ignore[union-attr]
        requests: list[int] = []
        original = service.read

        def counting_read(params: ua.ReadParameters) -> list[ua.DataValue]:
            requests.append(len(params.NodesToRead))
            return original(params)

        service.read = counting_read
        try:
            conn = OpcUaConnection(config(server), subscription_ms=subscription_ms)
            async with conn:
                requests.clear()
                reading = await conn.read()
                # One Read service call for all signals, or none from the cache.
                assert requests == ([len(SIGNALS)] if subscription_ms is None else [])
                assert reading.rejected == {}
                assert dict(reading.values) == pytest.approx(machine.values)
                # The machine moves; the reads follow.
                machine.values.update(x_mm=-12.5, heartbeat=1234.0, run_state=1.0)
                server.publish()
                reading = await eventually(conn, lambda r: r.values["x_mm"] == -12.5)
                assert dict(reading.values) == pytest.approx(machine.values)
        finally:
            del service.read  # back to the class's method

    shared.run(body)


def test_write_is_applied_and_read_back(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        async with OpcUaConnection(config(server)) as conn:
            await conn.write("feed_override_pct", 42.5)
            assert await conn.read_signal("feed_override_pct") == 42.5
            await conn.write("feed_hold", 1.0)
            await conn.write("tool_length_wear_mm", -0.015)
            reading = await conn.read()
            assert reading.values["feed_hold"] == 1.0
            assert reading.values["tool_length_wear_mm"] == -0.015
            assert machine.commands == [
                ("feed_override_pct", 42.5),
                ("feed_hold", 1.0),
                ("tool_length_wear_mm", -0.015),
            ]

    shared.run(body)


@MODES
def test_write_read_back_sends_the_read_before_the_write_is_answered(
    shared: Shared, subscription_ms: float | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Heide 2025's write and read-back in one go: the Read of the feedback is on the secure
    channel before the Write's answer comes back, and still sees the value written (asyncua's
    server answers a channel's requests in order); a refused write raises, and the read-back
    sent with it does not disturb the requests after it."""

    async def body(server: Shared, machine: FakeMachine) -> None:
        async with OpcUaConnection(config(server), subscription_ms=subscription_ms) as conn:
            assert conn._client is not None
            protocol = conn._client.uaclient.protocol
            assert protocol is not None
            with watched(protocol) as traffic:
                await check(conn, machine, traffic)

    async def check(conn: OpcUaConnection, machine: FakeMachine, traffic: Traffic) -> None:
        events = traffic.events
        back = await conn.write_read_back("feed_override_pct", 37.0)
        assert events == ["Write", "Read", "Write answered", "Read answered"]
        assert traffic.writes[-1] == 2  # both in one socket write
        assert back.value == 37.0 and machine.commands == [("feed_override_pct", 37.0)]
        assert back.write_s > 0 and back.read_s >= 0
        assert await conn.read_signal("feed_override_pct") == 37.0
        with pytest.raises(CommandRejected, match="BadOutOfRange"):
            await conn.write_read_back("feed_override_pct", 151.0)
        assert conn.state is ConnectionState.CONNECTED
        spindle = machine.values["spindle_override_pct"]
        assert await conn.read_signal("spindle_override_pct") == spindle
        events.clear()
        assert (await conn.write_read_back("feed_override_pct", 38.0)).value == 38.0
        assert events == ["Write", "Read", "Write answered", "Read answered"]
        events.clear()  # as measure_latency with jitter asks (one proxy delay each)
        back = await conn.write_read_back("feed_override_pct", 39.0, pipelined=False)
        assert back.value == 39.0
        assert events == ["Write", "Write answered", "Read", "Read answered"]
        assert traffic.writes[-2:] == [1, 1]
        # a read-back that does not show the value written (here: a machine that rounds
        # the override) makes the connection wait for the write's answer from then on
        monkeypatch.setattr(machine, "quantised", True)
        assert (await conn.write_read_back("feed_override_pct", 40.4)).value == 40.0
        events.clear()
        assert (await conn.write_read_back("feed_override_pct", 41.0)).value == 41.0
        assert events == ["Write", "Write answered", "Read", "Read answered"]

    shared.run(body)


def test_a_started_write_is_in_the_socket_when_the_call_returns(shared: Shared) -> None:
    """start_write hands the Write to the socket before it returns (the twin's cycle goes on
    meanwhile); the future holds the answer: None, or the refusal."""

    async def body(server: Shared, machine: FakeMachine) -> None:
        async with OpcUaConnection(config(server)) as conn:
            assert conn._client is not None
            protocol = conn._client.uaclient.protocol
            assert protocol is not None
            with watched(protocol) as traffic:
                answer = conn.start_write("feed_override_pct", 44.0)
                assert traffic.events == ["Write"] and traffic.writes == [1]
                assert await answer is None
                assert machine.commands == [("feed_override_pct", 44.0)]
                refused = conn.start_write("feed_override_pct", 151.0)
                with pytest.raises(CommandRejected, match="BadOutOfRange"):
                    await refused
            assert conn.state is ConnectionState.CONNECTED
            assert (await conn.read()).values["feed_override_pct"] == 44.0

    shared.run(body)


def test_invalid_write_is_rejected_with_the_bad_status_and_the_connection_stays(
    shared: Shared,
) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        async with OpcUaConnection(config(server)) as conn:
            for value in (151.0, -5.0, math.nan):
                with pytest.raises(CommandRejected, match="BadOutOfRange"):
                    await conn.write("feed_override_pct", value)
            with pytest.raises(ConfigError, match="not a command"):
                await conn.write("x_mm", 1.0)
            assert conn.state is ConnectionState.CONNECTED
            assert machine.commands == []
            assert (await conn.read()).values["feed_override_pct"] == 1.0

    shared.run(body)


@MODES
def test_garbage_values_land_in_rejected(shared: Shared, subscription_ms: float | None) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        mapping = {
            # a String node where a number is expected (wrong type)
            "y_mm": "ns=2;s=Machine.Identification.Manufacturer",
            # a node the server does not have (Bad status)
            "z_mm": "ns=2;s=Machine.Monitoring.Axes.W.ActPos",
            # a browse path, resolved at connect: X's load read through the path
            "load_y_pct": "2:Machines/2:Machine/2:Monitoring/2:Axes/2:X/2:ActLoad",
        }
        conn = OpcUaConnection(config(server, mapping=mapping), subscription_ms=subscription_ms)
        async with conn:
            machine.values.update(
                force_x_n=math.nan,  # NaN in a Double
                spindle_rpm=math.inf,
                run_state=9.0,  # out of RunState's range
                heartbeat=math.nan,  # NaN in an Int32: the server publishes Bad status
            )
            server.publish()
            reading = await eventually(conn, lambda r: len(r.rejected) == 6)
            rejected = reading.rejected
            assert set(rejected) == {
                "y_mm",
                "z_mm",
                "force_x_n",
                "spindle_rpm",
                "run_state",
                "heartbeat",
            }
            assert "wrong type str" in rejected["y_mm"]
            assert "BadNodeIdUnknown" in rejected["z_mm"]
            assert "non-finite" in rejected["force_x_n"]
            assert "outside 0.0..5.0" in rejected["run_state"]
            assert "BadOutOfRange" in rejected["heartbeat"]
            assert not set(rejected) & set(reading.values)
            assert reading.values["load_y_pct"] == machine.values["load_x_pct"]
            assert reading.values["x_mm"] == machine.values["x_mm"]
            with pytest.raises(DataError, match="force_x_n"):
                await conn.read_signal("force_x_n")
            assert conn.state is ConnectionState.CONNECTED

    shared.run(body)


def test_bad_mappings_are_config_errors(shared: Shared) -> None:
    with pytest.raises(ConfigError, match="unknown signal"):
        OpcUaConnection(ConnectionConfig(mapping={"x_position": "ns=2;s=X"}))
    with pytest.raises(ConfigError, match="'opcua'"):
        OpcUaConnection(ConnectionConfig(transport="modbus", endpoint="modbus://127.0.0.1:502"))

    async def body(server: Shared, machine: FakeMachine) -> None:
        conn = OpcUaConnection(config(server, mapping={"x_mm": "2:Machines/2:Nowhere"}))
        with pytest.raises(ConfigError, match="browse path"):
            await conn.connect()
        await conn.close()

    shared.run(body)


def test_heartbeat_tells_a_frozen_server(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        async with OpcUaConnection(config(server), subscription_ms=None) as conn:
            first = await conn.read()
            assert conn.heartbeat_s == first.received_s
            second = await conn.read()  # the machine did not tick: the beat stands
            assert conn.heartbeat_s == first.received_s < second.received_s
            machine.values["heartbeat"] += 1
            server.publish()
            third = await conn.read()
            assert conn.heartbeat_s == third.received_s
        async with OpcUaConnection(config(server)) as conn:  # the subscription's cache
            await conn.read()
            before = conn.heartbeat_s
            machine.values["heartbeat"] += 1
            server.publish()
            await eventually(conn, lambda r: r.values["heartbeat"] == machine.values["heartbeat"])
            assert before is not None and conn.heartbeat_s is not None
            assert conn.heartbeat_s > before

    shared.run(body)


@MODES
def test_server_restart_mid_run_reconnects_and_reads_go_on(
    subscription_ms: float | None,
) -> None:
    async def body() -> None:
        machine = FakeMachine()
        server = OpcUaMachineServer(machine)
        await server.start()
        cfg = config(server, reconnect_initial_s=0.05, reconnect_max_s=0.2)
        conn = OpcUaConnection(cfg, subscription_ms=subscription_ms)
        await conn.connect()
        try:
            assert (await conn.read()).values["x_mm"] == machine.values["x_mm"]
            await server.stop()
            with pytest.raises(ConnectionLost):
                for _ in range(100):  # the cache notices the closed session within ms
                    await conn.read()
                    await asyncio.sleep(0.01)
            assert conn.state is ConnectionState.RECONNECTING
            await asyncio.sleep(0.3)  # attempts fail while the server is down
            assert conn.state is ConnectionState.RECONNECTING
            machine.values["x_mm"] = 99.5
            restarted = OpcUaMachineServer(machine, port=server.port)
            await restarted.start()
            try:
                while conn.state is not ConnectionState.CONNECTED:
                    await asyncio.sleep(0.02)
                assert conn.reconnects == 1
                assert (await conn.read()).values["x_mm"] == 99.5
            finally:
                await restarted.stop()
        finally:
            await conn.close()

    run(body)


# Security ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def certificates(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("pki")
    # DER certificates here (the PEM form is what tests/virtual/test_opcua_security.py uses)
    certificate(folder, "server", "server", der=True)
    certificate(folder, "twin", "client", der=True)
    return folder


@pytest.mark.parametrize("mode", ["Sign", "SignAndEncrypt"])
def test_secure_session_with_certificates_and_password(certificates: Path, mode: str) -> None:
    trusted = certificates / "trusted"  # the clients the server accepts: the twin
    trusted.mkdir(exist_ok=True)
    (trusted / "twin-cert.der").write_bytes((certificates / "twin-cert.der").read_bytes())
    server_security = OpcUaServerSecurity(
        mode=mode,  # type: ignore[arg-type]
        certificate=certificates / "server-cert.der",
        private_key=certificates / "server-key.pem",
        trust_folder=trusted,
    )
    users = UserTable({"operator": Account("operator", hash_password("s3cret"))}, anonymous=None)

    def client(
        server: OpcUaMachineServer, password: str | None, username: str | None = "operator"
    ) -> ConnectionConfig:
        security = OpcUaSecurityConfig(
            policy="Basic256Sha256",
            mode=mode,  # type: ignore[arg-type]
            certificate="twin-cert.der",
            private_key="twin-key.pem",
            server_certificate="server-cert.der",
            username=username,
            password=password,
        )
        return config(server, security=security)

    async def body() -> None:
        machine = FakeMachine()
        async with OpcUaMachineServer(machine, security=server_security, users=users) as server:
            # the cycle's read from the subscription, then by Read requests: every request
            # and answer signed (and encrypted) on the secure channel
            for subscription_ms, override in ((5.0, 90.0), (None, 80.0)):
                conn = OpcUaConnection(
                    client(server, "s3cret"), base_dir=certificates, subscription_ms=subscription_ms
                )
                async with conn:
                    reading = await conn.read()
                    assert dict(reading.values) == pytest.approx(machine.values)
                    await conn.write("spindle_override_pct", override)
                    assert await conn.read_signal("spindle_override_pct") == override
                    assert machine.values["spindle_override_pct"] == override
                    # the Write and its read-back framed (signed, encrypted) one after the
                    # other and sent in one socket write
                    back = await conn.write_read_back("spindle_override_pct", override - 1.0)
                    assert back.value == override - 1.0
            for refused in (client(server, "wrong"), client(server, None, username=None)):
                with pytest.raises(ConnectionLost):
                    await OpcUaConnection(refused, base_dir=certificates).connect()
            # No security at all: the endpoint is not offered.
            with pytest.raises(ConnectionLost):
                await OpcUaConnection(config(server)).connect()

    run(body)


def test_incomplete_client_security_is_a_config_error(tmp_path: Path) -> None:
    half = OpcUaSecurityConfig(policy="Basic256Sha256", mode="Sign")
    conn = OpcUaConnection(ConnectionConfig(security=half))

    async def body() -> None:
        with pytest.raises(ConfigError, match="certificate"):
            await conn.connect()

    run(body)
    missing = OpcUaSecurityConfig(
        policy="Basic256Sha256",
        mode="Sign",
        certificate="no.der",
        private_key="no.pem",
        server_certificate="no-server.der",
    )
    conn = OpcUaConnection(ConnectionConfig(security=missing), base_dir=tmp_path)

    async def body2() -> None:
        with pytest.raises(ConfigError, match="not found"):
            await conn.connect()

    run(body2)
    assert NODE_MAP["x_mm"].startswith("Machine.")
