"""The running twin over MQTT, against a Mosquitto of the test's own (docs/mqtt.md).

The demo twin runs in lockstep against an in-process virtual machine with ``[mqtt]`` on:

- an independent paho subscriber receives the twin's messages, and every one of them
  validates against the JSON Schema printed in docs/mqtt.md (``jsonschema``, not cnctwin's
  code); the telemetry carries exactly the values the cycle had; ``seq`` has no gap;
- values published with Mosquitto's ``mosquitto_pub`` reach the cycle as the extra signal,
  garbage from it never does, and a rule reading the signal decides (``notify``: no command).
"""

from __future__ import annotations

import asyncio
import json
import re
import shutil
import sys
from pathlib import Path
from typing import Any

import pytest
from timeouts import BODY_S

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "thread"))
from mqtt_helpers import Subscriber, private_broker, wait_for  # noqa: E402
from skips import missing  # noqa: E402
from twin_helpers import STEP_S  # noqa: E402

from cnctwin.control import RuleConfig  # noqa: E402
from cnctwin.thread import MqttConfig  # noqa: E402
from cnctwin.twin.config import RunConfig  # noqa: E402
from cnctwin.twin.local import LocalConnection  # noqa: E402
from cnctwin.twin.pipeline import build_twin  # noqa: E402
from cnctwin.twin.session import MqttLink  # noqa: E402
from cnctwin.twin.state import CycleState  # noqa: E402
from cnctwin.virtual import VirtualMachine  # noqa: E402

jsonschema = pytest.importorskip("jsonschema")

pytestmark = pytest.mark.services

DOC = Path(__file__).resolve().parents[2] / "docs" / "mqtt.md"


def documented_schemas() -> dict[str, Any]:
    """The JSON block after ``<!-- mqtt-schemas -->`` in docs/mqtt.md."""
    text = DOC.read_text("utf-8")
    block = re.search(r"<!-- mqtt-schemas -->\n```json\n(.*?)\n```", text, re.S)
    assert block is not None, "docs/mqtt.md lost its schema block"
    return json.loads(block.group(1))


def test_the_documented_schemas_are_valid_json_schemas() -> None:
    schemas = documented_schemas()
    assert set(schemas) == {"telemetry", "decisions", "events", "status"}
    for schema in schemas.values():
        jsonschema.Draft202012Validator.check_schema(schema)


