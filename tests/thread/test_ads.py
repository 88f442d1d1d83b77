"""AdsConnection against pyads' own ADS test server (``pyads.testserver``) on loopback.

The server is pyads' ``AdsTestServer`` with its unmodified ``AdvancedHandler``: symbols are
declared with pyads' ``PLCVariable`` (their bytes packed by pyads), every request the server
receives is in its ``request_history``, so batching, writes and what never reached the wire
are checked from the server's side.
"""

from __future__ import annotations

import asyncio
import math
import socket
import struct
from collections.abc import Awaitable, Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pyads
import pytest
from pyads.testserver import AdsTestServer, AdvancedHandler
from pyads.testserver.advanced_handler import PLCVariable
from timeouts import BODY_S

from cnctwin.errors import ConfigError
from cnctwin.thread import ConnectionLost, ConnectionState
from cnctwin.thread.ads import AdsConnection, parse_endpoint
from cnctwin.thread.ads_map import load_symbol_map, parse_symbol_map
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import CommandRejected

C = pyads.constants
NET_ID = "5.80.201.232.1.1"

MAP = """
[signals]
x_mm = { symbol = "GVL.fX", type = "LREAL", unit = "mm" }
y_mm = { symbol = "GVL.fY", type = "REAL" }
spindle_rpm = { symbol = "GVL.nSpeed", type = "DINT", scale = 0.1, unit = "rpm" }
force_x_n = { symbol = "GVL.nForceX", type = "INT", scale = 0.5 }
tool_number = { symbol = "GVL.nTool", type = "UINT" }
heartbeat = { symbol = "GVL.nBeat", type = "UDINT" }
run_state = { symbol = "GVL.nState", type = "USINT" }
feed_hold = { symbol = "GVL.bHold", type = "BOOL" }
feed_override_pct = { symbol = "GVL.fOverride", type = "LREAL" }
spindle_override_pct = { symbol = "GVL.nSpindleOvr", type = "UINT", scale = 0.01 }

[commands]
feed_override_pct = { symbol = "GVL.fOverrideCmd", type = "LREAL" }
spindle_override_pct = { symbol = "GVL.nSpindleOvr", type = "UINT", scale = 0.01 }
stop = { symbol = "GVL.bStopCmd", type = "BOOL" }
"""

#: symbol -> (value, ADS type, PLC type name), as a TwinCAT PLC would declare them.
VARIABLES: dict[str, tuple[float, int, str]] = {
    "GVL.fX": (123.456789, C.ADST_REAL64, "LREAL"),
    "GVL.fY": (-7.25, C.ADST_REAL32, "REAL"),
    "GVL.nSpeed": (96005, C.ADST_INT32, "DINT"),
    "GVL.nForceX": (-301, C.ADST_INT16, "INT"),
    "GVL.nTool": (4, C.ADST_UINT16, "UINT"),
    "GVL.nBeat": (4_000_000_000, C.ADST_UINT32, "UDINT"),
    "GVL.nState": (1, C.ADST_UINT8, "USINT"),
    "GVL.bHold": (0, C.ADST_BIT, "BOOL"),
    "GVL.fOverride": (100.0, C.ADST_REAL64, "LREAL"),
    "GVL.nSpindleOvr": (10000, C.ADST_UINT16, "UINT"),
    "GVL.fOverrideCmd": (100.0, C.ADST_REAL64, "LREAL"),
    "GVL.bStopCmd": (0, C.ADST_BIT, "BOOL"),
}


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextmanager
def ads_server(
    port: int = 0, variables: dict[str, tuple[float, int, str]] | None = None
) -> Iterator[AdsTestServer]:
    """pyads' test server with the AdvancedHandler and ``variables``; always stopped."""
    handler = AdvancedHandler()
    for name, (value, ads_type, type_name) in (variables or VARIABLES).items():
        handler.add_variable(PLCVariable(name, value, ads_type, type_name))
    server = AdsTestServer(handler=handler, ip_address="127.0.0.1", port=port, logging=False)
    try:
        server.server.listen(5)  # before the thread: a client never finds it not listening
        server.port = server.server.getsockname()[1]
        server.start()
        yield server
    finally:
        server.close()
        server.join(5.0)


