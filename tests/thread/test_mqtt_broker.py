"""The MQTT publisher and sensor source against a real Mosquitto of the test's own.

- The broker is killed (SIGKILL) and restarted mid-run: the publisher records the gap, and
  an independent paho subscriber with a persistent session receives every message the broker
  acknowledged; duplicates (QoS 1: at least once) only of messages in flight at the kill.
- Messages published by Mosquitto's own ``mosquitto_pub`` reach the source as values;
  garbage (too large, NaN, Infinity, not JSON, wrong unit, unknown keys, strings) is counted
  as rejected and never becomes a value.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import time
from collections import Counter

import pytest
from mqtt_helpers import WAIT_S, Subscriber, private_broker, wait_for
from skips import missing

from cnctwin.thread.mqtt import MqttPublisher, MqttSource
from cnctwin.thread.mqtt_config import MqttConfig

pytestmark = pytest.mark.services


def test_broker_killed_and_restarted_loses_nothing_it_acknowledged() -> None:
    with private_broker(persistence=True) as broker:
        config = MqttConfig.model_validate(
            {
                "enabled": True,
                "broker": broker.url,
                "client_id": "kill-test",
                "publish": {"topic_prefix": "kill", "buffer": 5000},
            }
        )
        sub = Subscriber(broker.port, "kill/events", persistent=True)
        publisher = MqttPublisher(config)
        publisher.start()
        try:
            wait_for(publisher.link.connected.is_set, "the publisher's connection")
            time.sleep(1.5)  # the subscriber's session reaches the broker's disk (autosave 1 s)
            offered = 0

            def offer(n: int) -> None:
                nonlocal offered
                for _ in range(n):
                    offered += 1
                    assert publisher.offer("events", {"n": offered})
                    time.sleep(0.002)

            offer(200)
            wait_for(lambda: publisher.acked >= 100, "acknowledgements before the kill")
            broker.stop(signal.SIGKILL)
            wait_for(lambda: not publisher.link.connected.is_set(), "the publisher to notice")
            offer(200)  # while the broker is away: buffered
            assert publisher.acked < offered
            time.sleep(1.0)
            broker.start()
            offer(200)
            wait_for(lambda: publisher.acked == offered, "every message acknowledged")
            acked = set(publisher.acked_seq)
            wait_for(lambda: acked <= {p["seq"] for p in sub.of("kill/events")}, "delivery")
        finally:
            publisher.stop(flush_s=0.5)
            sub.close()
        received = sub.of("kill/events")
        seqs = Counter(p["seq"] for p in received)
        assert set(seqs) == set(range(1, offered + 1))  # nothing lost, nothing made up
        assert all(p["n"] == p["seq"] for p in received)  # payloads intact
        duplicated = [s for s, k in seqs.items() if k > 1]
        # QoS 1 is at least once: only messages in flight at the kill may come twice
        assert len(duplicated) <= config.publish.buffer and len(duplicated) <= 20
        assert publisher.dropped == 0
        assert publisher.link.reconnects == 1 and len(publisher.link.gaps_s) == 1
        assert 1.0 <= publisher.link.gaps_s[0] < WAIT_S
        kinds = [e.kind for e in publisher.link.drain()]
        assert kinds == ["mqtt_lost", "mqtt_restored"]


def test_a_full_buffer_drops_new_messages_and_counts_them() -> None:
    with private_broker() as broker:
        config = MqttConfig.model_validate(
            {"enabled": True, "broker": broker.url, "publish": {"buffer": 10}}
        )
        broker.stop()
        publisher = MqttPublisher(config)
        publisher.start()
        try:
            results = [publisher.offer("events", {"i": i}) for i in range(25)]
        finally:
            publisher.stop(flush_s=0.0)
        assert results == [True] * 10 + [False] * 15
        assert publisher.dropped == 15 and publisher.offered == 10 and publisher.acked == 0


def test_mosquitto_pub_values_reach_the_source_and_garbage_is_rejected() -> None:
    if shutil.which("mosquitto_pub") is None:
        missing(
            "mosquitto_pub is not installed (Debian package mosquitto-clients)",
            "CNCTWIN_REQUIRE_SERVICES",
        )
    with private_broker() as broker:
        config = MqttConfig.model_validate(
            {
                "enabled": True,
                "broker": broker.url,
                "max_payload_bytes": 64,
                "signals": [
                    {"topic": "plant/dyno/fx", "signal": "force_x_n", "unit": "N"},
                    {"topic": "plant/vib", "signal": "vibration_g", "unit": "g", "high": 50},
                ],
            }
        )
        source = MqttSource(config)
        source.start()

        def pub(topic: str, message: str) -> None:
            subprocess.run(
                ["mosquitto_pub", "-p", str(broker.port), "-q", "1", "-t", topic, "-m", message],
                check=True,
                timeout=WAIT_S,
            )

        try:
            wait_for(source.link.connected.is_set, "the source's connection")
            time.sleep(0.3)  # its subscription settles
            pub("plant/dyno/fx", "-12.5")
            pub("plant/vib", '{"value": 3.25, "unit": "g"}')
            wait_for(lambda: len(source.latest()) == 2, "both values")
            garbage = [
                ("plant/vib", "x" * 100),  # beyond max_payload_bytes
                ("plant/vib", "NaN"),
                ("plant/vib", '{"value": Infinity}'),
                ("plant/vib", '{"value": 1e999}'),
                ("plant/vib", "not json"),
                ("plant/vib", '{"value": 2, "unit": "m/s^2"}'),
                ("plant/vib", '{"value": 2, "signal": "stop"}'),
                ("plant/vib", '"3.0"'),
                ("plant/vib", "true"),
                ("plant/vib", "51"),  # above high
                ("plant/dyno/fx", "[1, 2]"),
            ]
            for topic, message in garbage:
                pub(topic, message)
            pub("plant/vib", "4.5")  # after the garbage: a valid value still gets through
            wait_for(lambda: source.latest()["vibration_g"].value == 4.5, "the last valid value")
        finally:
            source.stop()
        latest = source.latest()
        assert latest["force_x_n"].value == -12.5
        stats = source.stats()
        # the oversized one never arrives (MQTT 5 maximum packet size) or is rejected
        rejected = sum(stats["rejected"].values())
        assert len(garbage) - 1 <= rejected <= len(garbage)
        assert stats["received"] == 3 + rejected
