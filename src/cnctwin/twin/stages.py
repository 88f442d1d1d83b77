"""The stages of one twin cycle (docs/twin.md; Heide 2025, Fig. 5).

Each stage is a small object with one method, :meth:`~Stage.process`, that takes the
cycle's :class:`~cnctwin.twin.state.CycleState` and returns it enriched; the runtime times
every stage. Stages know nothing of protocols: reading and writing go through a
:class:`~cnctwin.thread.MachineConnection`. A stage whose class sets ``per_sample = True``
computes from a sample: the runtime runs it only in cycles whose reading is a new sample
(:attr:`CycleState.new_sample`).

Names the read stage adds to :attr:`CycleState.predicted`: ``sample_age_s`` (s).

Names a stage adds to :attr:`CycleState.predicted` (units in the names):

- engagement: ``contact``, ``ae_mm``, ``ap_mm``, ``mrr_mm3_s``, ``feed_per_tooth_mm``;
- forces: ``predicted_force_x_n``, ``predicted_force_y_n``,
  ``predicted_force_z_n``, ``predicted_force_xy_n``, ``predicted_force_normal_n``,
  ``predicted_torque_nm``, ``predicted_power_w``;
- models: ``measured_force_xy_n``, ``force_band_low_n``, ``force_band_high_n``,
  ``force_residual_n``, ``force_scatter_n``, ``force_band_armed``, ``force_out_of_band``,
  ``deflection_um``, ``form_error_um``, ``form_error_out``;
- wear (:mod:`cnctwin.twin.tool_wear`): ``wear_vb_mm``, ``wear_sd_mm``, ``wear_stage``,
  ``wear_torque_nm``, ``wear_life_mm3``, ``wear_life_s``;
- adaptive feed (:mod:`cnctwin.twin.adaptive_feed`): ``adaptive_feed_reference``,
  ``adaptive_feed_value``, ``adaptive_feed_target_pct``, ``adaptive_feed_engaged``,
  ``adaptive_feed_teaching``;
- roughness (:mod:`cnctwin.twin.roughness`): ``roughness_ra_um``, ``roughness_kin_ra_um``,
  ``roughness_kin_rz_um``, ``roughness_kin_wall_rz_um``, ``roughness_section_ra_mean_um``,
  ``roughness_section_ra_max_um``, ``roughness_section_kin_rz_max_um``;
- chatter (:mod:`cnctwin.twin.chatter_live`): ``chatter_ratio``, ``chatter_frequency_hz``,
  ``chatter_detected``, ``chatter_vibration_um``, ``chatter_stable_rpm``, ``chatter_avoided``;
- residual stress (:mod:`cnctwin.twin.mirs`): ``mirs_max_mpa``, ``mirs_surface_xx_mpa``,
  ``mirs_surface_yy_mpa``, ``mirs_target_feed_pct``, ``mirs_target_spindle_pct``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Awaitable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cnctwin.learn import FilterSpec, WindowSpec, make_filter
from cnctwin.signals import (
    SlidingWindow,
)
from cnctwin.thread import SIGNALS, ConnectionLost, MachineConnection, RunState
from cnctwin.twin.adaptive_feed import ADAPTIVE_FEED_PREDICTIONS
from cnctwin.twin.chatter_live import CHATTER_PREDICTIONS
from cnctwin.twin.freshness import Freshness
from cnctwin.twin.mirs import MIRS_PREDICTIONS
from cnctwin.twin.monitoring import ForceBand
from cnctwin.twin.physics import TwinPhysics
from cnctwin.twin.plausibility import AXES, Plausibility
from cnctwin.twin.program import ProgramMap
from cnctwin.twin.roughness import ROUGHNESS_PREDICTIONS
from cnctwin.twin.settings import FormErrorConfig
from cnctwin.twin.state import CycleState, TwinEvent
from cnctwin.twin.tool_wear import WEAR_PREDICTIONS

if TYPE_CHECKING:
    from cnctwin.twin.config import RunConfig

__all__ = [
    "PLAUSIBLE_LIMITS",
    "PREDICTIONS",
    "CutStage",
    "EngagementStage",
    "FeatureStage",
    "FilterStage",
    "ForceBandStage",
    "FormErrorStage",
    "KinematicsStage",
    "ForceStage",
    "ReadStage",
    "Stage",
    "plausibility_problem",
]

#: Features a window may compute (methods of :class:`cnctwin.signals.windows.SlidingWindow`).

#: Every prediction name the stages add, for rule checking (units in the names).
PREDICTIONS = (
    "sample_age_s",
    "contact",
    "ae_mm",
    "ap_mm",
    "mrr_mm3_s",
    "feed_per_tooth_mm",
    "predicted_force_x_n",
    "predicted_force_y_n",
    "predicted_force_z_n",
    "predicted_force_xy_n",
    "predicted_force_normal_n",
    "predicted_torque_nm",
    "predicted_power_w",
    "measured_force_xy_n",
    "force_band_low_n",
    "force_band_high_n",
    "force_residual_n",
    "force_scatter_n",
    "force_band_armed",
    "force_out_of_band",
    "deflection_um",
    "form_error_um",
    "form_error_tolerance_um",
    "form_error_out",
    *WEAR_PREDICTIONS,
    *ADAPTIVE_FEED_PREDICTIONS,
    *ROUGHNESS_PREDICTIONS,
    *CHATTER_PREDICTIONS,
    *MIRS_PREDICTIONS,
)


class Stage(Protocol):
    """One step of the cycle."""

    name: str

    def process(self, state: CycleState) -> CycleState | Awaitable[CycleState]:
        """Enrich the cycle's state (a coroutine for stages that talk to the machine)."""
        ...


