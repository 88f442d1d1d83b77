"""The virtual machine's MTConnect agent: every response validates against the 2.7 schemas.

The independent checks are the MTConnect Institute's own XSD 1.0 schemas
(../shared/data/mtconnect/schemas), applied by xmlschema (an XSD processor of its own, not
the agent's code) with no network access, and an HTTP client the project did not write
(httpx). A real probe of the reference agent is the positive control; a corrupted response is
the negative one. The reader's end-to-end test compares what it reads with the NC program's
own coordinates and feed.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from timeouts import BODY_S

from cnctwin.errors import ConfigError
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import CommandRejected
from cnctwin.thread.mtconnect import MTConnectConnection
from cnctwin.thread.signals import COMMANDS, RunState
from cnctwin.virtual import MachineClock, MTConnectAgent

xmlschema = pytest.importorskip("xmlschema", reason="xmlschema (test dependency) not installed")

KINDS = ("Devices", "Streams", "Error", "Assets")


@pytest.fixture(scope="module")
def schemas(request: pytest.FixtureRequest) -> dict[str, object]:
    folder = request.getfixturevalue("shared_data") / "mtconnect" / "schemas"
    if not folder.is_dir():
        pytest.skip(f"{folder} is absent (MTConnect 2.7 schemas of ../shared/data)")
    return {
        kind: xmlschema.XMLSchema10(str(folder / f"MTConnect{kind}_2.7_1.0.xsd")) for kind in KINDS
    }


def errors(schemas: dict[str, object], kind: str, document: bytes) -> list[str]:
    schema = schemas[kind]
    return [str(e).splitlines()[0] for e in schema.iter_errors(document.decode())]  # type: ignore[attr-defined]


class Machine:
    """A machine whose signals the test sets."""

    def __init__(self) -> None:
        self.values: dict[str, float] = {
            "x_mm": 12.5, "y_mm": -3.25, "z_mm": 100.0, "feed_mm_min": 1500.0,
            "spindle_rpm": 9000.0, "spindle_rpm_command": 9000.0, "load_x_pct": 12.0,
            "run_state": float(RunState.RUNNING), "program_line": 42.0, "tool_number": 3.0,
            "feed_override_pct": 80.0, "spindle_override_pct": 100.0, "emergency_stop": 0.0,
            "spindle_torque_nm": math.nan,
        }  # fmt: skip

    def snapshot(self) -> dict[str, float]:
        return dict(self.values)


def test_the_reference_probe_validates_and_a_corrupted_response_does_not(
    schemas: dict[str, object], shared_data: Path
) -> None:
    probe = (shared_data / "mtconnect" / "samples" / "demo_Devices_2.7.xml").read_bytes()
    assert errors(schemas, "Devices", probe) == []
    agent = MTConnectAgent(Machine())
    agent.publish()
    _, current = agent.answer("GET", "/current")
    assert errors(schemas, "Streams", current) == []
    renamed = current.replace(b"<Position ", b"<Positio ").replace(b"</Position>", b"</Positio>")
    assert errors(schemas, "Streams", renamed) != []
    assert errors(schemas, "Streams", current.replace(b' nextSequence="', b' next="')) != []
    _, probe_doc = agent.answer("GET", "/probe")
    assert errors(schemas, "Devices", probe_doc.replace(b'category="SAMPLE"', b'category="X"'))


REQUESTS = [
    ("/probe", 200, "Devices"),
    ("/", 200, "Devices"),
    ("/cnctwin-vm/probe", 200, "Devices"),
    ("/current", 200, "Streams"),
    ("/cnctwin-vm/current", 200, "Streams"),
    ("/sample", 200, "Streams"),
    ("/sample?from={first}&count=3", 200, "Streams"),
    ("/sample?count=64", 200, "Streams"),
    ("/assets", 200, "Assets"),
    ("/sample?from=1", 400, "Error"),  # overrun: the oldest observations are gone
    ("/sample?from=999999", 400, "Error"),
    ("/sample?count=0", 400, "Error"),
    ("/sample?count=65", 400, "Error"),
    ("/sample?from=abc", 400, "Error"),
    ("/sample?interval=100", 400, "Error"),
    ("/current?path=//Axes", 400, "Error"),
    ("/no-such-device/probe", 404, "Error"),
    ("/cnctwin-vm/no-such-request", 404, "Error"),
]


@pytest.fixture
def agent_url() -> Iterator[tuple[str, MTConnectAgent, Machine]]:
    """An agent on a free loopback port in a thread of its own, stopped afterwards."""
    import threading

    machine = Machine()
    agent = MTConnectAgent(machine, buffer_size=64)
    loop = asyncio.new_event_loop()
    ready = threading.Event()

    def serve() -> None:
        asyncio.set_event_loop(loop)
        loop.run_until_complete(agent.start())
        ready.set()
        loop.run_forever()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    assert ready.wait(BODY_S)
    try:
        yield agent.endpoint, agent, machine
    finally:
        asyncio.run_coroutine_threadsafe(agent.stop(), loop).result(BODY_S)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(BODY_S)
        loop.close()


def test_every_response_over_http_validates(
    schemas: dict[str, object], agent_url: tuple[str, MTConnectAgent, Machine]
) -> None:
    url, agent, machine = agent_url
    with httpx.Client(base_url=url, timeout=BODY_S) as client:
        for i in range(80):  # more changes than the 64-observation buffer holds
            machine.values["x_mm"] = float(i)
            agent.publish()
        for pattern, status, kind in REQUESTS:
            target = pattern.format(first=agent.first_sequence)
            response = client.get(target)
            assert response.status_code == status, target
            assert response.headers["content-type"].startswith("text/xml")
            assert errors(schemas, kind, response.content) == [], target
            root = response.text
            assert f"<MTConnect{kind} " in root, target
        post = client.post("/probe")
        assert post.status_code == 405
        assert errors(schemas, "Error", post.content) == []
        assert "<InvalidRequest>" in post.text


def test_sample_windows_follow_the_sequence_numbers(
    agent_url: tuple[str, MTConnectAgent, Machine],
) -> None:
    from cnctwin.thread.mtconnect_documents import AgentError, parse_streams

    url, agent, machine = agent_url
    with httpx.Client(base_url=url, timeout=BODY_S) as client:
        current = parse_streams(client.get("/current").content)
        start = current.header.next_sequence
        assert start is not None
        for value in (1.0, 2.0, 3.0, 4.0, 5.0):
            machine.values["y_mm"] = value
            agent.publish()
        window = parse_streams(client.get(f"/sample?from={start}&count=3").content)
        assert [o.sequence for o in window.observations] == [start, start + 1, start + 2]
        assert [o.value for o in window.observations] == ["1", "2", "3"]
        assert window.header.next_sequence == start + 3
        rest = parse_streams(client.get(f"/sample?from={start + 3}&count=50").content)
        assert [o.value for o in rest.observations] == ["4", "5"]
        assert rest.header.next_sequence == rest.header.last_sequence + 1  # type: ignore[operator]
        for i in range(100):  # overrun the buffer: the oldest observations are gone
            machine.values["y_mm"] = 100.0 + i
            agent.publish()
        with pytest.raises(AgentError, match="OUT_OF_RANGE"):
            parse_streams(client.get(f"/sample?from={start}").content)
        assert parse_streams(client.get("/current").content).header.first_sequence == (
            agent.next_sequence - 64
        )


def test_values_are_in_the_standard_units_and_unknown_is_unavailable() -> None:
    from cnctwin.thread.mtconnect_documents import parse_streams

    machine = Machine()
    agent = MTConnectAgent(machine)
    agent.publish()
    obs = {
        o.data_item_id: o for o in parse_streams(agent.answer("GET", "/current")[1]).observations
    }
    assert float(obs["feed"].value) == 1500.0 / 60.0  # PATH_FEEDRATE in MILLIMETER/SECOND
    assert obs["x_pos"].value == "12.5" and obs["x_pos"].sub_type == "ACTUAL"
    assert obs["execution"].value == "ACTIVE" and obs["line"].value == "42"
    assert obs["s_torque"].value == "UNAVAILABLE"  # NaN
    assert obs["system"].value == "NORMAL"
    machine.values["run_state"] = float(RunState.FAULT)
    agent.publish()
    obs = {
        o.data_item_id: o for o in parse_streams(agent.answer("GET", "/current")[1]).observations
    }
    assert (obs["execution"].value, obs["system"].value) == ("STOPPED", "FAULT")


def test_agent_refuses_a_network_interface_without_insecure() -> None:
    with pytest.raises(ConfigError, match="MTConnect agent has no security"):
        MTConnectAgent(Machine(), host="0.0.0.0")


# The reader against the agent serving the virtual machine ----------------------------
PROGRAM = """G21 G90 G17
T1 M6
S6000 M3
G0 X-10 Y10 Z5
G1 X70 F1200
G0 Z20
M30
"""


def test_reader_follows_the_program_on_the_virtual_machine(make_vm, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    vm = make_vm(PROGRAM)

    async def main() -> list[dict[str, float]]:
        seen: list[dict[str, float]] = []
        async with MTConnectAgent(vm) as agent:
            clock = MachineClock(vm, vm.tick_s, speed=4.0)
            clock.add_listener(agent.publish)
            config = ConnectionConfig(
                transport="mtconnect", endpoint=agent.endpoint, timeout_s=BODY_S
            )
            async with MTConnectConnection(config) as reader, clock:
                while not vm.finished:
                    seen.append(dict((await reader.read()).values))
                    await asyncio.sleep(0.02)
                await asyncio.sleep(0.05)
                seen.append(dict((await reader.read()).values))
                for name in COMMANDS:  # read-only: no command reaches the machine
                    with pytest.raises(CommandRejected, match="MTConnect is read-only"):
                        await reader.write(name, 1.0)
                assert reader.gaps == [] and reader.agent_restarts == 0
        return seen

    seen = asyncio.run(asyncio.wait_for(main(), BODY_S))
    moving = [s for s in seen if s.get("z_mm") == pytest.approx(5.0, abs=1e-6)]
    assert len(moving) >= 5
    xs = [s["x_mm"] for s in moving]
    # Along the program's G1 line: Y 10, Z 5, X from -10 to 70 and never back.
    assert all(-10.0 - 1e-6 <= x <= 70.0 + 1e-6 for x in xs)
    assert xs == sorted(xs)
    assert all(s["y_mm"] == pytest.approx(10.0, abs=1e-6) for s in moving)
    cruising = [s["feed_mm_min"] for s in moving if 5.0 < s["x_mm"] < 55.0]
    assert cruising and all(f == pytest.approx(1200.0, rel=1e-3) for f in cruising)  # F1200
    last = seen[-1]
    assert (last["x_mm"], last["y_mm"], last["z_mm"]) == pytest.approx((70.0, 10.0, 20.0))
    assert last["run_state"] == RunState.FINISHED
    assert last["tool_number"] == 1.0


# The twin over MTConnect ---------------------------------------------------------------
def test_the_twin_watches_the_demo_over_mtconnect_and_never_touches_the_machine() -> None:
    """``cnctwin run`` with ``transport = "mtconnect"``: the demo twin (control enabled, a hole
    in the machine's blank) follows the program to its end; no command reaches the machine."""
    from importlib.resources import as_file, files

    from cnctwin.twin import MachineServer, RunSummary, load_run_config, run_session

    with as_file(files("cnctwin.examples")) as folder:
        config = load_run_config(Path(folder) / "demo_twin.toml")
    assert config.control.enabled  # the twin would act; MTConnect cannot carry it

    async def main() -> tuple[RunSummary, dict[str, float], list[str]]:
        kinds: list[str] = []
        async with MachineServer(config, "mtconnect", speed=10.0) as machine:
            assert machine.endpoint.startswith("http://127.0.0.1:")
            connection = config.connection.model_copy(
                update={"transport": "mtconnect", "endpoint": machine.endpoint}
            )
            summary = await run_session(
                config.model_copy(update={"connection": connection}),
                duration_s=BODY_S,
                on_start=lambda _twin: machine.go(),
                on_cycle=lambda state: kinds.extend(e.kind for e in state.events),
            )
            return summary, machine.vm.snapshot(), kinds

    summary, machine, kinds = asyncio.run(asyncio.wait_for(main(), 2 * BODY_S))
    assert summary.ended == "finished"  # EXECUTION PROGRAM_COMPLETED, read over MTConnect
    assert machine["run_state"] == RunState.FINISHED
    assert machine["feed_override_pct"] == 100.0 and machine["stop"] == 0.0
    assert machine["feed_hold"] == 0.0 and machine["emergency_stop"] == 0.0
    assert summary.cycles > 0 and "connected" in kinds


def test_other_clients_read_it_urllib_and_http_1_0() -> None:
    """The standard library's urllib (HTTP/1.1, ``Connection: close``) and a bare HTTP/1.0
    request: each gets its whole document and the connection closed after it."""
    import urllib.request

    from cnctwin.thread.mtconnect_documents import parse_devices, parse_streams

    async def main() -> None:
        async with MTConnectAgent(Machine()) as agent:
            loop = asyncio.get_running_loop()

            def fetch() -> bytes:
                with urllib.request.urlopen(agent.endpoint + "/current", timeout=BODY_S) as r:
                    data: bytes = r.read()
                    return data

            current = parse_streams(await loop.run_in_executor(None, fetch))
            assert {o.data_item_id for o in current.observations} >= {"x_pos", "execution"}
            reader, writer = await asyncio.open_connection(agent.host, agent.port)
            writer.write(b"GET /probe HTTP/1.0\r\n\r\n")
            await writer.drain()
            answer = await reader.read()  # to the end: the agent closes
            writer.close()
            head, _, body = answer.partition(b"\r\n\r\n")
            assert head.startswith(b"HTTP/1.1 200") and b"Connection: close" in head
            assert parse_devices(body).devices == ("cnctwin-vm",)

    asyncio.run(asyncio.wait_for(main(), BODY_S))


# Real observations: the reference agent's Okuma, fed its adapter's SHDR log -------------------
def _last_raw(text: str, key: str) -> str:
    """The last value of ``key`` in the raw SHDR text, by a regular expression."""
    import re

    return re.findall(rf"\|{re.escape(key)}\|([^|\n]*)", text)[-1]


def test_real_okuma_observations_fed_by_shdr_validate_and_read_back(
    schemas: dict[str, object], shared_data: Path
) -> None:
    """The README's test: the agent loaded with the reference agent's device model and fed
    the Okuma adapter's SHDR log serves real observations of 100+ real data items; every
    answer validates, and the reader reads the raw file's last values back over HTTP."""
    from cnctwin.thread.mtconnect_documents import parse_streams

    folder = shared_data / "mtconnect" / "samples"
    probe = (folder / "demo_Devices_2.7.xml").read_bytes()
    text = (folder / "okuma_shdr_first298lines.txt").read_text()
    agent = MTConnectAgent(Machine(), buffer_size=4096)
    agent.load_devices(probe)
    feed = agent.feed_shdr(text.splitlines())
    assert feed.rejected == ["line 1: no data item 'ApplicationInstallDate'"]
    first = agent.first_sequence
    for target, kind in [
        ("/probe", "Devices"),
        ("/current", "Streams"),
        ("/OKUMA/current", "Streams"),
        ("/Mazak/current", "Streams"),  # every value UNAVAILABLE: the log is the Okuma's
        (f"/sample?from={first}&count=4096", "Streams"),
        (f"/OKUMA/sample?from={first + 500}&count=50", "Streams"),
        ("/NoSuchMachine/current", "Error"),
    ]:
        _, document = agent.answer("GET", target)
        assert errors(schemas, kind, document) == [], target
    assert agent.answer("GET", "/probe")[1] == probe
    okuma = parse_streams(agent.answer("GET", "/OKUMA/current")[1])
    by_id = {o.data_item_id: o for o in okuma.observations}
    assert {o.device for o in okuma.observations} == {"OKUMA"}
    assert by_id["LX1actw"].value == _last_raw(text, "X1actw") == "-119.9999"
    assert by_id["Lp1LPathPos"].value == _last_raw(text, "p1LPathPos")
    assert by_id["Lpexecution"].value == _last_raw(text, "pexecution")
    assert by_id["Lsystem"].value == "NORMAL" and by_id["Lsystem"].element == "Normal"
    # p1Fact is sent in its nativeUnits, MILLIMETER/MINUTE; served in MILLIMETER/SECOND
    assert float(by_id["Lp1Fact"].value) == pytest.approx(float(_last_raw(text, "p1Fact")) / 60)

    async def read() -> dict[str, float]:
        async with agent:
            config = ConnectionConfig(
                transport="mtconnect",
                endpoint=agent.endpoint + "/OKUMA",
                timeout_s=BODY_S,
                mapping={"z_mm": "POSITION:ACTUAL@Z1"},
            )
            async with MTConnectConnection(config) as reader:
                return dict((await reader.read()).values)

    values = asyncio.run(asyncio.wait_for(read(), BODY_S))
    assert values["x_mm"] == float(_last_raw(text, "X1actm"))
    assert values["z_mm"] == float(_last_raw(text, "Z1actm"))
    assert values["feed_mm_min"] == pytest.approx(float(_last_raw(text, "p1Fact")), abs=1e-4)
    assert values["load_x_pct"] == float(_last_raw(text, "X1load"))
    assert values["spindle_override_pct"] == float(_last_raw(text, "S1ovr"))
