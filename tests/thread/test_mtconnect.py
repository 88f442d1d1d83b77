"""MTConnectConnection: sequence tracking, gaps, agent restarts, garbage, and read-only.

Two agents: the virtual machine's (:class:`MTConnectAgent`, restarted mid-run on the same
port, its buffer overrun) and a canned one written here, whose documents are hand-made text
(the MTConnect Standard's elements and attributes, not the project's agent): it serves
garbage values, a changed instanceId and a buffer that starts past the reader.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from urllib.parse import parse_qs, urlsplit

import pytest
from timeouts import BODY_S

from cnctwin.errors import ConfigError
from cnctwin.thread import ConnectionLost, ConnectionState
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import CommandRejected
from cnctwin.thread.mtconnect import MTConnectConnection, parse_endpoint
from cnctwin.thread.signals import COMMANDS, RunState
from cnctwin.virtual import MTConnectAgent


def config(endpoint: str, **kwargs: object) -> ConnectionConfig:
    return ConnectionConfig(
        transport="mtconnect", endpoint=endpoint, timeout_s=5.0, reconnect_initial_s=0.02,
        reconnect_max_s=0.1, **kwargs,  # type: ignore[arg-type]
    )  # fmt: skip


class Machine:
    def __init__(self) -> None:
        self.values = {"x_mm": 1.0, "y_mm": 2.0, "z_mm": 3.0, "feed_mm_min": 600.0,
                       "run_state": float(RunState.RUNNING), "program_line": 7.0}  # fmt: skip

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)


async def wait_connected(reader: MTConnectConnection) -> None:
    while reader.state is not ConnectionState.CONNECTED:
        await asyncio.sleep(0.01)


# The virtual machine's agent ----------------------------------------------------------
def test_agent_restart_mid_run_is_detected_and_the_reader_recovers() -> None:
    machine = Machine()

    async def main() -> None:
        agent = MTConnectAgent(machine)
        await agent.start()
        try:
            async with MTConnectConnection(config(agent.endpoint)) as reader:
                first = agent.instance_id
                assert (await reader.read()).values["x_mm"] == 1.0
                machine.values["x_mm"] = 4.0
                agent.publish()
                assert (await reader.read()).values["x_mm"] == 4.0
                expected = reader.next_sequence
                assert expected == agent.next_sequence
                await agent.stop()  # the agent goes down ...
                machine.values["x_mm"] = 9.0
                with pytest.raises(ConnectionLost):
                    await reader.read()
                agent = MTConnectAgent(machine, port=agent.port)  # ... and comes back anew
                await agent.start()
                await wait_connected(reader)
                reading = await reader.read()
                assert reading.values["x_mm"] == 9.0
                assert agent.instance_id != first and reader.instance_id == agent.instance_id
                assert reader.agent_restarts == 1 and reader.reconnects == 1
                (gap,) = reader.gaps
                assert (gap.instance_id, gap.expected) == (first, expected)
                assert (gap.resumed_instance_id, gap.resumed) == (
                    agent.instance_id,
                    agent.next_sequence,
                )
                assert "agent restarted" in gap.reason
                machine.values["x_mm"] = 10.0
                agent.publish()
                assert (await reader.read()).values["x_mm"] == 10.0  # sampling goes on
        finally:
            await agent.stop()

    asyncio.run(asyncio.wait_for(main(), BODY_S))


def test_buffer_overrun_is_recorded_as_a_gap_and_reading_resumes_from_current() -> None:
    machine = Machine()

    async def main() -> None:
        async with MTConnectAgent(machine, buffer_size=16) as agent:
            async with MTConnectConnection(config(agent.endpoint, sample_count=2)) as reader:
                await reader.read()
                expected = reader.next_sequence
                assert expected is not None
                for i in range(40):  # 40 observations into a buffer of 16
                    machine.values["y_mm"] = float(i)
                    agent.publish()
                reading = await reader.read()
                assert reading.values["y_mm"] == 39.0
                (gap,) = reader.gaps
                assert gap.expected == expected and gap.resumed == agent.next_sequence
                assert gap.instance_id == gap.resumed_instance_id == agent.instance_id
                assert "buffer overrun" in gap.reason and reader.agent_restarts == 0
                # Within the buffer, the reader catches up in several requests, no gap.
                for i in range(12):
                    machine.values["y_mm"] = 100.0 + i
                    agent.publish()
                before = reader.requests
                assert (await reader.read()).values["y_mm"] == 111.0
                assert reader.requests - before == 6  # 12 observations, 2 per request
                assert len(reader.gaps) == 1

    asyncio.run(asyncio.wait_for(main(), BODY_S))


def test_every_command_is_refused_as_read_only() -> None:
    async def main() -> None:
        async with MTConnectAgent(Machine()) as agent:
            async with MTConnectConnection(config(agent.endpoint)) as reader:
                for name in COMMANDS:
                    with pytest.raises(CommandRejected, match="MTConnect is read-only"):
                        await reader.write(name, 50.0)
                assert reader.state is ConnectionState.CONNECTED

    asyncio.run(asyncio.wait_for(main(), BODY_S))


# A canned agent ---------------------------------------------------------------------
PROBE = """<?xml version="1.0"?>
<MTConnectDevices xmlns="urn:mtconnect.org:MTConnectDevices:2.0">
<Header creationTime="2024-05-01T10:00:00Z" sender="canned" instanceId="{instance}" version="2.0"
 bufferSize="100" assetBufferSize="1" assetCount="0"/>