def variable(server: AdsTestServer, name: str) -> PLCVariable:
    return server.handler.get_variable_by_name(name)


def config(endpoint: str, map_path: Path, **kwargs: object) -> ConnectionConfig:
    return ConnectionConfig(
        transport="ads", endpoint=endpoint, symbol_map=str(map_path), timeout_s=2.0,
        reconnect_initial_s=0.05, reconnect_max_s=0.2, local_net_id="127.0.0.1.1.20", **kwargs,  # type: ignore[arg-type]
    )  # fmt: skip


@pytest.fixture
def map_path(tmp_path: Path) -> Path:
    path = tmp_path / "symbols.toml"
    path.write_text(MAP, encoding="utf-8")
    return path


def run(
    map_path: Path,
    body: Callable[[AdsTestServer, AdsConnection], Awaitable[None]],
    variables: dict[str, tuple[float, int, str]] | None = None,
) -> None:
    with ads_server(variables=variables) as server:

        async def main() -> None:
            endpoint = f"ads://{NET_ID}:851@127.0.0.1:{server.port}"
            async with AdsConnection(config(endpoint, map_path)) as connection:
                await body(server, connection)

        asyncio.run(asyncio.wait_for(main(), BODY_S))


def requests(server: AdsTestServer, command: int, group: int | None = None) -> list[object]:
    """Requests of ``command`` (ADSCOMMAND_*), optionally to ``group``, the server received."""
    found = []
    for packet in server.request_history:
        header = packet.ams_header
        if struct.unpack("<H", header.command_id)[0] != command:
            continue
        if group is not None and struct.unpack_from("<I", header.data)[0] != group:
            continue
        found.append(packet)
    return found


def test_one_sum_read_decodes_every_type_as_pyads_packed_it(map_path: Path) -> None:
    async def body(server: AdsTestServer, connection: AdsConnection) -> None:
        before = len(requests(server, C.ADSCOMMAND_READWRITE, C.ADSIGRP_SUMUP_READ))
        reading = await connection.read()
        after = requests(server, C.ADSCOMMAND_READWRITE, C.ADSIGRP_SUMUP_READ)
        assert len(after) == before + 1  # every signal in one request
        assert reading.rejected == {}
        assert reading.values == {
            "x_mm": 123.456789,
            "y_mm": -7.25,
            "spindle_rpm": pytest.approx(9600.5, abs=1e-9),
            "force_x_n": -150.5,
            "tool_number": 4.0,
            "heartbeat": 4_000_000_000.0,
            "run_state": 1.0,
            "feed_hold": 0.0,
            "feed_override_pct": 100.0,
            "spindle_override_pct": pytest.approx(100.0),
        }
        assert reading.sequence == 4_000_000_000.0

    run(map_path, body)