#: Largest magnitude a reading may have to be taken as a measurement, by unit: beyond it a
#: value is garbage (a wrong register, an uninitialised variable), not a machine state.
PLAUSIBLE_LIMITS = {
    "mm": 1e5,
    "mm/min": 1e6,
    "rpm": 1e6,
    "N": 1e6,
    "N m": 1e5,
    "A": 1e5,
    "W": 1e8,
    "%": 1e4,
    "s": 1e9,
    "1": 1e12,
}


def plausibility_problem(name: str, value: float) -> str | None:
    """Why a finite reading of signal ``name`` is garbage, or ``None`` when it is plausible.

    A value is implausible outside the signal's range in :data:`cnctwin.thread.SIGNALS`
    (when it has one) or beyond :data:`PLAUSIBLE_LIMITS` for its unit.
    """
    spec = SIGNALS.get(name)
    if spec is None:
        return None
    if spec.low is not None and value < spec.low:
        return f"{value!r} below {spec.low:g} {spec.unit}"
    if spec.high is not None and value > spec.high:
        return f"{value!r} above {spec.high:g} {spec.unit}"
    limit = PLAUSIBLE_LIMITS.get(spec.unit)
    if limit is not None and abs(value) > limit:
        return f"{value!r} beyond the plausible +-{limit:g} {spec.unit}"
    return None


