"""The running twin over Beckhoff ADS: the virtual machine behind pyads' ADS test server.

A server killed and restarted mid-run (the twin reconnects and records the gap), and commands
that reach the PLC only when ``[control]`` is enabled, counted from the server's side (pyads'
record of every request it received).
"""

from __future__ import annotations

import asyncio
import struct
from collections.abc import Callable

import pytest
from pyads import constants
from timeouts import BODY_S

from cnctwin.control import RuleConfig
from cnctwin.thread.signals import RunState
from cnctwin.twin.config import RunConfig
from cnctwin.twin.host import MachineServer
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.session import run_session
from cnctwin.twin.state import CycleState
from cnctwin.virtual import AdsMachineServer


def _over_ads(config: RunConfig, endpoint: str, **control: object) -> RunConfig:
    connection = config.connection.model_copy(update={"transport": "ads", "endpoint": endpoint})
    virtual = config.virtual.model_copy(update={"faults": []})  # type: ignore[union-attr]
    return config.model_copy(
        update={
            "connection": connection,
            "virtual": virtual,
            "control": config.control.model_copy(update=control),
        }
    )


def _command_writes(server: AdsMachineServer) -> int:
    """WRITE requests to a command symbol the server received."""
    commands = server.handler.commands
    count = 0
    for packet in server.request_history:
        header = packet.ams_header
        if struct.unpack("<H", header.command_id)[0] != constants.ADSCOMMAND_WRITE:
            continue
        if struct.unpack_from("<II", header.data) in commands:
            count += 1
    return count


def test_server_killed_and_restarted_mid_run_reconnects_and_records_the_gap(
    demo_config: RunConfig,
) -> None:
    async def main() -> tuple[RunSummary, RunState, list[float]]:
        async with MachineServer(demo_config, "ads", speed=1.0) as machine:
            config = _over_ads(demo_config, machine.endpoint)
            stop = asyncio.Event()
            restarted: list[bool] = []
            gaps: list[float] = []
            task = None

            async def outage() -> None:
                await asyncio.sleep(1.0)
                await machine.clock.stop()
                await machine.stop_server()
                await asyncio.sleep(1.0)
                await machine.restart_server()
                restarted.append(True)
                machine.go()

            def go(_twin: object) -> None:
                nonlocal task
                machine.go()
                task = asyncio.get_running_loop().create_task(outage())

            def watch(state: CycleState) -> None:
                for event in state.events:
                    if restarted and event.kind == "connection_restored":
                        gaps.append(event.data["gap_s"])
                if gaps:
                    stop.set()

            summary = await run_session(
                config, duration_s=BODY_S, stop_event=stop, on_cycle=watch, on_start=go
            )
            assert task is not None
            await task
            return summary, machine.vm.run_state, gaps

    summary, run_state, gaps = asyncio.run(asyncio.wait_for(main(), 2 * BODY_S))
    assert summary.reconnects >= 1
    assert gaps and gaps[0] >= 0.9  # the server was away 1 s
    assert summary.gaps_s[-1] == pytest.approx(gaps[0])
    assert run_state == RunState.RUNNING  # the twin did not stop the machine


@pytest.mark.parametrize("enabled", [False, True])
def test_commands_reach_the_plc_only_with_control_enabled(
    demo_config: RunConfig, enabled: bool
) -> None:
    rule = RuleConfig.model_validate(
        {
            "name": "lower_the_feed",
            "condition": "feed_override_pct > 95",
            "action": "feed_override",
            "value": 80,
        }
    )
    config = demo_config.model_copy(update={"rules": [rule]})

    async def main() -> tuple[int, float, int]:
        async with MachineServer(config, "ads", speed=1.0) as machine:
            server = machine.server
            assert isinstance(server, AdsMachineServer)
            settings = _over_ads(config, machine.endpoint, enabled=enabled)
            stop = asyncio.Event()
            cycles = [0]

            def watch(_state: CycleState) -> None:
                cycles[0] += 1
                if cycles[0] >= 60:
                    stop.set()

            go: Callable[[object], None] = lambda _twin: machine.go()  # noqa: E731
            summary = await run_session(
                settings, duration_s=BODY_S, stop_event=stop, on_cycle=watch, on_start=go
            )
            override = machine.vm.snapshot()["feed_override_pct"]
            return _command_writes(server), override, summary.decisions

    writes, override, decisions = asyncio.run(asyncio.wait_for(main(), BODY_S))
    assert decisions >= 1  # the rule fired either way
    if enabled:
        assert writes >= 1 and override == 80.0
    else:
        assert writes == 0 and override == 100.0
