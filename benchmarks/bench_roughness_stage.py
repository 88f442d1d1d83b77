"""Cost: the roughness stage in the twin's cycle (docs/roughness.md, "In the running twin").

The twin of ``examples/roughness/roughness_twin.toml`` (three slots, a bull-nose end mill, the
kinematic roughness) runs in lockstep against the in-process virtual machine (one machine step
of 25 ms per cycle), timed on the wall clock like a live run: the roughness stage's time per new
sample (p50, p99, max) and the whole cycle's p99, in three configurations:

- ``off``: no roughness stage (the baseline cycle);
- ``kinematic``: the example as shipped (feed marks and section summaries);
- ``power law``: the power law evaluated on every cutting sample too. The virtual machine has
  no vibration sensor, so for this timing only the law's vibration feature reads the measured
  spindle power instead (the same lookup and arithmetic; the values are not a roughness).

Usage::

    python benchmarks/bench_roughness_stage.py [--quick] [--repeats N] [--json]

``--quick`` (CI): one run of each.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
from pathlib import Path
from typing import Any

from cnctwin.twin import LocalConnection, RunConfig, build_twin, load_run_config
from cnctwin.virtual import VirtualMachine

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "roughness" / "roughness_twin.toml"
STEP_S = 0.025


def _variant(config: RunConfig, name: str) -> RunConfig:
    """The example with the roughness stage off, as shipped, or with the power law on."""
    rough = config.twin.roughness
    if name == "off":
        rough = rough.model_copy(update={"enabled": False})
    elif name == "power law":
        rough = rough.model_copy(update={"features": {"vibration_g": "spindle_power_w"}})
    return config.model_copy(update={"twin": config.twin.model_copy(update={"roughness": rough})})


def run(config: RunConfig) -> dict[str, Any]:
    """One lockstep run of the program; the stage's and the cycle's times, ms."""
    virtual = config.virtual
    assert virtual is not None
    vm = VirtualMachine(virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)

    async def main() -> dict[str, Any]:
        await conn.connect()
        try:
            twin = build_twin(config, conn, program=virtual.program, realtime=False)
            summary = await twin.runtime.run(duration_s=120.0)
        finally:
            await conn.close()
        stage = summary.stages_ms.get("roughness", {})
        sections = summary.stage_results.get("roughness", {}).get("sections", [])
        return {
            "ended": summary.ended,
            "cycles": summary.cycles,
            "cycle_p99_ms": summary.cycle_p99_ms,
            "stage_p50_ms": stage.get("p50_ms"),
            "stage_p99_ms": stage.get("p99_ms"),
            "stage_max_ms": stage.get("max_ms"),
            "sections": len(sections),
        }

    return asyncio.run(main())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one run of each configuration")
    parser.add_argument("--repeats", type=int, default=5, help="runs of each configuration")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    repeats = 1 if args.quick else args.repeats
    config = load_run_config(EXAMPLE)
    results: dict[str, list[dict[str, Any]]] = {}
    for _ in range(repeats):  # interleaved: a load change hits every configuration alike
        for name in ("off", "kinematic", "power law"):
            results.setdefault(name, []).append(run(_variant(config, name)))
    report = {
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}",
        "repeats": repeats,
        "runs": results,
    }
    if args.json:
        print(json.dumps(report))
        return
    print(f"roughness stage, lockstep, {report['machine']}, {repeats} run(s) each")
    print(f"{'configuration':<12} {'cycle p99':>10} {'stage p50':>10} {'stage p99':>10}")
    for name, runs in results.items():
        for r in runs:
            p50 = "-" if r["stage_p50_ms"] is None else f"{r['stage_p50_ms']:.3f}"
            p99 = "-" if r["stage_p99_ms"] is None else f"{r['stage_p99_ms']:.3f}"
            print(f"{name:<12} {r['cycle_p99_ms']:>10.3f} {p50:>10} {p99:>10}  (ms)")


if __name__ == "__main__":
    main()