class ReadStage:
    """Step 1: one batched read of the machine (Heide 2025, Fig. 5, "read machine state").

    Values the connection delivered but that cannot be a machine state (out of the signal's
    range or beyond :data:`PLAUSIBLE_LIMITS`, beyond the machine's axis dynamics or override
    range: :class:`~cnctwin.twin.plausibility.Plausibility`) join the connection's rejects
    (NaN, wrong types): an invalid value never reaches the stages, which hold the signal's
    last valid value, and an event says when a signal turns invalid.

    Each reading is judged new sample or repeat (:class:`~cnctwin.twin.freshness.
    Freshness`). A repeat shows the last sample's state (its values, predictions and
    position) and computes nothing new; a stale reading counts as no sample at all.

    Parameters
    ----------
    connection
        The machine.
    freshness
        New-sample and age judgement; ``None`` takes every reading as a new, current sample.
    plausibility
        Axis-jump and override checks; ``None`` checks only the catalogue ranges.

    Attributes
    ----------
    failures
        Reads that failed.
    garbage
        Values rejected so far (in new samples).
    """

    name = "read"

    def __init__(
        self,
        connection: MachineConnection,
        freshness: Freshness | None = None,
        plausibility: Plausibility | None = None,
    ) -> None:
        self.connection = connection
        self.freshness = freshness
        self.plausibility = plausibility
        self.failures = 0
        self.garbage = 0
        self._reconnects = connection.reconnects
        self._invalid: set[str] = set()
        self._sample: CycleState | None = None

    @classmethod
    def from_config(cls, connection: MachineConnection, config: RunConfig) -> ReadStage:
        """The read stage of a configuration: ``[twin] max_sample_age_s`` for freshness,
        ``[machine]`` and ``[twin.plausibility]`` for plausibility."""
        return cls(
            connection,
            Freshness(config.twin.max_sample_age_s),
            Plausibility(config.machine, config.twin.plausibility),
        )

    def forget(self) -> None:
        """Drop the reference position and the last sample (after a gap)."""
        if self.plausibility is not None:
            self.plausibility.forget()
        self._sample = None

    async def process(self, state: CycleState) -> CycleState:
        """Fill ``measured``, ``rejected``, ``received_s``, ``connected`` and the sample's
        freshness (``new_sample``, ``stale``, ``sample_age_s``, ``last_sample_s``)."""
        try:
            reading = await self.connection.read()
        except ConnectionLost:
            self.failures += 1
            state.connected = False
            if self.freshness is not None and self.freshness.last_fresh_s is not None:
                # a gap starts at the last fresh sample, also when a read times out
                state.last_sample_s = self.freshness.last_fresh_s
            return state
        state.connected = True
        state.received_s = reading.received_s
        if self.connection.reconnects != self._reconnects:
            self._reconnects = self.connection.reconnects
            how = self.connection.last_reconnect
            state.events.append(
                TwinEvent(
                    "reconnected", f"connection restored: {how}", reading.received_s, {"how": how}
                )
            )
        if self.freshness is not None:
            check = self.freshness.check(reading)
            state.new_sample, state.stale, state.sample_age_s = check.new, check.stale, check.age_s
            last = self.freshness.last_fresh_s
            state.last_sample_s = math.nan if last is None else last
        else:
            state.new_sample, state.sample_age_s = True, 0.0
            state.last_sample_s = reading.received_s
        if not state.new_sample:
            self._repeat(state)
            return state
        measured: dict[str, float] = {}
        rejected = dict(reading.rejected)
        for name, value in reading.values.items():
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                rejected[name] = f"not a finite number: {value!r}"
                continue
            problem = plausibility_problem(name, value)
            if problem is None:
                measured[name] = float(value)
            else:
                rejected[name] = problem
        if self.plausibility is not None:
            verdict = self.plausibility.check(measured, reading.received_s)
            for name, reason in verdict.invalid.items():
                rejected[name] = reason
                del measured[name]
            state.path_break = verdict.path_break
        self.garbage += len(rejected)
        self._announce(state, reading.values, rejected)
        state.measured = measured
        state.rejected = rejected
        state.predicted["sample_age_s"] = state.sample_age_s
        self._sample = state
        return state

    def _repeat(self, state: CycleState) -> None:
        """A reading with nothing new: show the last sample's state."""
        last = self._sample
        if last is None:
            return
        state.measured = dict(last.measured)
        state.rejected = dict(last.rejected)
        state.position_mm, state.tool, state.line = last.position_mm, last.tool, last.line
        state.filtered = dict(last.filtered)
        state.features = dict(last.features)
        state.predicted = dict(last.predicted)
        state.predicted["sample_age_s"] = state.sample_age_s

    def _announce(
        self, state: CycleState, raw: Mapping[str, float], rejected: Mapping[str, str]
    ) -> None:
        """An event for every signal that turns invalid with this sample."""
        for name in [n for n in rejected if n not in self._invalid]:
            value = raw.get(name)
            shown = (
                value if isinstance(value, float | int) and math.isfinite(value) else repr(value)
            )
            state.events.append(
                TwinEvent(
                    "signal_invalid",
                    f"{name} invalid: {rejected[name]}",
                    state.received_s,
                    {"signal": name, "value": shown, "reason": rejected[name]},
                )
            )
        self._invalid = set(rejected)


