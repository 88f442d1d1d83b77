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
from twin_helpers import ServerOutage, served, without_faults

from cnctwin.control import RuleConfig
from cnctwin.thread.signals import RunState
from cnctwin.twin.config import RunConfig
from cnctwin.twin.host import MachineServer
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.session import run_session
from cnctwin.twin.state import CycleState
from cnctwin.virtual import AdsMachineServer


def _over_ads(config: RunConfig, endpoint: str, **control: object) -> RunConfig:
    ads = served(without_faults(config), endpoint, transport="ads")
    return ads.model_copy(update={"control": ads.control.model_copy(update=control)})


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
            outage = ServerOutage(machine, after_s=1.0)
            stop = asyncio.Event()

            def watch(state: CycleState) -> None:
                outage.watch(state)
                if outage.restored:
                    stop.set()

            summary = await run_session(
                config, duration_s=BODY_S, stop_event=stop, on_cycle=watch, on_start=outage.on_start
            )
            await outage.finished()
            return summary, machine.vm.run_state, [gap for _, gap in outage.restored]

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
