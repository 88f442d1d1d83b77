"""``cnctwin virtual serve``: a virtual machine in its own process, read by a real client."""

from __future__ import annotations

import asyncio
import math
import subprocess
import sys

import pytest

from cnctwin.cli.app import run
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.modbus import ModbusConnection
from cnctwin.thread.opcua import OpcUaConnection
from cnctwin.thread.signals import SIGNALS, RunState


async def _read_until_moving(connection: OpcUaConnection | ModbusConnection) -> dict[str, float]:
    async with connection:
        for _ in range(200):
            values = dict((await connection.read()).values)
            if values.get("run_state") == RunState.RUNNING and values.get("t_s", 0.0) > 0.2:
                return values
            await asyncio.sleep(0.05)
    raise AssertionError("the served machine never reported RUNNING")


@pytest.mark.parametrize("transport", ["opcua", "modbus"])
def test_served_machine_is_read_by_a_client_and_ends_with_its_program(transport: str) -> None:
    # The server runs in a child process (as a separate machine would); the client sees every
    # read signal, the machine running; --once ends the server with the program (exit 0).
    server = subprocess.Popen(
        [sys.executable, "-m", "cnctwin", "virtual", "serve", "--port", "0", "--speed", "20",
         "--transport", transport, "--once"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert server.stdout is not None
        endpoint = server.stdout.readline().strip()
        assert endpoint.startswith("opc.tcp://" if transport == "opcua" else "modbus://")
        config = ConnectionConfig(transport=transport, endpoint=endpoint, timeout_s=5.0)  # type: ignore[arg-type]
        connection = OpcUaConnection(config) if transport == "opcua" else ModbusConnection(config)
        values = asyncio.run(_read_until_moving(connection))
        assert set(SIGNALS) <= set(values)
        assert all(math.isfinite(values[name]) for name in ("x_mm", "y_mm", "z_mm", "t_s"))
        assert values["feed_override_pct"] == 100.0
        _, err = server.communicate(timeout=120)
        assert server.returncode == 0, err
        assert "program finished" in err
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--transport", "mqtt"], "--transport 'mqtt'; valid: opcua, modbus"),
        (["--port", "70000"], "--port 70000; give 0 (a free port) to 65535"),
        (["--speed", "0"], "--speed 0.0: give a value > 0 and <= 20 x real time"),
        (["--config", "no-such.toml"], "no-such.toml: cannot read configuration"),
    ],
)
def test_bad_options_are_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["virtual", "serve", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1