<Devices><Device id="d1" name="mill" uuid="mill-1"><DataItems>
<DataItem id="av" type="AVAILABILITY" category="EVENT"/></DataItems>
<Components><Axes id="ax"><Components>
<Linear id="lx" name="X"><DataItems><DataItem id="Xact" type="POSITION" subType="ACTUAL"
 category="SAMPLE" units="MILLIMETER"/></DataItems></Linear>
<Linear id="ly" name="Y"><DataItems><DataItem id="Yact" type="POSITION" subType="ACTUAL"
 category="SAMPLE" units="MILLIMETER"/></DataItems></Linear>
<Linear id="lz" name="Z"><DataItems><DataItem id="Zact" type="POSITION" subType="ACTUAL"
 category="SAMPLE" units="MILLIMETER"/></DataItems></Linear>
</Components></Axes>
<Controller id="c"><Components><Path id="p"><DataItems>
<DataItem id="exec" type="EXECUTION" category="EVENT"/>
<DataItem id="ln" type="LINE_NUMBER" subType="ABSOLUTE" category="EVENT"/>
<DataItem id="fr" type="PATH_FEEDRATE" subType="ACTUAL" category="SAMPLE"
 units="MILLIMETER/SECOND"/>
</DataItems></Path></Components></Controller></Components></Device></Devices>
</MTConnectDevices>"""

STREAMS = """<?xml version="1.0"?>
<MTConnectStreams xmlns="urn:mtconnect.org:MTConnectStreams:2.0">
<Header creationTime="2024-05-01T10:00:01Z" sender="canned" instanceId="{instance}" version="2.0"
 bufferSize="100" firstSequence="{first}" lastSequence="{last}" nextSequence="{next}"/>
<Streams><DeviceStream name="mill" uuid="mill-1">
<ComponentStream component="Linear" name="X" componentId="lx"><Samples>{body}</Samples>
</ComponentStream>{device}</DeviceStream></Streams></MTConnectStreams>"""


def availability(sequence: int, value: str) -> str:
    """The device's ComponentStream with its AVAILABILITY."""
    return (
        '<ComponentStream component="Device" name="mill" componentId="d1"><Events>'
        f"{obs('av', sequence, value, 'Availability')}</Events></ComponentStream>"
    )


def obs(item: str, sequence: int, value: str, element: str = "Position") -> str:
    return (
        f'<{element} dataItemId="{item}" sequence="{sequence}" '
        f'timestamp="2024-05-01T10:00:00.{sequence:06d}Z">{value}</{element}>'
    )


Route = Callable[[str, dict[str, list[str]]], str]