def test_a_subscriber_gets_the_documented_payloads_and_mosquitto_pub_feeds_a_rule(
    demo_config: RunConfig,
) -> None:
    if shutil.which("mosquitto_pub") is None:
        missing(
            "mosquitto_pub is not installed (Debian package mosquitto-clients)",
            "CNCTWIN_REQUIRE_SERVICES",
        )
    validators = {k: jsonschema.Draft202012Validator(v) for k, v in documented_schemas().items()}
    with private_broker() as broker:
        mqtt = {
            "enabled": True,
            "broker": broker.url,
            "client_id": "twin-test",
            "publish": {"topic_prefix": "cell", "telemetry_hz": 1000.0},
            "signals": [{"topic": "plant/vib", "signal": "vibration_g", "unit": "g", "high": 50}],
        }
        rule = {
            "name": "vibration_high",
            "condition": "vibration_g > 1",
            "action": "notify",
            "cooldown_s": 100.0,
            "reason": "spindle vibration {vibration_g:.2f} g above 1 g",
        }
        config = demo_config.model_copy(
            update={
                "mqtt": MqttConfig.model_validate(mqtt),
                "rules": [*demo_config.rules, RuleConfig.model_validate(rule)],
            }
        )
        sub = Subscriber(broker.port, "cell/#")
        states: dict[int, dict[str, Any]] = {}
        seen: list[float] = []

        def keep(state: CycleState) -> None:
            states[state.index] = dict(state.measured)
            if "vibration_g" in state.measured:
                seen.append(state.measured["vibration_g"])

        async def pub(message: str) -> None:
            proc = await asyncio.create_subprocess_exec(
                "mosquitto_pub", "-p", str(broker.port), "-q", "1", "-t", "plant/vib", "-m", message
            )
            await proc.wait()

        async def feed(source: Any) -> None:
            await asyncio.to_thread(source.link.connected.wait, BODY_S)
            await asyncio.sleep(0.3)  # the source's subscription settles
            await pub("0.5")
            await pub('{"value": NaN}')  # garbage: rejected by the source
            await pub('{"value": 2.0, "unit": "g"}')  # fires the rule
            await pub("999")  # above high: rejected

        assert config.virtual is not None
        vm = VirtualMachine(config.virtual.model_copy(update={"faults": []}), config)
        conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
        try:
            with MqttLink(config, "local") as link:
                assert link.publisher is not None and link.source is not None

                async def main() -> Any:
                    await conn.connect()
                    twin = build_twin(
                        config,
                        conn,
                        program=config.virtual.program if config.virtual else None,
                        realtime=False,
                        mqtt_source=link.source,
                        mqtt_publisher=link.publisher,
                    )
                    twin.runtime.on_cycle = keep
                    feeding = asyncio.create_task(feed(link.source))
                    stop = asyncio.Event()

                    async def until_fed() -> None:
                        await feeding
                        await asyncio.to_thread(
                            wait_for, lambda: 2.0 in seen, "the rule's value in the cycle", BODY_S
                        )
                        for _ in range(20):  # a few more cycles: the decision is published
                            await asyncio.sleep(0.01)
                        stop.set()

                    ender = asyncio.create_task(until_fed())
                    summary = await twin.runtime.run(duration_s=BODY_S, stop_event=stop)
                    await ender
                    await conn.close()
                    return summary

                summary = asyncio.run(asyncio.wait_for(main(), BODY_S))
                publisher = link.publisher
            offered = publisher.offered
            wait_for(lambda: len([m for t, m in sub.messages if "seq" in m]) >= offered, "delivery")
        finally:
            sub.close()

    # the sensor values published by mosquitto_pub reached the cycle; garbage never did
    assert set(seen) == {0.5, 2.0}
    assert summary.outlets["mqtt_publish"]["source"]["rejected"] == {"plant/vib": 2}
    # every message is a documented payload
    by_topic: dict[str, list[Any]] = {}
    for topic, message in sub.messages:
        kind = topic.removeprefix("cell/")
        errors = sorted(validators[kind].iter_errors(message), key=str)
        assert not errors, f"{topic}: {message}\n{errors[0].message}"
        by_topic.setdefault(kind, []).append(message)
    assert [m["online"] for m in by_topic["status"]] == [True, False]
    seqs = sorted(m["seq"] for kind in ("telemetry", "decisions", "events") for m in by_topic[kind])
    assert seqs == list(range(1, offered + 1))  # a live broker: no gap, no repeat
    # the telemetry is the cycle's own values
    for message in by_topic["telemetry"]:
        assert message["measured"] == states[message["cycle"]]
    assert len(by_topic["telemetry"]) >= 10
    # the rule that read the MQTT signal decided: published, recorded, no command
    decision = next(m for m in by_topic["decisions"] if m["rule"] == "vibration_high")
    assert decision["action"] == "notify" and decision["command"] is None
    assert decision["reason"].startswith("spindle vibration 2.00 g")
    kinds = [m["kind"] for m in by_topic["events"]]
    assert "mqtt_rejected" in kinds and "signal_invalid" in kinds


class _Link:
    def __init__(self, events: list[Any]) -> None:
        self.events = events

    def drain(self) -> list[Any]:
        out, self.events = self.events, []
        return out


class _Publisher:
    """Stands in for the publisher: its link reports a loss and a return of the broker."""

    def __init__(self) -> None:
        from cnctwin.thread import LinkEvent

        self.link = _Link(
            [
                LinkEvent("mqtt_lost", 10.0, {"reason": "broker gone"}),
                LinkEvent("mqtt_restored", 12.5, {"gap_s": 2.5}),
            ]
        )
        self.offered: list[tuple[str, dict[str, Any]]] = []

    def offer(self, kind: str, payload: dict[str, Any]) -> bool:
        self.offered.append((kind, payload))
        return True


def test_the_broker_gap_becomes_events_of_the_run_published_with_the_documented_schema() -> None:
    from cnctwin.twin.mqtt import MqttOutlet

    validator = jsonschema.Draft202012Validator(documented_schemas()["events"])
    publisher = _Publisher()
    outlet = MqttOutlet(publisher, None, telemetry_hz=10.0, t0_s=2.0)  # type: ignore[arg-type]
    state = CycleState(0, 0.0)
    outlet.send(state)
    assert [(e.kind, e.t_s) for e in state.events] == [("mqtt_lost", 10.0), ("mqtt_restored", 12.5)]
    assert state.events[1].data == {"role": "publisher", "gap_s": 2.5}
    assert "after a gap of 2.500 s" in state.events[1].message
    sent = [payload for kind, payload in publisher.offered if kind == "events"]
    assert [p["t_s"] for p in sent] == [8.0, 10.5]  # since the run's start
    for payload in sent:
        assert not list(validator.iter_errors({"seq": 1, **payload}))
    assert not [kind for kind, _ in publisher.offered if kind == "telemetry"]  # no sample yet
