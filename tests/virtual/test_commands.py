"""Commands to the virtual machine: applied at once, read back, invalid ones refused."""

from __future__ import annotations

import math

import pytest
from vm_helpers import MakeVM

from cnctwin.errors import ConfigError
from cnctwin.thread.signals import COMMANDS, SIGNALS

PROGRAM = "G21 G90 G94\nG1 X60 F600\nM30\n"


def test_snapshot_has_every_signal(make_vm: MakeVM) -> None:
    vm = make_vm(PROGRAM)
    vm.step(0.005)
    snapshot = vm.snapshot()
    assert set(snapshot) == set(SIGNALS)
    assert all(isinstance(value, float) and math.isfinite(value) for value in snapshot.values())


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("feed_override_pct", 0.0),
        ("feed_override_pct", 150.0),
        ("spindle_override_pct", 50.0),
        ("spindle_override_pct", 120.0),
        ("tool_length_wear_mm", -0.05),
        ("tool_radius_wear_mm", 0.02),
        ("feed_hold", 1.0),
        ("stop", 1.0),
    ],
)
def test_commands_read_back_at_once(make_vm: MakeVM, name: str, value: float) -> None:
    vm = make_vm(PROGRAM)
    vm.command(name, value)
    assert vm.snapshot()[name] == value
    vm.step(0.005)
    assert vm.snapshot()[name] == value


@pytest.mark.parametrize(
    ("name", "value", "words"),
    [
        ("feed_override_pct", math.nan, ["nan", "0 to 150 %"]),
        ("feed_override_pct", 300.0, ["300", "0 to 150 %"]),
        ("feed_override_pct", -1.0, ["-1", "0 to 150 %"]),
        ("spindle_override_pct", 40.0, ["40", "50 to 120 %"]),
        ("spindle_override_pct", math.inf, ["inf", "50 to 120 %"]),
        ("tool_length_wear_mm", 2.0, ["2", "-1 to 1 mm"]),
        ("feed_hold", 0.5, ["0.5", "0 or 1"]),
        ("stop", 2.0, ["2", "0 or 1"]),
        ("feed_override_pct", "fast", ["'fast'", "0 to 150 %"]),
        ("spindle_rpm", 1000.0, ["'spindle_rpm'", "feed_override_pct", "stop"]),
        ("warp_drive", 1.0, ["'warp_drive'", "valid commands"]),
    ],
)
def test_invalid_commands_are_refused(
    make_vm: MakeVM, name: str, value: object, words: list[str]
) -> None:
    vm = make_vm(PROGRAM)
    before = vm.snapshot()
    with pytest.raises(ConfigError) as info:
        vm.command(name, value)  # type: ignore[arg-type]
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message
    assert vm.snapshot() == before  # nothing applied


def test_every_command_is_accepted_at_its_limits(make_vm: MakeVM) -> None:
    vm = make_vm(PROGRAM)
    for name, spec in COMMANDS.items():
        if name == "stop":
            continue
        assert spec.low is not None and spec.high is not None
        for value in (spec.low, spec.high):
            vm.command(name, value)
            assert vm.snapshot()[name] == value


def test_spindle_override_scales_the_speed(make_vm: MakeVM) -> None:
    vm = make_vm("G21 G90\nS8000 M3\nG4 P3\nM30\n")
    vm.command("spindle_override_pct", 75.0)
    for _ in range(400):
        vm.step(0.005)
    s = vm.snapshot()
    assert s["spindle_rpm_command"] == 6000.0
    assert s["spindle_rpm"] == pytest.approx(6000.0, rel=1e-3)


def test_length_wear_offset_moves_the_z_axis(make_vm: MakeVM) -> None:
    vm = make_vm(PROGRAM)
    vm.command("tool_length_wear_mm", 0.1)
    vm.step(0.005)
    assert vm.snapshot()["z_mm"] == pytest.approx(0.1)
