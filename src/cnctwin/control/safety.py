"""The safety filter every command passes, and the policy for a lost and regained machine.

:class:`SafetyFilter` turns each :class:`~cnctwin.control.rules.Decision` into a
:class:`Verdict`: what may be written to the machine, or why not. In order:

1. a notification is recorded, never written;
2. with ``[control] enabled = false`` every command is blocked (and recorded as blocked);
3. a non-finite value, or a stop with value 0, is blocked (the twin never releases a stop);
4. an override is clamped to its bounds;
5. a command equal to the last one sent to that target is a duplicate when it was sent less
   than ``min_interval_s`` ago or the machine's read-back already shows it;
5a. an override is never raised (above the last value sent, else 100 %) while the reading
   passed with the decision lacks a valid value of it (an invalid or unserved signal);
6. stop and feed hold pass now: a safety action is never delayed;
7. an override waits ``min_interval_s`` after the last command to its target and needs a
   token of the bucket that allows ``max_commands_per_s`` over all targets; otherwise it is
   rate limited (dropped);
8. an override moves from the last value sent (or the machine's read-back) by at most
   ``max_rise_pct_per_s`` / ``max_fall_pct_per_s`` times the time since; a clamped move is
   continued toward the decision's value by :meth:`SafetyFilter.follow_up` on later cycles.

So whatever the rules produce, at most ``1 + T / min_interval_s`` overrides per target and
``max_commands_per_s * (1 + T)`` overrides in all reach the machine in ``T`` s, each inside
its bounds.

:class:`LostMachinePolicy` decides what the twin writes when the machine comes back after a
lost connection; docs/control.md gives the reasoning.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

from cnctwin.control.config import ControlConfig
from cnctwin.control.rules import Decision
from cnctwin.errors import InputError

__all__ = [
    "ESCALATION_RULE",
    "OFFSET_COMMANDS",
    "Commanded",
    "LostMachinePolicy",
    "Outcome",
    "ReconnectAction",
    "SafetyFilter",
    "Verdict",
]

logger = logging.getLogger(__name__)

Outcome = Literal["sent", "clamped", "blocked", "duplicate", "rate_limited", "recorded"]

#: Reason a decision is recorded as blocked while control is off.
DISABLED_NOTE = "control disabled ([control] enabled = false)"
#: Decisions made by the reconnection policy carry this rule name.
RECONNECT_RULE = "reconnect"
#: Steps of a stop's escalation carry this rule name.
ESCALATION_RULE = "stop_escalation"

#: Commands that latch on the machine (the twin never releases a stop or an emergency stop;
#: it re-asserts any of them after a lost connection, see :class:`LostMachinePolicy`).
_LATCHING = ("stop", "feed_hold", "emergency_stop")
_EPS = 1e-9
#: The tool wear-offset commands (mm) that :meth:`SafetyFilter.check_offset` passes.
OFFSET_COMMANDS = ("tool_length_wear_mm", "tool_radius_wear_mm")
#: A read-back within this of the value sent confirms a wear offset, mm (a Modbus register
#: carries 0.1 um steps).
OFFSET_TOLERANCE_MM = 1e-4
#: Action name of a wear-offset decision.
OFFSET_ACTION = "tool_offset"


@dataclass(frozen=True, slots=True)
class Verdict:
    """The safety filter's answer to one decision.

    Attributes
    ----------
    decision
        The decision as the rule engine made it.
    outcome
        ``"sent"`` (write ``value``), ``"clamped"`` (write ``value``, which differs from the
        decision's), ``"blocked"``, ``"duplicate"``, ``"rate_limited"`` or ``"recorded"``
        (a notification, or a reconnection note: nothing to write).
    command
        The command signal to write (``None`` for a notification).
    value
        The value to write when ``send`` is true, else ``None``.
    note
        Why the outcome is not a plain ``"sent"`` (empty otherwise).
    """

    decision: Decision
    outcome: Outcome
    command: str | None
    value: float | None
    note: str = ""

    @property
    def send(self) -> bool:
        """Whether the twin writes ``command`` = ``value`` to the machine."""
        return self.outcome in ("sent", "clamped")


@dataclass(frozen=True, slots=True)
class Commanded:
    """The last value the twin sent to one command, and whether the machine confirmed it.

    Attributes
    ----------
    value
        The value sent (% for overrides, 1/0 for stop and feed hold).
    time_s
        When it was sent, s.
    confirmed
        Whether a read-back has shown the value since it was sent.
    """

    value: float
    time_s: float
    confirmed: bool = False


@dataclass(frozen=True, slots=True)
class ReconnectAction:
    """One item of the reconnection plan.

    Attributes
    ----------
    command
        The command signal concerned.
    value
        The value to write, or ``None`` for a note that writes nothing.
    reason
        Why, in one line.
    """

    command: str
    value: float | None
    reason: str


class LostMachinePolicy:
    """What the twin writes when the connection to the machine comes back.

    The twin cannot write while the connection is down; what it commanded before stays on
    the machine. On reconnection, from what the twin last sent (:class:`Commanded`) and the
    machine's read-back:

    - **stop**, **feed hold** and **emergency stop** the twin set stay: the twin never
      releases them by itself.
      If the machine shows them released and the twin had never seen them take effect, they
      are written again (the command may have been lost with the connection); if the twin had
      seen them take effect, an operator released them on purpose and the twin leaves that
      decision to the operator (a note is recorded). A release (feed hold 0) is never
      repeated.
    - a **feed override lowered** by the twin is never raised back by the reconnection: if the
      machine now runs faster than the twin left it (e.g. a restarted control at 100 %), the
      lower value is written again; a value even lower (an operator's) is left alone.
    - a **feed override raised** above ``feed_ceiling_pct`` (100 %, the programmed feed) by the
      twin is brought back to the ceiling: running faster than programmed is allowed only
      while the twin is watching, and it was not.
    - the **spindle override** is left as the machine has it: neither direction is safe in
      general (a lower speed raises the chip load); a difference is noted.
    - a **tool wear offset** is never written again: a correction is computed from a
      measured part and the offset the machine had; after a gap the machine's value (an
      operator may have set it, or the write was lost) is the reference of the next
      correction, and a difference is noted.
    - with ``on_reconnect = "feed_hold"`` or ``"stop"`` a feed hold or a stop follows.

    Parameters
    ----------
    on_reconnect
        ``"resume"``, ``"feed_hold"`` or ``"stop"`` (see :class:`ControlConfig`).
    feed_ceiling_pct
        Highest feed override that survives a lost connection, %.
    tolerance_pct
        Read-back tolerance of an override, %.
    """

    def __init__(
        self,
        on_reconnect: Literal["resume", "feed_hold", "stop"] = "resume",
        feed_ceiling_pct: float = 100.0,
        tolerance_pct: float = 0.5,
    ) -> None:
        self.on_reconnect = on_reconnect
        self.feed_ceiling_pct = feed_ceiling_pct
        self.tolerance_pct = tolerance_pct

    def plan(
        self, commanded: Mapping[str, Commanded], readback: Mapping[str, float]
    ) -> list[ReconnectAction]:
        """The writes (and notes) that restore a safe state, in the order to send them.

        Parameters
        ----------
        commanded
            Command signal -> what the twin last sent.
        readback
            The machine's values after reconnection (command signals among them; a missing or
            non-finite one counts as unknown).
        """
        actions: list[ReconnectAction] = []
        for name in _LATCHING:
            sent = commanded.get(name)
            if sent is None or sent.value < 0.5:
                continue
            now = _finite(readback.get(name))
            if now is not None and now >= 0.5:
                continue
            if sent.confirmed and now is not None:
                actions.append(
                    ReconnectAction(
                        name,
                        None,
                        f"{name} set by the twin was released on the machine "
                        f"during the gap; left to the operator",
                    )
                )
            else:
                actions.append(
                    ReconnectAction(
                        name,
                        1.0,
                        f"{name} set by the twin was not confirmed before the "
                        f"connection was lost; written again",
                    )
                )
        feed = commanded.get("feed_override_pct")
        if feed is not None:
            now = _finite(readback.get("feed_override_pct"))
            keep = min(feed.value, self.feed_ceiling_pct)
            if now is None or now > keep + self.tolerance_pct:
                why = (
                    f"feed override raised to {feed.value:g} % by the twin is capped at "
                    f"{self.feed_ceiling_pct:g} % after a lost connection"
                    if feed.value > self.feed_ceiling_pct
                    else f"feed override lowered to {feed.value:g} % by the twin stays lowered"
                )
                shown = "unknown" if now is None else f"{now:g} %"
                actions.append(
                    ReconnectAction("feed_override_pct", keep, f"{why} (machine: {shown})")
                )
        spindle = commanded.get("spindle_override_pct")
        if spindle is not None:
            now = _finite(readback.get("spindle_override_pct"))
            if now is None or abs(now - spindle.value) > self.tolerance_pct:
                shown = "unknown" if now is None else f"{now:g} %"
                actions.append(
                    ReconnectAction(
                        "spindle_override_pct",
                        None,
                        f"spindle override {shown} differs from "
                        f"the twin's {spindle.value:g} %; left as the machine has it",
                    )
                )
        for name in OFFSET_COMMANDS:
            sent = commanded.get(name)
            if sent is None:
                continue
            now = _finite(readback.get(name))
            if now is None or abs(now - sent.value) > OFFSET_TOLERANCE_MM:
                shown = "unknown" if now is None else f"{now:g} mm"
                actions.append(
                    ReconnectAction(
                        name,
                        None,
                        f"{name} {shown} differs from the twin's {sent.value:g} mm; left as "
                        f"the machine has it (the next measured part corrects from it)",
                    )
                )
        if self.on_reconnect != "resume":
            actions.append(
                ReconnectAction(
                    self.on_reconnect,
                    1.0,
                    f"on_reconnect = {self.on_reconnect!r}: the twin was blind during the gap",
                )
            )
        return actions


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


class SafetyFilter:
    """Every command of the twin passes here: enable switch, bounds, deduplication, rates.

    Parameters
    ----------
    config
        The ``[control]`` table.

    Attributes
    ----------
    commanded
        Command signal -> the last value sent (:class:`Commanded`).
    counts
        Outcome -> number of verdicts so far.
    """

    def __init__(self, config: ControlConfig) -> None:
        self.config = config
        self.policy = LostMachinePolicy(
            config.on_reconnect, tolerance_pct=config.readback_tolerance_pct
        )
        self.commanded: dict[str, Commanded] = {}
        self.counts: dict[str, int] = {}
        self._pending: dict[str, Decision] = {}
        self._tokens = config.max_commands_per_s
        self._tokens_s: float | None = None

    # -- read-back ---------------------------------------------------------------------
    def _tolerance(self, command: str) -> float:
        if command in OFFSET_COMMANDS:
            return OFFSET_TOLERANCE_MM
        return self.config.readback_tolerance_pct if command.endswith("_pct") else 0.5

    def observe(self, readback: Mapping[str, float]) -> None:
        """Mark commands confirmed that the machine's read-back shows (values by signal name)."""
        for name, sent in self.commanded.items():
            if sent.confirmed:
                continue
            now = _finite(readback.get(name))
            if now is not None and abs(now - sent.value) <= self._tolerance(name):
                self.commanded[name] = replace(sent, confirmed=True)

    # -- the filter --------------------------------------------------------------------
    def check(
        self,
        decision: Decision,
        now_s: float,
        readback: Mapping[str, float] | None = None,
    ) -> Verdict:
        """The verdict on one decision at time ``now_s`` (s).

        Parameters
        ----------
        decision
            A decision of the rule engine.
        now_s
            Current time, s (monotonic; the same clock as the decisions').
        readback
            The machine's current values by signal name, if known (confirms commands and is
            the reference of the rate limit before the first command).
        """
        if readback:
            self.observe(readback)
        if decision.command is None:
            note = "tool change requested" if decision.action == "tool_change" else "notification"
            return self._count(Verdict(decision, "recorded", None, None, note))
        # a new decision ends a ramp in progress toward an older one, whatever its outcome
        self._pending.pop(decision.command, None)
        return self._count(self._filter(decision, now_s, readback or {}))

    def _filter(self, decision: Decision, now_s: float, readback: Mapping[str, float]) -> Verdict:
        command = str(decision.command)
        config = self.config
        if not config.enabled:
            return Verdict(decision, "blocked", command, None, DISABLED_NOTE)
        value = decision.value
        if value is None or not math.isfinite(value):
            return Verdict(decision, "blocked", command, None, f"value {value!r} is not finite")
        last = self.commanded.get(command)
        if command in _LATCHING:
            value = 1.0 if value >= 0.5 else 0.0
            if command == "stop" and value == 0.0:
                return Verdict(decision, "blocked", command, None, "the twin never releases a stop")
            if self._duplicate(command, value, last, now_s, readback):
                return Verdict(decision, "duplicate", command, None, "already commanded")
            return self._sent(decision, command, value, now_s, "")
        limits = config.limits(command)
        if limits is None:
            return Verdict(decision, "blocked", command, None, f"{command} is not a rule command")
        notes = []
        bounded = min(max(value, limits.min_pct), limits.max_pct)
        if bounded != value:
            notes.append(f"{value:g} % clamped to [{limits.min_pct:g}, {limits.max_pct:g}] %")
        if self._duplicate(command, bounded, last, now_s, readback):
            return Verdict(decision, "duplicate", command, None, "already commanded")
        if readback and _finite(readback.get(command)) is None:
            # the machine's reading of this override is invalid (or not served) this cycle:
            # never raise what cannot be seen (above the last value sent, else 100 %)
            reference = last.value if last is not None else 100.0
            if bounded > reference + _EPS:
                return Verdict(
                    decision,
                    "blocked",
                    command,
                    None,
                    f"no valid {command} reading: not raised above {reference:g} %",
                )
        if last is not None and now_s - last.time_s + _EPS < config.min_interval_s:
            return Verdict(
                decision,
                "rate_limited",
                command,
                None,
                f"{now_s - last.time_s:.3f} s since the last {command} command "
                f"(min_interval_s = {config.min_interval_s:g})",
            )
        if not self._take_token(now_s):
            return Verdict(
                decision,
                "rate_limited",
                command,
                None,
                f"more than max_commands_per_s = {config.max_commands_per_s:g}",
            )
        base = last.value if last is not None else _finite(readback.get(command))
        target = bounded
        if base is not None:
            dt = now_s - last.time_s if last is not None else config.min_interval_s
            if target > base and limits.max_rise_pct_per_s is not None:
                target = min(target, base + limits.max_rise_pct_per_s * dt)
            elif target < base and limits.max_fall_pct_per_s is not None:
                target = max(target, base - limits.max_fall_pct_per_s * dt)
        if target != bounded:
            notes.append(
                f"rate limited from {base:g} % to {target:g} % on the way to {bounded:g} %"
            )
            self._pending[command] = replace(decision, value=bounded)
        else:
            self._pending.pop(command, None)
        return self._sent(decision, command, target, now_s, "; ".join(notes))

    def _duplicate(
        self,
        command: str,
        value: float,
        last: Commanded | None,
        now_s: float,
        readback: Mapping[str, float],
    ) -> bool:
        if last is None or abs(last.value - value) > _EPS:
            return False
        if now_s - last.time_s + _EPS < self.config.min_interval_s:
            return True
        now = _finite(readback.get(command))
        return now is None or abs(now - value) <= self._tolerance(command)

    def _take_token(self, now_s: float) -> bool:
        capacity = self.config.max_commands_per_s
        if self._tokens_s is not None:
            self._tokens = min(capacity, self._tokens + (now_s - self._tokens_s) * capacity)
        self._tokens_s = now_s
        if self._tokens < 1.0 - _EPS:
            return False
        self._tokens -= 1.0
        return True

    def _sent(
        self, decision: Decision, command: str, value: float, now_s: float, note: str
    ) -> Verdict:
        self.commanded[command] = Commanded(value, now_s)
        outcome: Outcome = "sent" if abs(value - (decision.value or 0.0)) <= _EPS else "clamped"
        if command in _LATCHING:
            outcome = "sent"
        return Verdict(decision, outcome, command, value, note)

    def _count(self, verdict: Verdict) -> Verdict:
        self.counts[verdict.outcome] = self.counts.get(verdict.outcome, 0) + 1
        if verdict.outcome == "blocked":
            logger.info("decision of rule %r blocked: %s", verdict.decision.rule, verdict.note)
        return verdict

    def follow_up(self, now_s: float, readback: Mapping[str, float] | None = None) -> list[Verdict]:
        """Continue rate-limited moves toward their decisions' values (call once per cycle).

        Returns the verdicts of the steps due now (each a ``"sent"`` or ``"clamped"`` write,
        or a ``"rate_limited"`` that waits).
        """
        if readback:
            self.observe(readback)
        verdicts = []
        for decision in list(self._pending.values()):
            step = replace(decision, time_s=now_s)
            verdicts.append(self._count(self._filter(step, now_s, readback or {})))
        return verdicts

    # -- tool wear offsets -------------------------------------------------------------
    def check_offset(
        self,
        decision: Decision,
        command: str,
        tool: int,
        readback: Mapping[str, float],
    ) -> Verdict:
        """The verdict on setting a tool wear offset: ``command`` = ``decision.value`` (mm).

        In order: blocked with control disabled; blocked for an unknown offset command, a tool
        that is not the machine's active tool (the machine's wear-offset signals are those of
        the tool in the spindle or turret station), a missing read-back of the offset (a
        step cannot be bounded without it), a value that is not finite, a change
        larger than ``[control.tool_offset] max_step_mm`` or an offset larger in magnitude
        than ``max_total_mm``; a duplicate when the machine already shows the value; else
        sent. A correction is never clamped: a part made with part of a correction is
        neither the old nor the intended one, and a correction beyond the bounds means a bad
        measurement or a wrong tool, which the operator decides.

        Parameters
        ----------
        decision
            ``action`` ``"tool_offset"``, ``value`` the wear offset to set, mm.
        command
            ``"tool_length_wear_mm"`` or ``"tool_radius_wear_mm"``.
        tool
            Tool number the offset belongs to.
        readback
            The machine's current values by signal name (``tool_number`` and ``command``).
        """
        self.observe(readback)
        return self._count(self._offset_verdict(decision, command, tool, readback))

    def _offset_verdict(
        self, decision: Decision, command: str, tool: int, readback: Mapping[str, float]
    ) -> Verdict:
        def blocked(note: str) -> Verdict:
            return Verdict(decision, "blocked", command, None, note)

        if not self.config.enabled:
            return blocked(DISABLED_NOTE)
        if command not in OFFSET_COMMANDS:
            return blocked(f"{command} is not a wear offset ({', '.join(OFFSET_COMMANDS)})")
        active = _finite(readback.get("tool_number"))
        if active is None or int(active) != tool:
            shown = "unknown" if active is None else f"T{int(active)}"
            return blocked(f"T{tool} is not the machine's active tool ({shown})")
        now = _finite(readback.get(command))
        if now is None:
            return blocked(f"no valid {command} reading: the step cannot be bounded")
        value = decision.value
        if value is None or not math.isfinite(value):
            return blocked(f"value {value!r} is not finite")
        limits = self.config.tool_offset
        if abs(value - now) > limits.max_step_mm + _EPS:
            return blocked(
                f"step {value - now:+g} mm from {now:g} mm exceeds max_step_mm = "
                f"{limits.max_step_mm:g}"
            )
        if abs(value) > limits.max_total_mm + _EPS:
            return blocked(f"{value:g} mm exceeds max_total_mm = {limits.max_total_mm:g}")
        if abs(value - now) <= OFFSET_TOLERANCE_MM:
            return Verdict(decision, "duplicate", command, None, "the machine shows it")
        self.commanded[command] = Commanded(value, decision.time_s)
        return Verdict(decision, "sent", command, value, "")

    # -- stop escalation ---------------------------------------------------------------
    def escalate(self, command: str, now_s: float, reason: str) -> Verdict:
        """The verdict on one step of a stop's escalation (docs/control.md): ``command`` = 1.

        A step continues a stop that already passed this filter, so it is never deduplicated
        or rate limited; with control disabled it is blocked like every command.

        Parameters
        ----------
        command
            ``"feed_hold"``, ``"stop"`` or ``"emergency_stop"``.
        now_s
            Current time, s.
        reason
            Why the step is taken, one line.
        """
        if command not in _LATCHING:
            raise InputError(f"escalation to {command!r}; valid: {', '.join(_LATCHING)}")
        decision = Decision(now_s, ESCALATION_RULE, command, 1.0, reason)
        if not self.config.enabled:
            return self._count(Verdict(decision, "blocked", command, None, DISABLED_NOTE))
        return self._count(self._sent(decision, command, 1.0, now_s, ""))

    # -- lost machine ------------------------------------------------------------------
    def after_reconnect(self, readback: Mapping[str, float], now_s: float) -> list[Verdict]:
        """The writes and notes of :class:`LostMachinePolicy` when the machine is back.

        Rate-limit references restart from the read-back, unfinished ramps are dropped, and
        the plan's writes pass the bounds (never the rate limit: each is a step toward the
        safe side). Nothing is written when control is disabled.
        """
        self._pending.clear()
        self._tokens = self.config.max_commands_per_s
        self._tokens_s = now_s
        if not self.config.enabled:
            return []
        verdicts = []
        for action in self.policy.plan(self.commanded, readback):
            kind = {
                "feed_override_pct": "feed_override",
                "spindle_override_pct": "spindle_override",
                **dict.fromkeys(OFFSET_COMMANDS, OFFSET_ACTION),
            }.get(action.command, action.command)
            decision = Decision(now_s, RECONNECT_RULE, kind, action.value, action.reason)
            if action.value is None:
                verdict = Verdict(decision, "recorded", action.command, None, action.reason)
            else:
                value = action.value
                limits = self.config.limits(action.command)
                if limits is not None:
                    value = min(max(value, limits.min_pct), limits.max_pct)
                verdict = self._sent(decision, action.command, value, now_s, action.reason)
            logger.warning("after reconnection: %s", action.reason)
            verdicts.append(self._count(verdict))
        for name in list(self.commanded):
            if not any(v.command == name and v.send for v in verdicts):
                now = _finite(readback.get(name))
                if now is not None:
                    self.commanded[name] = Commanded(now, now_s, confirmed=True)
        return verdicts

    def pending(self) -> dict[str, float]:
        """Command -> value still to reach by :meth:`follow_up`."""
        return {name: float(d.value or 0.0) for name, d in self._pending.items()}