class KinematicsStage:
    """Step 2: the twin's tool tip from the machine's axes and its own reading of the program.

    The machine reports its controlled point in the machine frame (``x_mm``, ``y_mm``,
    ``z_mm``: the tool tip plus the tool length offset and the length wear offset), the tool
    in the spindle and the executing line. The twin takes off the offset its own
    interpretation of the program gives for that line (:class:`~cnctwin.twin.program.
    ProgramMap`) and the wear offset the machine reads back. A missing or garbage axis keeps
    the last good position; the machine time ``t_s`` gives the time between two positions.

    Parameters
    ----------
    program
        Tool offsets by line (and by tool).
    deadband_mm
        Axis noise dead band, mm: a reading within it of the held axis position keeps the
        held one (:attr:`~cnctwin.twin.settings.TwinSettings.position_deadband_mm`).
    """

    per_sample = True
    name = "kinematics"

    def __init__(self, program: ProgramMap, deadband_mm: float = 0.0) -> None:
        self.program = program
        self.deadband_mm = deadband_mm
        self._axes = np.full(3, np.nan)
        self._t_s = math.nan
        self._tool = 0
        self._line = 0

    def forget(self) -> None:
        """Drop the previous machine time (after a gap in the connection)."""
        self._t_s = math.nan

    def process(self, state: CycleState) -> CycleState:
        """Set ``position_mm``, ``tool``, ``line`` and ``dt_machine_s``."""
        if not state.connected:
            return state
        m = state.measured
        axes = self._axes.copy()
        for axis, name in enumerate(("x_mm", "y_mm", "z_mm")):
            value = m.get(name)
            if value is not None and not abs(value - axes[axis]) <= self.deadband_mm:
                axes[axis] = value
        self._axes = axes
        tool = m.get("tool_number")
        if tool is not None and 0 <= tool < 1e6:
            self._tool = int(tool)
        line = m.get("program_line")
        if line is not None and 0 <= line < 1e9:
            self._line = int(line)
        t = m.get("t_s")
        if t is not None:
            state.dt_machine_s = t - self._t_s if math.isfinite(self._t_s) else 0.0
            self._t_s = t
        dx, dy, dz = self.program.offset_mm(self._line, self._tool)
        wear = m.get("tool_length_wear_mm", 0.0)
        tip = axes - np.array((dx, dy, dz + wear))
        state.position_mm = tip if bool(np.all(np.isfinite(tip))) else None
        state.tool = self._tool
        state.line = self._line
        return state


class CutStage:
    """Step 3: Boolean cut of the twin's own dexel stock at the tool position.

    The twin's blank is the configured one, so it stands for the machine's blank only when
    the twin has watched the program from its start. On the first reading the stage checks
    the machine's program clock: a program already running for more than ``attach_s`` makes
    the blank *unsynchronized* (the force band stays off, an event says so); when the
    program clock goes back (the program started again) the twin takes a fresh blank and is
    synchronized again.

    Parameters
    ----------
    physics
        The twin's stock, tools and material.
    attach_s
        Machine time after which a running program counts as already under way, s.
    """

    per_sample = True
    name = "cut"

    def __init__(self, physics: TwinPhysics, attach_s: float = 1.0) -> None:
        self.twin = physics
        self.attach_s = attach_s
        self._last_t_s: float | None = None

    def forget(self) -> None:
        """Start a new path after a gap: the machine moved while the twin was blind."""
        self.twin.forget_position()

    def process(self, state: CycleState) -> CycleState:
        """Set ``engagement`` and the predicted ``feed_per_tooth_mm``."""
        m = state.measured
        t = m.get("t_s")
        fresh_blank = t is not None and self._synchronize(state, t)
        if state.position_mm is None:
            return state
        if fresh_blank and any(axis in state.rejected for axis in AXES):
            return state  # the held position is the old run's: not on the fresh blank
        if state.path_break:
            self.twin.forget_position()
        engagement, fz = self.twin.cut(
            state.position_mm,
            state.tool,
            m.get("spindle_rpm", 0.0),
            m.get("feed_mm_min", 0.0),
            state.dt_machine_s,
        )
        state.engagement = engagement
        state.predicted["feed_per_tooth_mm"] = fz
        return state

    def _synchronize(self, state: CycleState, t_s: float) -> bool:
        """Check the program clock; ``True`` when the twin took a fresh blank."""
        last, self._last_t_s = self._last_t_s, t_s
        running = state.measured.get("run_state") in (RunState.RUNNING, RunState.FEED_HOLD)
        if last is None:
            if running and t_s > self.attach_s:
                self.twin.synchronized = False
                state.events.append(
                    TwinEvent(
                        "blank_unknown",
                        f"attached to a program running for {t_s:.1f} s: the twin does not "
                        "know what was cut, force monitoring is off until the program starts "
                        "again",
                        time.monotonic(),
                        {"t_s": t_s},
                    )
                )
        elif t_s < last - self.attach_s:
            self.twin.reset_stock()
            state.events.append(
                TwinEvent(
                    "blank_reset",
                    "the program started again: the twin takes a fresh blank",
                    time.monotonic(),
                    {"t_s": t_s},
                )
            )
            return True
        return False