def test_a_command_is_written_once_and_read_back(map_path: Path) -> None:
    async def body(server: AdsTestServer, connection: AdsConnection) -> None:
        await connection.write("feed_override_pct", 72.5)
        await connection.write("spindle_override_pct", 87.5)
        await connection.write("stop", 1.0)
        # what pyads' server holds, decoded independently of cnctwin
        assert struct.unpack("<d", variable(server, "GVL.fOverrideCmd").value)[0] == 72.5
        assert struct.unpack("<H", variable(server, "GVL.nSpindleOvr").value)[0] == 8750
        assert variable(server, "GVL.bStopCmd").value == b"\x01"
        assert len(requests(server, C.ADSCOMMAND_WRITE)) == 3
        # a command is read back at its [signals] symbol when there is one
        assert await connection.read_signal("spindle_override_pct") == pytest.approx(87.5)
        assert await connection.read_signal("feed_override_pct") == 100.0  # GVL.fOverride
        assert await connection.read_signal("stop") == 1.0  # its own symbol

    run(map_path, body)


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("feed_override_pct", math.nan, "outside 0..150"),
        ("feed_override_pct", 151.0, "outside 0..150"),
        ("spindle_override_pct", 49.0, "outside 50..120"),
        ("feed_hold", 1.0, "has no symbol"),
    ],
)
def test_bad_commands_are_refused_before_the_wire(
    map_path: Path, name: str, value: float, message: str
) -> None:
    async def body(server: AdsTestServer, connection: AdsConnection) -> None:
        with pytest.raises(CommandRejected, match=message) as err:
            await connection.write(name, value)
        assert "\n" not in str(err.value)
        assert requests(server, C.ADSCOMMAND_WRITE) == []
        assert connection.state is ConnectionState.CONNECTED

    run(map_path, body)


def test_garbage_values_are_rejected_and_the_rest_kept(map_path: Path) -> None:
    async def body(server: AdsTestServer, connection: AdsConnection) -> None:
        variable(server, "GVL.fX").value = struct.pack("<d", math.nan)
        variable(server, "GVL.fY").value = struct.pack("<f", math.inf)
        variable(server, "GVL.fOverride").value = struct.pack("<d", 400.0)
        variable(server, "GVL.nState").value = b"\x09"
        reading = await connection.read()
        assert set(reading.rejected) == {"x_mm", "y_mm", "feed_override_pct", "run_state"}
        assert "not a finite number" in reading.rejected["x_mm"]
        assert "GVL.fX (LREAL)" in reading.rejected["x_mm"]
        assert "400 outside the plausible range 0..150" in reading.rejected["feed_override_pct"]
        assert "9 outside the plausible range 0..5" in reading.rejected["run_state"]
        assert reading.values["tool_number"] == 4.0
        assert all(math.isfinite(v) for v in reading.values.values())

    run(map_path, body)


def test_an_answer_of_the_wrong_size_is_rejected_not_zero_filled(map_path: Path) -> None:
    async def body(server: AdsTestServer, connection: AdsConnection) -> None:
        # after the connection resolved GVL.fX as 8 bytes, the PLC serves 4: the sum-read
        # answer is 4 bytes short (pyads' buffer would hold zeros at its end)
        variable(server, "GVL.fX").value = struct.pack("<f", 1.0)
        reading = await connection.read()
        assert reading.values == {}
        assert "Insufficient data" in reading.rejected["feed_override_pct"]
        assert connection.state is ConnectionState.CONNECTED
        variable(server, "GVL.fX").value = struct.pack("<d", 2.0)
        assert (await connection.read()).values["x_mm"] == 2.0

    run(map_path, body)


def test_a_symbol_of_the_wrong_type_or_size_is_unusable_not_misread(map_path: Path) -> None:
    variables = dict(VARIABLES)
    variables["GVL.fX"] = (12345, C.ADST_INT16, "INT")  # the map says LREAL
    variables["GVL.fOverrideCmd"] = (100.0, C.ADST_REAL32, "REAL")  # same kind, 4 bytes

    async def body(server: AdsTestServer, connection: AdsConnection) -> None:
        reading = await connection.read()
        assert "x_mm" not in reading.values
        assert "is INT (2 bytes" in reading.rejected["x_mm"]
        assert "LREAL (8 bytes" in reading.rejected["x_mm"]
        assert reading.values["y_mm"] == -7.25
        with pytest.raises(CommandRejected, match=r"is REAL \(4 bytes"):
            await connection.write("feed_override_pct", 50.0)
        assert requests(server, C.ADSCOMMAND_WRITE) == []

    run(map_path, body, variables)


