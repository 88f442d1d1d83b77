"""Tool wear-offset writes: the safety filter's bounds, the write and read-back over OPC UA and
Modbus TCP (the virtual machine's servers on loopback), the refusal of read-only transports, and
the lost-machine policy for an offset."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager

import pytest

from cnctwin.control import ControlConfig, Decision, LostMachinePolicy, SafetyFilter
from cnctwin.control.safety import Commanded
from cnctwin.errors import InputError
from cnctwin.thread import ConnectionConfig, MachineConnection
from cnctwin.thread.signals import SIGNALS
from cnctwin.twin import RunConfig, apply_correction, open_connection, write_tool_offset
from cnctwin.virtual.machine import check_command
from cnctwin.virtual.modbus_server import ModbusMachineServer
from cnctwin.virtual.mtconnect_agent import MTConnectAgent
from cnctwin.virtual.opcua_server import OpcUaMachineServer, free_port
from cnctwin.virtual.users import UserTable

ENABLED = ControlConfig(enabled=True)


class Machine:
    """A machine with tool 3 active and the virtual machine's range check of commands."""

    def __init__(self, radius_wear_mm: float = 0.0) -> None:
        self.values = dict.fromkeys(SIGNALS, 0.0)
        self.values.update(tool_number=3.0, run_state=1.0, feed_override_pct=100.0)
        self.values["spindle_override_pct"] = 100.0
        self.values["work_offset"] = 1.0
        self.values["tool_radius_wear_mm"] = radius_wear_mm
        self.commands: list[tuple[str, float]] = []

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)

    def command(self, name: str, value: float) -> None:
        self.values[name] = check_command(name, value)
        self.commands.append((name, value))


def _decision(value: float | None) -> Decision:
    return Decision(0.0, "wear_compensation", "tool_offset", value, "part 7 measured")


def test_the_filter_bounds_each_step_and_the_total() -> None:
    readback = {"tool_number": 3.0, "tool_radius_wear_mm": 0.28}
    cases = [
        (ControlConfig(), 3, 0.27, "blocked", "control disabled"),
        (ENABLED, 4, 0.27, "blocked", "T4 is not the machine's active tool (T3)"),
        (ENABLED, 3, 0.20, "blocked", "step -0.08 mm from 0.28 mm exceeds max_step_mm = 0.05"),
        (ENABLED, 3, 0.31, "blocked", "0.31 mm exceeds max_total_mm = 0.3"),
        (ENABLED, 3, float("nan"), "blocked", "not finite"),
        (ENABLED, 3, 0.28, "duplicate", "the machine shows it"),
        (ENABLED, 3, 0.27, "sent", ""),
    ]
    for config, tool, value, outcome, note in cases:
        verdict = SafetyFilter(config).check_offset(
            _decision(value), "tool_radius_wear_mm", tool, readback
        )
        assert (verdict.outcome, verdict.send) == (outcome, outcome == "sent")
        assert note in verdict.note
    unread = SafetyFilter(ENABLED).check_offset(
        _decision(0.0), "tool_radius_wear_mm", 3, {"tool_number": 3.0}
    )
    assert unread.outcome == "blocked" and "cannot be bounded" in unread.note


def test_a_lost_connection_never_repeats_an_offset_write() -> None:
    commanded = {"tool_radius_wear_mm": Commanded(-0.01, 1.0, confirmed=False)}
    policy = LostMachinePolicy()
    (note,) = policy.plan(commanded, {"tool_radius_wear_mm": 0.0})
    assert note.value is None and "left as the machine has it" in note.reason
    assert policy.plan(commanded, {"tool_radius_wear_mm": -0.01}) == []
    safety = SafetyFilter(ENABLED)
    safety.commanded.update(commanded)
    (verdict,) = safety.after_reconnect({"tool_radius_wear_mm": 0.0}, 2.0)
    assert not verdict.send and verdict.outcome == "recorded"
    assert verdict.decision.action == "tool_offset"


@asynccontextmanager
async def _opcua(machine: Machine, role: str) -> AsyncIterator[ConnectionConfig]:
    async with OpcUaMachineServer(machine, users=UserTable(anonymous=role)) as server:

        async def publish() -> None:
            while True:
                server.publish(machine.snapshot())
                await asyncio.sleep(0.005)

        task = asyncio.get_running_loop().create_task(publish())
        try:
            yield ConnectionConfig(transport="opcua", endpoint=server.endpoint)
        finally:
            task.cancel()


