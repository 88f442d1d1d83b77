"""A recorded machine (``virtual serve --replay``): real logs served, read back by real clients.

The UMich experiment is checked against the CSV read with the standard library's ``csv``
module and the README's units, row by row, through asyncua's own client (not cnctwin's
connection); the replay is stepped by hand between reads, so nothing depends on wall time.
A recorded twin run goes through the historian's own export (CSV and Parquet) and back.
"""

from __future__ import annotations

import asyncio
import csv
import math
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from asyncua import Client, ua
from timeouts import BODY_S

from cnctwin.errors import ConfigError, DataError
from cnctwin.store import Historian
from cnctwin.thread.opcua import NAMESPACE_URI, NODE_MAP
from cnctwin.thread.signals import RunState
from cnctwin.virtual import (
    ModbusMachineServer,
    MTConnectAgent,
    OpcUaMachineServer,
    ReplayMachine,
    UserTable,
    load_replay_map,
    read_replay_log,
)

REPO = Path(__file__).resolve().parents[2]
UMICH_MAP = REPO / "examples" / "replay" / "umich.toml"
LAYERS = {f"Layer {n} {d}" for n in (1, 2, 3) for d in ("Up", "Down")}


def _umich_expected(path: Path) -> list[dict[str, float]]:
    """The rows a replay must serve, from the CSV and the README's units alone: glitch rows
    (the home snapshot, X 198 mm and feed 50, inside a cutting layer) left out."""
    rows = []
    with path.open(newline="") as f:
        for k, row in enumerate(csv.DictReader(f)):
            cell = {name: float(v) for name, v in row.items() if name != "Machining_Process"}
            home = cell["X1_ActualPosition"] == 198 and cell["M1_CURRENT_FEEDRATE"] == 50
            if home and row["Machining_Process"] in LAYERS:
                continue
            speed = math.sqrt(sum(cell[f"{a}1_ActualVelocity"] ** 2 for a in "XYZ"))
            rows.append(
                {
                    "t_s": 0.1 * k,
                    "x_mm": cell["X1_ActualPosition"],
                    "y_mm": cell["Y1_ActualPosition"],
                    "z_mm": cell["Z1_ActualPosition"],
                    "feed_mm_min": speed * 60.0,
                    "spindle_rpm": cell["S1_ActualVelocity"] * 60.0,
                    "spindle_rpm_command": cell["S1_CommandVelocity"] * 60.0,
                    "spindle_current_a": cell["S1_CurrentFeedback"],
                    "spindle_power_w": cell["S1_OutputPower"] * 1000.0,
                    "program_line": cell["M1_sequence_number"],
                    "tool_number": 1.0,
                }
            )
    return rows


@pytest.fixture(scope="module")
def umich(shared_data: Path) -> Path:
    path = shared_data / "umich_cnc_mill_tool_wear" / "experiment_04.csv"
    if not path.is_file():
        pytest.fail(f"{path} is missing from the shared data")
    return path


