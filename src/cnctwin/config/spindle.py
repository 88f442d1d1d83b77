"""The ``[machine.spindle]`` section: the spindle drive the signal prediction runs.

A named drive preset (:data:`cnctwin.drives.SPINDLE_PRESETS`), optionally with its motor or its
speed controller replaced by explicit parameters, and optionally the spindle's continuous (S1)
rating, against which the predicted cutting load is checked. Parameters are SI; every key names
its unit. The preset name is checked where the drive is built
(:func:`cnctwin.simulation.signals.spindle_drive_parameters`), so that loading a configuration does
not import the drive models.
"""

from __future__ import annotations

from pydantic import Field

from cnctwin.config.base import Section

__all__ = ["SpeedControllerConfig", "SpindleConfig", "SpindleMotorConfig"]


class SpindleMotorConfig(Section):
    """Spindle motor parameters (Christiand 2024, Eq. 10-12), replacing the preset's motor.

    Attributes
    ----------
    resistance_ohm
        Armature resistance, ohm (> 0, <= 1000).
    inductance_h
        Armature inductance, H (> 0, <= 10).
    torque_constant_nm_a
        Torque constant, N m/A (> 0, <= 1000).
    back_emf_constant_v_s_rad
        Back-EMF constant, V s/rad (> 0, <= 1000).
    inertia_kg_m2
        Rotor, spindle and tool inertia, kg m^2 (> 0, <= 1000).
    viscous_friction_nm_s_rad
        Viscous friction coefficient, N m s/rad (0 to 1000).
    coulomb_friction_nm
        Coulomb friction torque, N m (0 to 100,000).

    The upper bounds lie orders of magnitude beyond any spindle drive; they keep the drive's
    matrices finite.
    """

    resistance_ohm: float = Field(gt=0, le=1e3)
    inductance_h: float = Field(gt=0, le=10)
    torque_constant_nm_a: float = Field(gt=0, le=1e3)
    back_emf_constant_v_s_rad: float = Field(gt=0, le=1e3)
    inertia_kg_m2: float = Field(gt=0, le=1e3)
    viscous_friction_nm_s_rad: float = Field(ge=0, le=1e3)
    coulomb_friction_nm: float = Field(default=0.0, ge=0, le=1e5)


class SpeedControllerConfig(Section):
    """PID speed controller (Christiand 2024, Eq. 13-14), replacing the preset's controller.

    Attributes
    ----------
    kp_v_s_rad
        Proportional gain, V s/rad (0 to 10,000).
    ki_v_rad
        Integral gain, V/rad (0 to 1,000,000).
    kd_v_s2_rad
        Derivative gain on the measured speed, V s^2/rad (0 to 100).
    voltage_limit_v
        Symmetric armature voltage limit, V (> 0, <= 100,000); none if not given.
    """

    kp_v_s_rad: float = Field(ge=0, le=1e4)
    ki_v_rad: float = Field(ge=0, le=1e6)
    kd_v_s2_rad: float = Field(default=0.0, ge=0, le=100)
    voltage_limit_v: float | None = Field(default=None, gt=0, le=1e5)


class SpindleConfig(Section):
    """The spindle drive.

    Attributes
    ----------
    preset
        Name of a spindle-drive preset: ``"machining-centre-15kw"`` (the default, a 15 kW,
        12,000 rpm machining-centre spindle) or ``"christiand2024"`` (the micro-milling spindle
        of Christiand 2024); see docs/signals.md.
    motor
        Explicit motor parameters replacing the preset's motor.
    controller
        Explicit speed-controller parameters replacing the preset's controller.
    rated_power_kw
        Continuous (S1) power of the spindle, kW, if known (> 0, <= 10,000).
    rated_torque_nm
        Continuous (S1) torque of the spindle below its base speed, N m, if known (> 0,
        <= 100,000). With either
        rating, a cut that needs more than ``min(rated_torque_nm, rated_power_kw / speed)``
        is reported as an overload.
    """

    preset: str = "machining-centre-15kw"
    motor: SpindleMotorConfig | None = None
    controller: SpeedControllerConfig | None = None
    rated_power_kw: float | None = Field(default=None, gt=0, le=1e4)
    rated_torque_nm: float | None = Field(default=None, gt=0, le=1e5)
