"""The twin's MQTT link (docs/mqtt.md): external sensor signals into the cycle, and the
cycle's telemetry, decisions and events out to the broker.

:class:`MqttSignalStage` runs right after the read stage: each ``[[mqtt.signals]]`` value
that is fresh (received within its ``max_age_s``) joins the sample's measured signals; a
stale or missing one is left out and marked invalid (``rejected``), like a garbage value of
the machine. MQTT values are measurements only: the machine's state and every command stay
with ``[connection]``.

:class:`MqttOutlet` runs after the watchdog, once per cycle: it hands the cycle's telemetry
(at most ``telemetry_hz``), decisions and events to the
:class:`~cnctwin.thread.MqttPublisher`, which never blocks, and turns the broker's comings
and goings and the rejected sensor payloads into events of the run. The payloads are built
by :func:`telemetry_payload`, :func:`decision_payload` and :func:`event_payload`; their JSON
Schema is in docs/mqtt.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from cnctwin.errors import ConfigError
from cnctwin.twin.stages import PREDICTIONS
from cnctwin.twin.state import CycleState, TwinEvent

if TYPE_CHECKING:  # paho-mqtt loads only with an enabled [mqtt]
    from cnctwin.thread import LinkEvent, MqttPublisher, MqttSignalConfig, MqttSource

__all__ = [
    "SCHEMAS",
    "MqttOutlet",
    "MqttSignalStage",
    "decision_payload",
    "event_payload",
    "telemetry_payload",
]

#: The ``schema`` of each message kind (docs/mqtt.md gives each one's JSON Schema).
SCHEMAS = {
    "telemetry": "cnctwin.telemetry.v1",
    "decisions": "cnctwin.decision.v1",
    "events": "cnctwin.event.v1",
    "status": "cnctwin.status.v1",
}

#: Shortest time between two ``mqtt_rejected`` events of one topic, s (a flood of garbage
#: is counted, not recorded message by message).
REJECTED_EVERY_S = 1.0


class MqttSignalStage:
    """Step 1b: the fresh values of the external sensor signals join the sample.

    Parameters
    ----------
    source
        The MQTT source (subscribed to the signals' topics).
    signals
        The ``[[mqtt.signals]]`` entries.
    clock
        The source's clock, s (``time.monotonic``).

    Raises
    ------
    ConfigError
        When an extra signal's name is one of the twin's predictions or a filtered name.
    """

    name = "mqtt_signals"
    per_sample = True

    def __init__(
        self,
        source: MqttSource,
        signals: Sequence[MqttSignalConfig],
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        for spec in signals:
            if spec.signal in PREDICTIONS or spec.signal.startswith("filtered_"):
                raise ConfigError(
                    f"[mqtt] signals: {spec.signal!r} is a name the twin computes; "
                    "give the external signal another name"
                )
        self.source = source
        self.signals = list(signals)
        self._clock = clock
        self._invalid: set[str] = set()

    def process(self, state: CycleState) -> CycleState:
        """Add fresh MQTT values to ``measured``; mark stale or missing ones ``rejected``."""
        latest = self.source.latest()
        now = self._clock()
        invalid: dict[str, tuple[str, str]] = {}
        for spec in self.signals:
            name = spec.signal
            got = latest.get(name)
            state.measured.pop(name, None)  # the machine's own value of it is not used
            if got is None:
                reason = f"no value yet from MQTT topic {spec.topic}"
            elif now - got.received_s > spec.max_age_s:
                reason = (
                    f"MQTT value {now - got.received_s:.3f} s old, beyond max_age_s "
                    f"{spec.max_age_s:g} (topic {spec.topic})"
                )
            else:
                state.measured[name] = got.value
                state.rejected.pop(name, None)
                continue
            state.rejected[name] = reason
            invalid[name] = (spec.topic, reason)
        for name in [n for n in invalid if n not in self._invalid]:
            topic, reason = invalid[name]
            state.events.append(
                TwinEvent(
                    "signal_invalid",
                    f"{name} invalid: {reason}",
                    now,
                    {"signal": name, "topic": topic, "reason": reason},
                )
            )
        self._invalid = set(invalid)
        return state


def _number(value: Any) -> float | None:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, int | float):
        return float(value) if math.isfinite(value) else None
    return None


def telemetry_payload(state: CycleState, t_s: float, time_unix_s: float) -> dict[str, Any]:
    """The telemetry message of one cycle (schema ``cnctwin.telemetry.v1``, docs/mqtt.md).

    Parameters
    ----------
    state
        The cycle.
    t_s
        Time of its sample since the run's start, s.
    time_unix_s
        The same instant as Unix time, s.
    """
    return {
        "schema": SCHEMAS["telemetry"],
        "time_unix_s": time_unix_s,
        "t_s": t_s,
        "cycle": state.index,
        "measured": {k: _number(v) for k, v in state.measured.items()},
        "rejected": dict(state.rejected),
        "filtered": {k: _number(v) for k, v in state.filtered.items()},
        "features": {k: _number(v) for k, v in state.features.items()},
        "predicted": {k: _number(v) for k, v in state.predicted.items()},
    }


def decision_payload(result: Any, t_s: float, time_unix_s: float) -> dict[str, Any]:
    """The message of one decision (schema ``cnctwin.decision.v1``).

    Parameters
    ----------
    result
        A :class:`~cnctwin.twin.actions.CommandResult` (the decision, the safety filter's
        verdict, the read-back).
    t_s, time_unix_s
        When, s since the run's start and Unix s.
    """
    verdict = result.verdict
    decision = verdict.decision
    value = verdict.value if verdict.value is not None else decision.value
    return {
        "schema": SCHEMAS["decisions"],
        "time_unix_s": time_unix_s,
        "t_s": t_s,
        "rule": decision.rule,
        "action": decision.action,
        "command": verdict.command,
        "value": _number(value),
        "outcome": verdict.outcome,
        "reason": decision.reason if not verdict.note else f"{decision.reason}; {verdict.note}",
        "readback": _number(result.readback),
        "confirmed": bool(result.confirmed),
    }


def event_payload(event: TwinEvent, t_s: float, time_unix_s: float) -> dict[str, Any]:
    """The message of one event (schema ``cnctwin.event.v1``).

    Parameters
    ----------
    event
        The event.
    t_s, time_unix_s
        When, s since the run's start and Unix s.
    """
    return {
        "schema": SCHEMAS["events"],
        "time_unix_s": time_unix_s,
        "t_s": t_s,
        "kind": event.kind,
        "message": event.message,
        "data": dict(event.data),
    }


class MqttOutlet:
    """Hands each cycle's telemetry, decisions and events to the publisher (never blocks).

    Parameters
    ----------
    publisher
        The publisher, or ``None`` (only the source's events then).
    source
        The sensor source, or ``None``.
    telemetry_hz
        Telemetry messages per second at most, Hz (twin clock).
    t0_s
        ``time.monotonic()`` of the run's start (times are seconds since it, as recorded).
    """

    name = "mqtt_publish"

    def __init__(
        self,
        publisher: MqttPublisher | None,
        source: MqttSource | None,
        *,
        telemetry_hz: float,
        t0_s: float,
    ) -> None:
        self.publisher = publisher
        self.source = source
        self.period_s = 1.0 / telemetry_hz
        self.t0_s = t0_s
        self._unix_offset_s = time.time() - time.monotonic()
        self._next_s = -math.inf
        self._rejected_s: dict[str, float] = {}

    def send(self, state: CycleState) -> None:
        """Publish this cycle's messages; add the link's and the source's events to it."""
        self._link_events(state)
        pub = self.publisher
        if pub is None:
            return
        if state.connected and state.new_sample and state.time_s >= self._next_s:
            self._next_s = max(self._next_s + self.period_s, state.time_s)
            at = state.received_s if math.isfinite(state.received_s) else state.deadline_s
            pub.offer(
                "telemetry", telemetry_payload(state, at - self.t0_s, at + self._unix_offset_s)
            )
        for result in state.decisions:
            at = result.written_s if math.isfinite(result.written_s) else time.monotonic()
            pub.offer(
                "decisions", decision_payload(result, at - self.t0_s, at + self._unix_offset_s)
            )
        for event in state.events:
            pub.offer(
                "events",
                event_payload(event, event.t_s - self.t0_s, event.t_s + self._unix_offset_s),
            )

    def stats(self) -> dict[str, Any]:
        """The publisher's and the source's counts (JSON-ready)."""
        out: dict[str, Any] = {}
        if self.publisher is not None:
            out["publisher"] = self.publisher.stats()
        if self.source is not None:
            out["source"] = self.source.stats()
        return out

    def _link_events(self, state: CycleState) -> None:
        for role, link_owner in (("publisher", self.publisher), ("source", self.source)):
            if link_owner is None:
                continue
            for link_event in link_owner.link.drain():
                state.events.append(_twin_event(role, link_event))
        if self.source is None:
            return
        now = time.monotonic()
        for topic, problem in self.source.problems().items():
            if now - self._rejected_s.get(topic, -math.inf) < REJECTED_EVERY_S:
                continue
            self._rejected_s[topic] = now
            count = self.source.rejected.get(topic, 0)
            state.events.append(
                TwinEvent(
                    "mqtt_rejected",
                    f"MQTT message on {topic} rejected: {problem}",
                    now,
                    {"topic": topic, "reason": problem, "rejected_total": count},
                )
            )


def _twin_event(role: str, event: LinkEvent) -> TwinEvent:
    if event.kind == "mqtt_lost":
        message = f"MQTT broker lost by the {role}: {event.data.get('reason', '')}"
    else:
        message = f"MQTT broker back for the {role} after a gap of {event.data['gap_s']:.3f} s"
    return TwinEvent(event.kind, message, event.t_s, {"role": role, **event.data})
