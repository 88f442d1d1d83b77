"""ModbusConnection against the real Modbus machine server on loopback.

The server counts the requests it receives, so batching is checked from the server's side;
values are compared with what the machine (a fake with known signals) holds.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Awaitable, Callable

import numpy as np
import pytest
from timeouts import BODY_S

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread import ConnectionLost, ConnectionState
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import CommandRejected
from cnctwin.thread.modbus import ModbusConnection, parse_endpoint
from cnctwin.thread.modbus_map import RegisterAddress, parse_address, plan_reads
from cnctwin.thread.signals import COMMANDS, SIGNALS
from cnctwin.virtual.modbus_server import ModbusMachineServer


class FakeMachine:
    """A machine with fixed signals; commands are range-checked and ``stop`` latches."""

    def __init__(self) -> None:
        self.values: dict[str, float] = {
            name: 1000.0 * (i + 1) / 7.0 - 500.0 for i, name in enumerate(SIGNALS)
        }
        self.values.update(
            t_s=3.5, spindle_rpm=9600.0, program_line=120.0, heartbeat=17.0, tool_number=4.0,
            work_offset=2.0, run_state=1.0, feed_override_pct=100.0, spindle_override_pct=100.0,
            feed_hold=0.0, stop=0.0, emergency_stop=0.0, tool_length_wear_mm=0.0,
            tool_radius_wear_mm=0.0,
        )  # fmt: skip

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        spec = COMMANDS[name]
        assert spec.low is not None and spec.high is not None
        if not spec.low <= value <= spec.high:
            raise ConfigError(f"{name}={value} outside {spec.low}..{spec.high}")
        if name == "stop" and self.values["stop"] and not value:
            raise ConfigError("stop is latched")
        self.values[name] = value


def config(endpoint: str, **kwargs: object) -> ConnectionConfig:
    return ConnectionConfig(
        transport="modbus", endpoint=endpoint, timeout_s=1.0, reconnect_initial_s=0.05,
        reconnect_max_s=0.2, **kwargs,  # type: ignore[arg-type]
    )  # fmt: skip


def run(
    body: Callable[[ModbusMachineServer, ModbusConnection], Awaitable[None]],
    machine: FakeMachine | None = None,
    mapping: dict[str, str] | None = None,
) -> None:
    """Run ``body(server, connection)`` against a fresh server on a free port, 20 s at most."""
    machine = machine or FakeMachine()

    async def main() -> None:
        async with ModbusMachineServer(machine) as server:
            connection = ModbusConnection(config(server.endpoint, mapping=mapping or {}))
            async with connection:
                await body(server, connection)

    asyncio.run(asyncio.wait_for(main(), 20.0))


def as_float32(value: float) -> float:
    return float(np.float32(value))


def reads(server: ModbusMachineServer) -> int:
    return sum(server.request_counts[code] for code in (1, 2, 3, 4))


def test_one_request_reads_every_signal_and_each_equals_the_machine() -> None:
    machine = FakeMachine()

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        assert connection.state is ConnectionState.CONNECTED
        reading = await connection.read()
        assert reads(server) == 1 and server.request_counts[4] == 1
        assert reading.rejected == {}
        assert set(reading.values) == set(SIGNALS)
        for name, value in reading.values.items():
            assert value == as_float32(machine.values[name]), name

    run(body, machine)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("feed_override_pct", 42.5),
        ("feed_override_pct", 0.0),
        ("spindle_override_pct", 120.0),
        ("tool_length_wear_mm", -0.0125),
        ("tool_radius_wear_mm", 0.3),
        ("feed_hold", 1.0),
        ("stop", 1.0),
    ],
)
def test_each_command_is_written_and_read_back(name: str, value: float) -> None:
    machine = FakeMachine()

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        await connection.write(name, value)
        assert machine.values[name] == pytest.approx(value, abs=1e-12)
        reading = await connection.read()
        assert reading.values[name] == as_float32(value)

    run(body, machine)


def test_write_read_back_writes_then_reads_the_feedback() -> None:
    """The default write and read-back of a connection: the read after the write's answer."""
    machine = FakeMachine()

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        before = reads(server)
        back = await connection.write_read_back("feed_override_pct", 42.0)
        assert back.value == 42.0 == machine.values["feed_override_pct"]
        assert back.write_s > 0 and back.read_s > 0
        assert reads(server) == before + 1  # one read, after the write's answer
        with pytest.raises(CommandRejected, match="ILLEGAL DATA VALUE"):
            await connection.write_read_back("feed_override_pct", 151.0)

    run(body, machine)


