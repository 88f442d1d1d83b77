"""Step 10 of the cycle: rules decide, the safety filter bounds, commands go out and are read back.

:class:`RuleStage` evaluates the ``[[rules]]`` on everything the cycle knows (measured and
filtered signals, features, predictions). :class:`ActionStage` passes each decision through
the :class:`~cnctwin.control.SafetyFilter` (enable switch, bounds, deduplication, rate
limits), writes what passes, and verifies it by reading the machine back: an override counts as
done when the machine shows it. A stop, feed hold or emergency stop is acknowledged by its
read-back but confirmed only by motion (:mod:`cnctwin.twin.stopping`): until the axes are
seen at rest the stage watches them cycle by cycle and escalates feed hold -> stop ->
emergency stop when a step does not bring them to rest in time; each step is recorded as a
decision with its reason, and a stop that no step confirms is an event and a decision
record. Every decision is recorded with its rule, its reason, the filter's verdict and the
read-back.

Lost connection (the policy, docs/twin.md): while the machine is lost nothing is written and
the rules' hold timers restart; when it is back, :meth:`SafetyFilter.after_reconnect`
(:class:`~cnctwin.control.LostMachinePolicy`) says what to write so that nothing the twin
commanded stays in a dangerous state: a stop or hold it set stays, a lowered feed override
stays lowered, a feed override raised above 100 % comes back to 100 %.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

from cnctwin.control import Decision, RuleEngine, SafetyFilter, Verdict
from cnctwin.thread import CommandRejected, ConnectionLost, MachineConnection
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.settings import StopConfirmationConfig
from cnctwin.twin.state import CycleState, TwinEvent
from cnctwin.twin.stopping import LADDER, StopStatus, StopWatch

__all__ = ["ActionStage", "CommandResult", "RuleStage"]

logger = logging.getLogger(__name__)


class RuleStage:
    """Evaluates the rules; their decisions go to ``state.commands``.

    Parameters
    ----------
    engine
        The rule engine of the ``[[rules]]``.
    """

    name = "rules"
    per_sample = True  # a repeat of the last sample is no new evidence: rules wait for one

    def __init__(self, engine: RuleEngine) -> None:
        self.engine = engine

    def forget(self) -> None:
        """Restart hold timers and cooldowns (after a gap: the signals were not seen)."""
        self.engine.reset()

    def process(self, state: CycleState) -> CycleState:
        """Add this cycle's decisions (most conservative first) to ``state.commands``."""
        if not state.connected:
            return state
        state.commands.extend(self.engine.evaluate(state.signals(), state.time_s))
        return state


@dataclass(frozen=True, slots=True)
class CommandResult:
    """One decision after the safety filter and, when written, the machine's read-back.

    Attributes
    ----------
    verdict
        The safety filter's verdict.
    readback
        The value the machine showed after the write, or ``None``.
    confirmed
        Whether the read-back showed the command in effect.
    written_s
        ``time.monotonic()`` of the write, s (NaN when nothing was written).
    confirmed_s
        ``time.monotonic()`` of the confirming read-back, s (NaN without).
    """

    verdict: Verdict
    readback: float | None
    confirmed: bool
    written_s: float
    confirmed_s: float


