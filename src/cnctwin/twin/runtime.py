"""The twin's runtime: a fixed-period asyncio cycle over the stages, timed and watched.

Every ``cycle_s`` (12.5 ms after Heide 2025, Fig. 5) the runtime runs the stages in order
on a fresh :class:`~cnctwin.twin.state.CycleState`. Deadlines are absolute (``t0 + k *
cycle_s``): a late wake-up does not push later cycles back. A cycle whose stages end after
its period is an *overrun*; the runtime then skips the deadlines it missed instead of
running cycles back to back. Each stage is timed (``time.perf_counter``), and the summary
gives per-stage and whole-cycle p50/p99.

A watchdog follows the connection: a failed read, a ``heartbeat`` signal that has not
changed for ``watchdog_s``, or a stale reading (older than ``[twin] max_sample_age_s``,
:mod:`cnctwin.twin.freshness`) marks the machine *lost*; the next new sample with a moving
heartbeat marks it *restored*. Both are recorded as events; the gap runs from the last
fresh sample to the first fresh one after it, and the action stage applies the
lost-connection policy (see docs/twin.md). A cycle whose reading is no new sample runs only
the stages that are not ``per_sample`` (the actions' time-based work) and records no frame.

The run ends when the machine reports its program finished, when it has stopped (after the
twin's stop is confirmed by motion, :mod:`cnctwin.twin.stopping`), after ``duration_s``, or
when ``stop_event`` is set.
"""

from __future__ import annotations

import asyncio
import gc
import inspect
import logging
import math
import time
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

from cnctwin.thread import RunState
from cnctwin.twin.actions import ActionStage
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.settings import OverloadConfig
from cnctwin.twin.stages import Stage
from cnctwin.twin.state import CycleState, TwinEvent
from cnctwin.twin.timing import OverloadMonitor, TimingSeries

__all__ = ["Outlet", "RunSummary", "TwinRuntime"]

logger = logging.getLogger(__name__)

# events the watchdog records itself (:meth:`TwinRuntime._emit`) as it raises them
_RECORDED_BY_WATCH = ("reached", "connected", "connection_lost", "connection_restored")


class Outlet(Protocol):
    """Where each finished cycle goes out (the MQTT publisher, docs/mqtt.md): called after
    the watchdog with the cycle's state, it must not block; events it appends are recorded."""

    name: str

    def send(self, state: CycleState) -> None:
        """Hand the cycle on (quickly: its time counts in the cycle's)."""
        ...

    def stats(self) -> dict[str, Any]:
        """Figures for the run's summary (JSON-ready)."""
        ...


