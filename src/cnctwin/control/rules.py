"""The rule engine: conditions over signals and predictions, held for a duration, become decisions.

Every cycle the twin hands the engine the cycle's values (measured signals, filtered signals,
features, predictions: one flat mapping name -> float) and the cycle's time. For each rule, in
the order of the configuration:

- the condition is evaluated only if every name it reads is present and finite; otherwise it
  counts as false (a missing or garbage value never fires a rule) and the hold timer restarts;
- a condition that has held without interruption for ``for_s`` fires the rule, if the rule
  has not fired within ``cooldown_s``; while it keeps holding, it fires again each
  ``cooldown_s`` (so a ``step`` lowers an override step by step until the condition clears);
- a firing becomes a :class:`Decision` with the value to command and a reason that names the
  values that caused it.

Decisions of one cycle come out most conservative first (stop, feed hold, then overrides by
increasing value, then tool-change requests and notifications), so a safety filter that passes
one command per target per interval passes the safest. Decisions are not commands yet: each
passes :class:`~cnctwin.control.safety.SafetyFilter`.
"""

from __future__ import annotations

import logging
import math
import string
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

from cnctwin.control.config import ACTION_COMMANDS, RuleConfig
from cnctwin.control.expression import Expression
from cnctwin.errors import ConfigError

__all__ = ["Decision", "RuleEngine"]

logger = logging.getLogger(__name__)

#: Fields a reason template may use besides the signal and prediction names.
REASON_FIELDS = ("value", "rule", "held_s")

_ACTION_ORDER = {
    "stop": 0,
    "feed_hold": 1,
    "feed_override": 2,
    "spindle_override": 3,
    "tool_change": 4,
}
_TOLERANCE_S = 1e-9  # float slack when comparing held durations with for_s and cooldowns


@dataclass(frozen=True, slots=True)
class Decision:
    """What a rule decided, and why.

    Attributes
    ----------
    time_s
        Cycle time at which the rule fired, s.
    rule
        The rule's name.
    action
        ``"stop"``, ``"feed_hold"``, ``"feed_override"``, ``"spindle_override"``,
        ``"tool_change"`` or ``"notify"``.
    value
        The value to command: override in %, 1/0 for stop and feed hold, ``None`` for a
        tool-change request and notify.
    reason
        One line of text (the rule's template, or the condition with its values).
    values
        The values of the names the condition and the value read, when the rule fired.
    """

    time_s: float
    rule: str
    action: str
    value: float | None
    reason: str
    values: Mapping[str, float] = field(default_factory=dict)

    @property
    def command(self) -> str | None:
        """The command signal the decision writes (``None`` for tool_change and notify)."""
        return ACTION_COMMANDS[self.action]


class _CompiledRule:
    __slots__ = (
        "condition",
        "config",
        "fired_s",
        "reads",
        "since_s",
        "step_base",
        "template",
        "value",
    )

    def __init__(self, config: RuleConfig, valid_names: Collection[str] | None) -> None:
        origin = f"rule {config.name!r}"
        self.config = config
        self.condition = Expression(
            config.condition, valid_names, f"{origin} condition", logical=True
        )
        self.value: Expression | float | None
        if isinstance(config.value, str):
            self.value = Expression(config.value, valid_names, f"{origin} value")
        else:
            self.value = config.value
        if config.action == "stop":
            self.value = 1.0
        elif config.action == "feed_hold" and config.value is None:
            self.value = 1.0
        self.step_base: str | None = None
        if config.step is not None:
            self.step_base = ACTION_COMMANDS[config.action]
            if valid_names is not None and self.step_base not in valid_names:
                raise ConfigError(
                    f"{origin} steps the override relative to {self.step_base!r}, which is not "
                    f"among the valid names; read the override back or give an absolute value"
                )
        reads = list(self.condition.names)
        for name in self.value.names if isinstance(self.value, Expression) else ():
            if name not in reads:
                reads.append(name)
        if self.step_base is not None and self.step_base not in reads:
            reads.append(self.step_base)
        self.reads = tuple(reads)
        self.template = config.reason
        if self.template is not None:
            allowed = set(REASON_FIELDS)
            if valid_names is not None:
                allowed.update(valid_names)
            try:
                fields = [f for _, f, _, _ in string.Formatter().parse(self.template) if f]
            except ValueError as err:
                raise ConfigError(
                    f"{origin} reason {self.template!r} is not a valid template ({err}); "
                    f"write e.g. 'force {{force_n:.0f}} N'"
                ) from None
            unknown = [f for f in fields if f not in allowed and valid_names is not None]
            if unknown:
                raise ConfigError(
                    f"{origin} reason {self.template!r} uses unknown field(s) "
                    f"{', '.join(unknown)}; valid fields are names of signals and predictions "
                    f"and {', '.join(REASON_FIELDS)}"
                )
        self.since_s: float | None = None
        self.fired_s: float | None = None


