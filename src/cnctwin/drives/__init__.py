"""Drives: the spindle motor with PID speed control and the machining events that gate it.

Public API::

    from cnctwin.drives import MachiningEvents, SpindleDrive, spindle_preset

    drive = SpindleDrive(spindle_preset("christiand2024"))      # Christiand 2024, Table 5
    t = np.arange(0.0, 8.0, 1e-4)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 8)], feed_s=[(3, 7)],
                                            contact_s=[(4, 6)])
    result = drive.simulate(t, 20000.0, 1e-3, events)           # rpm in, N m load
    result.speed, result.current, result.torque                 # rad/s, A, N m

    drive.step(0.0125, 20000.0, 1e-3, EventState())             # the live twin, one cycle

Units are SI (rad/s, A, V, N m, s); speeds in rpm only where names say so.
"""

from cnctwin.drives.events import (
    CONTACT_VOLUME_THRESHOLD_M3,
    EventState,
    MachiningEvents,
    contact_from_collision_volume,
)
from cnctwin.drives.presets import SPINDLE_PRESETS, spindle_preset
from cnctwin.drives.spindle import (
    RAD_S_PER_RPM,
    SpeedController,
    SpindleDrive,
    SpindleDriveParameters,
    SpindleMotor,
    SpindleResult,
    SpindleSample,
    SpindleState,
    SteadyState,
)

__all__ = [
    "CONTACT_VOLUME_THRESHOLD_M3",
    "RAD_S_PER_RPM",
    "SPINDLE_PRESETS",
    "EventState",
    "MachiningEvents",
    "SpeedController",
    "SpindleDrive",
    "SpindleDriveParameters",
    "SpindleMotor",
    "SpindleResult",
    "SpindleSample",
    "SpindleState",
    "SteadyState",
    "contact_from_collision_volume",
    "spindle_preset",
]
