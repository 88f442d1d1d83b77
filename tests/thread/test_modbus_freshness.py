"""Modbus carries no time stamps: the heartbeat register is the reading's sample counter."""

from __future__ import annotations

from test_modbus import FakeMachine, run

from cnctwin.thread.modbus import ModbusConnection
from cnctwin.twin.freshness import Freshness
from cnctwin.virtual.modbus_server import ModbusMachineServer


def test_the_heartbeat_register_tells_a_new_sample_from_a_repeat() -> None:
    machine = FakeMachine()

    async def body(server: ModbusMachineServer, connection: ModbusConnection) -> None:
        judge = Freshness(60.0)
        first = await connection.read()
        assert first.source_time_s is None and first.sequence == machine.values["heartbeat"]
        assert judge.check(first).new
        repeat = await connection.read()  # the machine did not tick: the same counter
        check = judge.check(repeat)
        assert not check.new and check.basis == "sample counter"
        machine.values["heartbeat"] += 1.0
        server.publish()
        assert judge.check(await connection.read()).new

    run(body, machine)
