"""The dashboard's tap on the twin cycle, and its fan-out to the browsers.

The twin never waits for the dashboard. After each cycle the runtime hands its
:class:`~cnctwin.twin.state.CycleState` to :meth:`LiveFeed.put`, which appends a reference to
a bounded deque (O(1), no copy, no lock the twin can block on): when the dashboard falls
behind, the oldest cycles are dropped and counted. Events and decisions go to a second
bounded deque of their own, so that dropping cycles never drops them from the timeline
(unless more than its capacity pile up between two reads).

The server side (:class:`Hub`, on the web server's own event loop and thread) drains the feed
about ten times a second, turns the cycles into one JSON message and puts it into each
browser's own bounded queue without waiting; a browser whose queue is full (a slow or dead
connection) is dropped and its stream ends.
"""

from __future__ import annotations

import asyncio
import math
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from cnctwin.thread import RunState
from cnctwin.twin import CycleState, TwinEvent

__all__ = [
    "SERIES",
    "Hub",
    "LiveFeed",
    "Subscriber",
    "decision_item",
    "event_item",
    "run_state_name",
    "series_of",
]

#: The per-cycle series the page plots: name -> (where, signal). ``where`` is ``"m"``
#: (measured, the machine's reading) or ``"p"`` (the twin's predictions and derived values);
#: units in the names.
SERIES: dict[str, tuple[str, str]] = {
    "t_s": ("m", "t_s"),
    "force_measured_n": ("p", "measured_force_xy_n"),
    "force_predicted_n": ("p", "predicted_force_xy_n"),
    "force_band_low_n": ("p", "force_band_low_n"),
    "force_band_high_n": ("p", "force_band_high_n"),
    "spindle_rpm": ("m", "spindle_rpm"),
    "spindle_torque_nm": ("m", "spindle_torque_nm"),
    "torque_predicted_nm": ("p", "predicted_torque_nm"),
    "spindle_power_w": ("m", "spindle_power_w"),
    "power_predicted_w": ("p", "predicted_power_w"),
    "spindle_current_a": ("m", "spindle_current_a"),
    "feed_mm_min": ("m", "feed_mm_min"),
    "feed_override_pct": ("m", "feed_override_pct"),
    "spindle_override_pct": ("m", "spindle_override_pct"),
    "ae_mm": ("p", "ae_mm"),
    "ap_mm": ("p", "ap_mm"),
    "mrr_mm3_s": ("p", "mrr_mm3_s"),
    "form_error_um": ("p", "form_error_um"),
    "form_error_tolerance_um": ("p", "form_error_tolerance_um"),
}


class LiveFeed:
    """Bounded hand-over of cycles from the twin to the dashboard (drop oldest).

    Parameters
    ----------
    capacity
        Cycles kept until the dashboard reads them (>= 1); older ones are dropped.
    timeline_capacity
        Events and decisions kept until read (>= 1).
    """

    def __init__(self, capacity: int = 256, timeline_capacity: int = 1024) -> None:
        if capacity < 1 or timeline_capacity < 1:
            raise ValueError(
                f"capacity {capacity}, timeline_capacity {timeline_capacity}; give >= 1"
            )
        self._cycles: deque[CycleState] = deque(maxlen=capacity)
        self._timeline: deque[TwinEvent | Any] = deque(maxlen=timeline_capacity)
        self.put_count = 0
        self.taken_count = 0
        self.latest: CycleState | None = None

    def put(self, state: CycleState) -> None:
        """Hand one finished cycle over (the twin's thread; never blocks, never copies)."""
        self._cycles.append(state)
        self.latest = state
        self.put_count += 1
        if state.events:
            self._timeline.extend(state.events)
        if state.decisions:
            self._timeline.extend(state.decisions)

    def take(self) -> tuple[list[CycleState], list[Any]]:
        """The cycles and the timeline items put since the last take, oldest first."""
        cycles = _drain(self._cycles)
        self.taken_count += len(cycles)
        return cycles, _drain(self._timeline)

    @property
    def dropped(self) -> int:
        """Cycles dropped because the dashboard did not take them in time."""
        return max(self.put_count - self.taken_count - len(self._cycles), 0)


def _drain(queue: deque[Any]) -> list[Any]:
    out = []
    while True:
        try:
            out.append(queue.popleft())
        except IndexError:
            return out


