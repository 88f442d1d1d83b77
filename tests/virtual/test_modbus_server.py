"""The Modbus TCP machine server, checked with a plain pymodbus client on loopback.

The client decodes registers with pymodbus' own converters (not cnctwin's), so the register map
of docs/modbus.md is checked from the other side of the protocol.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable

import numpy as np
import pytest
from pymodbus.client import AsyncModbusTcpClient

from cnctwin.errors import ConfigError
from cnctwin.thread.modbus_map import READ_MAP
from cnctwin.thread.signals import COMMANDS, SIGNALS
from cnctwin.virtual.modbus_server import ModbusMachineServer

DT = AsyncModbusTcpClient.DATATYPE
ILLEGAL_ADDRESS = 2
ILLEGAL_DATA_VALUE = 3


class FakeMachine:
    """A machine with fixed signals; commands are range-checked and ``stop`` latches."""

    def __init__(self) -> None:
        self.values: dict[str, float] = {
            name: 1000.0 * (i + 1) / 7.0 - 500.0 for i, name in enumerate(SIGNALS)
        }
        self.values.update(
            t_s=12.375, program_line=70000.0, heartbeat=4_000_000_000.0, tool_number=3.0,
            work_offset=1.0, run_state=1.0, feed_override_pct=100.0, spindle_override_pct=100.0,
            feed_hold=0.0, stop=0.0, emergency_stop=0.0, tool_length_wear_mm=0.0,
            tool_radius_wear_mm=0.0,
        )  # fmt: skip
        self.commands: list[tuple[str, float]] = []

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        if name == "stop" and self.values["stop"] and not value:
            raise ConfigError("stop is latched: cannot write stop=0")
        self.commands.append((name, value))
        self.values[name] = value


def run(body: Callable[[ModbusMachineServer, AsyncModbusTcpClient], Awaitable[None]],
        machine: FakeMachine | None = None) -> FakeMachine:  # fmt: skip
    """Run ``body(server, client)`` against a fresh server on a free port, 20 s at most."""
    machine = machine or FakeMachine()

    async def main() -> None:
        async with ModbusMachineServer(machine) as server:
            client = AsyncModbusTcpClient("127.0.0.1", port=server.port, timeout=2.0, retries=0)
            assert await client.connect()
            try:
                await body(server, client)
            finally:
                client.close()

    asyncio.run(asyncio.wait_for(main(), 20.0))
    return machine


def decode(registers: list[int], address: int, type_: str) -> float:
    """Decode the documented register type with pymodbus' converter."""
    datatype = {"float32": DT.FLOAT32, "uint32": DT.UINT32, "uint16": DT.UINT16}[type_]
    words = registers[address : address + datatype.value[1]]
    return float(AsyncModbusTcpClient.convert_from_registers(words, datatype))  # type: ignore[arg-type]


def test_server_listens_on_a_free_port_and_names_its_endpoint() -> None:
    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        assert server.port > 0
        assert server.endpoint == f"modbus://127.0.0.1:{server.port}"

    run(body)


def test_every_signal_is_in_one_input_register_block() -> None:
    machine = FakeMachine()

    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        end = max(a.address + a.width for a in READ_MAP.values())
        response = await client.read_input_registers(0, count=end, device_id=1)
        assert not response.isError()
        assert set(READ_MAP) == set(SIGNALS)
        for name, addr in READ_MAP.items():
            got = decode(response.registers, addr.address, addr.type)
            expected = machine.values[name]
            if addr.type == "float32":
                expected = float(np.float32(expected))  # what float32 can hold
            assert got == expected, name
        assert server.request_counts[4] == 1

    run(body, machine)


def test_publish_refreshes_the_block_and_marks_garbage_invalid() -> None:
    machine = FakeMachine()

    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        machine.values.update(x_mm=-42.25, force_x_n=math.nan, tool_number=math.nan,
                              program_line=-5.0, run_state=7.0)  # fmt: skip
        before = await client.read_input_registers(2, count=2, device_id=1)
        assert decode(before.registers, 0, "float32") != -42.25  # not published yet
        server.publish()
        regs = (await client.read_input_registers(0, count=49, device_id=1)).registers
        assert decode(regs, READ_MAP["x_mm"].address, "float32") == -42.25
        assert math.isnan(decode(regs, READ_MAP["force_x_n"].address, "float32"))
        assert regs[READ_MAP["tool_number"].address] == 0xFFFF  # NaN in an int register
        pl = READ_MAP["program_line"].address
        assert regs[pl : pl + 2] == [0xFFFF, 0xFFFF]  # negative in a uint32
        assert regs[READ_MAP["run_state"].address] == 7  # representable: the client judges it
        server.publish({"x_mm": 1.5})  # a snapshot without the other signals
        regs = (await client.read_input_registers(0, count=49, device_id=1)).registers
        assert decode(regs, READ_MAP["x_mm"].address, "float32") == 1.5
        assert math.isnan(decode(regs, READ_MAP["t_s"].address, "float32"))

    run(body, machine)


