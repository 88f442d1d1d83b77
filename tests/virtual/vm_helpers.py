"""Helpers for the virtual machine's tests: a small machine, quiet sensors, running to the end."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from cnctwin.config import MachiningConfig
from cnctwin.virtual import NoiseConfig, VirtualMachine

#: No sensor noise: the signals are the physics alone.
QUIET = NoiseConfig(
    position_mm=0.0,
    feed_mm_min=0.0,
    spindle_rpm=0.0,
    force_n=0.0,
    torque_nm=0.0,
    current_a=0.0,
    power_w=0.0,
    load_pct=0.0,
)

#: ``make_vm(program_text, physics_config=None, **virtual_keys)`` (the fixture of conftest.py).
MakeVM = Callable[..., VirtualMachine]

#: Accelerations of the test machine, mm/s^2 (X, Y, Z).
ACCEL_MM_S2 = (2000.0, 2000.0, 1500.0)


def physics(**stock: Any) -> MachiningConfig:
    """A 3-axis mill with a 10 mm, 3-flute end mill (T1) and a block of AA6060-T6.

    The block is 60 x 20 x 10 mm, from (0, 0, -10) to (60, 20, 0) in machine coordinates,
    unless ``stock`` says otherwise; no work or tool offsets, so the axes read the tool tip.
    """
    return MachiningConfig.model_validate(
        {
            "machine": {
                "rapid_mm_min": 6000.0,
                "axes": {
                    axis: {
                        "min_mm": -500.0,
                        "max_mm": 500.0,
                        "max_velocity_mm_min": 12000.0,
                        "max_accel_mm_s2": accel,
                    }
                    for axis, accel in zip("xyz", ACCEL_MM_S2, strict=True)
                },
            },
            "tools": [
                {
                    "number": 1,
                    "kind": "flat",
                    "diameter_mm": 10.0,
                    "flutes": 3,
                    "helix_deg": 45.0,
                    "flute_length_mm": 22.0,
                }
            ],
            "stock": {"min_mm": [0.0, 0.0, -10.0], "max_mm": [60.0, 20.0, 0.0], **stock},
            "material": {"name": "AA6060-T6"},
            "simulation": {"density_per_mm": 10.0},
        }
    )


def run_to_end(vm: VirtualMachine, limit_s: float = 120.0) -> list[dict[str, float]]:
    """Step the machine at its tick until it finishes; every snapshot, in order."""
    snapshots = []
    while not vm.finished:
        vm.step(vm.tick_s)
        snapshots.append(vm.snapshot())
        assert vm.time_s < limit_s, "the program did not finish"
    return snapshots
