"""Step 9c of the cycle: the tool's flank wear from the spindle torque (Christiand 2024's EKF).

:class:`WearStage` feeds :class:`cnctwin.wear.WearEKF` one step per new sample: the material
the twin's stock lost in the sample (mm^3) and, while the tool cuts, the measured spindle
torque against the torque without wear: the idle torque (learnt while the spindle turns in
air at a steady speed) plus the mechanistic model's cutting torque (``predicted_torque_nm``
of the force stage). Christiand 2024's wear-torque model holds for the cutting conditions it
was calibrated in, so the filter updates only in a steady cut: the spindle speed and the
predicted cutting torque held (within ``steady_fraction``) for ``settle_samples`` samples;
entering and leaving the material, and speed changes (a stop braking the spindle), only
predict. Its estimate, stage and remaining life become predictions that rules
read and the historian records; a stage entry is an event. One filter per tool number.

Names it adds to :attr:`CycleState.predicted` (units in the names): ``wear_vb_mm``,
``wear_sd_mm``, ``wear_stage`` (1-4), ``wear_torque_nm`` (measured minus the torque without
wear, in contact), ``wear_life_mm3`` and ``wear_life_s`` (material and cutting time left to
``life_vb_mm``; the time at the mean removal rate while cutting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from cnctwin.twin.physics import TwinPhysics
from cnctwin.twin.settings import WearConfig
from cnctwin.twin.state import CycleState, TwinEvent
from cnctwin.wear import LogisticWear, StageMonitor, WearEKF, WearTorque, remaining_life

__all__ = ["WEAR_PREDICTIONS", "WearStage"]

#: The names the wear stage adds (units in the names).
WEAR_PREDICTIONS = (
    "wear_vb_mm",
    "wear_sd_mm",
    "wear_stage",
    "wear_torque_nm",
    "wear_life_mm3",
    "wear_life_s",
)

# A spindle speed counts as steady (idle torque may be learnt) when it moved less than this
# fraction plus this many rpm since the last sample (acceleration torque would bias it).
_STEADY_FRACTION = 0.005
_STEADY_RPM = 5.0


@dataclass
class _ToolWear:
    """One tool's filter, stage monitor and cutting history."""

    ekf: WearEKF
    stages: StageMonitor
    cut_s: float = 0.0
    removed_mm3: float = 0.0
    #: Stage (as text) -> the estimate when the tool entered it: cut s, VB mm, sd mm.
    entries: dict[str, dict[str, float]] = field(default_factory=dict)
    vb_mm: float = math.nan
    sd_mm: float = math.nan


