"""Plausibility of a sample against the machine's own limits: axis dynamics and override ranges.

A value can be a finite number inside its signal's catalogue range and still be no machine
state: an axis 1 m from where it was one cycle ago, a feed override above what the machine's
dial allows. :class:`Plausibility` marks such a value *invalid for that sample*; the read
stage then keeps it out of the cycle (the twin holds the last valid position, so nothing is
cut along an implausible jump, and every rule that reads it stays quiet).

Axis jumps. Between two samples ``dt`` s apart an axis moves at most
``v_max dt + a_max dt^2 / 2`` (``v_max``: the larger of the axis's ``max_velocity_mm_min``
and the machine's ``rapid_mm_min``, over 60; ``a_max``: ``max_accel_mm_s2``, from
``[machine]``). A move beyond ``jump_margin`` times that plus ``jump_floor_mm`` is a jump;
``dt`` is the larger of the machine-time step (``t_s``) and the receive-time step, so a slow
or scaled-time machine is never judged too strictly. A jump invalidates the whole position
(x, y and z: one reading of the tool). The first sample, and the first after :meth:`forget`
(a lost connection), is the new reference. When the sample after a jump agrees with the
jumped position instead of the old one, the axis really is there: the new position is taken
and :attr:`PlausibilityResult.path_break` says the path starts anew (no cut joins the two).

Units: mm, mm/min, mm/s^2, %, s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from cnctwin.config import MachineConfig
from cnctwin.twin.settings import PlausibilityConfig

__all__ = ["AXES", "Plausibility", "PlausibilityResult"]

#: The position signals, in axis order.
AXES = ("x_mm", "y_mm", "z_mm")


@dataclass(slots=True)
class PlausibilityResult:
    """The verdict on one sample.

    Attributes
    ----------
    invalid
        Signal name -> one-line reason, for each value that is no machine state.
    path_break
        The position moved to a place it could not reach continuously, and the twin takes
        it: the next cut starts a new path.
    """

    invalid: dict[str, str] = field(default_factory=dict)
    path_break: bool = False


class Plausibility:
    """Checks samples against the machine's axis dynamics and override ranges.

    Parameters
    ----------
    machine
        ``[machine]``: axis velocities and accelerations, rapid rate.
    config
        ``[twin.plausibility]``: margin, floor, override ranges.
    """

    def __init__(self, machine: MachineConfig, config: PlausibilityConfig) -> None:
        axes = machine.axes
        self.config = config
        self.v_max_mm_s = np.array(
            [
                max(a.max_velocity_mm_min, machine.rapid_mm_min) / 60.0
                for a in (axes.x, axes.y, axes.z)
            ]
        )
        self.a_max_mm_s2 = np.array([a.max_accel_mm_s2 for a in (axes.x, axes.y, axes.z)])
        self._ref: np.ndarray | None = None
        self._ref_times = (math.nan, math.nan)
        self._candidate: np.ndarray | None = None
        self._candidate_times = (math.nan, math.nan)

    def forget(self) -> None:
        """Drop the reference position (after a gap: the machine moved unseen)."""
        self._ref = self._candidate = None

    def reach_mm(self, dt_s: float) -> np.ndarray:
        """Largest plausible move of each axis in ``dt_s`` s, margin and floor included, mm."""
        dt = max(dt_s, 0.0)
        c = self.config
        return c.jump_margin * (self.v_max_mm_s * dt + 0.5 * self.a_max_mm_s2 * dt * dt) + (
            c.jump_floor_mm
        )

    def check(self, values: Mapping[str, float], received_s: float) -> PlausibilityResult:
        """Judge one sample's values (finite numbers, canonical names); ``received_s`` is its
        receive time (monotonic s)."""
        result = PlausibilityResult()
        self._overrides(values, result)
        if all(name in values for name in AXES):
            self._position(values, received_s, result)
        return result

    def _overrides(self, values: Mapping[str, float], result: PlausibilityResult) -> None:
        c = self.config
        feed = values.get("feed_override_pct")
        if feed is not None and not 0.0 <= feed <= c.feed_override_max_pct:
            result.invalid["feed_override_pct"] = (
                f"feed override {feed:g} % outside the machine's 0..{c.feed_override_max_pct:g} % "
                "([twin.plausibility] feed_override_max_pct)"
            )
        spindle = values.get("spindle_override_pct")
        low, high = c.spindle_override_min_pct, c.spindle_override_max_pct
        if spindle is not None and not low <= spindle <= high:
            result.invalid["spindle_override_pct"] = (
                f"spindle override {spindle:g} % outside the machine's {low:g}..{high:g} % "
                "([twin.plausibility] spindle_override_min_pct/max_pct)"
            )

    def _position(
        self, values: Mapping[str, float], received_s: float, result: PlausibilityResult
    ) -> None:
        position = np.array([values[name] for name in AXES])
        times = (values.get("t_s", math.nan), received_s)
        if self._ref is None:
            self._take(position, times)
            return
        if self._fits(position, times, self._ref, self._ref_times):
            self._take(position, times)
            return
        if self._candidate is not None and self._fits(
            position, times, self._candidate, self._candidate_times
        ):
            self._take(position, times)
            result.path_break = True
            return
        moved = np.abs(position - self._ref)
        axis = int(np.argmax(moved / self.reach_mm(self._dt(times, self._ref_times))))
        reason = (
            f"{AXES[axis]} jumped {moved[axis]:.3f} mm, beyond the axis dynamics "
            f"({self.reach_mm(self._dt(times, self._ref_times))[axis]:.3f} mm reachable)"
        )
        for name in AXES:
            result.invalid[name] = reason
        self._candidate, self._candidate_times = position, times

    def _take(self, position: np.ndarray, times: tuple[float, float]) -> None:
        self._ref, self._ref_times = position, times
        self._candidate = None

    def _fits(
        self,
        position: np.ndarray,
        times: tuple[float, float],
        ref: np.ndarray,
        ref_times: tuple[float, float],
    ) -> bool:
        reach = self.reach_mm(self._dt(times, ref_times))
        return bool(np.all(np.abs(position - ref) <= reach))

    @staticmethod
    def _dt(times: tuple[float, float], ref_times: tuple[float, float]) -> float:
        steps = [now - then for now, then in zip(times, ref_times, strict=True)]
        finite = [s for s in steps if math.isfinite(s)]
        return max(finite) if finite else 0.0