def test_server_killed_and_restarted_reconnects_without_repeating_a_command(
    map_path: Path,
) -> None:
    port = _free_port()
    endpoint = f"ads://{NET_ID}:851@127.0.0.1:{port}"
    group = C.ADSCOMMAND_WRITE
    history: list[int] = []

    async def main() -> None:
        connection = AdsConnection(config(endpoint, map_path))
        with ads_server(port) as first:
            await connection.connect()
            await connection.write("feed_override_pct", 90.0)
            history.append(len(requests(first, group)))
        try:
            with pytest.raises(ConnectionLost):  # the server is gone
                await connection.read()
            assert connection.state is ConnectionState.RECONNECTING
            with pytest.raises(ConnectionLost, match="not connected"):  # never queued
                await connection.write("feed_override_pct", 80.0)
            await asyncio.sleep(0.5)  # backoff attempts against nothing
            with ads_server(port) as second:
                while connection.state is not ConnectionState.CONNECTED:
                    await asyncio.sleep(0.02)
                reading = await connection.read()
                assert reading.values["x_mm"] == 123.456789
                await connection.write("feed_override_pct", 70.0)
                history.append(len(requests(second, group)))
                assert struct.unpack("<d", variable(second, "GVL.fOverrideCmd").value)[0] == 70
        finally:
            await connection.close()
        assert connection.reconnects == 1
        assert connection.last_reconnect == "closed and opened anew"

    asyncio.run(asyncio.wait_for(main(), BODY_S))
    assert history == [1, 1]  # each server saw exactly the write made while it was up


def test_connect_to_nothing_is_connection_lost(map_path: Path) -> None:
    endpoint = f"ads://{NET_ID}:851@127.0.0.1:{_free_port()}"

    async def main() -> None:
        with pytest.raises(ConnectionLost, match="cannot connect"):
            await AdsConnection(config(endpoint, map_path)).connect()

    asyncio.run(asyncio.wait_for(main(), BODY_S))


@pytest.mark.parametrize(
    ("endpoint", "expected"),
    [
        (
            "ads://5.80.201.232.1.1:851@192.168.0.10",
            ("5.80.201.232.1.1", 851, "192.168.0.10", 48898),
        ),
        ("ads://5.80.201.232.1.1@plc.local:1000", ("5.80.201.232.1.1", 851, "plc.local", 1000)),
        ("ads://127.0.0.1.1.1:852@127.0.0.1:48899", ("127.0.0.1.1.1", 852, "127.0.0.1", 48899)),
    ],
)
def test_endpoint_forms(endpoint: str, expected: tuple[str, int, str, int]) -> None:
    parsed = parse_endpoint(endpoint)
    assert (parsed.net_id, parsed.ams_port, parsed.host, parsed.port) == expected


@pytest.mark.parametrize(
    "endpoint",
    [
        "ads://192.168.0.10",  # no Net ID
        "ads://5.80.201.232.1:851@h",  # five numbers
        "ads://5.80.201.232.1.256:851@h",
        "ads://5.80.201.232.1.1:0@h",
        "ads://5.80.201.232.1.1:x@h",
        "ads://5.80.201.232.1.1@h:99999",
        "modbus://5.80.201.232.1.1@h",
        "ads://5.80.201.232.1.1@h/path",
    ],
)
def test_bad_endpoints_are_one_line_config_errors(endpoint: str) -> None:
    with pytest.raises(ConfigError, match="ADS endpoint") as err:
        parse_endpoint(endpoint)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[signals]\nx = { symbol = "A", type = "LREAL" }', "unknown signal 'x'"),
        ('[signals]\nx_mm = { symbol = "A", type = "FLOAT" }', "type 'FLOAT' is not one of"),
        ('[signals]\nx_mm = { symbol = "A", type = "LREAL", unit = "m" }', "unit 'm'"),
        ('[signals]\nx_mm = { symbol = "A", type = "INT", scale = 0 }', "scale 0"),
        ('[signals]\nx_mm = { symbol = "", type = "INT" }', "symbol ''"),
        ('[signals]\nx_mm = { symbol = "A", type = "INT", offset = 1 }', "unknown key"),
        ('[commands]\nx_mm = { symbol = "A", type = "LREAL" }', "unknown command 'x_mm'"),
        ('[signal]\nx_mm = { symbol = "A", type = "LREAL" }', "unknown table"),
        ("[signals]\n", "maps no signal"),
        ("[signals\n", "not TOML"),
    ],
)
def test_bad_symbol_maps_are_one_line_config_errors(
    tmp_path: Path, text: str, message: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match=message) as err:
        load_symbol_map(path)
    assert "\n" not in str(err.value) and "bad.toml" in str(err.value)


