"""The virtual machine's path honours the wear offsets: length along Z, radius under G41/G42.

Closed forms: with cutter radius compensation the tool centre runs at the compensation
radius ``r + w`` from the programmed contour, so a wall cut along X stands ``w`` further out
and the part keeps ``w x length x depth`` more material; the length wear offset lowers or
raises the floor of a face cut by exactly ``w``.
"""

from __future__ import annotations

import asyncio

import pytest
from vm_helpers import MakeVM, run_to_end

from cnctwin.control import ControlConfig, SafetyFilter
from cnctwin.thread import ConnectionConfig
from cnctwin.twin import OffsetWrite, open_connection, write_tool_offset
from cnctwin.virtual import VirtualMachine
from cnctwin.virtual.modbus_server import ModbusMachineServer

#: A wall along X at Y14 (the contour), the 10 mm cutter on its left (+Y side, G41), 5 mm
#: deep through the whole 60 mm block; lead-in and lead-out outside the block.
WALL = (
    "G21 G90 G94 G17\nT1 M6\nS8000 M3\nG0 Z10\nG0 X-20 Y30\nG0 Z-5\n"
    "G41 D1 G1 X-10 Y14 F3000\nG1 X70\nG40 G1 X80 Y40\nG0 Z10\nM30\n"
)
#: The same wall with the cutter on the right of the travel (G42, moving -X).
WALL_RIGHT = (
    "G21 G90 G94 G17\nT1 M6\nS8000 M3\nG0 Z10\nG0 X80 Y30\nG0 Z-5\n"
    "G42 D1 G1 X70 Y14 F3000\nG1 X-10\nG40 G1 X-20 Y40\nG0 Z10\nM30\n"
)
#: A slot 2 mm deep along Y10 without compensation.
FACE = "G21 G90 G94\nT1 M6\nS8000 M3\nG0 Z10\nG0 X-10 Y10\nG0 Z-2\nG1 X70 F3000\nG0 Z10\nM30\n"

_LENGTH_MM = 60.0
_DEPTH_MM = 5.0
#: A coarse stock and tick: the closed forms do not depend on them.
_FAST = {"density_per_mm": 4.0, "tick_ms": 10.0}


def _run(vm: VirtualMachine, **wear: float) -> list[dict[str, float]]:
    for name, value in wear.items():
        vm.command(name, value)
    return run_to_end(vm)


def _y_on_wall(snapshots: list[dict[str, float]]) -> list[float]:
    """The Y axis while the tool runs along the wall (X between the block's ends)."""
    return [s["y_mm"] for s in snapshots if 5.0 < s["x_mm"] < 55.0 and s["z_mm"] < 0.0]


def test_radius_wear_moves_the_compensated_path_and_the_wall(make_vm: MakeVM) -> None:
    wear_mm = 0.3
    plain = make_vm(WALL, **_FAST)
    y_plain = _y_on_wall(_run(plain))
    worn = make_vm(WALL, **_FAST)
    y_worn = _y_on_wall(_run(worn, tool_radius_wear_mm=wear_mm))
    # the cutter's centre: radius 5 on the +Y side of the contour Y14, plus the wear offset
    assert y_plain and y_worn
    assert y_plain == pytest.approx([19.0] * len(y_plain), abs=1e-9)
    assert y_worn == pytest.approx([19.0 + wear_mm] * len(y_worn), abs=1e-9)
    # rays along Y measure the wall's position exactly: it stands wear_mm further out, so the
    # part keeps wear x length x depth more material
    extra = worn.stock.volume_mm3("y") - plain.stock.volume_mm3("y")
    assert extra == pytest.approx(wear_mm * _LENGTH_MM * _DEPTH_MM, rel=1e-6)


def test_radius_wear_follows_the_side_of_g42(make_vm: MakeVM) -> None:
    wear_mm = -0.15
    y = _y_on_wall(_run(make_vm(WALL_RIGHT, **_FAST), tool_radius_wear_mm=wear_mm))
    # moving -X with the cutter on the right: its centre on the +Y side too
    assert y and y == pytest.approx([19.0 + wear_mm] * len(y), abs=1e-9)


def test_length_wear_moves_the_floor_and_radius_wear_needs_compensation(
    make_vm: MakeVM,
) -> None:
    wear_mm = 0.25
    vm = make_vm(FACE, **_FAST)
    snapshots = _run(vm, tool_length_wear_mm=wear_mm, tool_radius_wear_mm=0.5)
    y = [s["y_mm"] for s in snapshots if s["z_mm"] < 0.0]
    assert y and all(value == pytest.approx(10.0, abs=1e-12) for value in y)
    grid = vm.stock.grid
    i = int((30.0 - grid.origin_mm[0]) / grid.pitch_mm[0])
    j = int((10.0 - grid.origin_mm[1]) / grid.pitch_mm[1])
    top = float(vm.stock.ray_intervals_mm("z", i, j)[-1, 1])
    # the slot's floor is 2 mm deep less the offset
    assert top == pytest.approx(-2.0 + wear_mm, abs=1e-4)


def test_a_diameter_correction_written_over_modbus_moves_the_compensated_wall(
    make_vm: MakeVM,
) -> None:
    """End to end: the lathe twin's diameter correction, through the safety filter and Modbus
    TCP, becomes half of it on the radius wear, and the wall the machine cuts stands there."""
    correction_mm = 0.08
    vm = make_vm(WALL, **_FAST)
    while vm.snapshot()["tool_number"] != 1.0:
        vm.step(vm.tick_s)

    async def write() -> OffsetWrite:
        async with ModbusMachineServer(vm) as server:
            config = ConnectionConfig(transport="modbus", endpoint=server.endpoint)
            async with open_connection(config) as connection:
                return await write_tool_offset(
                    connection, SafetyFilter(ControlConfig(enabled=True)), tool=1,
                    axis="diameter", correction_mm=correction_mm, reason="part 1",
                )  # fmt: skip

    result = asyncio.run(asyncio.wait_for(write(), 20.0))
    assert result.confirmed and result.readback_mm == pytest.approx(0.04, abs=1e-4)
    run_to_end(vm)
    plain = make_vm(WALL, **_FAST)
    run_to_end(plain)
    wear_mm = vm.snapshot()["tool_radius_wear_mm"]
    assert wear_mm == pytest.approx(correction_mm / 2.0, abs=1e-4)
    # the wall stands wear_mm further out along the whole 60 mm block, 5 mm deep
    extra = vm.stock.volume_mm3("y") - plain.stock.volume_mm3("y")
    assert extra == pytest.approx(wear_mm * _LENGTH_MM * _DEPTH_MM, rel=1e-6)