def test_umich_replay_over_opcua_reads_back_the_file_row_by_row(umich: Path) -> None:
    expected = _umich_expected(umich)
    log = read_replay_log(umich, load_replay_map(UMICH_MAP))
    # experiment 4: 532 rows, of which the README's glitches inside a layer are dropped
    assert log.rows_read == 532
    assert log.rows == len(expected) < 532
    assert sum(log.glitch_rows.values()) == 532 - len(expected)
    assert log.metadata["feedrate"] == "6" and log.metadata["clamp_pressure"] == "2.5"
    replay = ReplayMachine(log)
    names = list(expected[0])
    expected = [{**row, "t_s": round(row["t_s"], 9)} for row in expected]

    async def body() -> None:
        server = OpcUaMachineServer(replay, users=UserTable(anonymous="operator"))
        async with server:
            client = Client(server.endpoint, timeout=10.0)
            await client.connect()
            try:
                ns = await client.get_namespace_index(NAMESPACE_URI)
                nodes = [client.get_node(ua.NodeId(NODE_MAP[n], ns)) for n in names]
                force = client.get_node(ua.NodeId(NODE_MAP["force_x_n"], ns))
                assert math.isnan(await force.read_value())  # not in the log: not invented
                # tick k (0.1 s each) serves the last row recorded at or before 0.1 k s: a
                # glitch row's time passes with the row before it
                shown = 0
                for k in range(log.rows_read):
                    if k:
                        replay.step(replay.tick_s)
                        server.publish()
                    while shown + 1 < len(expected) and expected[shown + 1]["t_s"] <= 0.1 * k:
                        shown += 1
                    row = expected[shown]
                    got = await client.read_values(nodes)
                    for name, value in zip(names, got, strict=True):
                        assert value == pytest.approx(row[name], rel=1e-9, abs=1e-9), (k, name)
                assert shown == len(expected) - 1
                # an override is accepted and read back; the recording goes on unchanged
                feed = client.get_node(ua.NodeId(NODE_MAP["feed_override_pct"], ns))
                await feed.write_value(ua.DataValue(ua.Variant(50.0, ua.VariantType.Double)))
                assert await feed.read_value() == 50.0
                assert replay.snapshot()["x_mm"] == expected[-1]["x_mm"]
                replay.step(replay.tick_s)
                assert replay.finished
                server.publish()
                state = client.get_node(ua.NodeId(NODE_MAP["run_state"], ns))
                assert await state.read_value() == RunState.FINISHED
            finally:
                await client.disconnect()

    asyncio.run(asyncio.wait_for(body(), BODY_S))


def test_umich_replay_over_modbus_reads_back_float32(umich: Path) -> None:
    from pymodbus.client import AsyncModbusTcpClient

    from cnctwin.thread import READ_MAP

    replay = ReplayMachine(read_replay_log(umich, load_replay_map(UMICH_MAP)))
    for _ in range(40):
        replay.step(replay.tick_s)
    want = replay.snapshot()

    async def body() -> None:
        async with ModbusMachineServer(replay) as server:
            client = AsyncModbusTcpClient("127.0.0.1", port=server.port, timeout=10.0)
            await client.connect()
            try:
                for name in ("x_mm", "spindle_rpm", "force_x_n"):
                    addr = READ_MAP[name]
                    answer = await client.read_input_registers(
                        addr.address, count=addr.width, device_id=1
                    )
                    value = addr.decode(answer.registers)
                    if math.isnan(want[name]):
                        assert value is None or math.isnan(value), name
                    else:
                        assert value == pytest.approx(want[name], rel=1e-6), name
            finally:
                client.close()

    asyncio.run(asyncio.wait_for(body(), BODY_S))


def test_umich_replay_as_an_mtconnect_agent_marks_what_is_not_recorded(umich: Path) -> None:
    replay = ReplayMachine(read_replay_log(umich, load_replay_map(UMICH_MAP)))
    replay.step(replay.tick_s)
    agent = MTConnectAgent(replay)
    agent.publish()
    status, body = agent.answer("GET", "/current")
    assert status == 200
    root = ElementTree.fromstring(body)
    items = {e.get("dataItemId"): e.text for e in root.iter() if e.get("dataItemId")}
    assert float(items["x_pos"] or "nan") == replay.snapshot()["x_mm"]
    assert items["x_load"] == "UNAVAILABLE" and items["s_torque"] == "UNAVAILABLE"