class EngagementStage:
    """Step 4: engagement figures of the cut (Heide 2025, Fig. 5, "engagement")."""

    per_sample = True
    name = "engagement"

    def process(self, state: CycleState) -> CycleState:
        """Add ``contact``, ``ae_mm``, ``ap_mm`` and ``mrr_mm3_s`` to the predictions."""
        e = state.engagement
        p = state.predicted
        if e is None or not e.contact:
            p.update(contact=0.0, ae_mm=0.0, ap_mm=0.0, mrr_mm3_s=0.0)
            return state
        p.update(contact=1.0, ae_mm=e.ae_mm, ap_mm=e.ap_mm, mrr_mm3_s=e.mrr_mm3_s)
        return state


class ForceStage:
    """Step 6: forces, torque and power of the mechanistic model.

    Parameters
    ----------
    physics
        The twin's tools and material (the mechanistic force model's inputs).
    """

    per_sample = True
    name = "forces"

    def __init__(self, physics: TwinPhysics) -> None:
        self.twin = physics

    def process(self, state: CycleState) -> CycleState:
        """Add the ``predicted_*`` forces (N), torque (N m) and power (W)."""
        p = state.predicted
        e = state.engagement
        if e is None or not e.contact:
            f = None
        else:
            f = self.twin.forces(
                e, state.tool, state.measured.get("spindle_rpm", 0.0), p["feed_per_tooth_mm"]
            )
        if f is None:
            p.update(
                predicted_force_x_n=0.0,
                predicted_force_y_n=0.0,
                predicted_force_z_n=0.0,
                predicted_force_xy_n=0.0,
                predicted_force_normal_n=0.0,
                predicted_torque_nm=0.0,
                predicted_power_w=0.0,
            )
            return state
        p.update(
            predicted_force_x_n=f.fx_n,
            predicted_force_y_n=f.fy_n,
            predicted_force_z_n=f.fz_n,
            predicted_force_xy_n=math.hypot(f.fx_n, f.fy_n),
            predicted_force_normal_n=f.normal_n,
            predicted_torque_nm=f.torque_nm,
            predicted_power_w=f.power_w,
        )
        return state


class FilterStage:
    """Step 7: causal filters on measured signals (Heide 2025, Sec. 2.3: Hampel, Kalman,
    Butterworth).

    Parameters
    ----------
    filters
        Filter configuration by measured signal name.
    cycle_s
        Sample period, s.
    """

    per_sample = True
    name = "filters"

    def __init__(self, filters: Mapping[str, FilterSpec], cycle_s: float) -> None:
        self.filters = {name: make_filter(cfg, cycle_s) for name, cfg in filters.items()}

    def process(self, state: CycleState) -> CycleState:
        """Set ``filtered`` for every filtered signal (NaN-safe: a missing sample is held)."""
        if not state.connected:
            return state
        for name, flt in self.filters.items():
            state.filtered[name] = flt.update(state.measured.get(name, math.nan))
        return state


@dataclass
class _Window:
    signal: str
    window: SlidingWindow
    features: tuple[str, ...]


class FeatureStage:
    """Step 8: sliding windows and their features (``"<signal>_<feature>"``).

    Parameters
    ----------
    windows
        Which signals, how long, which features (of :data:`cnctwin.learn.WINDOW_FEATURES`).
    cycle_s
        Sample period, s.
    """

    per_sample = True
    name = "features"

    def __init__(self, windows: Sequence[WindowSpec], cycle_s: float) -> None:
        self.windows = [
            _Window(w.signal, SlidingWindow(w.length, 1.0 / cycle_s), tuple(w.features))
            for w in windows
        ]

    def process(self, state: CycleState) -> CycleState:
        """Push this cycle's value of each windowed signal; add its features."""
        if not state.connected:
            return state
        for w in self.windows:
            value = state.filtered.get(w.signal)
            if value is None:
                value = state.predicted.get(w.signal, state.measured.get(w.signal, math.nan))
            if not math.isfinite(value):
                continue
            w.window.push(value, state.measured.get("t_s"))
            for feature in w.features:
                state.features[f"{w.signal}_{feature}"] = float(getattr(w.window, feature)())
        return state