def series_of(cycles: Iterable[CycleState]) -> dict[str, list[float | None]]:
    """The :data:`SERIES` of the cycles that brought a new sample, column by column.

    Missing and non-finite values are ``None`` (JSON ``null``: a gap in the plot).
    """
    columns: dict[str, list[float | None]] = {name: [] for name in SERIES}
    for state in cycles:
        if not state.new_sample:
            continue
        sources = {"m": state.measured, "p": state.predicted}
        for name, (where, key) in SERIES.items():
            columns[name].append(_finite(sources[where].get(key)))
    return columns


def _finite(value: float | None) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def event_item(event: TwinEvent, t0_s: float) -> dict[str, Any]:
    """A timeline entry for a runtime event (``t_s``: s since the run's start)."""
    return {
        "kind": "event",
        "t_s": event.t_s - t0_s,
        "who": "twin",
        "what": event.kind,
        "outcome": "",
        "values": _finite_values(event.data),
        "reason": event.message,
    }


def decision_item(result: Any, t0_s: float) -> dict[str, Any]:
    """A timeline entry for a decision (:class:`cnctwin.twin.actions.CommandResult`).

    ``who`` is the rule's name (``dashboard`` for a command from the page, with the
    client's address in the reason); ``values`` are the figures the rule read.
    """
    verdict = result.verdict
    decision = verdict.decision
    value = verdict.value if verdict.value is not None else decision.value
    return {
        "kind": "decision",
        "t_s": decision.time_s - t0_s,
        "who": decision.rule,
        "what": f"{verdict.command or decision.action}",
        "value": _finite(value),
        "outcome": verdict.outcome
        if result.confirmed or not verdict.send
        else f"{verdict.outcome}, not confirmed by read-back",
        "readback": _finite(result.readback),
        "values": _finite_values(decision.values),
        "reason": decision.reason + (f" [{verdict.note}]" if verdict.note else ""),
    }


def _finite_values(values: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, float | int) and not isinstance(value, bool):
            out[key] = _finite(float(value))
        elif isinstance(value, str | bool) or value is None:
            out[key] = value
        else:
            out[key] = str(value)
    return out


def run_state_name(value: float | None) -> str:
    """The :class:`~cnctwin.thread.signals.RunState` name of a ``run_state`` reading."""
    if value is None or not math.isfinite(value):
        return "-"
    try:
        return RunState(int(value)).name.lower()
    except ValueError:
        return f"unknown ({value:g})"


@dataclass(eq=False)
class Subscriber:
    """One browser's stream: its own bounded queue of JSON messages.

    Attributes
    ----------
    queue
        Messages not yet sent to the browser.
    closed
        Dropped (too slow, or gone): the stream ends.
    """

    queue: asyncio.Queue[str]
    closed: bool = False


class Hub:
    """Fans each message out to every browser without waiting for any.

    Parameters
    ----------
    queue_size
        Messages a browser may have pending (>= 1); one more and it is dropped.
    """

    def __init__(self, queue_size: int = 20) -> None:
        if queue_size < 1:
            raise ValueError(f"queue_size {queue_size}; give >= 1")
        self.queue_size = queue_size
        self.subscribers: set[Subscriber] = set()
        self.opened = 0
        self.dropped = 0

    def subscribe(self) -> Subscriber:
        """A new browser stream (call on the hub's event loop)."""
        sub = Subscriber(asyncio.Queue(maxsize=self.queue_size))
        self.subscribers.add(sub)
        self.opened += 1
        return sub

    def unsubscribe(self, sub: Subscriber) -> None:
        """The browser went away, or is too slow: forget it; its stream ends."""
        sub.closed = True
        self.subscribers.discard(sub)

    def publish(self, message: str) -> None:
        """Queue ``message`` for every browser; drop those whose queue is full."""
        for sub in list(self.subscribers):
            try:
                sub.queue.put_nowait(message)
            except asyncio.QueueFull:
                self.dropped += 1
                self.unsubscribe(sub)

    async def next_message(self, sub: Subscriber, timeout_s: float) -> str | None:
        """The browser's next message; ``None`` after ``timeout_s`` s without one, or when
        the browser was dropped (then ``sub.closed`` is true)."""
        if sub.closed:
            return None
        try:
            message = await asyncio.wait_for(sub.queue.get(), timeout_s)
        except TimeoutError:
            return None
        return None if sub.closed else message
