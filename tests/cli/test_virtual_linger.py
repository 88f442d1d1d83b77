"""``cnctwin virtual serve --once`` after the program's end: it waits for connected OPC UA
clients (a twin still compiling on its first run must find the machine there), not forever.

The served machine is real (asyncua's server, counted through its open connections), the
client is the twin's own OPC UA connection; the grace and the hold limit are shortened.
"""

from __future__ import annotations

import asyncio
from importlib.resources import as_file, files
from pathlib import Path

import pytest
from timeouts import BODY_S

from cnctwin.cli import virtual as virtual_cli
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.opcua import OpcUaConnection
from cnctwin.twin.config import RunConfig, load_run_config
from cnctwin.twin.host import MachineServer
from cnctwin.virtual import UserTable


def load_demo_config() -> RunConfig:
    with as_file(files("cnctwin.examples")) as folder:
        return load_run_config(Path(folder) / "demo_twin.toml")


@pytest.fixture
def short_waits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(virtual_cli, "END_GRACE_S", 0.3)
    monkeypatch.setattr(virtual_cli, "END_HOLD_MAX_S", BODY_S)


async def _client(machine: MachineServer) -> OpcUaConnection:
    config = ConnectionConfig(transport="opcua", endpoint=machine.endpoint, timeout_s=30.0)
    connection = OpcUaConnection(config)
    await connection.connect()
    return connection


@pytest.mark.usefixtures("short_waits")
def test_the_server_stays_while_a_client_is_connected_and_goes_when_it_leaves() -> None:
    async def body() -> None:
        server = MachineServer(load_demo_config(), "opcua", users=UserTable(anonymous="read-only"))
        async with server:
            assert server.clients == 0
            client = await _client(server)
            assert server.clients == 1
            stop = asyncio.Event()
            linger = asyncio.create_task(virtual_cli._linger(server, stop))
            # ten times the grace with the client connected: still serving
            await asyncio.sleep(3.0)
            assert not linger.done()
            await client.close()
            await asyncio.wait_for(linger, BODY_S)
            assert server.clients == 0

    asyncio.run(asyncio.wait_for(body(), 2 * BODY_S))


@pytest.mark.usefixtures("short_waits")
def test_without_clients_the_server_goes_after_the_grace() -> None:
    async def body() -> None:
        server = MachineServer(load_demo_config(), "opcua", users=UserTable(anonymous="read-only"))
        async with server:
            loop = asyncio.get_running_loop()
            start = loop.time()
            await asyncio.wait_for(virtual_cli._linger(server, asyncio.Event()), BODY_S)
            assert loop.time() - start >= virtual_cli.END_GRACE_S

    asyncio.run(asyncio.wait_for(body(), 2 * BODY_S))


def test_a_client_that_stays_is_waited_for_at_most_the_hold_limit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(virtual_cli, "END_GRACE_S", 0.1)
    monkeypatch.setattr(virtual_cli, "END_HOLD_MAX_S", 0.5)

    async def body() -> None:
        server = MachineServer(load_demo_config(), "opcua", users=UserTable(anonymous="read-only"))
        async with server:
            client = await _client(server)
            try:
                loop = asyncio.get_running_loop()
                start = loop.time()
                await asyncio.wait_for(virtual_cli._linger(server, asyncio.Event()), BODY_S)
                assert loop.time() - start >= 0.5
                assert server.clients == 1
            finally:
                await client.close()

    asyncio.run(asyncio.wait_for(body(), 2 * BODY_S))


def test_other_transports_have_no_client_count() -> None:
    server = MachineServer(load_demo_config(), "modbus")
    assert server.clients is None