class ForceBandStage:
    """Step 9a: the force band of use case 1 (Heide 2025, Sec. 3.1).

    The measured force is the XY resultant of the dynamometer (``force_x_n``, ``force_y_n``,
    filtered where a filter is configured); the prediction is that of the force stage.

    Parameters
    ----------
    band
        The band model.
    physics
        The twin's blank: while it is not synchronized with the machine's, the band is off.
    """

    per_sample = True
    name = "force_band"

    def __init__(self, band: ForceBand, physics: TwinPhysics | None = None) -> None:
        self.band = band
        self.twin = physics

    def forget(self) -> None:
        """Settle again before arming (after a gap in the connection)."""
        self.band.reset_contact()

    def process(self, state: CycleState) -> CycleState:
        """Add ``measured_force_xy_n`` and the ``force_band_*`` / ``force_*`` predictions."""
        if not state.connected:
            return state
        fx = state.filtered.get("force_x_n", state.measured.get("force_x_n", math.nan))
        fy = state.filtered.get("force_y_n", state.measured.get("force_y_n", math.nan))
        p = state.predicted
        if not (math.isfinite(fx) and math.isfinite(fy)):
            p["force_out_of_band"] = 0.0
            p["force_band_armed"] = 0.0
            return state
        if self.twin is not None and not self.twin.synchronized:
            p["force_out_of_band"] = 0.0
            p["force_band_armed"] = 0.0
            return state
        measured = math.hypot(fx, fy)
        result = self.band.update(p.get("predicted_force_xy_n", 0.0), measured)
        p.update(
            measured_force_xy_n=measured,
            force_band_low_n=result.low_n,
            force_band_high_n=result.high_n,
            force_residual_n=result.residual_n,
            force_scatter_n=result.scatter_n,
            force_band_armed=float(result.armed),
            force_out_of_band=float(result.out_of_band),
        )
        return state


class FormErrorStage:
    """Step 9b: form error of the wall from the tool's static deflection (Heide 2025, use
    case 2; :mod:`cnctwin.quality.form_error`).

    The predicted force normal to the feed direction in the XY plane (the wall's normal in
    side milling) over the tool's bending stiffness at the tip gives the wall's deviation.
    Like the force band, it is off (0) while the twin's blank is not synchronized with the
    machine's: the predicted force would come from material the machine already removed.

    Parameters
    ----------
    config
        Tolerance, stiffness or overhang, Young's modulus.
    physics
        The twin's tools (diameter and fluted length for the stiffness).
    """

    per_sample = True
    name = "form_error"

    def __init__(self, config: FormErrorConfig, physics: TwinPhysics) -> None:
        from cnctwin.quality import end_mill_stiffness

        self.tolerance_um = config.tolerance_um
        self.twin = physics
        self.stiffness_n_m: dict[int, float] = {}
        for number, cutter in physics.cutters.items():
            if config.stiffness_n_um is not None:
                self.stiffness_n_m[number] = config.stiffness_n_um * 1e6
                continue
            overhang = config.overhang_mm
            self.stiffness_n_m[number] = end_mill_stiffness(
                cutter.diameter_mm * 1e-3,
                overhang * 1e-3,
                min(cutter.flute_length_mm, overhang) * 1e-3,
                youngs_modulus_pa=config.youngs_modulus_gpa * 1e9,
            )

    def process(self, state: CycleState) -> CycleState:
        """Add ``deflection_um``, ``form_error_um``, ``form_error_tolerance_um`` and
        ``form_error_out``."""
        from cnctwin.quality import form_error

        p = state.predicted
        k = self.stiffness_n_m.get(state.tool)
        if k is None or not state.connected or not self.twin.synchronized:
            p.update(deflection_um=0.0, form_error_um=0.0, form_error_out=0.0)
        else:
            normal = abs(p.get("predicted_force_normal_n", 0.0))
            error_um = float(form_error(normal, k)) * 1e6
            p.update(
                deflection_um=float(form_error(p.get("predicted_force_xy_n", 0.0), k)) * 1e6,
                form_error_um=error_um,
                form_error_out=float(error_um > self.tolerance_um),
            )
        p["form_error_tolerance_um"] = self.tolerance_um
        return state