class RuleEngine:
    """Evaluates every rule each cycle, with hold durations and cooldowns.

    Parameters
    ----------
    rules
        The ``[[rules]]`` of the configuration; names must be unique.
    valid_names
        The signal and prediction names the twin provides. Given, every expression and
        reason template is checked against it at construction (an unknown name is a
        :class:`~cnctwin.errors.ConfigError` naming the rule, the expression and the valid
        names); ``None`` checks syntax only.

    Attributes
    ----------
    skipped
        Rule name -> number of firings that produced no decision because a value could not
        be computed (missing or non-finite input, division by zero).
    """

    def __init__(
        self, rules: Sequence[RuleConfig], valid_names: Collection[str] | None = None
    ) -> None:
        names = [rule.name for rule in rules]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ConfigError(
                f"[[rules]] names {', '.join(map(repr, duplicates))} appear more than once; "
                f"give each rule a unique name"
            )
        self._rules = [_CompiledRule(rule, valid_names) for rule in rules]
        self.skipped: dict[str, int] = {name: 0 for name in names}

    @property
    def rules(self) -> list[RuleConfig]:
        """The rules, in evaluation order."""
        return [rule.config for rule in self._rules]

    def reset(self) -> None:
        """Forget hold timers and cooldowns (after a gap in the machine's signals)."""
        for rule in self._rules:
            rule.since_s = rule.fired_s = None

    def evaluate(self, values: Mapping[str, float], now_s: float) -> list[Decision]:
        """The decisions of this cycle, most conservative first.

        Parameters
        ----------
        values
            Signal and prediction name -> value (flags as 0/1).
        now_s
            The cycle's time, s (monotonic).
        """
        decisions: list[Decision] = []
        for rule in self._rules:
            condition = rule.condition
            holds = False
            if condition.finite_inputs(values):
                try:
                    holds = bool(condition.evaluate(values))
                except (ZeroDivisionError, OverflowError):
                    holds = False
            if not holds:
                rule.since_s = None
                continue
            if rule.since_s is None:
                rule.since_s = now_s
            config = rule.config
            held_s = now_s - rule.since_s
            if held_s + _TOLERANCE_S < config.for_s:
                continue
            if rule.fired_s is not None and now_s - rule.fired_s + _TOLERANCE_S < config.cooldown_s:
                continue
            rule.fired_s = now_s
            decision = self._decide(rule, values, now_s, held_s)
            if decision is None:
                self.skipped[config.name] += 1
            else:
                decisions.append(decision)
        if len(decisions) > 1:
            decisions.sort(key=_conservative_order)
        return decisions

    def _decide(
        self, rule: _CompiledRule, values: Mapping[str, float], now_s: float, held_s: float
    ) -> Decision | None:
        config = rule.config
        value: float | None
        try:
            if isinstance(rule.value, Expression):
                value = (
                    float(rule.value.evaluate(values))
                    if rule.value.finite_inputs(values)
                    else math.nan
                )
            elif rule.step_base is not None:
                value = float(values.get(rule.step_base, math.nan)) + float(config.step or 0.0)
            else:
                value = rule.value
        except (ZeroDivisionError, OverflowError):
            value = math.nan
        if value is not None and not math.isfinite(value):
            logger.warning(
                "rule %r fired but its value could not be computed from %s",
                config.name,
                {name: values.get(name) for name in rule.reads},
            )
            return None
        used = {name: float(values[name]) for name in rule.reads if name in values}
        return Decision(
            time_s=now_s,
            rule=config.name,
            action=config.action,
            value=value,
            reason=_reason(rule, values, used, value, held_s),
            values=used,
        )


def _reason(
    rule: _CompiledRule,
    values: Mapping[str, float],
    used: Mapping[str, float],
    value: float | None,
    held_s: float,
) -> str:
    if rule.template is not None:
        try:
            return rule.template.format_map(
                {**values, "value": value, "rule": rule.config.name, "held_s": held_s}
            )
        except (KeyError, ValueError, TypeError) as err:
            logger.warning("rule %r reason template failed: %s", rule.config.name, err)
    shown = ", ".join(f"{name}={val:.6g}" for name, val in used.items())
    return f"{rule.config.condition} held {held_s:.3f} s ({shown})"


def _conservative_order(decision: Decision) -> tuple[int, float]:
    rank = _ACTION_ORDER.get(decision.action, len(_ACTION_ORDER))
    value = decision.value if decision.value is not None else 0.0
    if decision.action == "feed_hold":
        value = -value  # a hold (1) before a release (0)
    return rank, value