def test_a_log_over_the_memory_limit_is_refused_before_it_is_read(
    umich: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CNCTWIN_MEMORY_LIMIT_GB", "0.001")  # 1 MB: under 8 x the 234 kB file
    with pytest.raises(ConfigError, match=r"replay log .*experiment_04\.csv") as err:
        read_replay_log(umich, load_replay_map(UMICH_MAP))
    assert "\n" not in str(err.value)


def test_replay_loops_after_the_recorded_duration(umich: Path) -> None:
    log = read_replay_log(umich, load_replay_map(UMICH_MAP))
    assert log.duration_s == pytest.approx(53.2)  # 532 rows of 100 ms, glitch time included
    replay = ReplayMachine(log, loop=True)
    first = replay.snapshot()
    for _ in range(531):
        replay.step(log.period_s)
    assert replay.passes == 0 and replay.index == log.rows - 1
    replay.step(log.period_s)
    again = replay.snapshot()
    assert replay.passes == 1 and not replay.finished
    assert again["x_mm"] == first["x_mm"] and again["t_s"] == 0.0
    assert again["heartbeat"] == 532  # counts on through the loop
    with pytest.raises(DataError, match="finite tick"):
        replay.step(0.0)


def test_historian_export_replays_signal_for_signal(tmp_path: Path) -> None:
    # A twin's recorded run, exported by the historian, replayed without a mapping.
    times = np.arange(50) * 0.0125
    with Historian.open(tmp_path / "h.sqlite") as h:
        run = h.start_run({"program": "demo.ngc"})
        for i, t in enumerate(times):
            values = {"t_s": t, "x_mm": 1.5 * i, "spindle_rpm": 8000.0 + i}
            if i % 2 == 0:
                values["force_x_n"] = -10.0 * i  # recorded at every second instant only
            values["feed_override_pct"] = 80.0  # a command: never replayed
            h.record_samples(run, float(t), values)
        h.end_run(run)
        files = h.export(run, tmp_path / "run.csv") + h.export(run, tmp_path / "run.parquet")
    for path in (files[0], files[4]):
        log = read_replay_log(path)
        assert log.rows == 50 and log.period_s == pytest.approx(0.0125)
        assert log.held_cells == 25
        replay = ReplayMachine(log)
        for i in range(50):
            snap = replay.snapshot()
            assert snap["x_mm"] == 1.5 * i and snap["spindle_rpm"] == 8000.0 + i
            assert snap["force_x_n"] == -10.0 * (i - i % 2)  # the previous recorded value
            assert snap["t_s"] == times[i] and snap["feed_override_pct"] == 100.0
            replay.step(replay.tick_s)
        assert replay.finished


def _csv(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "time_s,x_mm\n0,1\n0.1,abc\n",
            r"bad\.csv: column 'x_mm' is not numeric \(line 3: 'abc'\)",
        ),
        ("time_s,x_mm\n0,1\n-0.1,2\n", r"bad\.csv: column 'time_s' goes back in time at line 3"),
        ("t,x_mm\n0,1\n", r"bad\.csv: column 'time_s' is missing"),
        ("a,b\n0,1\n", r"bad\.csv: no column is a canonical signal"),
        ("time_s,x_mm\n", r"bad\.csv: no data rows"),
    ],
)
def test_bad_logs_give_one_line_errors(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(DataError, match=message) as err:
        read_replay_log(_csv(tmp_path / "bad.csv", text))
    assert "\n" not in str(err.value)


def test_bad_mappings_and_missing_columns_name_the_key_and_file(
    tmp_path: Path, umich: Path
) -> None:
    bad_unit = _csv(tmp_path / "m.toml", '[signals]\nx_mm = { column = "X", unit = "kW" }\n')
    with pytest.raises(ConfigError, match=r"m\.toml: .*'kW' cannot be converted to mm; valid: mm"):
        load_replay_map(bad_unit)
    bad_name = _csv(tmp_path / "n.toml", '[signals]\nx = { column = "X" }\n')
    with pytest.raises(ConfigError, match=r"n\.toml: .*signals\.x: not a canonical signal"):
        load_replay_map(bad_name)
    command = _csv(tmp_path / "c.toml", '[signals]\nstop = { column = "X" }\n')
    with pytest.raises(ConfigError, match=r"signals\.stop: not replayed"):
        load_replay_map(command)
    missing = _csv(
        tmp_path / "x.toml", '[log]\nperiod_s = 0.1\n[signals]\nx_mm = { column = "X9_Pos" }\n'
    )
    with pytest.raises(DataError, match=r"experiment_04\.csv: column 'X9_Pos' is missing"):
        read_replay_log(umich, load_replay_map(missing))
    text = _csv(
        tmp_path / "t.toml",
        '[log]\nperiod_s = 0.1\n[signals]\nx_mm = { column = "Machining_Process" }\n',
    )
    with pytest.raises(DataError, match=r"column 'Machining_Process' is not numeric \(line 2"):
        read_replay_log(umich, load_replay_map(text))