def test_a_refused_write_raises_one_line_and_keeps_the_connection() -> None:
    machine = FakeMachine()

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        with pytest.raises(CommandRejected, match=r"feed_override_pct=151.*ILLEGAL DATA VALUE"):
            await connection.write("feed_override_pct", 151.0)
        await connection.write("stop", 1.0)
        with pytest.raises(CommandRejected, match="refused command stop=0"):
            await connection.write("stop", 0.0)
        writes = server.request_counts[6]
        with pytest.raises(CommandRejected, match="does not fit uint16"):
            await connection.write("feed_override_pct", 1000.0)  # 100000 raw: not sent
        assert server.request_counts[6] == writes
        assert connection.state is ConnectionState.CONNECTED
        reading = await connection.read()
        assert reading.values["feed_override_pct"] == 100.0
        assert reading.values["stop"] == 1.0

    run(body, machine)
    assert machine.values["feed_override_pct"] == 100.0


def test_read_signal_reads_only_that_signal() -> None:
    machine = FakeMachine()
    machine.values["force_x_n"] = math.nan

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        await connection.write("feed_override_pct", 33.3)
        assert await connection.read_signal("feed_override_pct") == as_float32(33.3)
        assert reads(server) == 1
        with pytest.raises(DataError, match=r"'force_x_n' unusable: not a finite number"):
            await connection.read_signal("force_x_n")

    run(body, machine)


def test_mapping_overrides_address_scale_and_command_register() -> None:
    machine = FakeMachine()
    mapping = {
        "x_mm": "ir:4:float32",  # x and y swapped: the override is really used
        "y_mm": " ir:2:FLOAT32 ",
        "spindle_rpm": "IR:10:float32:0.5",
        "feed_override_pct": "hr:0:uint16:0.01",  # read back from the holding register
        "stop": "none",  # the last register of the block: the rest stays contiguous
    }

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        await connection.write("feed_override_pct", 75.25)
        before = reads(server)
        reading = await connection.read()
        assert reads(server) - before == 2  # the input block (across 32-33) and the hr
        assert server.request_counts[3] == 1
        assert reading.values["x_mm"] == as_float32(machine.values["y_mm"])
        assert reading.values["y_mm"] == as_float32(machine.values["x_mm"])
        assert reading.values["spindle_rpm"] == 4800.0
        assert reading.values["feed_override_pct"] == 75.25
        assert "stop" not in reading.values and "stop" not in reading.rejected
        with pytest.raises(ConfigError, match="command 'stop' has no Modbus address"):
            await connection.write("stop", 1.0)

    run(body, machine, mapping)


@pytest.mark.parametrize(
    ("mapping", "message"),
    [
        ({"x_mm": "ir:2"}, r"'ir:2' of signal 'x_mm': 2 field\(s\)"),
        ({"x_mm": "xx:2:float32"}, r"'xx:2:float32' of signal 'x_mm': table 'xx'"),
        ({"x_mm": "ir:two:float32"}, r"address 'two' is not an integer"),
        ({"x_mm": "ir:2:double"}, r"type 'double' is not one of"),
        ({"feed_hold": "coil:0:uint16"}, r"table coil needs type bool"),
        ({"x_mm": "ir:65535:float32"}, r"address 65535 is outside"),
        ({"x_mm": "ir:2:float32:fast"}, r"scale 'fast' is not a number"),
        ({"x_mm": "ir:2:float32:0"}, r"scale '0' must be a finite non-zero"),
        ({"x_position": "ir:2:float32"}, r"unknown signal 'x_position'"),
        ({"stop": "di:1:bool"}, r"command 'stop' is in read-only table 'di'"),
    ],
)
def test_bad_mapping_strings_are_one_line_errors(mapping: dict[str, str], message: str) -> None:
    with pytest.raises(ConfigError, match=message) as info:
        ModbusConnection(config("modbus://127.0.0.1:5020", mapping=mapping))
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "endpoint", ["opc.tcp://127.0.0.1:4840", "modbus://:502", "modbus://h:port", "modbus://h/x"]
)
def test_bad_endpoint_is_a_config_error(endpoint: str) -> None:
    with pytest.raises(ConfigError, match="modbus://HOST:PORT"):
        ModbusConnection(config(endpoint))


