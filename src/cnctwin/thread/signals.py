"""The twin's canonical signal names: what a machine connection reads and writes.

Every transport (OPC UA, Modbus TCP, ...) maps its own addresses onto these names, so the
twin's stages, rules and historian speak one vocabulary whatever the machine. Units follow
the project's edge convention: the names carry customary units where the machine reports
them (mm, mm/min, rpm, %), SI elsewhere (N, N m, A, W, s).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

__all__ = ["COMMANDS", "SIGNALS", "RunState", "SignalSpec", "implausible"]


class RunState(enum.IntEnum):
    """State of program execution, as the ``run_state`` signal reports it."""

    IDLE = 0
    RUNNING = 1
    FEED_HOLD = 2
    STOPPED = 3
    FINISHED = 4
    FAULT = 5


@dataclass(frozen=True)
class SignalSpec:
    """One canonical signal.

    Attributes
    ----------
    name
        Canonical name (snake case, unit suffix where the unit is not SI-obvious).
    unit
        Unit as text (``"mm"``, ``"1"`` for counts and flags).
    kind
        ``"float"``, ``"int"`` or ``"bool"``.
    writable
        Whether a twin may command it (a command; see :data:`COMMANDS`).
    low, high
        Range a machine accepts for a command (the virtual machine's limits; a safety filter
        may be narrower), or the plausible range of a reading; ``None`` when unbounded.
    description
        One line.
    """

    name: str
    unit: str
    kind: str
    writable: bool
    low: float | None
    high: float | None
    description: str


_SPECS = (
    SignalSpec("t_s", "s", "float", False, 0.0, None, "machine clock since program start"),
    SignalSpec("x_mm", "mm", "float", False, None, None, "X axis position, machine frame"),
    SignalSpec("y_mm", "mm", "float", False, None, None, "Y axis position, machine frame"),
    SignalSpec("z_mm", "mm", "float", False, None, None, "Z axis position, machine frame"),
    SignalSpec("feed_mm_min", "mm/min", "float", False, 0.0, None, "actual path speed"),
    SignalSpec("spindle_rpm", "rpm", "float", False, None, None, "actual spindle speed"),
    SignalSpec("spindle_rpm_command", "rpm", "float", False, None, None, "programmed S x override"),
    SignalSpec("spindle_torque_nm", "N m", "float", False, None, None, "spindle motor torque"),
    SignalSpec("spindle_current_a", "A", "float", False, None, None, "spindle motor current"),
    SignalSpec("spindle_power_w", "W", "float", False, None, None, "spindle electrical power"),
    SignalSpec("load_x_pct", "%", "float", False, None, None, "X drive load, % of rated"),
    SignalSpec("load_y_pct", "%", "float", False, None, None, "Y drive load, % of rated"),
    SignalSpec("load_z_pct", "%", "float", False, None, None, "Z drive load, % of rated"),
    SignalSpec("force_x_n", "N", "float", False, None, None, "dynamometer force X"),
    SignalSpec("force_y_n", "N", "float", False, None, None, "dynamometer force Y"),
    SignalSpec("force_z_n", "N", "float", False, None, None, "dynamometer force Z"),
    SignalSpec("program_line", "1", "int", False, 0.0, None, "line of the executing block"),
    SignalSpec("tool_number", "1", "int", False, 0.0, None, "tool in the spindle"),
    SignalSpec("work_offset", "1", "int", False, 1.0, 9.0, "active work offset, 1 = G54"),
    SignalSpec("run_state", "1", "int", False, 0.0, 5.0, "RunState of execution"),
    SignalSpec("heartbeat", "1", "int", False, 0.0, None, "counter the machine increments"),
    SignalSpec("feed_override_pct", "%", "float", True, 0.0, 150.0, "feed override"),
    SignalSpec("spindle_override_pct", "%", "float", True, 50.0, 120.0, "spindle override"),
    SignalSpec("feed_hold", "1", "bool", True, 0.0, 1.0, "feed hold (1 holds the axes)"),
    SignalSpec("stop", "1", "bool", True, 0.0, 1.0, "program stop (1 stops; latched)"),
    SignalSpec(
        "emergency_stop", "1", "bool", True, 0.0, 1.0, "emergency stop (1 stops; latched, alarm)"
    ),
    SignalSpec("tool_length_wear_mm", "mm", "float", True, -1.0, 1.0, "tool length wear offset"),
    SignalSpec("tool_radius_wear_mm", "mm", "float", True, -1.0, 1.0, "tool radius wear offset"),
)

#: Every canonical signal by name.
SIGNALS: dict[str, SignalSpec] = {spec.name: spec for spec in _SPECS}

#: The signals a twin may write (commands), by name; each is also read back.
COMMANDS: dict[str, SignalSpec] = {spec.name: spec for spec in _SPECS if spec.writable}


def implausible(name: str, value: float | None) -> str | None:
    """Why ``value`` of signal ``name`` (in the signal's unit) is garbage, or ``None``.

    Garbage is ``None`` (the device marked the value invalid), a value that is not a finite
    number, or one outside the signal's plausible range (:attr:`SignalSpec.low` ..
    :attr:`SignalSpec.high`).
    """
    if value is None:
        return "device marked the value invalid"
    if not math.isfinite(value):
        return f"not a finite number ({value!r})"
    spec = SIGNALS[name]
    if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
        low = "-inf" if spec.low is None else f"{spec.low:g}"
        high = "inf" if spec.high is None else f"{spec.high:g}"
        return f"{value:g} outside the plausible range {low}..{high}"
    return None
