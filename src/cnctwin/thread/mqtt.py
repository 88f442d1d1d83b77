"""MQTT: the twin's publisher and its external sensor source (docs/mqtt.md), over paho-mqtt.

paho-mqtt runs each client's network traffic in a thread of its own (``loop_start``), apart
from the twin's asyncio loop: a slow or absent broker never takes time from the cycle.

:class:`MqttPublisher` takes messages from the cycle with :meth:`~MqttPublisher.offer`
(no lock: a queue put and a count, microseconds), encodes them as JSON in a thread of its own and
hands them to paho with QoS 1. The local buffer (``[mqtt.publish] buffer``) holds what the
broker has not acknowledged: messages waiting while the broker is away and messages in
flight. paho sends the unacknowledged ones again after a reconnect (DUP set), so a
subscriber may see a message twice (QoS 1 is *at least once*); every message carries a
sequence number ``seq`` to tell. A message that finds the buffer full is dropped and
counted; nothing else is lost on the twin's side.

:class:`MqttSource` subscribes to the ``[[mqtt.signals]]`` topics and keeps the latest valid
value of each with its receive time; :func:`parse_sensor_payload` judges every payload as
untrusted input (size, JSON, finite number, unit, range).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import os
import queue
import ssl
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from paho.mqtt.enums import MQTTErrorCode

from cnctwin import finite_json
from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.latency import JitterProxy, LatencyResult, LatencyStats, _check_run
from cnctwin.thread.mqtt_config import MqttConfig, MqttSignalConfig, broker_address

__all__ = [
    "LinkEvent",
    "MqttPublisher",
    "MqttSource",
    "SensorValue",
    "measure_mqtt_latency",
    "parse_sensor_payload",
]

logger = logging.getLogger(__name__)

_OK = MQTTErrorCode.MQTT_ERR_SUCCESS
_NO_CONN = MQTTErrorCode.MQTT_ERR_NO_CONN  # a QoS 1 message is kept and sent once connected

#: Largest magnitude of a sensor value without a configured range.
_VALUE_LIMIT = 1e12


@dataclass(frozen=True, slots=True)
class LinkEvent:
    """The broker went away or came back.

    Attributes
    ----------
    kind
        ``"mqtt_lost"`` or ``"mqtt_restored"``.
    t_s
        ``time.monotonic()`` when the client noticed it, s.
    data
        ``reason`` (lost) or ``gap_s`` (restored: since the loss, s).
    """

    kind: str
    t_s: float
    data: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class SensorValue:
    """The latest valid value of one external signal.

    Attributes
    ----------
    value
        In the signal's unit.
    received_s
        ``time.monotonic()`` of its arrival, s.
    """

    value: float
    received_s: float


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a finite number")


def parse_sensor_payload(payload: bytes, spec: MqttSignalConfig, max_bytes: int) -> float:
    """The value of one sensor payload: a JSON number, or ``{"value": NUMBER}`` with an
    optional ``"unit"`` that must be the configured one and an optional integer ``"seq"``
    (the sender's message number, as the twin's own messages carry; not used).

    Parameters
    ----------
    payload
        The message as received.
    spec
        The signal's ``[[mqtt.signals]]`` entry (unit, range).
    max_bytes
        Largest payload accepted, bytes.

    Returns
    -------
    float
        The value, in the signal's unit.

    Raises
    ------
    DataError
        One line: what is wrong and what would be valid.
    """
    if len(payload) > max_bytes:
        raise DataError(f"payload of {len(payload)} bytes; valid: at most {max_bytes}")
    try:
        data = json.loads(payload.decode("utf-8"), parse_constant=_reject_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as err:
        raise DataError(
            f"payload is no JSON ({str(err)[:80]}); valid: 12.5 or " + '{"value": 12.5}'
        ) from None
    if isinstance(data, dict):
        unknown = set(data) - {"value", "unit", "seq"}
        if unknown:
            raise DataError(f"unknown keys {sorted(unknown)[:3]}; valid: value, unit, seq")
        seq = data.get("seq", 0)
        if isinstance(seq, bool) or not isinstance(seq, int):
            raise DataError(f"seq {type(seq).__name__}; valid: an integer")
        if "unit" in data and data["unit"] != spec.unit:
            raise DataError(f"unit {str(data['unit'])[:20]!r}; valid: {spec.unit!r}")
        if "value" not in data:
            raise DataError('no "value" key; valid: {"value": NUMBER}')
        data = data["value"]
    if isinstance(data, bool) or not isinstance(data, int | float):
        raise DataError(f"value {type(data).__name__} is no number")
    value = float(data)
    if not math.isfinite(value):
        raise DataError("value is not a finite number")
    low = spec.low if spec.low is not None else -_VALUE_LIMIT
    high = spec.high if spec.high is not None else _VALUE_LIMIT
    if not low <= value <= high:
        raise DataError(f"value {value:g} outside {low:g} to {high:g} {spec.unit}")
    return value


def _client(config: MqttConfig, suffix: str, *, v5: bool = False) -> Any:
    """A paho client of ``config`` (credentials, TLS, reconnect back-off), not connected."""
    from paho.mqtt.client import Client
    from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

    _, _, tls = broker_address(config.broker)
    client = Client(
        CallbackAPIVersion.VERSION2,
        client_id=f"{config.client_id}-{suffix}",
        protocol=MQTTProtocolVersion.MQTTv5 if v5 else MQTTProtocolVersion.MQTTv311,
        reconnect_on_failure=True,
    )
    if config.username is not None:
        password = None
        if config.password_env is not None:
            password = os.environ.get(config.password_env)
            if password is None:
                raise ConfigError(
                    f"[mqtt] password_env = {config.password_env!r}: no such environment "
                    "variable; set it to the broker password"
                )
        client.username_pw_set(config.username, password)
    if tls:
        context = ssl.create_default_context(
            cafile=str(config.ca_file) if config.ca_file is not None else None
        )
        if config.cert_file is not None and config.key_file is not None:
            context.load_cert_chain(str(config.cert_file), str(config.key_file))
        client.tls_set_context(context)
    client.reconnect_delay_set(min_delay=1, max_delay=max(1, math.ceil(config.reconnect_max_s)))
    return client


class _Link:
    """Connection bookkeeping shared by the publisher and the source: lost/restored events,
    gaps and reconnects (called from paho's network thread)."""

    def __init__(self, clock: Callable[[], float]) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self.connected = threading.Event()
        self.events: deque[LinkEvent] = deque(maxlen=1000)
        self.reconnects = 0
        self.gaps_s: list[float] = []
        self._lost_s: float | None = None
        self._ever = False
        self._closing = False

    def up(self) -> None:
        with self._lock:
            now = self._clock()
            if self._ever and self._lost_s is not None:
                gap = now - self._lost_s
                self.gaps_s.append(gap)
                self.reconnects += 1
                self.events.append(LinkEvent("mqtt_restored", now, {"gap_s": gap}))
            self._ever = True
            self._lost_s = None
            self.connected.set()

    def close(self) -> None:
        """The client disconnects on purpose: that is no loss."""
        with self._lock:
            self._closing = True

    def down(self, reason: str) -> None:
        with self._lock:
            self.connected.clear()
            if self._ever and self._lost_s is None and not self._closing:
                self._lost_s = self._clock()
                self.events.append(LinkEvent("mqtt_lost", self._lost_s, {"reason": reason}))

    def drain(self) -> list[LinkEvent]:
        with self._lock:
            out = list(self.events)
            self.events.clear()
        return out


def _connect(client: Any, config: MqttConfig, properties: Any = None) -> None:
    host, port, _ = broker_address(config.broker)
    client.connect_async(host, port, keepalive=config.keepalive_s, properties=properties)
    client.loop_start()


class MqttPublisher:
    """Publishes the twin's messages with a bounded local buffer, off the cycle's thread.

    The cycle's side (:meth:`offer`) takes no lock: a C-level queue put and integer counts,
    so a publisher thread that the OS has put aside never holds up the cycle.

    Parameters
    ----------
    config
        The ``[mqtt]`` table (broker, credentials, ``[mqtt.publish]``).
    clock
        Monotonic clock, s (link events, gaps, acknowledgement times).
    status
        Extra fields of the retained status message (``PREFIX/status``).

    Attributes
    ----------
    offered
        Messages taken from the cycle.
    acked
        Messages the broker acknowledged (QoS 1) or that left (QoS 0).
    dropped
        Messages dropped because the buffer was full.
    acked_seq
        Sequence numbers acknowledged, in order (the last 100,000).
    last_ack_s
        ``clock()`` of the last acknowledgement, s (NaN before the first).
    """

    def __init__(
        self,
        config: MqttConfig,
        *,
        clock: Callable[[], float] = time.monotonic,
        status: Mapping[str, Any] | None = None,
    ) -> None:
        self.config = config
        self.prefix = config.publish.topic_prefix
        self.qos = config.publish.qos
        self.capacity = config.publish.buffer
        self.link = _Link(clock)
        self.offered = 0
        self.acked = 0
        self.dropped = 0
        self.acked_seq: deque[int] = deque(maxlen=100_000)
        self.last_ack_s = math.nan
        self._clock = clock
        self._status = dict(status or {})
        self._queue: queue.SimpleQueue[tuple[int, str, dict[str, Any]] | None] = queue.SimpleQueue()
        self._lock = threading.Lock()  # the pump's and paho's, never the cycle's
        self._inflight: dict[int, int] = {}  # paho mid -> seq
        self._early: set[int] = set()  # mids acknowledged before they were registered
        self._own: set[int] = set()  # mids of the status messages
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._client = _client(config, "pub")
        self._client.max_queued_messages_set(self.capacity)
        self._client.max_inflight_messages_set(min(20, self.capacity))
        self._client.will_set(self.topic("status"), self._status_payload(False), 1, retain=True)
        self._client.on_connect = self._on_connect
        self._client.on_disconnect = self._on_disconnect
        self._client.on_publish = self._on_publish

    def topic(self, kind: str) -> str:
        """The topic of a message kind (``telemetry``, ``decisions``, ``events``, ``status``)."""
        return f"{self.prefix}/{kind}"

    @property
    def pending(self) -> int:
        """Messages offered and not yet acknowledged."""
        return self.offered - self.acked

    def start(self) -> None:
        """Connect in the background (it keeps trying; :meth:`offer` works meanwhile)."""
        self._thread = threading.Thread(target=self._pump, name="mqtt-publisher", daemon=True)
        self._thread.start()
        _connect(self._client, self.config)

    def offer(self, kind: str, payload: dict[str, Any]) -> bool:
        """Queue one message for ``PREFIX/kind``; never blocks. Call it from one thread (the
        cycle's).

        ``payload`` is encoded later: hand over a dict the caller no longer changes. A
        sequence number ``seq`` is added. Returns ``False`` when the buffer was full and
        the message was dropped.
        """
        if self.offered - self.acked >= self.capacity:
            self.dropped += 1
            return False
        self.offered += 1
        self._queue.put((self.offered, kind, payload))
        return True

    def stop(self, flush_s: float = 2.0) -> None:
        """Wait up to ``flush_s`` for the buffer to empty, mark the twin offline, disconnect."""
        deadline = time.monotonic() + flush_s
        while self.pending and self.link.connected.is_set() and time.monotonic() < deadline:
            time.sleep(0.01)
        self._stopping.set()
        self._queue.put(None)
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        if self.link.connected.is_set():
            info = self._client.publish(
                self.topic("status"), self._status_payload(False), 1, retain=True
            )
            with contextlib.suppress(Exception):
                info.wait_for_publish(timeout=1.0)
        self.link.close()
        self._client.disconnect()
        self._client.loop_stop()

    def stats(self) -> dict[str, Any]:
        """Counts and gaps (JSON-ready, units in the keys)."""
        return {
            "offered": self.offered,
            "acked": self.acked,
            "dropped": self.dropped,
            "pending": self.pending,
            "reconnects": self.link.reconnects,
            "gaps_s": list(self.link.gaps_s),
        }

    # ------------------------------------------------------------------ threads
    def _status_payload(self, online: bool) -> str:
        return finite_json.dumps({"online": online, "time_unix_s": time.time(), **self._status})

    def _pump(self) -> None:
        """Encode the offered messages and hand them to paho, in order."""
        while not self._stopping.is_set():
            item = self._queue.get()
            if item is None:
                return
            seq, kind, payload = item
            text = finite_json.dumps({"seq": seq, **payload})
            while not self._stopping.is_set():
                # paho keeps a QoS 1 message until its PUBACK, across reconnects. No lock of
                # ours is held while paho takes its own (its PUBACK callback takes ours).
                info = self._client.publish(self.topic(kind), text, self.qos)
                if info.rc == _OK or (self.qos == 1 and info.rc == _NO_CONN):
                    break
                # paho's queue is full, or QoS 0 without a broker: wait and try again
                self._stopping.wait(0.05)
            else:
                return
            with self._lock:
                if self.qos == 0 or info.mid in self._early:
                    self._early.discard(info.mid)
                    self._acknowledged(seq)
                else:
                    self._inflight[info.mid] = seq

    def _acknowledged(self, seq: int) -> None:
        """Count one acknowledgement (holding ``_lock``)."""
        self.acked_seq.append(seq)
        self.last_ack_s = self._clock()
        self.acked += 1

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:
            logger.warning("MQTT broker %s refused the publisher: %s", self.config.broker, reason)
            return
        info = client.publish(self.topic("status"), self._status_payload(True), 1, retain=True)
        with self._lock:
            self._own.add(info.mid)  # its PUBACK is no message of the cycle's
        self.link.up()

    def _on_disconnect(
        self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any
    ) -> None:
        self.link.down(str(reason))

    def _on_publish(self, client: Any, userdata: Any, mid: int, reason: Any, props: Any) -> None:
        with self._lock:
            if mid in self._own:
                self._own.discard(mid)
                return
            seq = self._inflight.pop(mid, None)
            if seq is None:  # acknowledged before :meth:`_pump` registered it
                self._early.add(mid)
            else:
                self._acknowledged(seq)


class MqttSource:
    """Subscribes to the ``[[mqtt.signals]]`` topics; keeps each signal's latest valid value.

    Parameters
    ----------
    config
        The ``[mqtt]`` table.
    clock
        Monotonic clock, s (receive times).

    Attributes
    ----------
    received
        Messages received.
    rejected
        Messages rejected, by topic.
    """

    def __init__(self, config: MqttConfig, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.config = config
        self.link = _Link(clock)
        self._clock = clock
        self._specs = {s.topic: s for s in config.signals}
        self._lock = threading.Lock()
        self._latest: dict[str, SensorValue] = {}
        self._problems: dict[str, str] = {}
        self.received = 0
        self.rejected: dict[str, int] = {}
        self._client = _client(config, "src", v5=True)
        self._client.on_connect = self._on_connect
        self._client.on_disconnect = self._on_disconnect
        self._client.on_message = self._on_message

    def start(self) -> None:
        """Connect in the background and subscribe (again after every reconnect)."""
        from paho.mqtt.packettypes import PacketTypes
        from paho.mqtt.properties import Properties

        props = Properties(PacketTypes.CONNECT)  # type: ignore[no-untyped-call]
        # the broker drops larger messages for this client instead of sending them
        props.MaximumPacketSize = self.config.max_payload_bytes + 512
        _connect(self._client, self.config, props)

    def stop(self) -> None:
        """Disconnect."""
        self.link.close()
        self._client.disconnect()
        self._client.loop_stop()

    def latest(self) -> dict[str, SensorValue]:
        """Signal name -> latest valid value (a copy)."""
        with self._lock:
            return dict(self._latest)

    def problems(self) -> dict[str, str]:
        """Topic -> why its last rejected message was rejected, for topics with rejections
        since the last call."""
        with self._lock:
            out = self._problems
            self._problems = {}
        return out

    def stats(self) -> dict[str, Any]:
        """Counts and gaps (JSON-ready)."""
        with self._lock:
            rejected = dict(self.rejected)
        return {
            "received": self.received,
            "rejected": rejected,
            "reconnects": self.link.reconnects,
            "gaps_s": list(self.link.gaps_s),
        }

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:
            logger.warning("MQTT broker %s refused the source: %s", self.config.broker, reason)
            return
        if self._specs:
            client.subscribe([(topic, 0) for topic in self._specs])
        self.link.up()

    def _on_disconnect(
        self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any
    ) -> None:
        self.link.down(str(reason))

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        now = self._clock()
        topic = message.topic
        spec = self._specs.get(topic)
        with self._lock:
            self.received += 1
        if spec is None:  # not subscribed: never expected, never trusted
            problem = "no [[mqtt.signals]] entry for this topic"
        else:
            try:
                value = parse_sensor_payload(message.payload, spec, self.config.max_payload_bytes)
            except DataError as err:
                problem = str(err)
            else:
                with self._lock:
                    self._latest[spec.signal] = SensorValue(value, now)
                return
        shown = topic[:200]
        with self._lock:
            self.rejected[shown] = self.rejected.get(shown, 0) + 1
            if len(self._problems) < 100:
                self._problems[shown] = problem


async def measure_mqtt_latency(
    endpoint: str,
    *,
    n: int,
    interval_s: float,
    jitter_ms: float = 0.0,
    seed: int = 0,
    timeout_s: float = 5.0,
) -> LatencyResult:
    """Heide 2025 section 2.5's round trip over MQTT: the twin's publisher sends a value,
    the twin's MQTT source receives it back through the broker.

    Each round trip offers one message (QoS 1) to :class:`MqttPublisher` and waits until
    :class:`MqttSource` holds its value: ``write_ms`` is offer -> the broker's PUBACK,
    ``round_trip_ms`` (and ``read_ms``: the broker pushes, there is no read request) offer ->
    the value in the source.

    Parameters
    ----------
    endpoint
        The broker, ``mqtt://HOST:PORT``.
    n, interval_s
        Round trips and the pause between them, s.
    jitter_ms, seed
        One-way jitter J on the publisher's path (a :class:`JitterProxy`), ms, and its seed.
    timeout_s
        Longest wait for one round trip, s.

    Raises
    ------
    DataError
        When a round trip takes longer than ``timeout_s`` or the broker cannot be reached.
    """
    _check_run(n, interval_s)
    host, port, _ = broker_address(endpoint)
    tag = f"{os.getpid()}-{time.monotonic_ns() % 10**9}"
    probe = {"topic": f"cnctwin/latency/{tag}/probe", "signal": "latency_probe", "unit": "1"}
    async with contextlib.AsyncExitStack() as stack:
        via = endpoint
        if jitter_ms > 0:
            proxy = await stack.enter_async_context(JitterProxy(host, port, jitter_ms, seed=seed))
            via = f"mqtt://{proxy.host}:{proxy.port}"
        base = {"enabled": True, "client_id": f"cnctwin-latency-{tag}", "signals": [probe]}
        clock = time.perf_counter
        source = MqttSource(MqttConfig.model_validate({**base, "broker": endpoint}), clock=clock)
        publisher = MqttPublisher(
            MqttConfig.model_validate(
                {**base, "broker": via, "publish": {"topic_prefix": f"cnctwin/latency/{tag}"}}
            ),
            clock=clock,
        )
        source.start()
        stack.callback(source.stop)
        publisher.start()
        stack.callback(publisher.stop, 0.5)
        for link, what in ((source.link, "source"), (publisher.link, "publisher")):
            if not await asyncio.to_thread(link.connected.wait, timeout_s):
                raise DataError(
                    f"MQTT broker {endpoint} not reached by the {what} in {timeout_s} s"
                )
        await asyncio.sleep(0.2)  # the source's subscription settles
        writes: list[float] = []
        trips: list[float] = []
        for i in range(n):
            value = float(i + 1)
            t0 = time.perf_counter()
            publisher.offer("probe", {"value": value})
            while True:
                got = source.latest().get("latency_probe")
                now = time.perf_counter()
                if got is not None and got.value == value and publisher.acked > i:
                    break
                if now - t0 > timeout_s:
                    raise DataError(f"MQTT probe {i + 1} not back within {timeout_s} s")
                await asyncio.sleep(0.0002)
            trips.append(got.received_s - t0)
            writes.append(publisher.last_ack_s - t0)
            if interval_s:
                await asyncio.sleep(interval_s)
    stats = LatencyStats.of(trips)
    return LatencyResult(
        n=n,
        round_trip_ms=stats,
        write_ms=LatencyStats.of(writes),
        read_ms=stats,
        polls_mean=1.0,
        signal="mqtt",
        interval_ms=interval_s * 1e3,
        jitter_ms=jitter_ms,
    )