class CannedAgent:
    """An HTTP/1.1 server answering ``route(request, query)``'s text (closes each answer)."""

    def __init__(self, route: Route) -> None:
        self.route = route
        self.seen: list[str] = []
        self.port = 0
        self._server: asyncio.Server | None = None

    async def __aenter__(self) -> CannedAgent:
        self._server = await asyncio.start_server(self._handle, "127.0.0.1", 0)
        self.port = int(self._server.sockets[0].getsockname()[1])
        return self

    async def __aexit__(self, *exc: object) -> None:
        assert self._server is not None
        self._server.close()
        await self._server.wait_closed()

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        head = await reader.readuntil(b"\r\n\r\n")
        target = head.split(b" ")[1].decode()
        parts = urlsplit(target)
        request = parts.path.strip("/").split("/")[-1]
        self.seen.append(request)
        body = self.route(request, parse_qs(parts.query)).encode()
        writer.write(
            b"HTTP/1.1 200 OK\r\nContent-Type: text/xml\r\nConnection: close\r\n"
            + f"Content-Length: {len(body)}\r\n\r\n".encode()
            + body
        )
        await writer.drain()
        writer.close()

    @property
    def endpoint(self) -> str:
        return f"http://127.0.0.1:{self.port}"


GOOD = "".join(
    [
        obs("Xact", 1, "1.5"),
        obs("Yact", 2, "2.5"),
        obs("Zact", 3, "3.5"),
        obs("fr", 4, "20", "PathFeedrate"),
        obs("exec", 5, "ACTIVE", "Execution"),
        obs("ln", 6, "30", "LineNumber"),
    ]
)


def test_garbage_values_are_rejected_counted_and_never_fed(
    caplog: pytest.LogCaptureFixture,
) -> None:
    garbage = "".join(
        [
            obs("Xact", 7, "NaN"),
            obs("Yact", 8, "abc"),
            obs("Zact", 9, "1e999"),
            obs("fr", 10, "-INF", "PathFeedrate"),
            obs("exec", 11, "RUNNING_FAST", "Execution"),
            obs("ln", 12, "12.5", "LineNumber"),
        ]
    )
    # Nothing new, then the garbage, then UNAVAILABLE, then a good value again.
    answers = {"sample": ["", garbage, obs("Xact", 13, "UNAVAILABLE"), obs("Xact", 14, "4.25")]}

    def route(request: str, query: dict[str, list[str]]) -> str:
        if request == "probe":
            return PROBE.format(instance=5)
        if request == "current":
            return STREAMS.format(instance=5, first=1, last=6, next=7, body=GOOD, device="")
        body = answers["sample"].pop(0)
        start = int(query["from"][0])
        last = start + body.count("dataItemId") - 1
        return STREAMS.format(instance=5, first=1, last=last, next=last + 1, body=body, device="")

    async def main() -> None:
        async with CannedAgent(route) as agent:
            async with MTConnectConnection(config(agent.endpoint)) as reader:
                values = (await reader.read()).values
                assert values["x_mm"] == 1.5 and values["feed_mm_min"] == 1200.0  # 20 mm/s
                assert values["run_state"] == RunState.RUNNING and values["program_line"] == 30
                # The sample carried only garbage: nothing of it is fed, not even the old values.
                reading = await reader.read()
                for name in ("x_mm", "y_mm", "z_mm", "feed_mm_min", "run_state", "program_line"):
                    assert name not in reading.values, name
                    assert all(math.isfinite(v) for v in reading.values.values())
                assert "not a finite number" in reading.rejected["x_mm"]
                assert "not a number" in reading.rejected["y_mm"]
                assert "not a finite number" in reading.rejected["z_mm"]
                assert "RUNNING_FAST" in reading.rejected["run_state"]
                assert "whole number" in reading.rejected["program_line"]
                assert dict(reader.garbage) == dict.fromkeys(
                    ["Xact", "Yact", "Zact", "fr", "exec", "ln"], 1
                )
                reading = await reader.read()  # UNAVAILABLE: rejected, not garbage
                assert reading.rejected["x_mm"] == "UNAVAILABLE at the agent"
                assert reader.garbage["Xact"] == 1
                assert (await reader.read()).values["x_mm"] == 4.25
        assert sum("MTConnect value rejected" in r.message for r in caplog.records) == 6

    asyncio.run(asyncio.wait_for(main(), BODY_S))