def test_endpoint_port_defaults_to_502_and_transport_must_be_modbus() -> None:
    assert parse_endpoint("modbus://plc.local") == ("plc.local", 502)
    with pytest.raises(ConfigError, match="transport 'opcua'"):
        ModbusConnection(ConnectionConfig(transport="opcua", endpoint="modbus://h:1"))


def test_plan_reads_bridges_gaps_up_to_the_protocol_limit() -> None:
    def ir(address: int, type_: str = "float32") -> RegisterAddress:
        return RegisterAddress("ir", address, type_)

    # 0-1, 2-3 touch, 3 overlaps; a gap to 10; 10..139 touching, more than 125 registers
    addresses = {"a": ir(0), "b": ir(2), "c": ir(3, "uint16"), "d": ir(10), "e": ir(12),
                 "f": ir(136), "g": ir(137), "h": RegisterAddress("coil", 3, "bool"),
                 "i": RegisterAddress("coil", 1999, "bool")}  # fmt: skip
    addresses.update({f"r{k}": ir(12 + 2 * k) for k in range(1, 62)})
    bridged = [(b.table, b.start, b.count, b.bridges_gaps) for b in plan_reads(addresses)]
    assert bridged == [("ir", 0, 124, True), ("ir", 124, 15, False), ("coil", 3, 1997, True)]
    strict = [(b.table, b.start, b.count) for b in plan_reads(addresses, bridge_gaps=False)]
    assert strict == [("ir", 0, 4), ("ir", 10, 124), ("ir", 134, 5), ("coil", 3, 1),
                      ("coil", 1999, 1)]  # fmt: skip
    assert parse_address("coil:3:bool", "h") == addresses["h"]


def test_a_refused_read_across_a_gap_falls_back_to_contiguous_blocks() -> None:
    mapping = {"force_z_n": "ir:60:float32"}  # the server has no registers 49..59

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        assert len(connection.blocks) == 1  # 0..61 in one request, planned
        first = await connection.read()
        assert reads(server) == 1 + 3  # refused, then 0-29, 32-48 and 60-61
        assert set(first.rejected) == {"force_z_n"}
        assert "ILLEGAL DATA ADDRESS" in first.rejected["force_z_n"]
        second = await connection.read()
        assert reads(server) == 4 + 3  # the fallback plan is kept
        assert second.values == first.values and len(second.values) == len(SIGNALS) - 1

    run(body, mapping=mapping)


def test_garbage_values_are_rejected_not_raised() -> None:
    machine = FakeMachine()
    machine.values.update(force_x_n=math.nan, force_y_n=math.inf, run_state=9.0,
                          tool_number=math.nan, work_offset=0.0)  # fmt: skip
    mapping = {"force_z_n": "ir:300:float32"}  # an address the device does not have

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        reading = await connection.read()
        assert set(reading.rejected) == {
            "force_x_n", "force_y_n", "run_state", "tool_number", "work_offset", "force_z_n"
        }  # fmt: skip
        assert "not a finite number (nan)" in reading.rejected["force_x_n"]
        assert "not a finite number (inf)" in reading.rejected["force_y_n"]
        assert "9 outside the plausible range 0..5" in reading.rejected["run_state"]
        assert "device marked the value invalid" in reading.rejected["tool_number"]
        assert "ILLEGAL DATA ADDRESS" in reading.rejected["force_z_n"]
        assert not set(reading.rejected) & set(reading.values)
        assert len(reading.values) == len(SIGNALS) - 6
        assert reading.values["x_mm"] == as_float32(machine.values["x_mm"])
        assert connection.state is ConnectionState.CONNECTED

    run(body, machine, mapping)


