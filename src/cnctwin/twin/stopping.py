"""Stop confirmation by motion, and the escalation when the machine does not stop.

A stop the twin sent counts as done only when the machine is seen at rest: every axis speed,
from successive positions (``x_mm``, ``y_mm``, ``z_mm``) over the machine clock ``t_s``
(the reading's arrival time where the machine has no clock), and the path feed
``feed_mm_min`` at most ``rest_speed_mm_min`` in ``rest_readings`` successive readings. A
``stop`` flag that reads back 1 while the axes move is no stop.

:class:`StopWatch` follows one stop from the write of its first step. Each step of the
ladder (:data:`LADDER`: feed hold, stop, emergency stop) has ``timeout_s`` of the twin's
clock to bring the axes to rest; when it does not, :meth:`StopWatch.update` names the next
step to write, where the machine offers it (its reading carries the command's read-back).
A step whose axes were last seen at rest, short of ``rest_readings`` new samples (a starved
machine publishes slowly), gets up to twice ``timeout_s`` before it counts as failed. It
never releases anything: a step adds to the ones before it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

from cnctwin.errors import InputError
from cnctwin.twin.settings import StopConfirmationConfig

__all__ = ["LADDER", "StopStatus", "StopWatch", "Verdict"]

#: The escalation ladder, mildest first: each is a latching command of
#: :data:`cnctwin.thread.signals.COMMANDS` that brings the axes to rest.
LADDER = ("feed_hold", "stop", "emergency_stop")

_AXES = ("x_mm", "y_mm", "z_mm")

Verdict = Literal["watching", "confirmed", "escalate", "failed"]


@dataclass(frozen=True, slots=True)
class StopStatus:
    """What one reading says about a stop in progress.

    Attributes
    ----------
    verdict
        ``"watching"`` (not at rest yet, time left), ``"confirmed"`` (at rest),
        ``"escalate"`` (time is up: write ``next_step``) or ``"failed"`` (time is up and no
        step is left, or escalation is off).
    step
        The step in force (a name of :data:`LADDER`).
    next_step
        The step to write now with ``"escalate"``, else ``None``.
    speed_mm_min
        The fastest axis speed or path feed last seen since the step was written, mm/min
        (NaN when none was).
    waited_s
        Time since the step in force was written, s.
    """

    verdict: Verdict
    step: str
    next_step: str | None
    speed_mm_min: float
    waited_s: float


class StopWatch:
    """Follows one stop from its first step until the axes rest or the ladder is spent.

    Parameters
    ----------
    step
        The step written first (a name of :data:`LADDER`).
    started_s
        When it was written, s (the twin's clock: ``CycleState.time_s``).
    config
        Timeout, rest speed and readings, whether to escalate.
    """

    def __init__(self, step: str, started_s: float, config: StopConfirmationConfig) -> None:
        if step not in LADDER:
            raise InputError(f"stop step {step!r}; valid: {', '.join(LADDER)}")
        self.step = step
        self.step_s = started_s
        self.started_s = started_s
        self.config = config
        self.steps = [step]
        self._last: tuple[float, tuple[float, ...]] | None = None
        self._rest = 0
        self._seen_mm_min = math.nan

    def escalated(self, step: str, now_s: float) -> None:
        """The step ``step`` was written at ``now_s`` (s): its timeout starts."""
        self.step = step
        self.step_s = now_s
        self.steps.append(step)

    def update(self, values: Mapping[str, float], now_s: float) -> StopStatus:
        """Judge one reading (canonical names) taken at the twin's time ``now_s`` (s)."""
        speed = self._speed(values, now_s)
        waited = now_s - self.step_s
        rest = self.config.rest_speed_mm_min
        if math.isfinite(speed):
            self._seen_mm_min = speed
            self._rest = self._rest + 1 if speed <= rest else 0
        if self._rest >= self.config.rest_readings:
            return StopStatus("confirmed", self.step, None, speed, waited)
        timeout = self.config.timeout_s
        if self._seen_mm_min <= rest:  # last seen at rest: wait for the confirming samples
            timeout *= 2.0
        if waited < timeout:
            return StopStatus("watching", self.step, None, self._seen_mm_min, waited)
        speed = self._seen_mm_min
        following = self._next(values)
        if following is None or not self.config.escalate:
            return StopStatus("failed", self.step, None, speed, waited)
        return StopStatus("escalate", self.step, following, speed, waited)

    def _next(self, values: Mapping[str, float]) -> str | None:
        """The next step the machine offers (its reading carries the read-back), or None."""
        for step in LADDER[LADDER.index(self.step) + 1 :]:
            if step in values:
                return step
        return None

    def _speed(self, values: Mapping[str, float], now_s: float) -> float:
        """Fastest axis speed (from the previous reading) or path feed, mm/min.

        NaN when nothing new is known: the same machine sample read again (``t_s`` did not
        advance), or neither a feed signal nor positions.
        """
        speeds = []
        feed = values.get("feed_mm_min")
        if feed is not None and math.isfinite(feed):
            speeds.append(abs(feed))
        t = values.get("t_s", now_s)
        position = tuple(values.get(axis, math.nan) for axis in _AXES)
        if math.isfinite(t) and all(math.isfinite(p) for p in position):
            if self._last is not None:
                t0, p0 = self._last
                if t == t0:
                    return math.nan
                if t > t0:
                    moved = max(abs(a - b) for a, b in zip(position, p0, strict=True))
                    speeds.append(moved / (t - t0) * 60.0)
            self._last = (t, position)
        return max(speeds) if speeds else math.nan
