"""Machine signals predicted along a program: cutting forces, spindle torque, power and current.

The offline twin of Christiand 2024's virtual resources (section 3.2), driven by the dexel cut of
Heide 2025. At every cycle of :func:`~cnctwin.simulation.cut.simulate_cut`:

1. the engagement of the step (contact intervals per axial slice, from the removed dexels) and
   the step's feed per tooth and spindle speed give the per-revolution mean forces, torque and
   power of the mechanistic model (Altintas 2012, ch. 2; Royandi 2026, Eq. 8-12; Ward 2021,
   Eq. 1-2) with the workpiece material's coefficients (:func:`cnctwin.mechanics.mean_forces`),
   and the peak resultant force over the revolution (:func:`cnctwin.mechanics.milling_forces`);
   a drill or a tap (:data:`cnctwin.geometry.AXIAL_KINDS`) takes the drilling model instead
   (:func:`cnctwin.mechanics.drilling_load`, :func:`cnctwin.mechanics.tapping_torque`): thrust
   along the tool axis, torque and power, with the workpiece's drilling coefficients
   (:func:`cnctwin.mechanics.drilling_material`); :func:`step_forces` is the one place that
   chooses the model by the tool's kind, for this prediction, the twin and the virtual machine;
2. the forces are turned from the tool frame (x along the feed, y to its left, z up the tool
   axis) into machine X, Y, Z by the step's feed direction;
3. the cutting torque loads the spindle drive (Christiand 2024, Eq. 10-18:
   :class:`cnctwin.drives.SpindleDrive`), gated by the machining events: spindle on while the
   commanded speed is above 0, feed on while the axes move, contact while the tool removes
   material. The drive gives the spindle speed, current and motor torque over time.

The feed-drive loads are the machine-frame force components: the cutting force each linear axis
has to carry (the force on the tool; a drive that moves the workpiece carries the opposite).
Axis currents are not predicted: at machining feeds they are dominated by friction and
acceleration forces, which the twin does not model.

Units: SI inside the physics; the signal table's columns carry their units in their names
(mm, mm/min, rpm, N, N m, W, A, s), as the rest of the simulation package does.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.config import SpindleConfig
from cnctwin.drives import (
    RAD_S_PER_RPM,
    MachiningEvents,
    SpeedController,
    SpindleDrive,
    SpindleDriveParameters,
    SpindleMotor,
    spindle_preset,
)
from cnctwin.errors import ConfigError
from cnctwin.geometry import AXIAL_KINDS, Cutter, DexelStock, slice_low_mm
from cnctwin.geometry import Engagement as DexelEngagement
from cnctwin.mechanics import (
    CuttingCoefficients,
    DrillingMaterial,
    ImmersionIntervals,
    drilling_load,
    drilling_material,
    mean_forces,
    milling_forces,
    tapping_torque,
)
from cnctwin.nc import AxisLimits, Segment
from cnctwin.simulation.cut import CutStep, StepTable, simulate_cut, step_durations

__all__ = [
    "SIGNAL_COLUMNS",
    "MachineSignals",
    "StepForces",
    "axial_forces",
    "axial_material",
    "drill_band_mm",
    "headline_warnings",
    "immersion_intervals",
    "simulate_signals",
    "spindle_drive_parameters",
    "step_forces",
]

#: Columns of a :class:`MachineSignals` table, in order; units in the names (see docs/signals.md).
SIGNAL_COLUMNS = (
    "t_s",
    "line",
    "tool",
    "x_mm",
    "y_mm",
    "z_mm",
    "spindle_cmd_rpm",
    "path_speed_mm_min",
    "feed_per_tooth_mm",
    "spindle_on",
    "feed_on",
    "contact",
    "ae_mm",
    "ap_mm",
    "mrr_mm3_s",
    "fx_n",
    "fy_n",
    "fz_n",
    "f_feed_n",
    "f_normal_n",
    "f_mean_n",
    "f_peak_n",
    "cutting_torque_nm",
    "cutting_power_w",
    "spindle_speed_rpm",
    "spindle_current_a",
    "motor_torque_nm",
    "spindle_power_w",
    "overload",
)

_FORCE_COLUMNS = (
    "fx_n",
    "fy_n",
    "fz_n",
    "f_feed_n",
    "f_normal_n",
    "f_mean_n",
    "f_peak_n",
    "cutting_torque_nm",
    "cutting_power_w",
)
_WAVEFORM_STEPS = 360  # spindle angles per revolution for the peak force (1 degree)
#: A headline maximum more than this times the larger of the two steps beside it is a
#: single-step spike (warned, see :func:`headline_warnings`).
SPIKE_FACTOR = 1.5
#: The headline maxima checked by :func:`headline_warnings`: column, summary key, unit.
_HEADLINES = (
    ("f_peak_n", "max_force_n", "N"),
    ("f_mean_n", "max_mean_force_n", "N"),
    ("cutting_power_w", "max_power_w", "W"),
    ("cutting_torque_nm", "max_spindle_torque_nm", "N m"),
)
#: A tap's feed per revolution more than this fraction off its pitch is warned (G84 needs
#: F = pitch x S).
TAP_FEED_TOLERANCE = 0.02
#: Memory one cycle of :func:`simulate_signals` takes, bytes: the step table, the signal
#: columns, the drive's arrays and the forces of a step in contact (measured: about 700 B a
#: cycle on the demo program; rounded up).
_ROW_BYTES = 1000


@dataclass(frozen=True, slots=True)
class StepForces:
    """Cutting load of one step, per-revolution means unless said otherwise.

    Attributes
    ----------
    fx_n, fy_n, fz_n
        Mean force on the tool along machine X, Y, Z, N.
    feed_n, normal_n
        Mean force on the tool along the feed direction and its left normal (tool frame x, y), N;
        0 for a drill or a tap, whose thrust is ``fz_n``.
    mean_n
        Magnitude of the mean force vector, N.
    peak_n
        Largest magnitude of the force over the revolution, N.
    torque_nm
        Mean cutting torque about the tool axis, N m (positive: resists an M3 spindle).
    power_w
        Mean cutting power (torque times commanded spindle speed), W.
    """

    fx_n: float
    fy_n: float
    fz_n: float
    feed_n: float
    normal_n: float
    mean_n: float
    peak_n: float
    torque_nm: float
    power_w: float

    def values(self) -> tuple[float, ...]:
        """The values in the order of the force columns of :data:`SIGNAL_COLUMNS`."""
        return (
            self.fx_n,
            self.fy_n,
            self.fz_n,
            self.feed_n,
            self.normal_n,
            self.mean_n,
            self.peak_n,
            self.torque_nm,
            self.power_w,
        )


@dataclass(slots=True)
class MachineSignals:
    """Predicted machine signals, one row per step of the program (see :data:`SIGNAL_COLUMNS`).

    The rows are those of :func:`~cnctwin.simulation.cut.simulate_cut`: one per cycle and one at
    the end of every segment; each stands for the time since the row before
    (:func:`~cnctwin.simulation.cut.step_durations`), and the time sums are weighted so.

    Attributes
    ----------
    columns
        Every column of :data:`SIGNAL_COLUMNS` as a float array of the same length.
    cycle_s
        Cycle time of the rows, s.
    drive
        Name of the spindle drive used (the preset, with ``+motor``/``+controller`` when
        replaced).
    warnings
        Findings worth a warning, one line each (e.g. a cut that overloads the spindle).
    """

    columns: dict[str, NDArray[np.float64]]
    cycle_s: float
    drive: str
    warnings: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.columns["t_s"].size)

    def table(self) -> NDArray[np.float64]:
        """The signals as an (n, len(SIGNAL_COLUMNS)) array, columns in that order."""
        return np.column_stack([self.columns[name] for name in SIGNAL_COLUMNS])

    def summary(self) -> dict[str, Any]:
        """Figures of the whole program (units in the keys).

        Returns
        -------
        dict
            ``process_time_s``, ``cutting_time_s``, ``max_force_n`` (largest peak force over a
            revolution), ``max_mean_force_n``, ``mean_power_w`` and ``max_power_w`` (cutting
            power while in contact), ``cutting_energy_j``, ``max_spindle_torque_nm`` (largest
            cutting torque), ``max_motor_torque_nm``, ``max_spindle_current_a``,
            ``mean_cutting_current_a`` (spindle current while in contact),
            ``min_cutting_speed_rpm`` (lowest spindle speed while in contact, 0 without),
            ``max_axis_force_n`` (largest |Fx|, |Fy|, |Fz|, by axis), ``overload_steps``,
            ``steps``, ``contact_steps``, ``spindle_drive``.
        """
        c = self.columns
        n = len(self)
        contact = c["contact"] > 0
        cutting = int(contact.sum())
        dt = step_durations(c["t_s"])
        cutting_s = float(dt[contact].sum())

        def peak(name: str) -> float:
            return float(np.max(c[name])) if n else 0.0

        def mean(name: str) -> float:
            if not cutting:
                return 0.0
            if cutting_s <= 0.0:
                return float(np.mean(c[name][contact]))
            return float(np.sum(c[name][contact] * dt[contact]) / cutting_s)

        return {
            "process_time_s": float(c["t_s"][-1]) if n else 0.0,
            "cutting_time_s": cutting_s,
            "max_force_n": peak("f_peak_n"),
            "max_mean_force_n": peak("f_mean_n"),
            "mean_power_w": mean("cutting_power_w"),
            "max_power_w": peak("cutting_power_w"),
            "cutting_energy_j": float(np.sum(c["cutting_power_w"] * dt)),
            "max_spindle_torque_nm": peak("cutting_torque_nm"),
            "max_motor_torque_nm": peak("motor_torque_nm"),
            "max_spindle_current_a": peak("spindle_current_a"),
            "mean_cutting_current_a": mean("spindle_current_a"),
            "min_cutting_speed_rpm": (
                float(np.min(c["spindle_speed_rpm"][contact])) if cutting else 0.0
            ),
            "max_axis_force_n": {
                axis: float(np.max(np.abs(c[f"f{axis}_n"]))) if n else 0.0 for axis in "xyz"
            },
            "overload_steps": int(np.sum(c["overload"] > 0)),
            "steps": n,
            "contact_steps": cutting,
            "spindle_drive": self.drive,
        }


def spindle_drive_parameters(spindle: SpindleConfig) -> SpindleDriveParameters:
    """The drive of a ``[machine.spindle]`` section: its preset, with motor or controller replaced.

    Parameters
    ----------
    spindle
        The section.

    Returns
    -------
    SpindleDriveParameters
        Motor and controller in SI units.

    Raises
    ------
    ConfigError
        If the preset is unknown (the message lists the valid presets).
    """
    try:
        params = spindle_preset(spindle.preset)
    except ConfigError as err:
        raise ConfigError(f"machine.spindle.preset: {err}") from None
    motor, controller = params.motor, params.controller
    if spindle.motor is not None:
        m = spindle.motor
        motor = SpindleMotor(
            resistance=m.resistance_ohm,
            inductance=m.inductance_h,
            torque_constant=m.torque_constant_nm_a,
            back_emf_constant=m.back_emf_constant_v_s_rad,
            inertia=m.inertia_kg_m2,
            viscous_friction=m.viscous_friction_nm_s_rad,
            coulomb_friction=m.coulomb_friction_nm,
        )
    if spindle.controller is not None:
        c = spindle.controller
        controller = SpeedController(
            kp=c.kp_v_s_rad, ki=c.ki_v_rad, kd=c.kd_v_s2_rad, voltage_limit=c.voltage_limit_v
        )
    return SpindleDriveParameters(motor, controller)


def immersion_intervals(
    engagement: DexelEngagement, pitch_z_mm: float
) -> ImmersionIntervals | None:
    """The force model's immersion intervals (m) of a dexel cut's engagement (mm); None without
    intervals.

    The dexel engagement gives, per slice with contact, its sampling height ``h`` above the tip
    and the height ``dz`` of tool it stands for: ``[low, low + dz]`` with ``low`` from
    :func:`~cnctwin.geometry.engagement.slice_low_mm` (:mod:`cnctwin.geometry.engagement`,
    "Intervals"); its
    intervals are sorted and disjoint within a slice, in ``[0, 2 pi]``. The force model's
    :class:`~cnctwin.mechanics.ImmersionIntervals` takes the same slices (a gap between two
    becomes a slice without contact) and intervals, built here with array operations (what
    :meth:`~cnctwin.mechanics.ImmersionIntervals.from_slices` does slice by slice, 30 times
    slower).

    Parameters
    ----------
    engagement
        Engagement of one cut (:func:`cnctwin.geometry.cut`), mm and rad.
    pitch_z_mm
        z pitch of the dexel grid, mm (> 0).

    Returns
    -------
    cnctwin.mechanics.ImmersionIntervals or None
        Slices and contact intervals in m and rad; None when the cut has no contact interval
        (no contact, or only the bottom face of the tool cut).
    """
    owner = engagement.interval_slice.astype(np.int64)
    dz = engagement.slice_dz_mm
    if owner.size == 0:
        return None
    keep = dz > 0.0
    own_kept = keep[owner]
    if not np.any(own_kept):
        return None
    low = slice_low_mm(engagement.slice_height_mm, pitch_z_mm)[keep]
    top = low + dz[keep]
    # A new run of slices starts at the first slice and after every gap; each later run
    # needs an empty slice across its gap.
    gap = np.ones(low.size, dtype=bool)
    gap[1:] = low[1:] > top[:-1] + 1e-9 * top[-1]
    starts = np.flatnonzero(gap)
    position = np.arange(low.size) + np.cumsum(gap) - 1  # force-model slice of each slice
    bounds = np.empty(low.size + starts.size)
    bounds[position + 1] = top
    bounds[position[starts]] = low[starts]
    counts = np.zeros(bounds.size - 1, dtype=np.int64)
    kept_index = np.cumsum(keep) - 1
    owner = kept_index[owner[own_kept]]
    counts[position] = np.bincount(owner, minlength=low.size)
    entry = engagement.interval_start_rad[own_kept]
    exit_ = engagement.interval_end_rad[own_kept]
    order = np.lexsort((entry, owner))
    return ImmersionIntervals(
        z_bounds_m=bounds * 1e-3,
        offsets=np.concatenate(([0], np.cumsum(counts))),
        entry_rad=entry[order].astype(np.float64),
        exit_rad=exit_[order].astype(np.float64),
    )


def step_forces(
    step: CutStep,
    coefficients: CuttingCoefficients,
    pitch_z_mm: float,
    *,
    waveform_steps: int = _WAVEFORM_STEPS,
    drilling: DrillingMaterial | None = None,
) -> StepForces:
    """Cutting forces, torque and power of one simulated step: the milling model, or the
    drilling model for a drill or a tap (the one place that chooses by the tool's kind).

    Parameters
    ----------
    step
        The step (cutter, engagement, feed per tooth in mm, spindle speed in rpm).
    coefficients
        Cutting coefficients of the workpiece material (Pa, N/m).
    pitch_z_mm
        z pitch of the dexel grid, mm.
    waveform_steps
        Spindle angles per revolution for the peak force (>= 1); 0: no waveform, the peak
        force is the mean force's magnitude (the virtual machine's cheaper load).
    drilling
        Drilling coefficients of the workpiece material (:func:`axial_material`), needed when
        the step's tool is a drill or a tap.

    Returns
    -------
    StepForces
        Per-revolution mean forces in the machine and tool frames (N), the peak force (N),
        cutting torque (N m) and power (W); all zero without a contact interval (a milling
        tool) or without feed (a drill or a tap, :func:`axial_forces`).

    Raises
    ------
    ConfigError
        For a drill or a tap without ``drilling`` coefficients.

    Notes
    -----
    The tool frame of :mod:`cnctwin.mechanics.milling` has x along the feed direction
    ``f = engagement.feed_dir`` and y along its left normal ``n = (-f_y, f_x)``, the frame of
    the dexel engagement's angles; so ``F_X = F_x f_x + F_y n_x``, ``F_Y = F_x f_y + F_y n_y``,
    and ``F_Z = F_z`` for a tool whose axis is machine +Z.
    """
    if step.cutter.kind in AXIAL_KINDS:
        if drilling is None:
            raise ConfigError(
                f"tool T{step.tool} is a {step.cutter.kind}: its forces need the workpiece's "
                "drilling coefficients (mechanics/data/drilling.toml)"
            )
        return axial_forces(step, drilling, pitch_z_mm)
    cut = immersion_intervals(step.engagement, pitch_z_mm)
    if cut is None:
        return StepForces(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    fz_m = step.feed_per_tooth_mm * 1e-3
    omega = step.spindle_rpm * RAD_S_PER_RPM
    mean = mean_forces(step.cutter, coefficients, cut, fz_m, omega)
    peak = mean.resultant_n
    if waveform_steps > 0:
        wave = milling_forces(step.cutter, coefficients, cut, fz_m, omega, steps=waveform_steps)
        peak = float(wave.resultant_n.max())
    fx, fy = step.engagement.feed_dir
    nx, ny = -fy, fx
    return StepForces(
        fx_n=mean.fx_n * fx + mean.fy_n * nx,
        fy_n=mean.fx_n * fy + mean.fy_n * ny,
        fz_n=mean.fz_n,
        feed_n=mean.fx_n,
        normal_n=mean.fy_n,
        mean_n=mean.resultant_n,
        peak_n=peak,
        torque_nm=mean.torque_nm,
        power_w=mean.power_w,
    )


def axial_forces(step: CutStep, drilling: DrillingMaterial, pitch_z_mm: float) -> StepForces:
    """Thrust (N), torque (N m) and power (W) of a drill's or a tap's step, fed along its axis.

    The feed per revolution is the step's feed per tooth times the tool's lips (flutes), so a
    plunge at ``F`` mm/min and ``S`` rpm feeds ``F / S`` mm per revolution. A drill's engaged
    radial band comes from the dexel engagement (:func:`drill_band_mm`) and loads the lip and
    chisel-edge model of :func:`cnctwin.mechanics.drilling_load`; a tap in contact gives the
    torque of :func:`cnctwin.mechanics.tapping_torque` (its chamfer's ramp is not modelled)
    and no thrust (its lead feeds it). The lateral forces of symmetric lips cancel: the force
    on the tool is the thrust along +Z (``fz_n``, pushing the tool back), and ``mean_n`` and
    ``peak_n`` are its magnitude.

    Parameters
    ----------
    step
        A step of a drill or a tap (feed per tooth in mm, spindle speed in rpm).
    drilling
        The workpiece's drilling coefficients.
    pitch_z_mm
        z pitch of the dexel grid, mm.
    """
    cutter = step.cutter
    feed_m = step.feed_per_tooth_mm * cutter.flutes * 1e-3
    omega = abs(step.spindle_rpm) * RAD_S_PER_RPM
    if feed_m <= 0.0 or not step.engagement.contact:
        return StepForces(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if cutter.kind == "tap":
        thrust = 0.0
        torque = tapping_torque(drilling, cutter.diameter_m, cutter.pitch_mm * 1e-3)
    else:
        inner, outer = drill_band_mm(step.engagement, cutter, pitch_z_mm)
        load = drilling_load(
            drilling,
            cutter.diameter_m,
            feed_m,
            point_angle_rad=cutter.tip_angle_rad,
            web_m=cutter.web_mm * 1e-3,
            lips=cutter.flutes,
            inner_radius_m=inner * 1e-3,
            outer_radius_m=outer * 1e-3,
        )
        thrust, torque = load.thrust_n, load.torque_nm
    return StepForces(0.0, 0.0, thrust, 0.0, 0.0, thrust, thrust, torque, torque * omega)


def drill_band_mm(
    engagement: DexelEngagement, cutter: Cutter, pitch_z_mm: float
) -> tuple[float, float]:
    """The radial band ``(inner, outer)`` of a drill's point in contact, mm.

    The slices with contact span the heights ``[low, low + dz]`` above the tip, ``low`` from
    :func:`~cnctwin.geometry.engagement.slice_low_mm` (as in :func:`immersion_intervals`); on
    the point's cone the radius is ``z tan(sigma / 2)``
    (:meth:`cnctwin.geometry.Cutter.radius_at`). Heights within one grid
    pitch ``p`` of the tip, or of the cone's top, count as the tip (radius 0) or the full
    radius: the grid resolves no finer, and a drill at full depth then loads its whole edge.

    Parameters
    ----------
    engagement
        The dexel engagement of the step, mm.
    cutter
        The drill.
    pitch_z_mm
        z pitch of the dexel grid, mm (> 0).

    Returns
    -------
    tuple of float
        Inner and outer radius in mm; ``(0, 0)`` without a slice in contact.
    """
    heights = engagement.slice_height_mm
    if heights.size == 0:
        return 0.0, 0.0
    low = slice_low_mm(heights, pitch_z_mm)
    z_low = float(low.min())
    z_top = float((low + engagement.slice_dz_mm).max())
    cone = cutter.cone_height_mm
    inner = 0.0 if z_low < pitch_z_mm else float(cutter.radius_at(min(z_low, cone)))
    outer = cutter.radius_mm if z_top > cone - pitch_z_mm else float(cutter.radius_at(z_top))
    return inner, outer


def axial_material(material_name: str, cutters: Mapping[int, Cutter]) -> DrillingMaterial | None:
    """The drilling coefficients of the workpiece when a tool is a drill or a tap, else None.

    Parameters
    ----------
    material_name
        The configuration's ``[material].name``.
    cutters
        The configured tools, by number.

    Raises
    ------
    ConfigError
        When a tool is a drill or a tap and the material has no drilling coefficients: one
        line naming ``material.name``, the tool and the valid materials.
    """
    axial = sorted(n for n, c in cutters.items() if c.kind in AXIAL_KINDS)
    if not axial:
        return None
    try:
        return drilling_material(material_name)
    except ConfigError as err:
        raise ConfigError(f"material.name (for the drill or tap T{axial[0]}): {err}") from None


def simulate_signals(
    segments: Iterable[Segment],
    stock: DexelStock,
    cutters: Mapping[int, Cutter],
    coefficients: CuttingCoefficients,
    drive: SpindleDriveParameters,
    *,
    rapid_mm_min: float,
    cycle_s: float = 0.0125,
    limits: AxisLimits | None = None,
    rated_power_w: float | None = None,
    rated_torque_nm: float | None = None,
    drive_name: str = "",
    on_chunk: Callable[[float], None] | None = None,
    drilling: DrillingMaterial | None = None,
) -> MachineSignals:
    """Cut the stock along a program and predict the machine's signals at every cycle.

    Parameters
    ----------
    segments
        The interpreted program.
    stock
        The stock, cut in place.
    cutters
        Geometry of every tool the program uses, by tool number (mm).
    coefficients
        Cutting coefficients of the workpiece material (Pa, N/m).
    drive
        Spindle motor and speed controller.
    rapid_mm_min
        The machine's rapid rate, mm/min.
    cycle_s
        Cycle time, s.
    limits
        Optional axis acceleration limits for the sampler.
    rated_power_w, rated_torque_nm
        Continuous (S1) power (W) and torque (N m) of the spindle, if known: a step that needs
        a cutting torque above ``min(rated_torque_nm, rated_power_w / omega)`` at its
        commanded speed ``omega`` is flagged in the ``overload`` column.
    drive_name
        Name of the drive, for the summary.
    on_chunk
        Called with the simulated time (s) after every chunk of cycles (for progress).
    drilling
        Drilling coefficients of the workpiece (:func:`axial_material`), needed when a tool
        is a drill or a tap. A tap whose feed per revolution is more than 2 % off its pitch
        (G84 needs ``F = pitch x S``) is warned, naming the line.

    Returns
    -------
    MachineSignals
        One row per cycle, the columns of :data:`SIGNAL_COLUMNS`.

    Raises
    ------
    cnctwin.errors.NCError
        When the program moves a tool that has no geometry.
    cnctwin.errors.ConfigError
        When a step's forces cannot be computed (:func:`step_forces`), naming the program's
        line, the tool and its tip.
    """
    pitch_z = stock.grid.pitch_mm[2]
    # The contact steps of the chunk being cut and their forces, then each chunk's as
    # arrays (80 B of forces a step, not a tuple of Python floats).
    index: list[int] = []
    loads: list[tuple[float, ...]] = []
    at_parts: list[NDArray[np.int64]] = []
    load_parts: list[NDArray[np.float64]] = []
    tap_feeds: dict[int, tuple[int, float, float]] = {}  # line: tool, feed/rev, pitch (mm)

    def observe(step: CutStep) -> None:
        try:
            forces = step_forces(step, coefficients, pitch_z, drilling=drilling)
        except ConfigError as err:
            x, y, z = step.tcp_mm
            raise ConfigError(
                f"line {step.line} (T{step.tool}, tip at X{x:.4g} Y{y:.4g} Z{z:.4g} mm, "
                f"machine coordinates): {err}"
            ) from err
        index.append(step.index)
        loads.append(forces.values())
        cutter = step.cutter
        if cutter.kind == "tap" and step.line not in tap_feeds:
            feed = step.feed_per_tooth_mm * cutter.flutes
            if abs(feed - cutter.pitch_mm) > TAP_FEED_TOLERANCE * cutter.pitch_mm:
                tap_feeds[step.line] = (step.tool, feed, cutter.pitch_mm)

    table = StepTable(row_bytes=_ROW_BYTES)
    for rows in simulate_cut(
        segments,
        stock,
        cutters,
        rapid_mm_min=rapid_mm_min,
        cycle_s=cycle_s,
        limits=limits,
        on_step=observe,
    ):
        table.append(rows)
        if index:
            at_parts.append(np.asarray(index, dtype=np.int64))
            load_parts.append(np.asarray(loads, dtype=np.float64))
            index.clear()
            loads.clear()
        if on_chunk is not None and len(rows):
            on_chunk(float(rows[-1, 0]))
    n = len(table)
    columns = {name: np.zeros(n) for name in SIGNAL_COLUMNS}
    for name in (
        "t_s", "line", "tool", "x_mm", "y_mm", "z_mm", "path_speed_mm_min",
        "feed_per_tooth_mm", "contact", "ae_mm", "ap_mm", "mrr_mm3_s",
    ):  # fmt: skip
        columns[name] = table.column(name)
    columns["spindle_cmd_rpm"] = table.column("spindle_rpm")
    columns["spindle_on"] = (columns["spindle_cmd_rpm"] > 0.0).astype(np.float64)
    columns["feed_on"] = (columns["path_speed_mm_min"] > 0.0).astype(np.float64)
    if at_parts:
        at = np.concatenate(at_parts)
        block = np.concatenate(load_parts)
        for k, name in enumerate(_FORCE_COLUMNS):
            columns[name][at] = block[:, k]
    _spindle(columns, drive, cycle_s)
    omega = columns["spindle_cmd_rpm"] * RAD_S_PER_RPM
    available = np.full(n, math.inf)
    if rated_torque_nm is not None:
        available = np.minimum(available, rated_torque_nm)
    if rated_power_w is not None:
        with np.errstate(divide="ignore"):
            available = np.minimum(available, rated_power_w / omega)
    columns["overload"] = (columns["cutting_torque_nm"] > available).astype(np.float64)
    warnings = headline_warnings(columns, table.column("rapid") > 0)
    warnings.extend(
        f"line {line}: tap T{tool} feeds {feed:.4g} mm per revolution but its pitch is "
        f"{pitch:.4g} mm: tapping needs F = pitch x S (the thread is cut wrong or the tap breaks)"
        for line, (tool, feed, pitch) in sorted(tap_feeds.items())
    )
    over = np.flatnonzero(columns["overload"])
    if over.size:
        k = int(over[np.argmax(columns["cutting_torque_nm"][over])])
        warnings.append(
            f"line {int(columns['line'][k])}: the cut needs {columns['cutting_torque_nm'][k]:.3g} "
            f"N m at {columns['spindle_cmd_rpm'][k]:.0f} rpm, more than the spindle's rating "
            f"of {available[k]:.3g} N m there ({over.size} steps overloaded in all)"
        )
    return MachineSignals(columns, cycle_s, drive_name, warnings)


def _spindle(
    columns: dict[str, NDArray[np.float64]], params: SpindleDriveParameters, cycle_s: float
) -> None:
    """Run the spindle drive over the cycles; fill speed, current, motor torque and power.

    The drive runs on the cycle grid (the rows at ``k * cycle_s``): each cycle's load is the
    cutting torque averaged over the rows of that cycle (the cycle's row and the segment ends
    before it, weighted by the time each stands for), its contact whether any of them cuts.
    The rows between two cycle times take the drive's values interpolated in time.
    """
    n = columns["t_s"].size
    if n == 0:
        return
    t_rows = columns["t_s"]
    grid_k = np.rint(t_rows / cycle_s)
    grid = np.flatnonzero(t_rows == grid_k * cycle_s)
    # Each row belongs to the cycle of the first grid row at or after it.
    cycle = np.searchsorted(grid, np.arange(n))
    m = grid.size
    dt = step_durations(t_rows)
    torque = np.bincount(cycle, columns["cutting_torque_nm"] * dt, m + 1)[:m] / cycle_s
    torque[0] = columns["cutting_torque_nm"][grid[0]]  # the first row stands for no time
    touched = np.bincount(cycle, columns["contact"], m + 1)[:m] > 0
    # The drive needs a time grid of at least two samples: a one-cycle program gets a copy.
    pad = 1 if m == 1 else 0
    t = np.arange(m + pad) * cycle_s
    rpm = columns["spindle_cmd_rpm"][grid]
    rpm = np.append(rpm, rpm[-1:] if pad else [])
    load = np.append(torque, torque[-1:] if pad else [])

    def flags(values: NDArray[np.bool_]) -> NDArray[np.bool_]:
        return np.append(values, values[-1:]) if pad else values

    events = MachiningEvents(
        flags(columns["spindle_on"][grid] > 0), flags(columns["feed_on"][grid] > 0), flags(touched)
    )
    result = SpindleDrive(params).simulate(t, rpm, load, events)
    t_grid = t_rows[grid]

    def at_rows(values: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.interp(t_rows, t_grid, values[:m]) if m < n else values[:m]

    columns["spindle_speed_rpm"] = at_rows(result.speed_rpm)
    columns["spindle_current_a"] = at_rows(result.current)
    columns["motor_torque_nm"] = at_rows(result.torque)
    columns["spindle_power_w"] = at_rows(result.torque * result.speed)


def headline_warnings(
    columns: Mapping[str, NDArray[np.float64]], rapid: NDArray[np.bool_]
) -> list[str]:
    """Warnings for a headline maximum of the summary that is not a steady cut.

    A maximum (largest peak force, mean force, cutting power, cutting torque) is warned when
    the step it comes from is a rapid move (a collision, not a cut: its feed per tooth is the
    rapid rate's), or when it is a single-step spike: more than :data:`SPIKE_FACTOR` times the
    larger of the two steps beside it (a transient of one step, e.g. a corner, an entry, or an
    artefact of the discretisation; the steady value is the one beside it).

    Parameters
    ----------
    columns
        The signal columns (:data:`SIGNAL_COLUMNS`; N, W, N m).
    rapid
        (n,) whether each step belongs to a rapid move.

    Returns
    -------
    list of str
        One line per step and finding, naming the source line and the maxima it holds.
    """
    found: dict[tuple[int, str], list[str]] = {}
    n = columns["t_s"].size
    for name, key, unit in _HEADLINES:
        values = columns[name]
        if n == 0 or not values.max() > 0.0:
            continue
        k = int(np.argmax(values))
        value = float(values[k])
        if rapid[k]:
            found.setdefault((k, "rapid"), []).append(f"{key} {value:.4g} {unit}")
            continue
        beside = max(
            float(values[k - 1]) if k > 0 else 0.0, float(values[k + 1]) if k + 1 < n else 0.0
        )
        if value > SPIKE_FACTOR * beside:
            found.setdefault((k, "spike"), []).append(
                f"{key} {value:.4g} {unit} (the steps beside it: {beside:.4g} {unit})"
            )
    warnings = []
    for (k, reason), maxima in found.items():
        line = int(columns["line"][k])
        what = "; ".join(maxima)
        verb = ("comes", "is") if len(maxima) == 1 else ("come", "are")
        if reason == "rapid":
            warnings.append(
                f"line {line}: {what} {verb[0]} from a rapid move that meets material (a "
                "collision, not a cut)"
            )
        else:
            warnings.append(
                f"line {line}: {what} {verb[1]} a single-step spike at t = "
                f"{columns['t_s'][k]:.4g} s, more than {SPIKE_FACTOR:g} times the steps beside it"
            )
    return warnings
