"""``cnctwin bench latency``: the JSON report, against the virtual machine it starts itself
and against a server named with ``--endpoint`` (OPC UA and Modbus TCP)."""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from timeouts import SERVER_START_S

from cnctwin.cli import run
from cnctwin.thread.signals import SIGNALS
from cnctwin.virtual.modbus_server import ModbusMachineServer
from cnctwin.virtual.opcua_server import OpcUaMachineServer
from cnctwin.virtual.users import UserTable

STATS = {"mean", "std", "min", "median", "p99", "max"}


class Machine:
    """Commands take effect at once."""

    def __init__(self) -> None:
        self.values = {name: 0.0 for name in SIGNALS}
        self.values.update(feed_override_pct=100.0, spindle_override_pct=100.0, work_offset=1.0)
        self.commands: list[tuple[str, float]] = []

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        self.commands.append((name, value))
        self.values[name] = value


@contextmanager
def serving(kind: str) -> Iterator[tuple[str, Machine]]:
    """A server for a Machine on its own event loop in a thread; yields (endpoint, machine)."""
    machine = Machine()
    loop = asyncio.new_event_loop()
    started = threading.Event()
    stop = asyncio.Event()
    endpoint: list[str] = []

    async def serve() -> None:
        server: OpcUaMachineServer | ModbusMachineServer
        if kind == "opcua":  # the latency bench writes commands anonymously
            server = OpcUaMachineServer(machine, users=UserTable(anonymous="operator"))
        else:
            server = ModbusMachineServer(machine)
        async with server:
            endpoint.append(server.endpoint)
            started.set()
            await stop.wait()

    thread = threading.Thread(target=loop.run_until_complete, args=(serve(),), daemon=True)
    thread.start()
    assert started.wait(SERVER_START_S), f"{kind} server not started in {SERVER_START_S} s"
    try:
        yield endpoint[0], machine
    finally:
        loop.call_soon_threadsafe(stop.set)
        thread.join(10.0)
        loop.close()


def check_report(out: str, n: int) -> dict[str, object]:
    report = json.loads(out)
    assert report["n"] == n
    for key in ("round_trip_ms", "write_ms", "read_ms"):
        stats = report[key]
        assert set(stats) == STATS, key
        assert 0 < stats["min"] <= stats["median"] <= stats["p99"] <= stats["max"], key
    assert report["round_trip_ms"]["min"] >= report["write_ms"]["min"]
    return report


def test_latency_json_against_the_virtual_machine(capsys: pytest.CaptureFixture[str]) -> None:
    code = run(["bench", "latency", "--n", "50", "--interval-ms", "1", "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    report = check_report(captured.out, 50)
    assert report["transport"] == "opcua"
    assert str(report["endpoint"]).startswith("opc.tcp://127.0.0.1:")


@pytest.mark.parametrize("kind", ["opcua", "modbus"])
def test_latency_against_a_given_endpoint_with_jitter(
    kind: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with serving(kind) as (endpoint, machine):
        args = ["bench", "latency", "--transport", kind, "--endpoint", endpoint]
        code = run([*args, "--n", "12", "--interval-ms", "0", "--jitter-ms", "3", "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    report = check_report(captured.out, 12)
    assert (report["endpoint"], report["jitter_ms"]) == (endpoint, 3.0)
    # Two requests per round trip, each held U(0, 6) ms by the proxy: 6 ms on average.
    assert report["round_trip_ms"]["mean"] > 2.0
    feed = [v for name, v in machine.commands if name == "feed_override_pct"]
    assert len(feed) == 13 and feed[-1] == 100.0


def test_bad_transport_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    code = run(["bench", "latency", "--transport", "profinet", "--n", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip().count("\n") == 0 and "'profinet'" in err
    assert all(t in err for t in ("opcua", "modbus", "mtconnect", "ads", "mqtt"))


def test_unreachable_endpoint_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    from cnctwin.virtual.opcua_server import free_port

    url = f"opc.tcp://127.0.0.1:{free_port()}/cnctwin"
    code = run(["bench", "latency", "--endpoint", url, "--n", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip().count("\n") == 0 and "cannot connect" in err
