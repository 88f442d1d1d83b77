"""The twin's OPC UA client against node-opcua's server (an independent implementation).

tests/interop/sinumerik_like_server.js serves the node ids of the shipped preset
examples/opcua/sinumerik_840d_sl.toml; the twin's :class:`OpcUaConnection` reads it through
that preset, writes the overrides as the server's operator user and reads them back, rejects
the garbage the server sends, and survives the server being killed and started again, with
every command reaching the machine exactly once.
"""

from __future__ import annotations

import asyncio
import math
import tomllib
from collections.abc import Iterator
from importlib.resources import as_file
from pathlib import Path

import pytest
from node_opcua import PASSWORD, USER, NodeProcess, start_sinumerik_like
from timeouts import BODY_S

from cnctwin.thread import CommandRejected, ConnectionLost, ConnectionState
from cnctwin.thread.config import ConnectionConfig, OpcUaSecurityConfig
from cnctwin.thread.opcua import OpcUaConnection
from cnctwin.virtual.opcua_server import free_port

PRESET = Path(__file__).resolve().parents[2] / "examples" / "opcua" / "sinumerik_840d_sl.toml"


def _config(port: int, *, user: str | None = USER, password: str | None = PASSWORD):
    table = tomllib.loads(PRESET.read_text())["connection"]
    return ConnectionConfig(
        transport="opcua",
        endpoint=f"opc.tcp://127.0.0.1:{port}",
        timeout_s=10.0,
        reconnect_initial_s=0.05,
        reconnect_max_s=0.5,
        mapping=table["mapping"],
        security=OpcUaSecurityConfig(username=user, password=password),
    )


@pytest.fixture(scope="module")
def server(node_pki: Path) -> Iterator[tuple[NodeProcess, int]]:
    port = free_port()
    process = start_sinumerik_like(port, node_pki)
    try:
        yield process, port
    finally:
        process.close()


def _run(body) -> None:
    async def main() -> None:
        await asyncio.wait_for(body(), BODY_S)

    asyncio.run(main())


@pytest.mark.parametrize("subscription_ms", [5.0, None], ids=["subscription", "read"])
def test_the_preset_reads_every_mapped_node(
    server: tuple[NodeProcess, int], subscription_ms: float | None
) -> None:
    _, port = server
    mapping = tomllib.loads(PRESET.read_text())["connection"]["mapping"]

    async def body() -> None:
        async with OpcUaConnection(_config(port), subscription_ms=subscription_ms) as conn:
            reading = await conn.read()
            mapped = {name for name, node in mapping.items() if node != "none"}
            assert set(reading.values) == mapped, reading.rejected
            assert not reading.rejected
            v = reading.values
            # the server's values (sinumerik_like_server.js): x = 100 + 10 sin t, y = 50 +
            # 10 cos t, so (x - 100)^2 + (y - 50)^2 = 100 at any t
            assert (v["x_mm"] - 100) ** 2 + (v["y_mm"] - 50) ** 2 == pytest.approx(100, rel=0.05)
            assert v["z_mm"] == -20.0
            assert (v["load_x_pct"], v["load_y_pct"], v["load_z_pct"]) == (12.5, 8.25, 20.0)
            assert v["spindle_rpm"] == pytest.approx(8000.0 * v["spindle_override_pct"] / 100)
            assert v["tool_number"] == 3.0
            assert v["t_s"] > 0
            assert reading.source_time_s is not None

    _run(body)


def test_override_written_by_the_operator_is_read_back_and_bad_writes_are_refused(
    server: tuple[NodeProcess, int],
) -> None:
    process, port = server

    async def body() -> None:
        async with OpcUaConnection(_config(port)) as conn:
            before = len(process.writes())
            await conn.write("feed_override_pct", 80.4)
            # the server rounds to whole percent: the read-back is the machine's value
            assert await conn.read_signal("feed_override_pct") == 80.0
            assert (await conn.read()).values["feed_override_pct"] == 80.0
            await conn.write("spindle_override_pct", 110.0)
            assert await conn.read_signal("spindle_override_pct") == 110.0
            # the machine applied it: its spindle turns 110 % of 8000 rpm (a Read request; the
            # subscription delivers it within its publishing interval)
            assert await conn.read_signal("spindle_rpm") == pytest.approx(8800.0)
            with pytest.raises(CommandRejected, match="BadOutOfRange"):
                await conn.write("feed_override_pct", 130.0)  # the server's range: 0..120 %
            with pytest.raises(CommandRejected, match="not mapped"):
                await conn.write("feed_hold", 1.0)
            assert conn.state is ConnectionState.CONNECTED
            applied = process.writes_since(before, 2)
            assert [(w["write"], w["value"], w["user"]) for w in applied] == [
                ("/Channel/State/feedRateIpoOvr", 80, USER),
                ("/Channel/Spindle/speedOvr[u1,1]", 110, USER),
            ]
            await conn.write("feed_override_pct", 100.0)
            await conn.write("spindle_override_pct", 100.0)

        # anonymous: reads, but the server's role permissions refuse its writes
        async with OpcUaConnection(_config(port, user=None, password=None)) as conn:
            assert "x_mm" in (await conn.read()).values
            count = len(process.writes())
            with pytest.raises(CommandRejected, match="BadUserAccessDenied|BadNotWritable"):
                await conn.write("feed_override_pct", 50.0)
            assert process.writes_since(count, 0) == []
        # a wrong password: no session at all
        with pytest.raises(ConnectionLost):
            async with OpcUaConnection(_config(port, password="wrong")):
                pass

    _run(body)