class ActionStage:
    """Passes decisions through the safety filter, writes them, verifies them by read-back.

    Parameters
    ----------
    connection
        The machine.
    safety
        The safety filter (it holds the ``[control]`` table: with control disabled every
        decision is recorded as blocked and nothing is written).
    recorder
        Where decisions go, or ``None``.
    readback_timeout_s
        How long to poll the machine for a read-back that acknowledges a write, s.
    stop_confirmation
        When a stop counts as done (motion at rest) and how it escalates.

    Attributes
    ----------
    stop_reactions_ms
        For each confirmed stop: from the first out-of-band sample of the anomaly (the
        reading in which ``force_out_of_band`` first became 1; the cycle's own reading when
        the stop came from another rule) to the reading that showed the axes at rest, ms.
    stop_outcome
        The last stop's state: ``None`` (none yet), ``"pending"`` (axes not yet at rest),
        ``"confirmed"`` or ``"failed"`` (no step of the escalation brought them to rest).
    results
        Every decision's result, in order (kept for tests and the live view; bounded).
    writes
        Commands written to the machine.
    decision_count
        Decisions recorded.
    """

    name = "actions"

    def __init__(
        self,
        connection: MachineConnection,
        safety: SafetyFilter,
        recorder: Recorder | None = None,
        *,
        readback_timeout_s: float = 0.25,
        stop_confirmation: StopConfirmationConfig | None = None,
    ) -> None:
        self.connection = connection
        self.safety = safety
        self.recorder = recorder
        self.readback_timeout_s = readback_timeout_s
        self.stop_confirmation = stop_confirmation or StopConfirmationConfig()
        self.stop_outcome: str | None = None
        self._watch: StopWatch | None = None
        self._watch_onset_s = math.nan
        self.stop_reactions_ms: list[float] = []
        self.results: list[CommandResult] = []
        self.writes = 0
        self.decision_count = 0
        self._online = True
        self._anomaly_s: float | None = None
        self._submitted: deque[Decision] = deque(maxlen=16)

    def submit(self, decision: Decision) -> None:
        """Queue a decision made outside the rules (an operator on the dashboard) for the
        next cycle, where it passes the safety filter, the write, the read-back and the
        record like a rule's. Safe from another thread; at most 16 wait (then the oldest is
        dropped), and none is kept while the machine is lost."""
        self._submitted.append(decision)

    # ------------------------------------------------------------------ the stage
    async def process(self, state: CycleState) -> CycleState:
        """Filter, write and verify this cycle's decisions; record each with its reason."""
        if not state.connected:
            self._submitted.clear()
            return state
        while self._submitted:
            state.commands.append(self._submitted.popleft())
        if state.predicted.get("force_out_of_band", 0.0) >= 0.5:
            if self._anomaly_s is None:
                self._anomaly_s = state.received_s
        else:
            self._anomaly_s = None
        now = state.time_s
        # a stop under way is judged on this reading before anything new is written
        watch = self._watch
        if watch is not None:
            await self._follow_stop(state, watch, watch.update(state.measured, now))
        verdicts = [self.safety.check(d, now, state.measured) for d in state.commands]
        # a ramp's step waiting for its rate limit is no decision: only steps sent count
        verdicts.extend(v for v in self.safety.follow_up(now, state.measured) if v.send)
        for verdict in verdicts:
            await self._carry_out(state, verdict)
        return state

    @property
    def stopping(self) -> bool:
        """Whether a stop was sent and the axes have not been seen at rest yet."""
        return self._watch is not None

    async def _carry_out(self, state: CycleState, verdict: Verdict) -> None:
        result = CommandResult(verdict, None, False, math.nan, math.nan)
        if verdict.send and self._online and verdict.command is not None:
            result = await self._write_and_verify(verdict)
            if verdict.command in LADDER and (verdict.value or 0.0) >= 0.5:
                self._watch_step(state, verdict.command)
        self._record(state, result)

    def _watch_step(self, state: CycleState, step: str) -> None:
        """A step of the ladder was written: start watching, or watch the stronger step."""
        watch = self._watch
        if watch is None:
            onset = self._anomaly_s if self._anomaly_s is not None else state.received_s
            self._watch = StopWatch(step, state.time_s, self.stop_confirmation)
            self._watch_onset_s = onset
            self.stop_outcome = "pending"
        elif LADDER.index(step) > LADDER.index(watch.step):
            watch.escalated(step, state.time_s)

    async def _follow_stop(self, state: CycleState, watch: StopWatch, status: StopStatus) -> None:
        """Act on one reading's verdict on the stop under way (see :mod:`.stopping`)."""
        if status.verdict == "watching":
            return
        steps = " -> ".join(watch.steps)
        if status.verdict == "confirmed":
            self._watch = None
            self.stop_outcome = "confirmed"
            arrived = state.received_s if math.isfinite(state.received_s) else time.monotonic()
            reaction_ms = (arrived - self._watch_onset_s) * 1e3
            self.stop_reactions_ms.append(reaction_ms)
            state.events.append(
                TwinEvent(
                    "stop_confirmed",
                    f"axes at rest after {steps}, {reaction_ms:.2f} ms after the first "
                    "out-of-band sample",
                    arrived,
                    {"stop_reaction_ms": reaction_ms, "steps": list(watch.steps)},
                )
            )
            return
        moving = (
            f"axes still moving at {status.speed_mm_min:.1f} mm/min"
            if math.isfinite(status.speed_mm_min)
            else "no motion signal to confirm rest"
        )
        why = (
            f"{status.step} not confirmed: {moving} {status.waited_s:.3f} s after it was "
            f"written (timeout_s = {self.stop_confirmation.timeout_s:g})"
        )
        if status.verdict == "escalate" and status.next_step is not None and self._online:
            reason = f"{why}; escalating to {status.next_step}"
            logger.warning("%s", reason)
            state.events.append(
                TwinEvent(
                    "stop_escalated",
                    reason,
                    time.monotonic(),
                    {
                        "from": status.step,
                        "to": status.next_step,
                        "speed_mm_min": status.speed_mm_min,
                    },
                )
            )
            verdict = self.safety.escalate(status.next_step, state.time_s, reason)
            await self._carry_out(state, verdict)
            if not verdict.send:
                self._fail(state, watch, f"{why}; escalation to {status.next_step} blocked")
            return
        if status.verdict == "escalate":
            return  # the machine is lost: the reconnection policy re-asserts the stop
        self._fail(state, watch, f"{why}; no further step (tried {steps})")

    def _fail(self, state: CycleState, watch: StopWatch, reason: str) -> None:
        """No step of the ladder stopped the axes: an event and a decision record."""
        self._watch = None
        self.stop_outcome = "failed"
        logger.error("stop not confirmed: %s", reason)
        now = time.monotonic()
        state.events.append(
            TwinEvent("stop_not_confirmed", reason, now, {"steps": list(watch.steps)})
        )
        if self.recorder is not None:
            self.recorder.decision(now, "stop_confirmation", watch.step, 1.0, reason, False, None)

    async def _write_and_verify(self, verdict: Verdict) -> CommandResult:
        name = str(verdict.command)
        value = float(verdict.value if verdict.value is not None else math.nan)
        written = time.monotonic()
        try:
            await self.connection.write(name, value)
        except (ConnectionLost, CommandRejected) as err:
            logger.warning("command %s=%g not carried out: %s", name, value, err)
            return CommandResult(verdict, None, False, written, math.nan)
        self.writes += 1
        deadline = written + self.readback_timeout_s
        readback: float | None = None
        while True:
            try:
                reading = await self.connection.read()
            except ConnectionLost:
                break
            now = time.monotonic()
            readback = reading.values.get(name)
            if name not in reading.values and name in LADDER:
                break  # a flag the machine does not read back: motion decides
            if _shows(name, value, reading.values, self.safety.config.readback_tolerance_pct):
                self.safety.observe(reading.values)
                return CommandResult(verdict, readback, True, written, now)
            if now >= deadline:
                break
            await asyncio.sleep(0.001)
        logger.warning("command %s=%g not confirmed by read-back (%r)", name, value, readback)
        return CommandResult(verdict, readback, False, written, math.nan)

    def _record(self, state: CycleState, result: CommandResult) -> None:
        verdict = result.verdict
        decision: Decision = verdict.decision
        self.decision_count += 1
        self.results.append(result)
        if len(self.results) > 10_000:
            del self.results[:5_000]
        state.decisions.append(result)
        reason = decision.reason
        if verdict.note:
            reason = f"{reason} [{verdict.outcome}: {verdict.note}]"
        elif verdict.outcome != "sent":
            reason = f"{reason} [{verdict.outcome}]"
        if verdict.send and not result.confirmed:
            reason += " [not confirmed by read-back]"
        logger.info("decision %s: %s -> %s", decision.rule, decision.action, verdict.outcome)
        if self.recorder is not None:
            value = verdict.value if verdict.value is not None else decision.value
            self.recorder.decision(
                time.monotonic(),
                decision.rule,
                verdict.command or decision.action,
                value if value is not None and math.isfinite(value) else 0.0,
                reason,
                verdict.send and result.confirmed,
                result.readback,
            )

    # ------------------------------------------------------------------ lost machine
    def connection_lost(self) -> None:
        """The machine is lost: write nothing until it is back."""
        self._online = False
        self._anomaly_s = None

    async def connection_restored(self, state: CycleState) -> list[TwinEvent]:
        """The machine is back: apply the lost-connection policy; return its events."""
        self._online = True
        now = time.monotonic()
        events = []
        for verdict in self.safety.after_reconnect(state.measured, state.time_s):
            await self._carry_out(state, verdict)
            events.append(
                TwinEvent(
                    "reconnect_policy",
                    verdict.note or verdict.decision.reason,
                    now,
                    {"command": verdict.command, "value": verdict.value},
                )
            )
        return events


def _shows(name: str, value: float, values: Mapping[str, float], tol_pct: float) -> bool:
    """Whether a reading shows the command ``name`` = ``value`` in effect."""
    got = values.get(name)
    if got is None or not math.isfinite(got):
        return False
    if name in LADDER:
        # a latched flag reads back 1: the machine took the command (that it stopped, only
        # its motion confirms: :mod:`cnctwin.twin.stopping`)
        return got >= 0.5
    tolerance = tol_pct if name.endswith("_pct") else 1e-6
    return abs(got - value) <= tolerance