def test_changed_instance_id_in_a_sample_means_a_restart_and_a_new_probe() -> None:
    state = {"instance": 5}

    def route(request: str, query: dict[str, list[str]]) -> str:
        instance = state["instance"]
        if request == "probe":
            return PROBE.format(instance=instance)
        if request == "current":
            body = GOOD if instance == 5 else obs("Xact", 3, "8.0")
            nxt = 7 if instance == 5 else 4
            return STREAMS.format(
                instance=instance, first=1, last=nxt - 1, next=nxt, body=body, device=""
            )
        state["instance"] = 6  # the agent restarted before answering this sample
        return STREAMS.format(
            instance=6, first=1, last=3, next=4, body=obs("Xact", 3, "8.0"), device=""
        )

    async def main() -> None:
        async with CannedAgent(route) as agent:
            async with MTConnectConnection(config(agent.endpoint)) as reader:
                reading = await reader.read()
                assert reading.values["x_mm"] == 8.0
                assert agent.seen == ["probe", "current", "sample", "probe", "current"]
                assert reader.agent_restarts == 1 and reader.instance_id == 6
                (gap,) = reader.gaps
                assert (gap.instance_id, gap.expected, gap.resumed_instance_id, gap.resumed) == (
                    5,
                    7,
                    6,
                    4,
                )
                assert reader.reconnects == 0  # the connection itself never failed

    asyncio.run(asyncio.wait_for(main(), BODY_S))


def test_a_buffer_that_starts_past_the_reader_is_a_gap() -> None:
    def route(request: str, query: dict[str, list[str]]) -> str:
        if request == "probe":
            return PROBE.format(instance=5)
        if request == "current" and len(agent.seen) < 3:
            return STREAMS.format(instance=5, first=1, last=6, next=7, body=GOOD, device="")
        if request == "current":
            return STREAMS.format(
                instance=5, first=50, last=99, next=100, body=obs("Xact", 99, "2"), device=""
            )
        # A lenient agent answers from its oldest observation instead of OUT_OF_RANGE.
        return STREAMS.format(
            instance=5, first=50, last=99, next=52, body=obs("Xact", 50, "1"), device=""
        )

    async def main() -> None:
        async with MTConnectConnection(config(agent.endpoint)) as reader:
            assert (await reader.read()).values["x_mm"] == 2.0
            (gap,) = reader.gaps
            assert (gap.expected, gap.resumed) == (7, 100)
            assert "agent's buffer starts at 50" in gap.reason
            assert reader.next_sequence == 100

    agent = CannedAgent(route)

    async def outer() -> None:
        async with agent:
            await main()

    asyncio.run(asyncio.wait_for(outer(), BODY_S))


def test_heartbeat_counts_answers_while_the_device_is_available() -> None:
    answers = [availability(8, "UNAVAILABLE"), "", availability(9, "AVAILABLE"), "", ""]

    def route(request: str, query: dict[str, list[str]]) -> str:
        if request == "probe":
            return PROBE.format(instance=5)
        if request == "current":
            return STREAMS.format(
                instance=5, first=1, last=7, next=8, body=GOOD, device=availability(7, "AVAILABLE")
            )
        device = answers.pop(0)
        start = int(query["from"][0])
        last = start + device.count("dataItemId") - 1
        return STREAMS.format(instance=5, first=1, last=last, next=last + 1, body="", device=device)

    async def main() -> None:
        async with CannedAgent(route) as agent:
            async with MTConnectConnection(config(agent.endpoint)) as reader:
                lost = await reader.read()  # the agent lost the machine's adapter
                assert "heartbeat" not in lost.values
                assert lost.rejected["heartbeat"] == "device UNAVAILABLE at the agent (mill)"
                assert "heartbeat" not in (await reader.read()).values
                beats = [(await reader.read()).values["heartbeat"] for _ in range(3)]
                assert beats == [3.0, 4.0, 5.0]  # one per answered read

    asyncio.run(asyncio.wait_for(main(), BODY_S))


