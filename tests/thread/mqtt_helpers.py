"""Helpers of the MQTT tests: a private Mosquitto per test, an independent paho subscriber."""

from __future__ import annotations

import json
import shutil
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import paho.mqtt.client as paho
from skips import missing

from cnctwin.thread.mosquitto import MOSQUITTO, Mosquitto

#: Longest wait for something a broker on loopback does in milliseconds, s (a loaded machine).
WAIT_S = 60.0


def require_mosquitto() -> None:
    """Skip (fail in CI) without the broker binary; CI installs it (.ci/run ensure_mosquitto)."""
    if shutil.which("mosquitto") is None and not shutil.which(MOSQUITTO):
        missing("Mosquitto is not installed (Debian package mosquitto)", "CNCTWIN_REQUIRE_SERVICES")


@contextmanager
def private_broker(*, persistence: bool = False) -> Iterator[Mosquitto]:
    """A Mosquitto of the test's own on a free loopback port, always stopped."""
    require_mosquitto()
    with Mosquitto(persistence=persistence) as broker:
        yield broker


def wait_for(condition: Callable[[], bool], what: str, timeout_s: float = WAIT_S) -> None:
    """Poll ``condition`` until true; fail naming ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.01)


class Subscriber:
    """A plain paho client (MQTT 3.1.1), independent of cnctwin's MQTT code, that keeps every
    message of ``pattern`` with its topic and parsed JSON payload.

    With ``persistent`` it keeps its session (clean session off, QoS 1): the broker queues
    messages for it while it is away.
    """

    def __init__(self, port: int, pattern: str, *, persistent: bool = False) -> None:
        self.messages: list[tuple[str, Any]] = []
        self.raw: list[tuple[str, bytes]] = []
        self.lock = threading.Lock()
        self.subscribed = threading.Event()
        self.client = paho.Client(
            paho.CallbackAPIVersion.VERSION2,
            client_id=f"test-subscriber-{port}",
            clean_session=not persistent,
        )
        self.client.reconnect_delay_set(1, 1)
        self.client.on_connect = lambda c, u, f, rc, p: c.subscribe(pattern, 1)
        self.client.on_subscribe = lambda c, u, mid, rc, p: self.subscribed.set()
        self.client.on_message = self._message
        self.client.connect("127.0.0.1", port, keepalive=5)
        self.client.loop_start()
        wait_for(self.subscribed.is_set, "the test subscriber's subscription")

    def _message(self, client: Any, userdata: Any, message: Any) -> None:
        with self.lock:
            self.raw.append((message.topic, message.payload))
            self.messages.append((message.topic, json.loads(message.payload)))

    def of(self, topic: str) -> list[Any]:
        """The payloads received on ``topic``."""
        with self.lock:
            return [payload for t, payload in self.messages if t == topic]

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()
