"""Helpers of the twin's tests: the packaged demo configuration, lockstep runs, a machine
server taken away mid-run."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

from cnctwin.store.historian import Historian
from cnctwin.twin.config import RunConfig, load_run_config
from cnctwin.twin.host import MachineServer
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


def without_faults(config: RunConfig) -> RunConfig:
    """``config`` with a virtual machine that injects no faults."""
    assert config.virtual is not None
    return config.model_copy(update={"virtual": config.virtual.model_copy(update={"faults": []})})


def served(config: RunConfig, endpoint: str, **connection: Any) -> RunConfig:
    """``config`` with the twin connecting to ``endpoint`` (and any other ``[connection]``
    fields given, such as ``transport``)."""
    update = {"endpoint": endpoint, **connection}
    return config.model_copy(update={"connection": config.connection.model_copy(update=update)})


@dataclass
class ServerOutage:
    """The machine's server taken away mid-run: ``after_s`` s after the twin starts the
    machine, the machine holds still and its server stops; ``away_s`` s later the server is
    back and the machine goes on. Pass :meth:`on_start` to ``run_session`` and call
    :meth:`watch` from its ``on_cycle``.

    Attributes
    ----------
    restored
        (cycle index, gap s) of each reconnection the twin reports after the restart.
    """

    machine: MachineServer
    after_s: float
    away_s: float = 1.0
    restored: list[tuple[int, float]] = field(default_factory=list)
    _restarted: bool = False
    _task: asyncio.Task[None] | None = None

    def on_start(self, _twin: object) -> None:
        """Start the machine and the outage."""
        self.machine.go()
        self._task = asyncio.get_running_loop().create_task(self._outage())

    async def _outage(self) -> None:
        # the machine holds still while the server is away, so the twin's blank stays true
        # however long a loaded computer takes to restart the server
        await asyncio.sleep(self.after_s)
        await self.machine.clock.stop()
        await self.machine.stop_server()
        await asyncio.sleep(self.away_s)
        await self.machine.restart_server()
        self._restarted = True
        self.machine.go()

    def watch(self, state: CycleState) -> None:
        """Note this cycle's reconnections that follow the restart."""
        if self._restarted:
            for event in state.events:
                if event.kind == "connection_restored":
                    self.restored.append((state.index, event.data["gap_s"]))

    async def finished(self) -> None:
        """Wait for the outage to be over (the server back)."""
        assert self._task is not None
        await self._task


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
