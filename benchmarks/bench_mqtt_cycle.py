"""Benchmark: what publishing over MQTT costs the twin's cycle (docs/mqtt.md).

The demo twin (packaged ``demo_twin.toml``: dexel cut, forces, filters, windows, force band,
form error, rules, control) runs against an in-process virtual machine at the twin's real
period (12.5 ms; the machine advances 25 ms per read, the demo's two times real time),
alternately without ``[mqtt]`` and with it (a private
Mosquitto on loopback, telemetry of every sample, QoS 1, one sensor signal subscribed).
Reported per variant: cycles, overruns, cycle work p50/p99/max (the stages plus the outlet)
and the MQTT outlet's own p50/p99/max, in ms, and the messages published and acknowledged.
``--lockstep`` runs the cycles back to back instead (no idle time between cycles: the
publisher's threads compete with the cycle for the interpreter).

Usage::

    python benchmarks/bench_mqtt_cycle.py [--quick] [--seconds S] [--rounds R] [--lockstep]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

from cnctwin.thread import Mosquitto, MqttPublisher, MqttSource
from cnctwin.twin import LocalConnection, RunConfig, build_twin, load_run_config
from cnctwin.virtual import VirtualMachine

STEP_S = 0.025  # machine time per cycle: the demo's 2x real time at 12.5 ms


def run_once(config: RunConfig, seconds: float, realtime: bool) -> dict[str, Any]:
    """One run of ``seconds`` wall time; MQTT when ``config.mqtt.enabled``."""
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual.model_copy(update={"faults": []}), config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    pub = src = None
    if config.mqtt.enabled:
        pub, src = MqttPublisher(config.mqtt), MqttSource(config.mqtt)
        pub.start()
        src.start()

    async def main() -> Any:
        await conn.connect()
        twin = build_twin(
            config,
            conn,
            program=config.virtual.program if config.virtual else None,
            realtime=realtime,
            mqtt_source=src,
            mqtt_publisher=pub,
        )
        summary = await twin.runtime.run(duration_s=seconds)
        await conn.close()
        return summary

    try:
        summary = asyncio.run(main())
    finally:
        if src is not None:
            src.stop()
        if pub is not None:
            pub.stop()
    out = {
        "mqtt": config.mqtt.enabled,
        "cycles": summary.cycles,
        "overruns": summary.overruns,
        "cycle_p50_ms": summary.cycle_p50_ms,
        "cycle_p99_ms": summary.cycle_p99_ms,
        "cycle_max_ms": summary.cycle_max_ms,
    }
    if pub is not None:
        out["outlet_ms"] = summary.stages_ms["mqtt_publish"]
        out["published"] = pub.stats()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="CI: 5 s per run, one round")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--lockstep", action="store_true", help="cycles back to back")
    args = parser.parse_args()
    seconds, rounds = (5.0, 1) if args.quick else (args.seconds, args.rounds)
    with as_file(files("cnctwin.examples")) as folder:
        base = load_run_config(Path(folder) / "demo_twin.toml")
    with Mosquitto() as broker:
        mqtt = base.mqtt.model_validate(
            {
                "enabled": True,
                "broker": broker.url,
                "publish": {"topic_prefix": "bench", "telemetry_hz": 1000.0},
                "signals": [{"topic": "bench/sensor", "signal": "bench_sensor", "unit": "1"}],
            }
        )
        with_mqtt = base.model_copy(update={"mqtt": mqtt})
        results = []
        for _ in range(rounds):
            for config in (base, with_mqtt):
                results.append(run_once(config, seconds, not args.lockstep))
                print(json.dumps(results[-1]), flush=True)
    load = Path("/proc/loadavg").read_text().split()[:3] if os.path.exists("/proc/loadavg") else []
    print(json.dumps({"loadavg": load}))


if __name__ == "__main__":
    main()