def test_encoding_refuses_what_the_type_cannot_hold() -> None:
    symbols = parse_symbol_map(
        {"signals": {"tool_number": {"symbol": "A", "type": "UINT", "scale": 0.01}}}, "m"
    )
    symbol = symbols.signals["tool_number"]
    assert symbol.encode(655.35) == struct.pack("<H", 65535)
    for value in (655.36, -0.01, math.inf, math.nan):
        with pytest.raises(ValueError):
            symbol.encode(value)


def test_the_shipped_maps_load_and_the_default_covers_every_signal() -> None:
    from cnctwin.thread import COMMANDS, SIGNALS, default_symbol_map

    default = default_symbol_map()
    assert set(default.signals) == set(SIGNALS)
    assert set(default.commands) == set(COMMANDS)
    repo = Path(__file__).resolve().parents[2]
    example = load_symbol_map(repo / "examples/ads/twincat_nc_symbols.toml")
    assert example.readback("feed_override_pct").symbol == "GVL_Axes.stAxisX.PlcToNc.Override"
    assert "emergency_stop" not in example.commands


def test_the_virtual_machine_server_obeys_pyads_own_client_and_refuses_out_of_range() -> None:
    from cnctwin.virtual import AdsMachineServer

    class Machine:
        def __init__(self) -> None:
            self.values = {"feed_override_pct": 100.0, "heartbeat": 3.0, "run_state": 1.0}

        def snapshot(self) -> dict[str, float]:
            return dict(self.values)

        def command(self, name: str, value: float) -> None:
            if not 0.0 <= value <= 150.0:
                raise ConfigError(f"{name}={value} out of range")
            self.values[name] = value

    machine = Machine()

    async def main() -> None:
        async with AdsMachineServer(machine) as server:
            plc = pyads.Connection(NET_ID, 851, f"127.0.0.1:{server.port}")
            plc.set_timeout(2000)

            def by_name() -> None:
                with plc:
                    plc.write_by_name("GVL_Twin.fFeedOverrideCmd", 55.0, pyads.PLCTYPE_LREAL)
                    with pytest.raises(pyads.ADSError, match="1803"):
                        plc.write_by_name("GVL_Twin.fFeedOverrideCmd", 400.0, pyads.PLCTYPE_LREAL)
                    with pytest.raises(pyads.ADSError, match="1827"):  # a reading, not a command
                        plc.write_by_name("GVL_Twin.fFeedOverride", 1.0, pyads.PLCTYPE_LREAL)
                    assert plc.read_by_name("GVL_Twin.fFeedOverride", pyads.PLCTYPE_LREAL) == 55.0

            await asyncio.to_thread(by_name)

    asyncio.run(asyncio.wait_for(main(), BODY_S))
    assert machine.values["feed_override_pct"] == 55.0


def test_the_virtual_ads_server_listens_on_loopback_unless_told_insecure() -> None:
    from cnctwin.virtual import AdsMachineServer

    class Machine:
        def snapshot(self) -> dict[str, float]:
            return {}

        def command(self, name: str, value: float) -> None:
            raise AssertionError("no command expected")

    with pytest.raises(ConfigError, match="ADS has no security.*--insecure"):
        AdsMachineServer(Machine(), host="0.0.0.0")
