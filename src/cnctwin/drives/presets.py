"""Named spindle-drive parameter sets.

``"christiand2024"``: the optimal DT parameters of Christiand et al. 2024, Table 5 (motor and
controller columns; a Nakanishi HES860 spindle on an E3000 controller, run at 20,000 rpm). The
published text lost the minus signs of the powers of ten; every exponent here is negative, the
only choice of signs that gives a plausible motor with a stable, settling speed loop. The
derivation, sign by sign, is in docs/drives.md and checked in tests/drives/test_presets.py.
The paper has no Coulomb friction and no voltage limit; neither has the preset. It is a
micro-milling spindle: its motor idles at 1.3 mN m and cannot carry the newton-metres of a 10 mm
end mill.

``"machining-centre-15kw"``: a representative spindle of a 40-taper vertical machining centre
(S1 15 kW from a base speed of 1,500 rpm, 95.5 N m, 12,000 rpm, 400 V supply), as the lumped DC
model of Christiand 2024 sees it. It is not one product's datasheet: every value is derived from
that rating by a stated rule (docs/signals.md, section "Spindle drive presets"), and checked in
tests/drives/test_machining_centre_preset.py. Its current is the torque-producing current
(``K_T`` = rated torque / rated current); the armature voltage is limited to the 560 V DC link.
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
        "machining-centre-15kw": SpindleDriveParameters(
            motor=SpindleMotor(
                resistance=0.72,  # ohm: copper loss 4 % of 15 kW at the rated 28.9 A
                inductance=7.2e-3,  # H: electrical time constant L/R = 10 ms
                torque_constant=3.3,  # N m/A: 95.5 N m rated torque / 28.9 A rated current
                back_emf_constant=0.40,  # V s/rad: 90 % of the 560 V DC link at 12,000 rpm
                inertia=0.025,  # kg m^2: motor rotor, spindle shaft, HSK-A63 holder and tool
                viscous_friction=6.3e-4,  # N m s/rad: 1 kW idle power at 12,000 rpm
            ),
            controller=SpeedController(
                kp=0.0362,  # V s/rad: closed-loop poles -20 and -40 +- 69j 1/s
                ki=6.98,  # V/rad
                kd=0.0,  # V s^2/rad
                voltage_limit=560.0,  # V: DC link of a 400 V three-phase inverter
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
