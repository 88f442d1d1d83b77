"""The ``[virtual]`` table: the simulated machine's program, clock, sensors and faults.

The physics of the virtual machine (machine, tools, stock, material, dexel density) is an
ordinary :class:`cnctwin.config.MachiningConfig`; this table says what the machine runs and how it
misbehaves. Units are in the key names (mm, ms, s, N, N m, A, W, %, rpm, Hz); every numeric
key has a range (docs/configuration.md), far beyond what a machine shows and small enough to
keep the simulation finite.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cnctwin.config import CoordinateMm, Section, Vec3Mm, resolve_file

__all__ = [
    "AxisDriveConfig",
    "ChatterFault",
    "FaultConfig",
    "HoleFault",
    "NoiseConfig",
    "ToolBreakageFault",
    "VibrationConfig",
    "VirtualMachineConfig",
    "WearFault",
]


class NoiseConfig(Section):
    """Standard deviations of the Gaussian sensor noise, per signal family (0: none).

    Attributes
    ----------
    position_mm
        Axis positions ``x_mm``, ``y_mm``, ``z_mm``, mm.
    feed_mm_min
        Path speed ``feed_mm_min``, mm/min.
    spindle_rpm
        Spindle speed ``spindle_rpm``, rpm.
    force_n
        Dynamometer forces ``force_x_n``, ``force_y_n``, ``force_z_n``, N.
    torque_nm
        Spindle torque, N m.
    current_a
        Spindle current, A.
    power_w
        Spindle power, W.
    load_pct
        Axis drive loads, % of rated.
    """

    position_mm: float = Field(default=0.0005, ge=0, le=100)
    feed_mm_min: float = Field(default=0.5, ge=0, le=1e5)
    spindle_rpm: float = Field(default=2.0, ge=0, le=1e5)
    force_n: float = Field(default=2.0, ge=0, le=1e5)
    torque_nm: float = Field(default=0.02, ge=0, le=1e4)
    current_a: float = Field(default=0.02, ge=0, le=1e4)
    power_w: float = Field(default=5.0, ge=0, le=1e6)
    load_pct: float = Field(default=0.1, ge=0, le=100)


class AxisDriveConfig(Section):
    """The feed drives, alike for X, Y and Z (``[virtual.axes]``), for the axis loads.

    Attributes
    ----------
    rated_force_n
        Force at 100 % load, N (> 0).
    friction_n
        Coulomb friction of a moving axis, N (>= 0).
    moving_mass_kg
        Mass the drive accelerates, kg (>= 0).
    """

    rated_force_n: float = Field(default=5000.0, gt=0, le=1e7)
    friction_n: float = Field(default=150.0, ge=0, le=1e6)
    moving_mass_kg: float = Field(default=150.0, ge=0, le=1e6)


class _Trigger(Section):
    """When a fault starts: at a machine time or when a program line first executes."""

    at_s: float | None = Field(default=None, ge=0, le=1e7)
    at_line: int | None = Field(default=None, ge=1, le=1_000_000_000)


class ToolBreakageFault(_Trigger):
    """The tool in the spindle breaks: its tip is gone, the machine goes on (``kind="breakage"``).

    Attributes
    ----------
    at_s, at_line
        Machine time (s) or program line at which the tool breaks; exactly one.
    lost_length_mm
        Length of tool lost from the tip, mm; ``None``: the whole fluted length (the stub
        cuts nothing).
    """

    kind: Literal["breakage"]
    lost_length_mm: float | None = Field(default=None, gt=0, le=2000)

    @model_validator(mode="after")
    def _one_trigger(self) -> ToolBreakageFault:
        if (self.at_s is None) == (self.at_line is None):
            raise PydanticCustomError(
                "fault_trigger", "give exactly one of at_s (s) and at_line (program line)"
            )
        return self


class HoleFault(Section):
    """Material missing from the machine's blank (not from the twin's) (``kind="hole"``).

    A box (``min_mm``, ``max_mm``) or a cylinder along Z (``center_mm`` = x, y;
    ``radius_mm``; ``z_mm`` = bottom, top), in machine coordinates, mm (Heide 2025, use case 1).
    """

    kind: Literal["hole"]
    shape: Literal["box", "cylinder"] = "box"
    min_mm: Vec3Mm | None = None
    max_mm: Vec3Mm | None = None
    center_mm: tuple[CoordinateMm, CoordinateMm] | None = None
    radius_mm: float | None = Field(default=None, gt=0, le=1e5)
    z_mm: tuple[CoordinateMm, CoordinateMm] | None = None

    @model_validator(mode="after")
    def _shape_keys(self) -> HoleFault:
        if self.shape == "box":
            if self.min_mm is None or self.max_mm is None:
                raise PydanticCustomError("hole_box", "a box hole needs min_mm and max_mm (mm)")
            for axis, lo, hi in zip("xyz", self.min_mm, self.max_mm, strict=True):
                if hi <= lo:
                    raise PydanticCustomError(
                        "hole_box",
                        "max_mm's {axis} ({hi}) must exceed min_mm's ({lo})",
                        {"axis": axis, "hi": hi, "lo": lo},
                    )
        else:
            if self.center_mm is None or self.radius_mm is None or self.z_mm is None:
                raise PydanticCustomError(
                    "hole_cylinder",
                    "a cylinder hole needs center_mm [x, y], radius_mm and z_mm [bottom, top]",
                )
            if self.z_mm[1] <= self.z_mm[0]:
                raise PydanticCustomError(
                    "hole_cylinder",
                    "z_mm's top ({top}) must exceed its bottom ({bottom})",
                    {"top": self.z_mm[1], "bottom": self.z_mm[0]},
                )
        return self


class WearFault(_Trigger):
    """Accelerated wear: the load grows with cutting time, or the tool's flank wears
    (``kind="wear"``).

    Two models, which may be combined:

    - *load growth*: the cutting forces and torque are scaled by
      ``1 + growth_per_min * t_cut_min`` (at most ``max_scale``), ``t_cut_min`` the time in
      contact since the fault started, min;
    - *flank wear* (with ``vb_rate_mm_min``): the tool in the spindle has a true flank wear
      VB, mm, from ``vb0_mm`` at the fault's start, growing with the time in contact as
      ``dVB/dt = vb_rate_mm_min (1 + (VB / vb_ref_mm)^2)`` (a rate that rises with the wear
      land, so the tool fails in finite time: ``VB = vb_ref tan(atan(VB0/vb_ref) + rate t /
      vb_ref)``, held at 2 mm). The wear land rubs the work: the tangential edge-force
      coefficient grows by ``edge_force_n_mm2 * VB`` (N/mm), which adds its torque to the
      spindle's (:meth:`cnctwin.virtual.faults.FaultInjector.rubbing_torque_nm`). Neither law
      is the wear twin's (the EKF of :mod:`cnctwin.wear`: logistic growth in material
      removed, a logarithmic wear torque), so the twin's estimate can be judged against it.

    Attributes
    ----------
    at_s, at_line
        Start (machine time, s, or program line); neither: from the start.
    growth_per_min
        Relative growth of the load per minute of cutting, 1/min (> 0); ``None``: 0.5 without
        a flank-wear rate, no load growth with one.
    max_scale
        Largest scale factor (>= 1).
    vb_rate_mm_min
        Flank-wear rate of the fresh edge per minute of cutting, mm/min; ``None``: no flank
        wear.
    vb0_mm
        Flank wear when the fault starts, mm.
    vb_ref_mm
        Wear at which the wear rate has doubled, mm.
    edge_force_n_mm2
        Growth of the tangential edge-force coefficient per mm of flank wear, N/mm per mm.
    """

    kind: Literal["wear"]
    growth_per_min: float | None = Field(default=None, gt=0, le=1000)
    max_scale: float = Field(default=3.0, ge=1, le=1000)
    vb_rate_mm_min: float | None = Field(default=None, gt=0, le=100)
    vb0_mm: float = Field(default=0.02, ge=0, le=1)
    vb_ref_mm: float = Field(default=0.3, gt=0, le=10)
    edge_force_n_mm2: float = Field(default=100.0, ge=0, le=1e5)

    @property
    def load_growth_per_min(self) -> float:
        """The load growth in effect, 1/min (see ``growth_per_min``)."""
        if self.growth_per_min is not None:
            return self.growth_per_min
        return 0.5 if self.vb_rate_mm_min is None else 0.0


class ChatterFault(_Trigger):
    """Chatter: a vibration at a chatter frequency added to the forces (``kind="chatter"``).

    While the tool cuts, ``amplitude_ratio`` times the mean force magnitude is added as a
    rotating force in the XY plane at ``frequency_hz`` (sampled at the end of each tick).

    Attributes
    ----------
    at_s, at_line
        Start (machine time, s, or program line); neither: from the start.
    until_s
        End, machine time, s; ``None``: to the end.
    frequency_hz
        Chatter frequency, Hz (> 0).
    amplitude_ratio
        Vibration amplitude over the mean force magnitude (> 0).
    """

    kind: Literal["chatter"]
    until_s: float | None = Field(default=None, gt=0, le=1e7)
    frequency_hz: float = Field(default=1250.0, gt=0, le=1e5)
    amplitude_ratio: float = Field(default=0.5, gt=0, le=100)


#: One ``[[virtual.faults]]`` entry, told apart by its ``kind``.
FaultConfig = Annotated[
    ToolBreakageFault | HoleFault | WearFault | ChatterFault, Field(discriminator="kind")
]


class VibrationConfig(Section):
    """The regenerative vibration of the cut and its sensor (``[virtual.vibration]``).

    With a stability file (the tool's modes, docs/stability.md) the machine integrates the
    time-domain milling model with those modes while it cuts (:mod:`cnctwin.virtual.vibration`,
    Royandi 2026, Eq. 1-12): an unstable depth chatters, a stable one does not. A tool-tip
    displacement sensor samples it at ``sample_rate_hz`` and the machine serves the samples as a
    block (``MachineConnection.read_block("vibration")``), x along the feed, y across it, um.

    Attributes
    ----------
    stability_file
        Stability file whose ``[[modes]]`` are the tool's (relative to this file); ``None``:
        no vibration (the default).
    tool
        The tool those modes are of (its number in ``[[tools]]``); other tools do not vibrate.
    sample_rate_hz
        Sampling rate of the displacement sensor, Hz (1 kHz to 100 kHz).
    steps_per_tooth
        Integration steps per tooth period; ``None``: 200 per cycle of the highest mode.
    noise_um
        Sensor noise (Gaussian, standard deviation), um.
    buffer_s
        Samples the machine keeps for a reader, s of signal (a reader slower than this loses
        samples).
    """

    stability_file: Path | None = None
    tool: int = Field(default=1, ge=0, le=10_000)
    sample_rate_hz: float = Field(default=10_000.0, ge=1_000.0, le=100_000.0)
    steps_per_tooth: int | None = Field(default=None, ge=20, le=10_000)
    noise_um: float = Field(default=0.05, ge=0.0, le=1_000.0)
    buffer_s: float = Field(default=1.0, gt=0.0, le=60.0)

    @field_validator("stability_file")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)


class VirtualMachineConfig(Section):
    """The simulated machine (``[virtual]``).

    Attributes
    ----------
    program
        NC program the machine runs; relative to the configuration file. ``None``: the
        packaged demo program (``cnctwin/examples/demo.ngc``).
    physics_config
        Configuration file with the machine, tools, stock and material of the simulated
        machine, used when the virtual machine is built without one; relative to this file.
        ``None``: the packaged ``demo.toml``.
    tick_ms
        Simulation step, ms (0.5 to 50): the machine's interpolation and sampling period.
    speed
        Time scale of :class:`~cnctwin.virtual.clock.MachineClock`: machine seconds per
        wall-clock second (1: real time).
    density_per_mm
        Dexels per mm of the machine's stock; ``None``: the physics' ``[simulation]`` value.
    junction_deviation_mm
        Corner speed of the path planner (grbl's junction deviation), mm (>= 0).
    noise
        Sensor noise.
    seed
        Seed of the noise generator: the same seed and commands give the same signals.
    axes
        Feed drives, for the axis loads.
    faults
        Injected faults and anomalies (``[[virtual.faults]]``), each with its ``kind``.
    vibration
        The cut's regenerative vibration and its displacement sensor (off by default).
    """

    program: Path | None = None
    physics_config: Path | None = None
    tick_ms: float = Field(default=5.0, ge=0.5, le=50.0)
    speed: float = Field(default=1.0, gt=0, le=1000.0)
    density_per_mm: float | None = Field(default=None, ge=0.1, le=100)
    junction_deviation_mm: float = Field(default=0.01, ge=0, le=100)
    noise: NoiseConfig = Field(default_factory=NoiseConfig)
    seed: int = Field(default=0, ge=0, le=2**64 - 1)
    axes: AxisDriveConfig = Field(default_factory=AxisDriveConfig)
    faults: list[FaultConfig] = Field(default_factory=list)
    vibration: VibrationConfig = Field(default_factory=VibrationConfig)

    @field_validator("program", "physics_config")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)

    @property
    def tick_s(self) -> float:
        """The simulation step, s."""
        return self.tick_ms * 1e-3