@dataclass
class RunSummary:
    """Figures of one run (units in the names).

    Attributes
    ----------
    cycles
        Cycles run.
    cycle_p50_ms, cycle_p99_ms, cycle_max_ms
        Cycle time (all stages, read and actions included), ms.
    overruns
        Cycles that ended after their period.
    overloaded_cycles
        Cycles run while the twin was overloaded (docs/twin.md, "Overload").
    overload_episodes
        Times the twin became overloaded.
    shed
        The optional stages shed at the worst of the overload, in the order they were shed.
    stop_reaction_ms
        From the first out-of-band sample of the anomaly that stopped the machine to the
        reading that showed the axes at rest, ms; ``None`` without a stop.
    stop_reactions_ms
        Every such reaction of the run, ms.
    feed_override_min
        Lowest feed override the machine reported, %.
    events
        Events recorded.
    decisions
        Decisions recorded.
    samples_recorded
        Cycles whose samples went to the historian.
    database
        The historian's location, or ``None`` without one.
    ended
        ``"finished"``, ``"stopped"``, ``"duration"`` or ``"interrupted"``.
    reconnects
        Times the connection was restored.
    gaps_s
        Length of each connection gap, s.
    stages_ms
        Stage name -> ``{"p50_ms", "p99_ms", "max_ms"}`` (outlets too).
    outlets
        Outlet name -> its figures (MQTT: messages offered, acknowledged, dropped, gaps).
    stage_results
        Stage name -> what the stage found over the run, for the stages that report it
        (a ``run_results()`` method; the roughness stage: its program sections).
    """

    cycles: int = 0
    cycle_p50_ms: float = 0.0
    cycle_p99_ms: float = 0.0
    cycle_max_ms: float = 0.0
    overruns: int = 0
    overloaded_cycles: int = 0
    overload_episodes: int = 0
    shed: list[str] = field(default_factory=list)
    stop_reaction_ms: float | None = None
    stop_reactions_ms: list[float] = field(default_factory=list)
    feed_override_min: float | None = None
    events: int = 0
    decisions: int = 0
    samples_recorded: int = 0
    database: str | None = None
    ended: str = ""
    reconnects: int = 0
    gaps_s: list[float] = field(default_factory=list)
    stages_ms: dict[str, dict[str, float]] = field(default_factory=dict)
    outlets: dict[str, dict[str, Any]] = field(default_factory=dict)
    stage_results: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The summary as JSON-ready values."""
        return asdict(self)


class TwinRuntime:
    """Runs the twin cycle against one machine connection.

    Parameters
    ----------
    stages
        The cycle's stages in order; the first reads the machine
        (:class:`~cnctwin.twin.stages.ReadStage`).
    actions
        The action stage (also among ``stages``), told about lost and restored connections.
    cycle_s
        Period, s.
    watchdog_s
        Heartbeat staleness (and read failure time) after which the machine counts as lost, s.
    recorder
        The historian's recorder, or ``None``.
    realtime
        Keep the period (sleep to each deadline). ``False`` runs cycles back to back (tests
        against a lockstep :class:`~cnctwin.twin.local.LocalConnection`); overruns are then
        not counted.
    on_cycle
        Called with every finished cycle's state (the live view); keep it quick.
    stop_hold_s
        After the machine reports STOPPED, keep cycling this long before ending, s.
    overload
        When the twin counts as overloaded, and whether it sheds (``None``: the defaults).
    shed_order
        The optional stages to shed while overloaded, first shed first (stage names, and
        ``"historian_detail"``: the historian keeps every ``sample_every``-th cycle).
    clock, sleep
        The clock (s) that times the cycles, the watchdog and the stop hold, and how the
        runtime waits (s): ``time.monotonic`` and
        ``asyncio.sleep``; tests give a fake clock whose sleep advances it.
    outlets
        Called with each cycle's state after the watchdog (:class:`Outlet`); their time
        counts in the cycle time.
    """

    def __init__(
        self,
        stages: Sequence[Stage],
        actions: ActionStage | None,
        *,
        cycle_s: float = 0.0125,
        watchdog_s: float = 0.5,
        recorder: Recorder | None = None,
        realtime: bool = True,
        on_cycle: Callable[[CycleState], None] | None = None,
        stop_hold_s: float = 0.1,
        overload: OverloadConfig | None = None,
        shed_order: Sequence[str] = (),
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], Awaitable[None]] = asyncio.sleep,
        outlets: Sequence[Outlet] = (),
    ) -> None:
        self.stages = list(stages)
        self.outlets = list(outlets)
        self.overload = overload or OverloadConfig()
        self.shed_order = tuple(shed_order) if self.overload.shed else ()
        self.load = OverloadMonitor(
            self.overload.window_cycles,
            self.overload.enter_fraction,
            self.overload.exit_fraction,
            len(self.shed_order),
        )
        self._clock = clock
        self._sleep = sleep
        self._shed: frozenset[str] = frozenset()
        self._shed_most: tuple[str, ...] = ()
        self.actions = actions
        self.cycle_s = cycle_s
        self.watchdog_s = watchdog_s
        self.recorder = recorder
        self.realtime = realtime
        self.on_cycle = on_cycle
        self.stop_hold_s = stop_hold_s
        names = [stage.name for stage in self.stages] + [outlet.name for outlet in self.outlets]
        self.timings = {name: TimingSeries() for name in names}
        self.cycle_times = TimingSeries()
        self.overruns = 0
        self.cycles = 0
        self.events: list[TwinEvent] = []
        self.connected = False
        self.feed_override_min: float | None = None
        self.last_state: CycleState | None = None
        self._last_beat: float | None = None
        self._beat_s = math.nan
        self._beat_received_s = math.inf
        self._lost_s: float | None = None
        self._gaps: list[float] = []
        self._reconnects = 0
        self._ever_connected = False
        self._reached = False
        self._stopped_since: float | None = None
        self._prepared = False

    # ------------------------------------------------------------------ loop
    def prepare(self) -> None:
        """Get ready for the first cycle (:meth:`run` calls it; call it earlier to start the
        machine right before the first read).

        Everything built so far (models, kernels, the protocol stack) lives as long as the
        run: it is moved out of the garbage collector's sight (``gc.freeze``), so a full
        collection in the middle of a cycle walks only what the cycles allocate (a full
        collection of the whole heap took 0.4 s on the 2-core sandbox, inside a cycle).
        """
        if self._prepared:
            return
        gc.collect()
        gc.freeze()
        self._prepared = True

    async def run(
        self, *, duration_s: float | None = None, stop_event: asyncio.Event | None = None
    ) -> RunSummary:
        """Cycle until the program ends, the machine stops, time is up or ``stop_event``.

        Parameters
        ----------
        duration_s
            Longest run, s (wall clock); ``None``: no limit.
        stop_event
            Set it to end the run after the current cycle (Ctrl-C).

        Returns
        -------
        RunSummary
            The run's figures; also recorded with the run when there is a recorder.
        """
        self.prepare()
        t0 = self._clock()
        self._beat_s = self._clock()
        deadline = t0
        ended = "interrupted"
        try:
            while True:
                if stop_event is not None and stop_event.is_set():
                    ended = "interrupted"
                    break
                clock = self._clock() if self.realtime else self.cycles * self.cycle_s
                state = CycleState(self.cycles, deadline, clock)
                started = self._clock()
                for stage in self.stages:
                    if getattr(stage, "per_sample", False) and not state.new_sample:
                        continue  # nothing new to compute: no duplicate sample downstream
                    if stage.name in self._shed:
                        continue  # overloaded: an optional stage is shed (docs/twin.md)
                    t_stage = self._clock()
                    result = stage.process(state)
                    if inspect.isawaitable(result):
                        result = await result
                    state = result
                    self.timings[stage.name].add(self._clock() - t_stage)
                work_s = self._clock() - started
                self.cycles += 1
                await self._watch(state)
                for outlet in self.outlets:
                    t_out = self._clock()
                    outlet.send(state)
                    spent = self._clock() - t_out
                    self.timings[outlet.name].add(spent)
                    work_s += spent
                self.cycle_times.add(work_s)
                if self.realtime:
                    self._judge_load(state, self._clock() > deadline + self.cycle_s)
                self._bookkeep(state)
                self.last_state = state
                if self.on_cycle is not None:
                    self.on_cycle(state)
                end = self._end_reason(state)
                if end is not None:
                    ended = end
                    break
                now = self._clock()
                if duration_s is not None and now - t0 >= duration_s:
                    ended = "duration"
                    break
                if not self.realtime:
                    await asyncio.sleep(0)
                    deadline = now
                    continue
                deadline += self.cycle_s
                if now > deadline:
                    self.overruns += 1
                    missed = math.ceil((now - deadline) / self.cycle_s)
                    deadline += missed * self.cycle_s
                await self._sleep(max(deadline - self._clock(), 0.0))
        except asyncio.CancelledError:
            ended = "interrupted"
            raise
        finally:
            if self.actions is not None:
                self.actions.close()
            summary = self.summary(ended)
            if self.recorder is not None:
                self.recorder.end(_status(ended), summary.to_dict())
        return summary

    # ------------------------------------------------------------------ overload
    def _judge_load(self, state: CycleState, overran: bool) -> None:
        """Follow the overrun fraction; say when the twin is overloaded, shed, recovered.

        The events join the cycle's (the historian, the live view) and the log (a warning:
        the terminal line). Cycles without the machine do not count: a read that times out
        is a lost connection (the watchdog's events), not a load.
        """
        if not (state.connected and self.connected):
            return
        change = self.load.update(overran)
        if change is None:
            return
        load = self.load
        shed = self.shed_order[: load.level]
        self._shed = frozenset(shed)
        if len(shed) > len(self._shed_most):
            self._shed_most = shed
        recent = (
            f"overruns in {load.fraction:.0%} of the last {load.window} cycles, cycle work p50 "
            f"{self.cycle_times.recent_percentile_ms(50, load.window):.1f} ms / p99 "
            f"{self.cycle_times.recent_percentile_ms(99, load.window):.1f} ms against a "
            f"period of {self.cycle_s * 1e3:g} ms"
        )
        data: dict[str, Any] = {
            "overrun_fraction": load.fraction,
            "cycle_p99_ms": self.cycle_times.recent_percentile_ms(99, load.window),
            "shed": list(shed),
        }
        if change == "cleared":
            event = TwinEvent(
                "overload_cleared", f"cycle keeps its period again ({recent})", self._clock(), data
            )
        elif change == "entered":
            doing = f"; shedding {shed[0]}" if shed else "; nothing optional to shed"
            event = TwinEvent(
                "overload",
                f"twin overloaded: {recent}{doing}; protection (reading, force band, rules, "
                "actions) still runs every cycle on the latest reading",
                self._clock(),
                data,
            )
        else:
            event = TwinEvent(
                "overload_shed",
                f"still overloaded ({recent}): shedding {shed[-1]} too",
                self._clock(),
                data,
            )
        logger.warning("%s", event.message)
        state.events.append(event)

    # ------------------------------------------------------------------ watchdog
    async def _watch(self, state: CycleState) -> None:
        now = self._clock()
        beat = state.measured.get("heartbeat") if state.connected else None
        if beat is not None and beat != self._last_beat:
            self._last_beat = beat
            self._beat_s = now
            self._beat_received_s = state.received_s
        if state.connected and not self._reached:
            # the machine answered: the twin watches it from here, and counts it connected
            # (alive) from its first fresh sample on, which a paused machine does not send
            self._reached = True
            self._emit(state, TwinEvent("reached", "machine answered its first read", now))
        stale = now - self._beat_s > self.watchdog_s
        alive = state.connected and not stale and not state.stale
        if self.connected and not alive:
            if not state.connected:
                why = "read failed"
            elif state.stale:
                why = f"sample {state.sample_age_s:.3f} s old, beyond [twin] max_sample_age_s"
            else:
                why = f"heartbeat stale for {now - self._beat_s:.3f} s"
            self.connected = False
            # the gap starts at the last fresh sample (with a moving heartbeat), not at its
            # detection
            start = min(state.last_sample_s, self._beat_received_s)
            if not math.isfinite(start):
                start = now
            self._lost_s = start
            self._emit(
                state,
                TwinEvent(
                    "connection_lost",
                    f"machine lost: {why}",
                    start,
                    {"detected_after_s": now - start},
                ),
            )
            if self.actions is not None:
                self.actions.connection_lost(state)
            for stage in self.stages:
                forget = getattr(stage, "forget", None)
                if callable(forget):
                    forget()
        elif not self.connected and alive and beat is not None and state.new_sample:
            self.connected = True
            if self._ever_connected:
                back = state.received_s if math.isfinite(state.received_s) else now
                gap = back - (self._lost_s if self._lost_s is not None else back)
                self._gaps.append(gap)
                self._reconnects += 1
                self._emit(
                    state,
                    TwinEvent(
                        "connection_restored",
                        f"machine back after a gap of {gap:.3f} s",
                        now,
                        {"gap_s": gap},
                    ),
                )
                if self.actions is not None:
                    for event in self.actions.connection_restored(state):
                        self._emit(state, event)
            else:
                self._emit(state, TwinEvent("connected", "machine connected", now))
            self._ever_connected = True

    def _emit(self, state: CycleState, event: TwinEvent) -> None:
        state.events.append(event)
        if self.recorder is not None:
            self.recorder.event(event)
        logger.info("%s", event.message)

    # ------------------------------------------------------------------ bookkeeping
    def _bookkeep(self, state: CycleState) -> None:
        if state.connected:
            override = state.measured.get("feed_override_pct")
            if override is not None and (
                self.feed_override_min is None or override < self.feed_override_min
            ):
                self.feed_override_min = override
        if self.recorder is not None:
            # overloaded with the historian's detail shed: every sample_every-th cycle's samples
            # (events and decisions are always kept)
            thinned = "historian_detail" in self._shed and state.index % self.overload.sample_every
            if not thinned:
                self.recorder.cycle(state)
            for event in state.events:
                if event.kind not in _RECORDED_BY_WATCH:
                    self.recorder.event(event)
        self.events.extend(state.events)

    def _end_reason(self, state: CycleState) -> str | None:
        if not (state.connected and self.connected):
            return None
        run_state = state.measured.get("run_state")
        if run_state == RunState.FINISHED:
            return "finished"
        # a stop the twin sent ends the run only once the axes are seen at rest
        # (docs/control.md, "Stop confirmation"): the flag alone is no stop, and a machine
        # that did not stop stays watched
        actions = self.actions
        if actions is not None and (actions.stopping or actions.stop_outcome == "failed"):
            return None
        confirmed = actions is not None and actions.stop_outcome == "confirmed"
        if run_state == RunState.STOPPED or (run_state == RunState.FAULT and confirmed):
            now = self._clock()
            if self._stopped_since is None:
                self._stopped_since = now
            if now - self._stopped_since >= self.stop_hold_s or not self.realtime:
                return "stopped"
        else:
            self._stopped_since = None
        return None

    def summary(self, ended: str = "") -> RunSummary:
        """The figures so far."""
        cycle = self.cycle_times.summary()
        reactions = list(self.actions.stop_reactions_ms) if self.actions is not None else []
        rec = self.recorder
        return RunSummary(
            cycles=self.cycles,
            cycle_p50_ms=cycle["p50_ms"],
            cycle_p99_ms=cycle["p99_ms"],
            cycle_max_ms=cycle["max_ms"],
            overruns=self.overruns,
            overloaded_cycles=self.load.overloaded_cycles,
            overload_episodes=self.load.episodes,
            shed=list(self._shed_most),
            stop_reaction_ms=reactions[0] if reactions else None,
            stop_reactions_ms=reactions,
            feed_override_min=self.feed_override_min,
            events=len(self.events),
            decisions=self.actions.decision_count if self.actions is not None else 0,
            samples_recorded=rec.samples if rec is not None else 0,
            database=rec.location if rec is not None else None,
            ended=ended,
            reconnects=self._reconnects,
            gaps_s=list(self._gaps),
            stages_ms={
                name: {k: v for k, v in series.summary().items() if k != "count"}
                for name, series in self.timings.items()
            },
            outlets={outlet.name: outlet.stats() for outlet in self.outlets},
            stage_results={
                stage.name: stage.run_results()
                for stage in self.stages
                if hasattr(stage, "run_results")
            },
        )


def _status(ended: str) -> str:
    return {"finished": "finished", "stopped": "stopped"}.get(ended, ended or "failed")