def test_a_restarted_agent_whose_probe_no_longer_fits_the_mapping_is_retried() -> None:
    state = {"instance": 5, "fits": True}

    def route(request: str, query: dict[str, list[str]]) -> str:
        instance = state["instance"]
        if request == "probe":
            probe = PROBE.format(instance=instance)
            return probe if state["fits"] else probe.replace('id="Zact"', 'id="Zw"')
        if request == "current":
            return STREAMS.format(instance=instance, first=1, last=6, next=7, body=GOOD, device="")
        return STREAMS.format(instance=instance, first=1, last=6, next=7, body="", device="")

    async def main() -> None:
        async with CannedAgent(route) as agent:
            reader = MTConnectConnection(config(agent.endpoint, mapping={"z_mm": "id=Zact"}))
            async with reader:
                assert (await reader.read()).values["z_mm"] == 3.5
                state.update(instance=6, fits=False)  # restarted with another device model
                with pytest.raises(ConnectionLost, match="matches no data item"):
                    await reader.read()
                await asyncio.sleep(0.3)  # reconnection attempts fail on the probe
                assert reader.state is ConnectionState.RECONNECTING
                state["fits"] = True
                await wait_connected(reader)
                assert (await reader.read()).values["z_mm"] == 3.5
                assert reader.instance_id == 6 and reader.agent_restarts == 1

    asyncio.run(asyncio.wait_for(main(), BODY_S))


# Configuration ----------------------------------------------------------------------
def test_endpoints_and_configuration_errors() -> None:
    assert parse_endpoint("http://10.0.0.5:5000") == ("10.0.0.5", 5000, "")
    assert parse_endpoint("http://agent/VMC-3Axis/") == ("agent", 80, "/VMC-3Axis")
    for bad in ("https://a:5000", "opc.tcp://a:4840", "http://a:5000/x/y", "http://a:99999",
                "http://a:5000/probe?x=1"):  # fmt: skip
        with pytest.raises(ConfigError, match="http://HOST:PORT"):
            parse_endpoint(bad)
    with pytest.raises(ConfigError, match="expected 'mtconnect'"):
        MTConnectConnection(ConnectionConfig(transport="modbus", endpoint="http://a:1"))

    async def main() -> None:
        async with MTConnectAgent(Machine()) as agent:
            reader = MTConnectConnection(config(agent.endpoint, mapping={"z_mm": "id=nothing"}))
            with pytest.raises(ConfigError, match="matches no data item"):
                await reader.connect()
            await reader.close()

    asyncio.run(asyncio.wait_for(main(), BODY_S))


def test_no_agent_is_a_clear_connection_error() -> None:
    async def main() -> None:
        async with MTConnectAgent(Machine()) as agent:
            port = agent.port
        reader = MTConnectConnection(config(f"http://127.0.0.1:{port}"))
        with pytest.raises(ConnectionLost, match="cannot connect"):
            await reader.connect()

    asyncio.run(asyncio.wait_for(main(), BODY_S))


# Latency ------------------------------------------------------------------------------
def test_read_latency_through_the_jitter_proxy_includes_the_delays() -> None:
    from cnctwin.thread.latency import measure_endpoint_latency

    async def main() -> None:
        async with MTConnectAgent(Machine()) as agent:
            direct = await measure_endpoint_latency(
                "mtconnect", agent.endpoint, n=5, interval_s=0.0
            )
            delayed = await measure_endpoint_latency(
                "mtconnect", agent.endpoint, n=20, interval_s=0.0, jitter_ms=10.0, seed=3
            )
        assert direct.n == 5 and direct.write_ms is None and direct.signal == "read"
        assert direct.round_trip_ms == direct.read_ms and direct.polls_mean == 1.0
        assert direct.to_dict()["write_ms"] is None
        # Each request waits U(0, 20) ms in the proxy: 20 of them average about 10 ms.
        assert delayed.read_ms.mean >= 5.0 and delayed.jitter_ms == 10.0
        assert delayed.read_ms.min >= 0.0 and delayed.read_ms.max <= BODY_S * 1e3

    asyncio.run(asyncio.wait_for(main(), BODY_S))
