"""The ``[mqtt]`` table of a twin configuration: the broker, what the twin publishes, and
which external sensor signals it takes in (docs/mqtt.md).

MQTT is publish and sensor input only: nothing received over MQTT is a command. A sensor
topic feeds one measured signal, either one of the canonical *sensor* signals
(:data:`SENSOR_SIGNALS`: forces, spindle torque, current, power, drive loads) or an extra
signal of its own name; the machine's state (axes, clock, run state, heartbeat, tool, line,
overrides, stop flags) comes only from ``[connection]``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal
from urllib.parse import urlsplit

from pydantic import Field, ValidationInfo, field_validator, model_validator

from cnctwin.config import Section, resolve_file
from cnctwin.thread.signals import SIGNALS

__all__ = [
    "SENSOR_SIGNALS",
    "MqttConfig",
    "MqttPublishConfig",
    "MqttSignalConfig",
    "broker_address",
]

#: Canonical signals an MQTT topic may feed: measurements of external sensors. The machine's
#: state (axes, clock, run state, heartbeat, tool, line, overrides, stop flags) is read only
#: from the machine: the watchdog, the stop confirmation and the read-backs trust nothing else.
SENSOR_SIGNALS = (
    "force_x_n",
    "force_y_n",
    "force_z_n",
    "spindle_torque_nm",
    "spindle_current_a",
    "spindle_power_w",
    "load_x_pct",
    "load_y_pct",
    "load_z_pct",
)

_NAME = re.compile(r"^[a-z][a-z0-9_]{0,62}$")
_SCHEMES = {"mqtt": False, "mqtts": True}


def broker_address(url: str) -> tuple[str, int, bool]:
    """Host, port and TLS of a broker URL ``mqtt://HOST[:PORT]`` or ``mqtts://HOST[:PORT]``.

    The default port is 1883 (``mqtt``) or 8883 (``mqtts``).

    Raises
    ------
    ValueError
        For another scheme, no host, a path or a port outside 1-65535.
    """
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        raise ValueError(f"{url!r} is no broker URL; valid: mqtt://HOST[:PORT]") from None
    if parts.scheme not in _SCHEMES or not parts.hostname or parts.path not in ("", "/"):
        raise ValueError(f"{url!r} is no broker URL; valid: mqtt://HOST[:PORT] or mqtts://...")
    if parts.username is not None or parts.query or parts.fragment:
        raise ValueError(
            f"{url!r}: user, query or fragment in the broker URL; give username and "
            "password_env as keys of [mqtt]"
        )
    tls = _SCHEMES[parts.scheme]
    return parts.hostname, port if port is not None else (8883 if tls else 1883), tls


def _check_topic(topic: str, what: str) -> str:
    """A topic to publish under or subscribe to: no wildcards, no ``$`` topics."""
    if not topic or len(topic.encode("utf-8")) > 200:
        raise ValueError(f"{what} {topic!r} must be 1 to 200 bytes")
    if any(c in topic for c in "+#\0") or topic.startswith("$"):
        raise ValueError(f"{what} {topic!r}: no wildcards (+ #), NUL or leading $")
    return topic


class MqttPublishConfig(Section):
    """What the twin publishes (``[mqtt.publish]``; topics and payloads: docs/mqtt.md).

    Attributes
    ----------
    enabled
        Publish telemetry, decisions, events and the status.
    topic_prefix
        Topics are ``PREFIX/telemetry``, ``PREFIX/decisions``, ``PREFIX/events`` and
        ``PREFIX/status``.
    qos
        0 (at most once) or 1 (at least once: unacknowledged messages are sent again after
        a reconnect).
    buffer
        Messages held locally that the broker has not acknowledged yet (queued while the
        broker is away, and in flight); a message that finds the buffer full is dropped
        and counted.
    telemetry_hz
        Telemetry messages per second at most, Hz (one per new sample at most); decisions
        and events are published as they happen.
    """

    enabled: bool = True
    topic_prefix: str = "cnctwin"
    qos: Literal[0, 1] = 1
    buffer: int = Field(default=10_000, ge=1, le=1_000_000)
    telemetry_hz: float = Field(default=10.0, gt=0.0, le=1000.0)

    @field_validator("topic_prefix")
    @classmethod
    def _prefix(cls, value: str) -> str:
        return _check_topic(value, "topic_prefix").rstrip("/") or "cnctwin"


class MqttSignalConfig(Section):
    """One external sensor signal fed by one topic (``[[mqtt.signals]]``).

    Attributes
    ----------
    topic
        The topic (no wildcards).
    signal
        A canonical sensor signal (:data:`SENSOR_SIGNALS`; it then replaces the machine's
        value of that signal) or an extra name (lower case, digits, ``_``; not a canonical
        signal) that rules, the historian and the telemetry see like a measured signal.
    unit
        The unit of the values; for a canonical signal its catalogue unit.
    max_age_s
        A value older than this (since it was received) is stale and not used, s.
    low, high
        Plausible range of the values; outside it a value is rejected.
    """

    topic: str
    signal: str
    unit: str = Field(min_length=1, max_length=16)
    max_age_s: float = Field(default=1.0, gt=0.0, le=3600.0)
    low: float | None = Field(default=None, ge=-1e12, le=1e12)
    high: float | None = Field(default=None, ge=-1e12, le=1e12)

    @field_validator("topic")
    @classmethod
    def _topic(cls, value: str) -> str:
        return _check_topic(value, "topic")

    @model_validator(mode="after")
    def _signal(self) -> MqttSignalConfig:
        spec = SIGNALS.get(self.signal)
        if spec is not None:
            if self.signal not in SENSOR_SIGNALS:
                raise ValueError(
                    f"signal {self.signal!r} is the machine's state, read only from "
                    f"[connection]; valid canonical signals: {', '.join(SENSOR_SIGNALS)}, or an "
                    "extra name"
                )
            if self.unit != spec.unit:
                raise ValueError(f"unit {self.unit!r} of {self.signal}; valid: {spec.unit!r}")
        elif not _NAME.match(self.signal):
            raise ValueError(
                f"signal {self.signal!r}; valid: a canonical sensor signal or an extra name of "
                "lower-case letters, digits and _ (starting with a letter, at most 63)"
            )
        if self.low is not None and self.high is not None and self.low >= self.high:
            raise ValueError(f"low={self.low:g} must be below high={self.high:g}")
        return self


class MqttConfig(Section):
    """The MQTT link (``[mqtt]``; docs/mqtt.md). Off unless ``enabled``.

    Attributes
    ----------
    enabled
        Connect to the broker.
    broker
        ``mqtt://HOST[:PORT]`` (default port 1883) or ``mqtts://HOST[:PORT]`` (TLS, 8883).
    client_id
        Prefix of the client ids (``-pub`` publishes, ``-src`` subscribes).
    username
        User name; ``None`` connects anonymously.
    password_env
        Environment variable that holds the password (it is never written in the file).
    ca_file
        CA certificates of the broker (PEM), relative to the configuration file; ``None``
        with ``mqtts``: the system's.
    cert_file, key_file
        This client's certificate and key (PEM) for brokers that ask for one.
    keepalive_s
        MQTT keep-alive, s: a broker silent for 1.5 times this counts as lost.
    reconnect_max_s
        Longest wait between reconnection attempts, s (they start at 1 s and double; paho
        counts in whole seconds).
    max_payload_bytes
        Largest sensor payload accepted, bytes; the broker is asked (MQTT 5 maximum packet
        size) not to send larger ones.
    publish
        What the twin publishes.
    signals
        External sensor signals, one topic each.
    """

    enabled: bool = False
    broker: str = "mqtt://127.0.0.1:1883"
    client_id: str = Field(default="cnctwin", min_length=1, max_length=64, pattern=r"^[\w.-]+$")
    username: str | None = Field(default=None, min_length=1, max_length=256)
    password_env: str | None = Field(default=None, pattern=r"^[A-Za-z_][A-Za-z0-9_]{0,127}$")
    ca_file: Path | None = None
    cert_file: Path | None = None
    key_file: Path | None = None
    keepalive_s: int = Field(default=10, ge=2, le=3600)
    reconnect_max_s: float = Field(default=5.0, ge=0.1, le=3600.0)
    max_payload_bytes: int = Field(default=1024, ge=16, le=65_536)
    publish: MqttPublishConfig = Field(default_factory=MqttPublishConfig)
    signals: list[MqttSignalConfig] = Field(default_factory=list, max_length=1000)

    @field_validator("broker")
    @classmethod
    def _broker(cls, value: str) -> str:
        broker_address(value)
        return value

    @field_validator("ca_file", "cert_file", "key_file")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)

    @model_validator(mode="after")
    def _unique(self) -> MqttConfig:
        if (self.cert_file is None) != (self.key_file is None):
            raise ValueError("cert_file and key_file go together: give both or neither")
        topics: dict[str, int] = {}
        names: dict[str, int] = {}
        for i, sig in enumerate(self.signals):
            for seen, key in ((topics, sig.topic), (names, sig.signal)):
                if key in seen:
                    raise ValueError(f"{key!r} is given twice, in signals[{seen[key]}] and [{i}]")
                seen[key] = i
        return self