@pytest.mark.parametrize(
    ("name", "address", "raw", "value"),
    [
        ("feed_override_pct", 0, 5000, 50.0),
        ("feed_override_pct", 0, 15000, 150.0),
        ("spindle_override_pct", 1, 8050, 80.5),
        ("tool_length_wear_mm", 2, 0x10000 - 250, -0.025),  # int16 -250 x 0.0001 mm
        ("tool_radius_wear_mm", 3, 1234, 0.1234),
    ],
)
def test_holding_register_write_is_applied_and_read_back(
    name: str, address: int, raw: int, value: float
) -> None:
    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        response = await client.write_register(address, raw, device_id=1)
        assert not response.isError()
        assert response.registers == [raw]
        hr = await client.read_holding_registers(address, count=1, device_id=1)
        assert hr.registers == [raw]
        ir = await client.read_input_registers(READ_MAP[name].address, count=2, device_id=1)
        assert decode(ir.registers, 0, "float32") == float(np.float32(value))

    machine = run(body)
    assert machine.commands == [(name, pytest.approx(value, abs=1e-12))]
    assert machine.values[name] == pytest.approx(value, abs=1e-12)


@pytest.mark.parametrize(("name", "coil"), [("feed_hold", 0), ("stop", 1)])
def test_coil_write_is_applied_and_read_back(name: str, coil: int) -> None:
    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        assert not (await client.write_coil(coil, True, device_id=1)).isError()
        assert (await client.read_coils(coil, count=1, device_id=1)).bits[0] is True
        assert (await client.read_discrete_inputs(coil, count=1, device_id=1)).bits[0] is True
        ir = await client.read_input_registers(READ_MAP[name].address, count=1, device_id=1)
        assert ir.registers == [1]

    machine = run(body)
    assert machine.commands == [(name, 1.0)]


def test_multi_register_write_applies_every_command() -> None:
    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        response = await client.write_registers(0, [7000, 11000], device_id=1)
        assert not response.isError()
        assert (await client.read_holding_registers(0, count=4, device_id=1)).registers == [
            7000, 11000, 0, 0
        ]  # fmt: skip

    machine = run(body)
    assert machine.commands == [("feed_override_pct", 70.0), ("spindle_override_pct", 110.0)]


@pytest.mark.parametrize(
    ("write", "code"),
    [
        (("register", 0, 15001), ILLEGAL_DATA_VALUE),  # feed override 150.01 % > 150 %
        (("register", 1, 4999), ILLEGAL_DATA_VALUE),  # spindle override 49.99 % < 50 %
        (("register", 2, 10001), ILLEGAL_DATA_VALUE),  # tool length wear 1.0001 mm
        (("register", 3, 0x8000), ILLEGAL_DATA_VALUE),  # the int16 "invalid" marker
        (("registers", 0, [5000, 2000]), ILLEGAL_DATA_VALUE),  # second value bad: none applied
        (("register", 4, 1), ILLEGAL_ADDRESS),  # past the command registers
        (("coil", 5, True), ILLEGAL_ADDRESS),  # an unmapped coil
    ],
)
def test_invalid_write_is_refused_with_an_exception_and_changes_nothing(
    write: tuple[str, int, object], code: int
) -> None:
    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        kind, address, value = write
        call = {
            "register": client.write_register,
            "registers": client.write_registers,
            "coil": client.write_coil,
        }[kind]
        response = await call(address, value, device_id=1)  # type: ignore[operator]
        assert response.isError()
        assert response.exception_code == code
        hr = await client.read_holding_registers(0, count=4, device_id=1)
        assert hr.registers == [10000, 10000, 0, 0]  # still answering, nothing changed

    machine = run(body)
    assert machine.commands == []


def test_a_write_the_machine_refuses_is_an_exception_and_read_back_shows_the_machine() -> None:
    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        assert not (await client.write_coil(1, True, device_id=1)).isError()
        response = await client.write_coil(1, False, device_id=1)  # stop is latched
        assert response.isError()
        assert response.exception_code == ILLEGAL_DATA_VALUE
        assert (await client.read_coils(1, count=1, device_id=1)).bits[0] is True

    machine = run(body)
    assert machine.values["stop"] == 1.0


def test_command_ranges_match_the_canonical_signals() -> None:
    # The refusals above are the ranges of COMMANDS; check the map covers them all.
    from cnctwin.thread.modbus_map import WRITE_MAP

    assert set(WRITE_MAP) == set(COMMANDS)
    for name, addr in WRITE_MAP.items():
        spec = COMMANDS[name]
        assert addr.decode(addr.encode(spec.high or 0.0)) == pytest.approx(spec.high)
        assert addr.decode(addr.encode(spec.low or 0.0)) == pytest.approx(spec.low)


def test_a_flood_of_1000_writes_leaves_the_server_answering() -> None:
    n = 1000

    async def body(server: ModbusMachineServer, client: AsyncModbusTcpClient) -> None:
        raws = [(i * 37) % 15001 for i in range(n)]
        # 10 connections writing at once, 100 writes each, none waiting for the others
        clients = [client] + [
            AsyncModbusTcpClient("127.0.0.1", port=server.port, timeout=5.0, retries=0)
            for _ in range(9)
        ]
        for extra in clients[1:]:
            assert await extra.connect()

        async def writer(k: int) -> None:
            for raw in raws[k::10]:
                response = await clients[k].write_register(0, raw, device_id=1)
                assert not response.isError()

        try:
            await asyncio.gather(*(writer(k) for k in range(10)))
        finally:
            for extra in clients[1:]:
                extra.close()
        assert server.request_counts[6] == n
        final = await client.write_register(0, 4321, device_id=1)
        assert final.registers == [4321]
        ir = await client.read_input_registers(READ_MAP["feed_override_pct"].address, count=2)
        assert decode(ir.registers, 0, "float32") == float(np.float32(43.21))

    machine = run(body)
    assert len(machine.commands) == n + 1
