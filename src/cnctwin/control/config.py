"""The ``[[rules]]`` and ``[control]`` tables of a twin configuration.

A rule says *when* (a condition over signals and predictions, held for a duration) and *what*
(stop, feed hold, a feed or spindle override, a tool-change request or a notification);
``[control]`` says whether the twin may command the machine at all and within which bounds and
rates. See docs/control.md.

Example::

    [control]
    enabled = true
    [control.feed_override]
    min_pct = 30
    max_pct = 100

    [[rules]]
    name = "hole_in_blank"
    condition = "measured_force_xy_n < force_band_low_n and feed_mm_min > 10"
    for_s = 0.025
    action = "stop"
    reason = "force {measured_force_xy_n:.0f} N below band {force_band_low_n:.0f} N"

    [[rules]]
    name = "form_error"
    condition = "form_error_um > 40"
    action = "feed_override"
    step = -10
    cooldown_s = 0.5
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cnctwin.config import Section
from cnctwin.control.expression import Expression
from cnctwin.errors import ConfigError
from cnctwin.thread import COMMANDS

__all__ = [
    "ACTION_COMMANDS",
    "ControlConfig",
    "OffsetLimits",
    "OverrideLimits",
    "RuleAction",
    "RuleConfig",
]

RuleAction = Literal[
    "stop", "feed_hold", "feed_override", "spindle_override", "tool_change", "notify"
]

#: The command (a name of :data:`cnctwin.thread.signals.COMMANDS`) each action writes;
#: ``tool_change`` and ``notify`` write none: no machine interface of cnctwin carries a
#: tool-change request, so the request is a decision record (the historian's, the log's)
#: for the operator or a line controller to act on.
ACTION_COMMANDS: dict[str, str | None] = {
    "stop": "stop",
    "feed_hold": "feed_hold",
    "feed_override": "feed_override_pct",
    "spindle_override": "spindle_override_pct",
    "tool_change": None,
    "notify": None,
}


class RuleConfig(Section):
    """One rule (an entry of ``[[rules]]``).

    Attributes
    ----------
    name
        Unique name of the rule (recorded with every decision).
    condition
        When the rule applies: an expression over signal and prediction names (see
        :mod:`cnctwin.control.expression`), e.g. ``"form_error_um > 40"``.
    for_s
        How long the condition must hold without interruption before the rule fires, s
        (0 to 3600; every numeric key's range is listed in docs/configuration.md).
    action
        ``"stop"`` (latched program stop), ``"feed_hold"``, ``"feed_override"``,
        ``"spindle_override"``, ``"tool_change"`` (a request for a tool change, recorded and
        logged; nothing is written to the machine) or ``"notify"`` (record and log only).
    value
        The commanded value: for an override the absolute override in %, a number or an
        expression evaluated when the rule fires (``"feed_override_pct * 0.5"``); for
        ``feed_hold`` 1 (hold, the default) or 0 (release). Not allowed for stop, tool_change
        and notify.
    step
        Instead of ``value``, for an override: a change in % relative to the override the
        machine reports (the ``feed_override_pct`` or ``spindle_override_pct`` reading), e.g.
        ``-10``; applied again every ``cooldown_s`` while the condition holds.
    reason
        Text recorded with the decision, a template whose ``{fields}`` are names of signals and
        predictions, ``value``, ``rule`` and ``held_s`` (``"{force_n:.0f} N"``); by default the
        condition with the values of its names.
    cooldown_s
        Least time between two firings of the rule, s.
    """

    name: str = Field(min_length=1)
    condition: str = Field(min_length=1)
    for_s: float = Field(default=0.0, ge=0.0, le=3600.0)
    action: RuleAction
    value: float | str | None = None
    step: float | None = Field(default=None, ge=-1000.0, le=1000.0)
    reason: str | None = None
    cooldown_s: float = Field(default=1.0, ge=0.0, le=3600.0)

    @field_validator("value")
    @classmethod
    def _value_in_range(cls, value: float | str | None) -> float | str | None:
        if isinstance(value, float | int) and not -1000.0 <= value <= 1000.0:
            raise PydanticCustomError(
                "value_range", "must be >= -1000 and <= 1000 (%), or an expression"
            )
        return value

    @model_validator(mode="after")
    def _value_fits_action(self) -> RuleConfig:
        origin = f"rule {self.name!r}"
        Expression(self.condition, origin=f"{origin} condition", logical=True)
        if isinstance(self.value, str):
            Expression(self.value, origin=f"{origin} value")
        override = self.action in ("feed_override", "spindle_override")
        if override and (self.value is None) == (self.step is None):
            raise ConfigError(
                f"{origin} ({self.action}) needs exactly one of 'value' (absolute %, number "
                f"or expression) and 'step' (relative %), got value={self.value!r}, "
                f"step={self.step!r}"
            )
        if not override and self.step is not None:
            raise ConfigError(f"{origin}: 'step' applies to overrides only, not {self.action}")
        if self.action in ("stop", "tool_change", "notify") and self.value is not None:
            raise ConfigError(
                f"{origin}: action {self.action!r} takes no 'value' (got {self.value!r})"
            )
        if self.action == "feed_hold" and self.value not in (None, 0, 1):
            raise ConfigError(
                f"{origin}: feed_hold value={self.value!r}; give 1 (hold) or 0 (release)"
            )
        return self


class OverrideLimits(Section):
    """Bounds and rates of one override command (``[control.feed_override]`` etc.).

    Attributes
    ----------
    min_pct, max_pct
        The range a command is clamped to, %, inside the machine's range.
    max_rise_pct_per_s, max_fall_pct_per_s
        Fastest increase and decrease, % per s, against the last command sent (or the
        machine's reading); ``None`` for no limit.
    """

    min_pct: float = Field(ge=0.0, le=1000.0)
    max_pct: float = Field(ge=0.0, le=1000.0)
    max_rise_pct_per_s: float | None = Field(default=None, gt=0.0, le=1e4)
    max_fall_pct_per_s: float | None = Field(default=None, gt=0.0, le=1e4)


def _feed_limits() -> OverrideLimits:
    # lowering the feed is the safe direction: not rate limited; raising is slow and capped at
    # the programmed feed
    return OverrideLimits(min_pct=10.0, max_pct=100.0, max_rise_pct_per_s=20.0)


def _spindle_limits() -> OverrideLimits:
    # neither direction of spindle speed is safe in general (a lower speed raises the chip
    # load): both directions are slow
    return OverrideLimits(
        min_pct=80.0, max_pct=110.0, max_rise_pct_per_s=10.0, max_fall_pct_per_s=10.0
    )


class OffsetLimits(Section):
    """Bounds of a tool wear-offset write (``[control.tool_offset]``).

    Attributes
    ----------
    max_step_mm
        Largest change of a wear offset in one write, mm (against the machine's read-back).
    max_total_mm
        Largest wear offset the twin may leave on the machine, mm in magnitude: the wear
        offset is the sum of all corrections since the tool was set up, so this bounds what
        the corrections add up to.
    """

    max_step_mm: float = Field(default=0.05, gt=0.0, le=1.0)
    max_total_mm: float = Field(default=0.3, gt=0.0, le=1.0)


class ControlConfig(Section):
    """Whether and how the twin may command the machine (``[control]``).

    Attributes
    ----------
    enabled
        Off by default: the twin evaluates its rules and records their decisions as blocked,
        but writes nothing to the machine.
    feed_override, spindle_override
        Bounds and rate limits of the overrides.
    min_interval_s
        Least time between two commands to the same target, s (stop and feed hold exempt).
    max_commands_per_s
        Most commands per s over all targets, >= 1 (a token bucket that holds 1 s worth;
        stop and feed hold exempt).
    readback_tolerance_pct
        A read-back within this of the value sent confirms an override, %.
    on_reconnect
        What the twin does when the connection comes back after a loss: ``"resume"``
        (re-assert what must stay, undo what must not, then go on), ``"feed_hold"`` (as
        resume, then hold the feed until an operator releases it: the twin was blind for the
        gap) or ``"stop"`` (as resume, then stop the program). See docs/control.md.
    tool_offset
        Bounds of a tool wear-offset write (one step and the total, mm).
    """

    enabled: bool = False
    feed_override: OverrideLimits = Field(default_factory=_feed_limits)
    spindle_override: OverrideLimits = Field(default_factory=_spindle_limits)
    min_interval_s: float = Field(default=0.1, gt=0.0, le=3600.0)
    max_commands_per_s: float = Field(default=20.0, ge=1.0, le=1000.0)
    readback_tolerance_pct: float = Field(default=0.5, ge=0.0, le=100.0)
    on_reconnect: Literal["resume", "feed_hold", "stop"] = "resume"
    tool_offset: OffsetLimits = Field(default_factory=OffsetLimits)

    @model_validator(mode="after")
    def _bounds_inside_machine_range(self) -> ControlConfig:
        for key, command in (
            ("feed_override", "feed_override_pct"),
            ("spindle_override", "spindle_override_pct"),
        ):
            limits: OverrideLimits = getattr(self, key)
            spec = COMMANDS[command]
            low = spec.low if spec.low is not None else 0.0
            high = spec.high if spec.high is not None else float("inf")
            if not low <= limits.min_pct <= limits.max_pct <= high:
                raise ConfigError(
                    f"[control.{key}] min_pct={limits.min_pct:g}, max_pct={limits.max_pct:g}; "
                    f"give {low:g} <= min_pct <= max_pct <= {high:g}"
                )
        return self

    def limits(self, command: str) -> OverrideLimits | None:
        """The limits of an override command by its signal name, ``None`` for others."""
        if command == "feed_override_pct":
            return self.feed_override
        if command == "spindle_override_pct":
            return self.spindle_override
        return None