class WearStage:
    """The wear EKF in the cycle (``[twin.wear]``).

    Parameters
    ----------
    config
        Models, noise, stages, life criterion.
    physics
        The twin's stock: while it is not synchronized with the machine's, the predicted
        cutting torque is not the machine's, and the filter only predicts.

    Attributes
    ----------
    idle_torque_nm
        The learnt idle torque, N m (``nan`` until the spindle was seen in air).
    """

    per_sample = True
    name = "wear"

    def __init__(self, config: WearConfig, physics: TwinPhysics | None = None) -> None:
        self.config = config
        self.twin = physics
        self.law = LogisticWear(config.q_per_mm3, config.vb_max_mm)
        self.torque_model = WearTorque(
            config.p0_nm, config.p1_per_mm, config.p2, config.p3_per_mm, config.p4_nm
        )
        self.idle_torque_nm = math.nan
        self._idle_n = 0
        self._rpm = math.nan
        self._predicted_nm = math.nan
        self._steady_n = 0
        self._tools: dict[int, _ToolWear] = {}

    def _tool(self, number: int) -> _ToolWear:
        """The state of tool ``number`` (a new tool at ``vb0_mm`` the first time)."""
        found = self._tools.get(number)
        if found is None:
            c = self.config
            ekf = WearEKF(
                self.law,
                self.torque_model,
                process_var_mm2=c.process_var_mm2,
                measurement_var_nm2=c.measurement_var_nm2,
                vb0_mm=c.vb0_mm,
                var0_mm2=c.sd0_mm**2,
            )
            found = _ToolWear(ekf, StageMonitor(c.stages_mm, c.expected_entry_s))
            found.stages.update(0.0, c.vb0_mm)  # a tool that starts worn starts in its stage
            self._tools[number] = found
        return found

    def forget(self) -> None:
        """After a gap: the speed and torque seen last are no reference for steadiness."""
        self._rpm = self._predicted_nm = math.nan
        self._steady_n = 0

    def _torque(self, state: CycleState) -> float:
        """The measured spindle torque magnitude, N m (``nan`` when not measured)."""
        c = self.config
        value = state.filtered.get(c.signal, state.measured.get(c.signal, math.nan))
        if c.signal == "spindle_current_a":
            value *= c.torque_constant_nm_a or math.nan
        return abs(value)

    def _steady(self, rpm: float) -> bool:
        """Whether the spindle speed held since the last sample (no acceleration torque)."""
        last, self._rpm = self._rpm, rpm
        return abs(rpm) > _STEADY_RPM and (
            abs(rpm - last) <= _STEADY_FRACTION * abs(rpm) + _STEADY_RPM
        )

    def _learn_idle(self, torque_nm: float) -> None:
        """Average the torque of a spindle turning in air at a steady speed."""
        if not math.isfinite(torque_nm):
            return
        self._idle_n = min(self._idle_n + 1, self.config.idle_samples)
        if self._idle_n == 1:
            self.idle_torque_nm = torque_nm
        else:
            self.idle_torque_nm += (torque_nm - self.idle_torque_nm) / self._idle_n

    def _settled(self, predicted_nm: float, steady_rpm: bool) -> bool:
        """Count samples of a steady cut (speed and predicted torque held); ``True`` once
        ``settle_samples`` of them followed one another."""
        last, self._predicted_nm = self._predicted_nm, predicted_nm
        held = abs(predicted_nm - last) <= self.config.steady_fraction * abs(predicted_nm)
        self._steady_n = self._steady_n + 1 if (held and steady_rpm) else 0
        return self._steady_n >= self.config.settle_samples

    def process(self, state: CycleState) -> CycleState:
        """Step the tool's filter; add the ``wear_*`` predictions and stage events."""
        if not state.connected or state.tool <= 0:
            return state
        p = state.predicted
        rpm = state.measured.get("spindle_rpm", math.nan)
        torque = self._torque(state)
        engagement = state.engagement
        contact = engagement is not None and bool(engagement.contact)
        tool = self._tool(state.tool)
        steady_rpm = self._steady(rpm)
        if not contact:
            self._settled(0.0, False)
            if steady_rpm:
                self._learn_idle(torque)
            step = tool.ekf.step(0.0)
        else:
            assert engagement is not None
            removed = max(float(engagement.removed_volume_mm3), 0.0)
            dt = state.dt_machine_s if math.isfinite(state.dt_machine_s) else 0.0
            tool.cut_s += max(dt, 0.0)
            tool.removed_mm3 += removed
            cutting_nm = abs(p.get("predicted_torque_nm", 0.0))
            settled = self._settled(cutting_nm, steady_rpm)
            synchronized = self.twin is None or self.twin.synchronized
            known = math.isfinite(torque) and math.isfinite(self.idle_torque_nm)
            if settled and synchronized and known:
                base = self.idle_torque_nm + cutting_nm
                step = tool.ekf.step(removed, torque, torque_base_nm=base)
                p["wear_torque_nm"] = torque - base
            else:
                step = tool.ekf.step(removed)
        vb, var = step.vb_mm, step.var_mm2
        tool.vb_mm, tool.sd_mm = vb, math.sqrt(max(var, 0.0))
        for event in tool.stages.update(tool.cut_s, vb):
            tool.entries[str(event.stage)] = {
                "cut_s": event.time_s,
                "vb_mm": event.vb_mm,
                "sd_mm": tool.sd_mm,
            }
            state.events.append(
                TwinEvent(
                    "wear_stage",
                    f"T{state.tool} {event.message}",
                    state.received_s,
                    {
                        "tool": state.tool,
                        "stage": event.stage,
                        "vb_mm": event.vb_mm,
                        "cut_s": event.time_s,
                        "early": event.early,
                    },
                )
            )
        rate = tool.removed_mm3 / tool.cut_s if tool.cut_s > 0.0 else None
        life = remaining_life(self.law, vb, var, self.config.life_vb_mm, removal_rate_mm3_s=rate)
        p.update(
            wear_vb_mm=vb,
            wear_sd_mm=math.sqrt(max(var, 0.0)),
            wear_stage=float(tool.stages.stage),
            wear_life_mm3=life.material_mm3,
        )
        if math.isfinite(life.time_s):
            p["wear_life_s"] = life.time_s
        return state

    def run_results(self) -> dict[str, Any]:
        """Per tool number (as text), for the run's summary: the last estimate (VB and its
        sd, mm; stage 1-4), cutting time (s), material removed (mm^3) and the estimate at
        each stage entry during the run (cut s, VB mm, sd mm)."""
        return {
            str(number): {
                "vb_mm": tool.vb_mm,
                "sd_mm": tool.sd_mm,
                "stage": tool.stages.stage,
                "cut_s": tool.cut_s,
                "removed_mm3": tool.removed_mm3,
                "stage_entries": dict(tool.entries),
            }
            for number, tool in self._tools.items()
        }