@asynccontextmanager
async def _modbus(machine: Machine, role: str) -> AsyncIterator[ConnectionConfig]:
    async with ModbusMachineServer(machine) as server:
        yield ConnectionConfig(transport="modbus", endpoint=server.endpoint)


def _run(body: Callable[[], Awaitable[None]]) -> None:
    asyncio.run(asyncio.wait_for(body(), 30.0))


async def _write(
    connection: MachineConnection, safety: SafetyFilter, correction_mm: float
) -> dict[str, object]:
    result = await write_tool_offset(
        connection,
        safety,
        tool=3,
        axis="diameter",
        correction_mm=correction_mm,
        reason="Bolyn correction after part 7",
    )
    return result.to_dict()


@pytest.mark.parametrize("serve", [_opcua, _modbus], ids=["opcua", "modbus"])
def test_a_diameter_correction_is_written_as_half_on_the_radius_and_read_back(serve) -> None:  # type: ignore[no-untyped-def]
    machine = Machine(radius_wear_mm=0.012)

    async def body() -> None:
        async with serve(machine, "operator") as config:
            async with open_connection(config) as connection:
                result = await _write(connection, SafetyFilter(ENABLED), -0.008)
        assert result["outcome"] == "sent" and result["confirmed"] is True
        assert result["before_mm"] == pytest.approx(0.012, abs=1e-4)
        assert result["readback_mm"] == pytest.approx(0.008, abs=1e-4)
        assert "Bolyn correction after part 7" in str(result["reason"])

    _run(body)
    # a diameter 8 um smaller: the tool moves 4 um toward the axis
    assert machine.commands == [("tool_radius_wear_mm", pytest.approx(0.008, abs=1e-4))]


def test_a_read_only_session_and_a_read_only_transport_refuse_the_write_cleanly() -> None:
    machine = Machine()

    async def body() -> None:
        async with _opcua(machine, "read-only") as config:
            async with open_connection(config) as connection:
                opcua = await _write(connection, SafetyFilter(ENABLED), 0.01)
        agent = MTConnectAgent(machine)
        async with agent:
            agent.publish(machine.snapshot())
            config = ConnectionConfig(transport="mtconnect", endpoint=agent.endpoint)
            async with open_connection(config) as connection:
                await asyncio.sleep(0.2)
                mtconnect = await _write(connection, SafetyFilter(ENABLED), 0.01)
        # the session's role refuses the write: passed by the filter, not carried out
        assert opcua["outcome"] == "sent" and opcua["confirmed"] is False
        assert "BadUserAccessDenied" in str(opcua["error"]) and "\n" not in str(opcua["error"])
        # an MTConnect agent serves no wear offset: the step cannot be bounded, nothing is sent
        assert mtconnect["outcome"] == "blocked" and mtconnect["confirmed"] is False
        assert "no valid tool_radius_wear_mm reading" in str(mtconnect["note"])

    _run(body)
    assert machine.commands == []


def test_with_control_disabled_nothing_connects() -> None:
    async def body() -> None:
        result = await write_tool_offset(
            None, SafetyFilter(ControlConfig()), tool=3, axis="length", correction_mm=0.01,
            reason="part 2",
        )  # fmt: skip
        assert result.verdict.outcome == "blocked" and result.before_mm is None

    _run(body)
    with pytest.raises(InputError, match="'x'"):
        asyncio.run(
            write_tool_offset(
                None,
                SafetyFilter(ENABLED),
                tool=3,
                axis="x",  # type: ignore[arg-type]
                correction_mm=0.01,
                reason="",
            )  # fmt: skip
        )


def test_an_unreachable_machine_leaves_the_offset_unwritten() -> None:
    config = RunConfig.model_validate(
        {
            "connection": {
                "transport": "modbus",
                "endpoint": f"modbus://127.0.0.1:{free_port('127.0.0.1')}",
                "timeout_s": 0.5,
            },
            "control": {"enabled": True},
        }
    )
    result = apply_correction(config, tool=1, axis="radius", correction_mm=0.005, reason="p1")
    assert result.verdict.outcome == "blocked" and result.error and not result.confirmed
