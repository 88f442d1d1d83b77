"""Helpers of the twin's tests: the packaged demo configuration, lockstep runs."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

from cnctwin.store.historian import Historian
from cnctwin.twin.config import RunConfig, load_run_config
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import Twin, build_twin
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.state import CycleState
from cnctwin.virtual import VirtualMachine

#: Machine time per twin cycle in lockstep runs: the demo's 2x real time at 12.5 ms.
STEP_S = 0.025


def load_demo_config() -> RunConfig:
    """The packaged ``demo_twin.toml`` (program path resolved)."""
    with as_file(files("cnctwin.examples")) as folder:
        return load_run_config(Path(folder) / "demo_twin.toml")


@dataclass
class LockstepRun:
    """The result of :func:`run_lockstep`."""

    summary: RunSummary
    vm: VirtualMachine
    twin: Twin
    states: list[dict[str, Any]] = field(default_factory=list)


def run_lockstep(
    config: RunConfig,
    *,
    hole: bool = True,
    historian: Historian | None = None,
    duration_s: float = 60.0,
) -> LockstepRun:
    """Run the twin against an in-process virtual machine, one machine step per cycle.

    Each cycle advances the machine by :data:`STEP_S` in ticks of its own ``tick_ms``, so
    the run is deterministic and as fast as the CPU allows.
    """
    assert config.virtual is not None
    virtual = config.virtual if hole else config.virtual.model_copy(update={"faults": []})
    vm = VirtualMachine(virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    states: list[dict[str, Any]] = []

    def keep(state: CycleState) -> None:
        states.append(
            {
                **state.measured,
                **state.predicted,
                "cycle": state.index,
                "line": state.line,
                "decisions": len(state.decisions),
            }
        )

    async def main() -> tuple[RunSummary, Twin]:
        await conn.connect()
        recorder = Recorder(historian, {"test": "lockstep"}, 0.0) if historian else None
        twin = build_twin(config, conn, recorder=recorder, program=virtual.program, realtime=False)
        twin.runtime.on_cycle = keep
        summary = await twin.runtime.run(duration_s=duration_s)
        await conn.close()
        return summary, twin

    summary, twin = asyncio.run(main())
    return LockstepRun(summary, vm, twin, states)
