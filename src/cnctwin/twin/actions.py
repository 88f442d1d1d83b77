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

**The cycle does not wait for the machine.** A write is sent in the cycle that decides it
(:meth:`MachineConnection.start_write`: over OPC UA the request is in the socket when the
stage returns) and settled in a later cycle, from that cycle's reading and the write's answer
when it has come. A write is recorded (and counted in ``state.decisions``) once settled:
*confirmed* when the machine answered it without a refusal and a reading that arrived after
the write shows the value (within ``readback_tolerance_pct`` for an override); *not carried
out* when the answer is a refusal (:class:`CommandRejected`) or a lost link
(:class:`ConnectionLost`); *not confirmed* when no reading shows it within
``readback_timeout_s`` of the twin's clock, when a later write of the same command with
another value supersedes it, when the machine is lost, or when the run ends first. A stop,
feed hold or emergency stop is sent at once and watched by motion from the next reading on,
whatever its read-back.

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
from cnctwin.thread import CommandRejected, ConnectionLost, MachineConnection, drop_answer
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
        The value the machine showed last after the write, or ``None``.
    confirmed
        Whether a read-back showed the command in effect.
    written_s
        ``time.monotonic()`` of the write, s (NaN when nothing was written).
    confirmed_s
        ``time.monotonic()`` of the arrival of the confirming reading, s (NaN without).
    note
        Why a command the safety filter let through is not confirmed (not written while the
        machine is lost, not carried out, superseded, no read-back in time, machine lost,
        run ended); empty otherwise.
    """

    verdict: Verdict
    readback: float | None
    confirmed: bool
    written_s: float
    confirmed_s: float
    note: str = ""


@dataclass(slots=True)
class _InFlight:
    """A command written whose answer or read-back has not settled it yet."""

    verdict: Verdict
    name: str
    value: float
    written_s: float  # time.monotonic() of the write
    deadline_s: float  # the twin's clock (CycleState.time_s) by which a read-back must show it
    answer: asyncio.Future[None]
    readback: float | None = None


class ActionStage:
    """Passes decisions through the safety filter, writes them, verifies them by read-back.

    A write is sent in the cycle and not waited for (:meth:`MachineConnection.start_write`):
    the machine's answer and the read-back that shows the command settle it in later cycles,
    from their readings (module notes, docs/control.md).

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
        How long after a write a reading may show it, s of the twin's clock
        (``CycleState.time_s``); a write not shown by then is recorded as not confirmed.
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
        Every decision's result, in the order they were settled (kept for tests and the
        live view; bounded).
    writes
        Commands sent to the machine.
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
        self._in_flight: list[_InFlight] = []

    def submit(self, decision: Decision) -> None:
        """Queue a decision made outside the rules (an operator on the dashboard) for the
        next cycle, where it passes the safety filter, the write, the read-back and the
        record like a rule's. Safe from another thread; at most 16 wait (then the oldest is
        dropped), and none is kept while the machine is lost."""
        self._submitted.append(decision)

    # ------------------------------------------------------------------ the stage
    def process(self, state: CycleState) -> CycleState:
        """Settle the writes of earlier cycles on this reading; filter and write this cycle's
        decisions; record each decision once settled, with its reason."""
        if self._in_flight:
            self._settle(state)
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
            self._follow_stop(state, watch, watch.update(state.measured, now))
        verdicts = [self.safety.check(d, now, state.measured) for d in state.commands]
        # a ramp's step waiting for its rate limit is no decision: only steps sent count
        verdicts.extend(v for v in self.safety.follow_up(now, state.measured) if v.send)
        for verdict in verdicts:
            self._carry_out(state, verdict)
        return state

    @property
    def stopping(self) -> bool:
        """Whether a stop was sent and the axes have not been seen at rest yet."""
        return self._watch is not None

    @property
    def in_flight(self) -> int:
        """Commands written and not settled yet (no answer or no read-back so far)."""
        return len(self._in_flight)

    def _carry_out(self, state: CycleState, verdict: Verdict) -> None:
        """Write what the verdict lets through (recorded once settled); record the rest."""
        if not (verdict.send and self._online and verdict.command is not None):
            lost = "not written: the machine is lost" if verdict.send else ""
            self._record(state, CommandResult(verdict, None, False, math.nan, math.nan, lost))
            return
        name = verdict.command
        value = float(verdict.value if verdict.value is not None else math.nan)
        tolerance = self.safety.config.readback_tolerance_pct
        for earlier in [p for p in self._in_flight if p.name == name]:
            # a later write of the same command: the earlier one can no longer be shown
            # unless the two are equal (then the same read-back shows both)
            if not _shows(name, earlier.value, {name: value}, tolerance):
                self._settle_one(state, earlier, f"superseded by {name}={value:g}")
        flight = _InFlight(
            verdict,
            name,
            value,
            time.monotonic(),
            state.time_s + self.readback_timeout_s,
            self.connection.start_write(name, value),
        )
        self.writes += 1
        self._in_flight.append(flight)
        if flight.answer.done():  # refused at the send (the link is down): settled now
            self._settle_answered(state, flight)
        if name in LADDER and value >= 0.5:
            self._watch_step(state, name)

    def _settle(self, state: CycleState) -> None:
        """Settle the writes in flight that this cycle's reading or their answers decide."""
        values = state.measured if state.connected else {}
        # a reading taken before a write cannot show it
        received = state.received_s if math.isfinite(state.received_s) else -math.inf
        tolerance = self.safety.config.readback_tolerance_pct
        for flight in list(self._in_flight):
            if flight.answer.done():
                if self._settle_answered(state, flight):
                    continue
                if received >= flight.written_s:
                    name = flight.name
                    if name in values:
                        flight.readback = values[name]
                    if _shows(name, flight.value, values, tolerance):
                        self.safety.observe(values)
                        self._in_flight.remove(flight)
                        self._record(
                            state,
                            CommandResult(
                                flight.verdict, flight.readback, True, flight.written_s, received
                            ),
                        )
                        continue
                    if state.connected and name in LADDER and name not in values:
                        # a flag the machine does not read back: motion decides
                        self._settle_one(state, flight, "the machine does not read it back")
                        continue
            if state.time_s >= flight.deadline_s:
                waited = "no answer" if not flight.answer.done() else "no read-back showed it"
                limit = f"readback_timeout_s = {self.readback_timeout_s:g}"
                self._settle_one(state, flight, f"{waited} within {limit}")

    def _settle_answered(self, state: CycleState, flight: _InFlight) -> bool:
        """Settle a write whose answer was a refusal or a lost link; whether it was."""
        answer = flight.answer
        err: BaseException | None
        if answer.cancelled():
            err = ConnectionLost("the wait for its answer was cancelled")
        else:
            err = answer.exception()
        if err is None:
            return False
        if not isinstance(err, ConnectionLost | CommandRejected):
            raise err
        logger.warning("command %s=%g not carried out: %s", flight.name, flight.value, err)
        self._settle_one(state, flight, f"not carried out: {err}")
        return True

    def _settle_one(self, state: CycleState | None, flight: _InFlight, note: str) -> None:
        """Record a write in flight as not confirmed, with why; its answer is not waited for."""
        self._in_flight.remove(flight)
        drop_answer(flight.answer)
        if not note.startswith("not carried out"):
            logger.warning("command %s=%g not confirmed: %s", flight.name, flight.value, note)
        result = CommandResult(
            flight.verdict, flight.readback, False, flight.written_s, math.nan, note
        )
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

    def _follow_stop(self, state: CycleState, watch: StopWatch, status: StopStatus) -> None:
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
            self._carry_out(state, verdict)
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

    def _record(self, state: CycleState | None, result: CommandResult) -> None:
        """Record a settled decision (in ``state.decisions`` too, where there is a cycle)."""
        verdict = result.verdict
        decision: Decision = verdict.decision
        self.decision_count += 1
        self.results.append(result)
        if len(self.results) > 10_000:
            del self.results[:5_000]
        if state is not None:
            state.decisions.append(result)
        reason = decision.reason
        if verdict.note:
            reason = f"{reason} [{verdict.outcome}: {verdict.note}]"
        elif verdict.outcome != "sent":
            reason = f"{reason} [{verdict.outcome}]"
        if verdict.send and not result.confirmed:
            reason += f" [not confirmed by read-back: {result.note}]"
        logger.info("decision %s: %s -> %s", decision.rule, decision.action, verdict.outcome)
        if self.recorder is not None:
            value = verdict.value if verdict.value is not None else decision.value
            written = result.written_s
            self.recorder.decision(
                written if math.isfinite(written) else time.monotonic(),
                decision.rule,
                verdict.command or decision.action,
                value if value is not None and math.isfinite(value) else 0.0,
                reason,
                verdict.send and result.confirmed,
                result.readback,
            )

    # ------------------------------------------------------------------ lost machine
    def connection_lost(self, state: CycleState) -> None:
        """The machine is lost: write nothing until it is back. The writes in flight are
        recorded as not confirmed now (none is sent again: the reconnection policy decides
        what to write when the machine is back)."""
        self._online = False
        self._anomaly_s = None
        for flight in list(self._in_flight):
            self._settle_one(state, flight, "the machine was lost before a read-back showed it")

    def connection_restored(self, state: CycleState) -> list[TwinEvent]:
        """The machine is back: apply the lost-connection policy; return its events."""
        self._online = True
        now = time.monotonic()
        events = []
        for verdict in self.safety.after_reconnect(state.measured, state.time_s):
            self._carry_out(state, verdict)
            events.append(
                TwinEvent(
                    "reconnect_policy",
                    verdict.note or verdict.decision.reason,
                    now,
                    {"command": verdict.command, "value": verdict.value},
                )
            )
        return events

    def close(self) -> None:
        """The run ends: the writes in flight are recorded as not confirmed."""
        for flight in list(self._in_flight):
            self._settle_one(None, flight, "the run ended before a read-back showed it")


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
