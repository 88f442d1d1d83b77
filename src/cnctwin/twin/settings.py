"""The ``[twin]`` table: the runtime's cycle, watchdog, filters, windows and monitoring models."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cnctwin.config import Section, resolve_file
from cnctwin.learn import FilterSpec, WindowSpec
from cnctwin.twin.adaptive_feed import AdaptiveFeedConfig
from cnctwin.twin.chatter_live import ChatterConfig
from cnctwin.twin.mirs import MirsConfig
from cnctwin.twin.roughness import RoughnessConfig

__all__ = [
    "ForceBandConfig",
    "FormErrorConfig",
    "ModelConfig",
    "OverloadConfig",
    "PlausibilityConfig",
    "StopConfirmationConfig",
    "TwinSettings",
    "WearConfig",
]


class ForceBandConfig(Section):
    """Force monitoring (Heide 2025, use case 1): a band around the predicted force.

    The band is ``predicted +- max(k * scatter, min_width_n, min_width_rel * predicted)``
    where ``scatter`` is the standard deviation of the residual (measured minus predicted)
    over the last ``scatter_window`` in-band cycles in contact (it also spans the previous
    cycle's prediction, see :mod:`cnctwin.twin.monitoring`). Outside it, the prediction
    ``force_out_of_band`` is 1.

    Attributes
    ----------
    enabled
        Compute the band.
    k
        Band half-width in residual standard deviations.
    min_width_n
        Smallest half-width, N (covers sensor noise before the scatter is known).
    min_width_rel
        Smallest half-width as a fraction of the predicted force (the model's relative
        error: coefficients, runout, wear).
    scatter_window
        Cycles of residual kept for the scatter.
    min_predicted_n
        The band is armed only while the predicted force is above this, N (in air the
        measured force is noise).
    settle_cycles
        Cycles in contact before the band is armed (entry transients), and after a gap in
        the connection.
    """

    enabled: bool = True
    k: float = Field(default=4.0, gt=0.0, le=100.0)
    min_width_n: float = Field(default=15.0, ge=0.0, le=1e6)
    min_width_rel: float = Field(default=0.1, ge=0.0, lt=1.0)
    scatter_window: int = Field(default=200, ge=10, le=100_000)
    min_predicted_n: float = Field(default=10.0, ge=0.0, le=1e6)
    settle_cycles: int = Field(default=8, ge=0, le=100_000)


class FormErrorConfig(Section):
    """Form-error prediction from tool deflection (Heide 2025, use case 2).

    Attributes
    ----------
    enabled
        Predict the form error.
    tolerance_um
        Half-width of the allowed band, um (Heide 2025: +-40 um).
    stiffness_n_um
        Tool stiffness at the tip, N/um; ``None`` computes it from the tool's diameter and
        ``overhang_mm`` (cantilever).
    overhang_mm
        Free length of the tool out of the holder, mm.
    youngs_modulus_gpa
        Young's modulus of the tool material, GPa (cemented carbide: about 600).
    """

    enabled: bool = True
    tolerance_um: float = Field(default=40.0, gt=0.0, le=10_000.0)
    stiffness_n_um: float | None = Field(default=None, gt=0.0, le=1e4)
    overhang_mm: float = Field(default=30.0, ge=0.1, le=2000.0)
    youngs_modulus_gpa: float = Field(default=600.0, ge=1.0, le=2000.0)


class WearConfig(Section):
    """Tool wear from the spindle torque (``[twin.wear]``; Christiand 2024's EKF,
    :class:`cnctwin.wear.WearEKF`; docs/wear-ekf.md).

    Every sample in contact, the measured spindle torque (or current times the torque
    constant) less the torque without wear (the idle torque the twin learns in air plus the
    predicted cutting torque) is the wear torque the filter explains with
    ``Tw = p0 ln(p1 VB / (p2 - p3 VB)) + p4`` (Eq. 8); between samples the wear grows with
    the material the twin's stock lost, ``VB += q dMR VB (1 - VB/VBmax)`` (Eq. 32). The
    defaults are the paper's Table 5-6 values for its 1 mm micro-mill (as recovered in
    docs/wear-ekf.md): calibrate them for another tool (``cnctwin.wear.fit_wear_torque``,
    ``fit_logistic_wear``). The paper gives no wear values for the stages: ``stages_mm`` is
    the user's "standard profile".

    Attributes
    ----------
    enabled
        Estimate the wear (off by default: the model needs a calibration).
    signal
        ``"spindle_torque_nm"`` or ``"spindle_current_a"`` (times ``torque_constant_nm_a``).
    torque_constant_nm_a
        Motor torque constant, N m/A, for the current signal.
    vb0_mm, sd0_mm
        Wear of the tool at the twin's start and its standard deviation, mm.
    q_per_mm3, vb_max_mm
        Logistic wear law: growth per mm^3 removed, 1/mm^3; saturation wear, mm.
    p0_nm, p1_per_mm, p2, p3_per_mm, p4_nm
        Wear-torque model (N m, 1/mm, 1, 1/mm, N m); ``VB < p2/p3``.
    process_var_mm2
        Prediction noise per sample that removes material, mm^2.
    measurement_var_nm2
        Torque measurement noise, (N m)^2 (sensor noise plus the cutting-torque model's error).
    stages_mm
        Wear at which stages II, III and IV begin, mm, increasing.
    expected_entry_s
        Cutting time at which a normal tool enters stages II, III and IV, s; an entry before
        it is flagged early. ``None``: no flag.
    life_vb_mm
        Tool-life criterion: the wear at the end of the tool's life, mm (ISO 8688-2 gives
        0.3 mm of uniform flank wear for end mills), below ``vb_max_mm``.
    idle_samples
        Samples over which the idle torque (spindle turning in air) is averaged.
    settle_samples
        Samples of a steady cut (spindle speed and predicted cutting torque held) before the
        filter takes the torque: the wear-torque model holds for a steady cut, not for the
        entry into the material, its exit, or a spindle that speeds up or brakes.
    steady_fraction
        Largest change of the predicted cutting torque between two samples of a steady cut,
        as a fraction of it.
    """

    enabled: bool = False
    signal: Literal["spindle_torque_nm", "spindle_current_a"] = "spindle_torque_nm"
    torque_constant_nm_a: float | None = Field(default=None, gt=0.0, le=1e3)
    vb0_mm: float = Field(default=0.02, gt=0.0, le=10.0)
    sd0_mm: float = Field(default=0.01, ge=0.0, le=10.0)
    q_per_mm3: float = Field(default=1.43, gt=0.0, le=1e6)
    vb_max_mm: float = Field(default=0.663, gt=0.0, le=10.0)
    p0_nm: float = Field(default=1.27e-4, gt=0.0, le=1e4)
    p1_per_mm: float = Field(default=8.0e5, gt=0.0, le=1e12)
    p2: float = Field(default=0.244, gt=0.0, le=1e6)
    p3_per_mm: float = Field(default=0.366, gt=0.0, le=1e6)
    p4_nm: float = Field(default=9.58e-4, ge=-1e4, le=1e4)
    process_var_mm2: float = Field(default=4.34e-8, ge=0.0, le=1.0)
    measurement_var_nm2: float = Field(default=1.6e-5, gt=0.0, le=1e6)
    stages_mm: tuple[float, float, float] = (0.05, 0.2, 0.55)
    expected_entry_s: tuple[float, float, float] | None = None
    life_vb_mm: float = Field(default=0.3, gt=0.0, le=10.0)
    idle_samples: int = Field(default=40, ge=1, le=100_000)
    settle_samples: int = Field(default=8, ge=1, le=100_000)
    steady_fraction: float = Field(default=0.05, gt=0.0, le=1.0)

    @model_validator(mode="after")
    def _consistent(self) -> WearConfig:
        a, b, c = self.stages_mm
        if not 0.0 < a < b < c:
            raise PydanticCustomError(
                "wear_stages", "stages_mm must be three increasing wear values > 0 mm"
            )
        limit = self.p2 / self.p3_per_mm
        for name, value in (("vb0_mm", self.vb0_mm), ("life_vb_mm", self.life_vb_mm)):
            if not value < self.vb_max_mm:
                raise PydanticCustomError(
                    "wear_range",
                    "{name} = {value} mm must be below vb_max_mm = {top} mm",
                    {"name": name, "value": value, "top": self.vb_max_mm},
                )
        if not self.vb_max_mm < limit:
            raise PydanticCustomError(
                "wear_domain",
                "vb_max_mm = {top} mm must be below p2/p3 = {limit} mm, where the wear "
                "torque's logarithm ends",
                {"top": self.vb_max_mm, "limit": f"{limit:.4g}"},
            )
        if self.signal == "spindle_current_a" and self.torque_constant_nm_a is None:
            raise PydanticCustomError(
                "wear_signal", "signal = 'spindle_current_a' needs torque_constant_nm_a (N m/A)"
            )
        return self


class StopConfirmationConfig(Section):
    """When a stop or feed hold the twin sent counts as done (``[twin.stop_confirmation]``).

    A stop is confirmed by motion, never by a flag's read-back: every axis speed (from
    successive positions over the machine clock ``t_s``) and the path feed ``feed_mm_min``
    must be at most ``rest_speed_mm_min`` in ``rest_readings`` successive readings. Without
    that within ``timeout_s`` the twin escalates: feed hold -> stop -> emergency stop (the
    last only where the connection reads the machine's ``emergency_stop`` back). See
    docs/control.md.

    Attributes
    ----------
    timeout_s
        Time each step of the escalation has to bring the axes to rest, s (the twin's clock).
    rest_speed_mm_min
        Largest axis speed and path feed that count as rest, mm/min (above the sensor noise
        of positions differenced over one cycle).
    rest_readings
        Successive readings at rest needed to confirm.
    escalate
        Take the next step when a step is not confirmed in time; ``false``: only the event.
    """

    timeout_s: float = Field(default=0.5, gt=0.0, le=60.0)
    rest_speed_mm_min: float = Field(default=6.0, gt=0.0, le=1e6)
    rest_readings: int = Field(default=2, ge=1, le=1000)
    escalate: bool = True


class OverloadConfig(Section):
    """What the twin does when its cycle cannot keep the period (``[twin.overload]``).

    The twin is *overloaded* when at least ``enter_fraction`` of the last ``window_cycles``
    cycles overran their period, and back to normal when at most ``exit_fraction`` did. While
    overloaded it sheds the optional stages (docs/twin.md gives the order); the reading, the
    force band, the rules and the actions are never shed.

    Attributes
    ----------
    window_cycles
        Cycles the overrun fraction is taken over.
    enter_fraction
        Overrun fraction from which the twin is overloaded (0 < f <= 1).
    exit_fraction
        Overrun fraction at or below which it is no longer overloaded (< ``enter_fraction``).
    shed
        Shed optional stages while overloaded (``false``: only report the overload).
    sample_every
        While overloaded, the historian keeps every ``sample_every``-th cycle's samples.
    """

    window_cycles: int = Field(default=40, ge=2, le=100_000)
    enter_fraction: float = Field(default=0.25, gt=0.0, le=1.0)
    exit_fraction: float = Field(default=0.05, ge=0.0, lt=1.0)
    shed: bool = True
    sample_every: int = Field(default=4, ge=1, le=10_000)

    @field_validator("exit_fraction")
    @classmethod
    def _below_enter(cls, value: float, info: ValidationInfo) -> float:
        enter = info.data.get("enter_fraction")
        if enter is not None and value >= enter:
            raise ValueError(f"exit_fraction={value:g} must be below enter_fraction={enter:g}")
        return value


class PlausibilityConfig(Section):
    """What counts as a machine state (``[twin.plausibility]``; see
    :mod:`cnctwin.twin.plausibility`).

    Attributes
    ----------
    jump_margin
        An axis may move this many times the distance its ``[machine.axes]`` velocity and
        acceleration allow between two samples before the move counts as a jump (1 = the
        limits exactly; the default 2 leaves room for time-stamp jitter).
    jump_floor_mm
        Move always plausible between two samples, mm (sensor noise, quantisation).
    feed_override_max_pct
        Highest feed override the machine's dial allows, %: a reading above it is invalid.
    spindle_override_min_pct, spindle_override_max_pct
        Range of the machine's spindle override, %: a reading outside it is invalid.
    """

    jump_margin: float = Field(default=2.0, ge=1.0, le=100.0)
    jump_floor_mm: float = Field(default=0.5, ge=0.0, le=1000.0)
    feed_override_max_pct: float = Field(default=150.0, gt=0.0, le=150.0)
    spindle_override_min_pct: float = Field(default=50.0, ge=0.0, le=120.0)
    spindle_override_max_pct: float = Field(default=120.0, gt=0.0, le=120.0)


class ModelConfig(Section):
    """A learned model the twin runs every sample (``[[twin.models]]``; see
    :mod:`cnctwin.twin.model_stage` and docs/twin.md).

    Attributes
    ----------
    name
        The model's prediction name (lower-case letters, digits, ``_``): the twin adds
        ``NAME`` (the prediction, in the target's unit), ``NAME_band``, ``NAME_low``,
        ``NAME_high`` (the stated band's half-width and edges), ``NAME_std`` (GPR) and
        ``NAME_ready`` (1 once every feature is known) for rules and the historian.
    path
        The ONNX model file (``cnctwin learn train``), relative to the configuration file.
    """

    name: str = Field(pattern=r"^[a-z][a-z0-9_]{0,39}$")
    path: Path

    @field_validator("path")
    @classmethod
    def _relative_to_file(cls, value: Path, info: ValidationInfo) -> Path:
        resolved = resolve_file(value, info)
        assert resolved is not None
        return resolved


class TwinSettings(Section):
    """The twin's runtime (``[twin]``).

    Attributes
    ----------
    cycle_s
        Cycle time, s, 0.001 to 1 (Heide 2025: 12.5 ms; no machine interface delivers
        readings faster than 1 ms). Every numeric key of ``[twin]`` has a range, listed in
        docs/twin.md.
    program
        The NC program the machine runs, relative to the configuration file: the twin reads
        the tool offset of each line from it. ``None``: ``[virtual].program`` when there is
        one, else the length of the tool in the spindle is taken as its offset (G43).
    watchdog_s
        The connection counts as lost when the machine's heartbeat has not changed for this
        long, s, or no read has succeeded for this long.
    density_per_mm
        Dexel density of the twin's stock, 1/mm; ``None`` takes ``[simulation]``'s.
    attach_s
        At the twin's first reading, a program already running for longer than this (machine
        time, s) may have cut the blank: the twin's blank is then not the machine's, and
        force monitoring stays off until the program starts again.
    position_deadband_mm
        An axis reading that moved less than this from the position the twin holds is taken
        as sensor noise and the held position kept, mm. Without it a standing axis (a plunge,
        the wall side of a pass) jitters across dexel ends and the twin's discrete cut takes
        slivers thinner than a micrometre as full contact.
    max_sample_age_s
        A reading older than this is stale: no current sample, and the machine counts as
        lost, s (age: the twin's clock minus the machine's time stamp, or the time since the
        last new sample where the transport carries no time stamps; see
        :mod:`cnctwin.twin.freshness`).
    realtime_priority
        SCHED_FIFO priority of the cycle's thread while it cycles, 1 to 98 (Linux; root,
        ``CAP_SYS_NICE`` or an rtprio limit); 0 (default): the ordinary scheduler
        (:mod:`cnctwin.twin.priority`).
    plausibility
        Axis-jump and override-range checks of every sample.
    filters
        Filters by measured signal name.
    windows
        Sliding windows and their features.
    force_band
        Force monitoring.
    form_error
        Form-error prediction.
    wear
        Tool wear from the spindle torque.
    adaptive_feed
        Adaptive feed control (Ward 2021, Eq. 7; :mod:`cnctwin.twin.adaptive_feed`).
    roughness
        Roughness per sample and program section (:mod:`cnctwin.twin.roughness`).
    chatter
        Online chatter detection and avoidance (:mod:`cnctwin.twin.chatter_live`).
    mirs
        Elastic residual stress prediction and control (Ward 2021, Sec. 3.3;
        :mod:`cnctwin.twin.mirs`).
    stop_confirmation
        When a stop counts as done, and the escalation when it does not.
    overload
        Overload detection and shedding.
    models
        Learned models run every sample, in order, after the monitoring models (at most 16).
    """

    cycle_s: float = Field(default=0.0125, ge=0.001, le=1.0)
    program: Path | None = None
    watchdog_s: float = Field(default=0.5, gt=0.0, le=3600.0)
    density_per_mm: float | None = Field(default=None, ge=0.1, le=100.0)
    attach_s: float = Field(default=1.0, ge=0.0, le=1e6)
    position_deadband_mm: float = Field(default=0.005, ge=0.0, le=100.0)
    max_sample_age_s: float = Field(default=2.0, gt=0.0, le=3600.0)
    realtime_priority: int = Field(default=0, ge=0, le=98)
    plausibility: PlausibilityConfig = Field(default_factory=PlausibilityConfig)
    filters: dict[str, FilterSpec] = Field(default_factory=dict)
    windows: list[WindowSpec] = Field(default_factory=list)
    force_band: ForceBandConfig = Field(default_factory=ForceBandConfig)
    form_error: FormErrorConfig = Field(default_factory=FormErrorConfig)
    wear: WearConfig = Field(default_factory=WearConfig)
    adaptive_feed: AdaptiveFeedConfig = Field(default_factory=AdaptiveFeedConfig)
    roughness: RoughnessConfig = Field(default_factory=RoughnessConfig)
    chatter: ChatterConfig = Field(default_factory=ChatterConfig)
    mirs: MirsConfig = Field(default_factory=MirsConfig)
    stop_confirmation: StopConfirmationConfig = Field(default_factory=StopConfirmationConfig)
    overload: OverloadConfig = Field(default_factory=OverloadConfig)
    models: list[ModelConfig] = Field(default_factory=list, max_length=16)

    @field_validator("program")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)
