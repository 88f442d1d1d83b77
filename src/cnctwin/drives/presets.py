"""Named spindle-drive parameter sets.

``"christiand2024"``: the optimal DT parameters of Christiand et al. 2024, Table 5 (motor and
controller columns; a Nakanishi HES860 spindle on an E3000 controller, run at 20,000 rpm). The
published text lost the minus signs of the powers of ten; every exponent here is negative, the
only choice of signs that gives a plausible motor with a stable, settling speed loop. The
derivation, sign by sign, is in docs/drives.md and checked in tests/drives/test_presets.py.
The paper has no Coulomb friction and no voltage limit; neither has the preset.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from cnctwin.drives.spindle import SpeedController, SpindleDriveParameters, SpindleMotor
from cnctwin.errors import ConfigError

__all__ = ["SPINDLE_PRESETS", "spindle_preset"]

SPINDLE_PRESETS: Mapping[str, SpindleDriveParameters] = MappingProxyType(
    {
        "christiand2024": SpindleDriveParameters(
            motor=SpindleMotor(
                resistance=1.40,  # ohm
                inductance=7.20e-2,  # H
                torque_constant=1.80e-2,  # N m/A
                back_emf_constant=6.00e-3,  # V s/rad
                inertia=6.06e-6,  # kg m^2
                viscous_friction=6.00e-7,  # N m s/rad
            ),
            controller=SpeedController(
                kp=5.00e-6,  # V s/rad
                ki=1.7e-2,  # V/rad
                kd=1.00e-11,  # V s^2/rad
            ),
        ),
    }
)
"""Spindle-drive presets by name."""


def spindle_preset(name: str) -> SpindleDriveParameters:
    """The spindle-drive parameters called ``name``.

    Parameters
    ----------
    name
        A key of :data:`SPINDLE_PRESETS`, e.g. ``"christiand2024"``.

    Returns
    -------
    SpindleDriveParameters
        Motor and controller parameters (SI units).

    Raises
    ------
    ConfigError
        If no preset has that name.
    """
    try:
        return SPINDLE_PRESETS[name]
    except KeyError:
        valid = ", ".join(sorted(SPINDLE_PRESETS))
        raise ConfigError(f"spindle preset {name!r} is unknown; valid presets: {valid}") from None
