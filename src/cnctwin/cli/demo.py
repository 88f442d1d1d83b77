"""``cnctwin demo``: the main job on its packaged default.

Interprets the packaged example program with the packaged configuration, samples the
tool tip at the twin's cycle time under the machine's axis limits, and prints a summary.
Later this grows into the live twin.
"""

from __future__ import annotations

from importlib.resources import as_file
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console

from cnctwin.cli.nc import inspect_report, report_table
from cnctwin.config import MachineConfig, load_config
from cnctwin.examples import example_file
from cnctwin.nc.segments import Segment

if TYPE_CHECKING:
    from cnctwin.nc.sampler import AxisLimits

__all__ = ["CYCLE_S", "demo"]

#: The twin's cycle time in s (Heide 2025, Fig. 5: 12.5 ms).
CYCLE_S = 0.0125


def demo() -> None:
    """Run the packaged example: interpret, sample every 12.5 ms, summarize."""
    from cnctwin.nc.sampler import TrajectorySampler  # heavy: numba kernels

    with (
        as_file(example_file("demo.toml")) as config_path,
        as_file(example_file("demo.ngc")) as program,
    ):
        config = load_config(config_path)
        segments: list[Segment] = []  # the packaged program is small
        report = inspect_report(program, config, on_segment=segments.append)
    report["file"] = "demo.ngc (packaged example)"
    sampler = TrajectorySampler(
        segments,
        rapid_mm_min=config.machine.rapid_mm_min,
        cycle_s=CYCLE_S,
        limits=_axis_limits(config.machine),
    )
    samples = 0
    peak_speed_mm_min = 0.0
    for chunk in sampler:
        samples += len(chunk.t_s)
        peak_speed_mm_min = max(peak_speed_mm_min, float(np.max(chunk.path_speed_mm_min)))
    table = report_table(report)
    table.add_section()
    table.add_row("sample period", f"{CYCLE_S * 1000.0:g} ms")
    table.add_row("samples", str(samples))
    table.add_row("duration with axis limits", f"{sampler.duration_s:.1f} s")
    table.add_row("peak path speed", f"{peak_speed_mm_min:.0f} mm/min")
    Console().print(table)


def _axis_limits(machine: MachineConfig) -> AxisLimits:
    """The sampler's acceleration (mm/s^2) and velocity (mm/s) limits of X, Y and Z."""
    from cnctwin.nc.sampler import AxisLimits

    x, y, z = machine.axes.x, machine.axes.y, machine.axes.z
    return AxisLimits(
        accel_mm_s2=(x.max_accel_mm_s2, y.max_accel_mm_s2, z.max_accel_mm_s2),
        velocity_mm_s=(
            x.max_velocity_mm_min / 60.0,
            y.max_velocity_mm_min / 60.0,
            z.max_velocity_mm_min / 60.0,
        ),
    )