def test_server_restart_mid_run_reconnects_and_reads_go_on() -> None:
    machine = FakeMachine()

    async def wait_for_state(connection: ModbusConnection, state: ConnectionState) -> None:
        while connection.state is not state:
            await asyncio.sleep(0.01)

    async def main() -> list[ConnectionState]:
        seen: list[ConnectionState] = []
        server = ModbusMachineServer(machine)
        await server.start()
        port = server.port
        # a request timeout far beyond any delay of a loaded machine: "at once" below is then
        # told from "after the timeout" by a wide margin
        cfg = config(server.endpoint).model_copy(update={"timeout_s": 60.0})
        connection = ModbusConnection(cfg)
        async with connection:
            machine.values["heartbeat"] = 1.0
            server.publish()
            assert (await connection.read()).values["heartbeat"] == 1.0
            await server.stop()
            lost_at = time.perf_counter()
            with pytest.raises(ConnectionLost, match="closed by the device"):
                await connection.read()
            assert time.perf_counter() - lost_at < 30.0  # seen at once, not after timeout_s
            seen.append(connection.state)
            await asyncio.sleep(0.3)  # several failed attempts against a closed port
            assert connection.state is ConnectionState.RECONNECTING
            with pytest.raises(ConnectionLost, match="not connected"):
                await connection.read()
            restarted = ModbusMachineServer(machine, port=port)
            async with restarted:
                machine.values["heartbeat"] = 2.0
                restarted.publish()
                await asyncio.wait_for(
                    wait_for_state(connection, ConnectionState.CONNECTED), BODY_S
                )
                seen.append(connection.state)
                assert (await connection.read()).values["heartbeat"] == 2.0
                await connection.write("feed_override_pct", 60.0)
                assert (await connection.read()).values["feed_override_pct"] == 60.0
            assert connection.reconnects == 1
        assert connection.state is ConnectionState.CLOSED
        return seen

    seen = asyncio.run(asyncio.wait_for(main(), BODY_S))
    assert seen == [ConnectionState.RECONNECTING, ConnectionState.CONNECTED]


def test_connect_to_nothing_is_connection_lost() -> None:
    async def main() -> None:
        probe = ModbusMachineServer(FakeMachine())
        await probe.start()
        port = probe.port
        await probe.stop()  # a port nobody listens on
        connection = ModbusConnection(config(f"modbus://127.0.0.1:{port}"))
        with pytest.raises(ConnectionLost, match="cannot connect"):
            await connection.connect()
        assert connection.state is ConnectionState.DISCONNECTED

    asyncio.run(asyncio.wait_for(main(), 10.0))


def test_the_virtual_machine_over_modbus_reads_its_snapshot_and_obeys_commands() -> None:
    from cnctwin.virtual import MachineClock, VirtualMachine, VirtualMachineConfig

    vm = VirtualMachine(VirtualMachineConfig())

    async def main() -> None:
        async with ModbusMachineServer(vm) as server:
            clock = MachineClock(vm, vm.tick_s, speed=1.0)
            clock.add_listener(server.publish)
            async with ModbusConnection(config(server.endpoint)) as connection:
                async with clock:
                    first = await connection.read()
                    await asyncio.sleep(0.2)
                    await connection.write("feed_override_pct", 50.0)
                    await asyncio.sleep(0.1)
                    second = await connection.read()
                    await connection.write("stop", 1.0)
                    await asyncio.sleep(0.1)
                last = await connection.read()  # clock stopped: the last published tick
        assert second.values["heartbeat"] > first.values["heartbeat"]
        assert second.values["feed_override_pct"] == 50.0
        assert last.rejected == {}
        snapshot = vm.snapshot()
        for name in SIGNALS:
            assert last.values[name] == as_float32(snapshot[name]), name
        assert last.values["stop"] == 1.0 and last.values["run_state"] == 3.0  # STOPPED

    asyncio.run(asyncio.wait_for(main(), 20.0))


def test_a_device_that_accepts_but_never_answers_times_out() -> None:
    async def main() -> None:
        accepted: list[asyncio.StreamWriter] = []

        async def swallow(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            accepted.append(writer)
            await reader.read()  # read requests, never answer

        silent = await asyncio.start_server(swallow, "127.0.0.1", 0)
        port = silent.sockets[0].getsockname()[1]
        cfg = config(f"modbus://127.0.0.1:{port}").model_copy(update={"timeout_s": 0.2})
        async with silent, ModbusConnection(cfg) as connection:
            started = time.perf_counter()
            with pytest.raises(ConnectionLost, match="read failed"):
                await connection.read()
            # not before the timeout (0.2 s, less the clock's slack); how soon after it depends
            # on the load, and the body's limit ends a read that never times out
            assert time.perf_counter() - started > 0.15
            assert connection.state is ConnectionState.RECONNECTING
        for writer in accepted:
            writer.close()
            await writer.wait_closed()

    asyncio.run(asyncio.wait_for(main(), BODY_S))