def test_garbage_from_the_server_is_rejected_and_the_rest_read(
    server: tuple[NodeProcess, int],
) -> None:
    process, port = server

    async def body() -> None:
        async with OpcUaConnection(_config(port), subscription_ms=None) as conn:
            process.send("garbage")
            try:
                reading = await conn.read()
            finally:
                process.send("clean")
            assert set(reading.rejected) == {"load_y_pct", "spindle_rpm", "tool_number"}
            assert "non-finite" in reading.rejected["load_y_pct"]
            assert "non-finite" in reading.rejected["spindle_rpm"]
            assert "outside" in reading.rejected["tool_number"]
            assert reading.values["load_x_pct"] == 12.5
            assert all(math.isfinite(v) for v in reading.values.values())
            assert "tool_number" in (await conn.read()).values

    _run(body)


def test_server_killed_and_restarted_reconnects_and_no_command_is_repeated_or_lost(
    node_pki: Path,
) -> None:
    port = free_port()
    first = start_sinumerik_like(port, node_pki)
    second: NodeProcess | None = None

    async def body() -> None:
        nonlocal second
        async with OpcUaConnection(_config(port)) as conn:
            await conn.write("feed_override_pct", 90.0)
            before = await conn.read()
            first.kill()
            with pytest.raises(ConnectionLost):
                for _ in range(1000):  # the cache notices the closed socket within ms
                    await conn.read()
                    await asyncio.sleep(0.01)
            # a command while the machine is away fails at once; it is not queued
            with pytest.raises(ConnectionLost):
                await conn.write("feed_override_pct", 70.0)
            second = await asyncio.to_thread(start_sinumerik_like, port, node_pki)
            deadline = asyncio.get_running_loop().time() + BODY_S / 2
            while conn.state is not ConnectionState.CONNECTED:
                assert asyncio.get_running_loop().time() < deadline, conn.state
                await asyncio.sleep(0.05)
            # the subscription is created anew on the new session: until its first
            # notification the cache holds the last values, with their old time stamps
            after = await conn.read()
            while after.source_time_s == before.source_time_s:
                assert asyncio.get_running_loop().time() < deadline, "no new sample"
                await asyncio.sleep(0.05)
                after = await conn.read()
            assert conn.reconnects == 1
            assert "new session" in conn.last_reconnect
            # the gap is visible: the restarted machine's clock starts again from 0
            assert after.received_s > before.received_s
            assert after.values["t_s"] < before.values["t_s"] + (
                after.received_s - before.received_s
            )
            assert after.values["feed_override_pct"] == 100.0  # a fresh control
            await conn.write("feed_override_pct", 75.0)
            assert await conn.read_signal("feed_override_pct") == 75.0
        # exactly one write reached each server: nothing lost, nothing repeated
        assert [w["value"] for w in first.writes_since(0, 1)] == [90]
        assert second is not None
        assert [w["value"] for w in second.writes_since(0, 1)] == [75]

    try:
        _run(body)
    finally:
        first.close()
        if second is not None:
            second.close()


@pytest.mark.parametrize("enabled", [False, True], ids=["control-off", "control-on"])
def test_the_twin_commands_the_node_opcua_machine_only_with_control_enabled(
    server: tuple[NodeProcess, int], enabled: bool
) -> None:
    """The whole twin (``run_session``) through the preset: a rule that fires once asks for
    a feed override of 90 %; with ``[control] enabled = false`` nothing reaches the server,
    with it enabled exactly one write does, and the read-back confirms it."""
    from cnctwin.control import RuleConfig
    from cnctwin.examples import example_file
    from cnctwin.twin.config import load_run_config
    from cnctwin.twin.session import run_session

    process, port = server
    with as_file(example_file("demo_twin.toml")) as path:
        demo = load_run_config(path)
    config = demo.model_copy(
        update={
            "connection": _config(port),
            "rules": [
                RuleConfig(
                    name="slow_down",
                    condition="spindle_rpm > 0",
                    action="feed_override",
                    value=90.0,
                    cooldown_s=1000.0,
                )
            ],
            "control": demo.control.model_copy(update={"enabled": enabled}),
        }
    )
    before = len(process.writes())

    async def body() -> None:
        summary = await run_session(config, duration_s=3.0)
        assert summary.cycles > 10
        async with OpcUaConnection(_config(port)) as conn:
            if enabled:
                assert await conn.read_signal("feed_override_pct") == 90.0
            await conn.write("feed_override_pct", 100.0)

    _run(body)
    applied = [w["value"] for w in process.writes_since(before, 2 if enabled else 1)]
    assert applied == ([90, 100] if enabled else [100])
