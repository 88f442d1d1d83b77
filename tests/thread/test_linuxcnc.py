"""The LinuxCNC connection against LinuxCNC itself: its simulator, driven over linuxcncrsh.

LinuxCNC (Debian's linuxcnc-uspace) runs its simulation configuration, written and started by
:mod:`linuxcnc_sim`; an :class:`~linuxcnc_sim.Operator` (a second linuxcncrsh session, written
from the protocol, not from the code under test) brings the machine up, runs a real program
(Fusion 360's ``1024_block_14bit.nc`` from ``../shared/data/gcode``) and reads what LinuxCNC
itself says: positions, overrides, program status.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import sqlite3
import subprocess
import sys
import time
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest
from linuxcnc_sim import LinuxCncSim, Operator

from cnctwin.errors import ConfigError
from cnctwin.thread import (
    CommandRejected,
    ConnectionConfig,
    ConnectionLost,
    ConnectionState,
    LinuxCncConnection,
    RunState,
)
from cnctwin.thread.linuxcnc import parse_endpoint

REPO = Path(__file__).resolve().parents[2]
PROGRAM = "gcode/fusion360_grbl_shooshx/1024_block_14bit.nc"
EXAMPLE = REPO / "examples" / "linuxcnc" / "block_14bit_twin.toml"
#: The program's first and last pass around the square: (first line, line after the pass).
FIRST_PASS, LAST_PASS = (20, 26), (34, 40)


@pytest.fixture(scope="module")
def sim(shared_data: Path) -> Iterator[LinuxCncSim]:
    machine = LinuxCncSim(shared_data / PROGRAM)
    try:
        machine.start()
        yield machine
    finally:
        machine.stop()


@pytest.fixture
def operator(sim: LinuxCncSim) -> Iterator[Operator]:
    sim.ensure_running()
    person = Operator(sim)
    try:
        person.machine_ready()
        yield person
    finally:
        try:
            person.set("abort")
        finally:
            person.close()


def config(port: int, enable: str | None = "EMCTOO") -> ConnectionConfig:
    return ConnectionConfig(
        transport="linuxcnc",
        endpoint=f"linuxcncrsh://127.0.0.1:{port}",
        timeout_s=5.0,
        reconnect_initial_s=0.2,
        reconnect_max_s=0.5,
        linuxcnc={"enable_password": enable},
    )


def test_endpoint_and_settings_refused_with_one_line() -> None:
    assert parse_endpoint("linuxcncrsh://cnc.local") == ("cnc.local", 5007)
    assert parse_endpoint("linuxcncrsh://10.0.0.8:5017") == ("10.0.0.8", 5017)
    for bad in (
        "http://10.0.0.8:5007",
        "linuxcncrsh://:5007",
        "linuxcncrsh://h:99999",
        "linuxcncrsh://h:5007/x",
    ):
        with pytest.raises(ConfigError, match="linuxcncrsh://HOST"):
            parse_endpoint(bad)
    with pytest.raises(ConfigError, match="mapping is not used"):
        LinuxCncConnection(config(5007).model_copy(update={"mapping": {"x_mm": "X"}}))


def test_lines_of_the_last_run_are_held_back_at_the_start_of_a_run() -> None:
    """LinuxCNC 2.9's answers to ``get program_line`` at the start of a run after a run
    aborted at line 20 (measured through linuxcncrsh, 2026-11-28): idle 20, 40 (where the last
    run's interpreter had read to), 0; then running 0, 40 and only then the run's own 15."""
    conn = LinuxCncConnection(config(5007))

    def shown(running: bool, line: float) -> float | None:
        values, rejected = {"program_line": line}, {}
        conn._drop_stale_line(running, values, rejected)
        assert ("program_line" in values) != ("program_line" in rejected)
        return values.get("program_line")

    assert [shown(False, line) for line in (20, 40, 0)] == [20, 40, 0]
    assert [shown(True, line) for line in (0, 40, 15, 16, 40, 0)] == [None, None, 15, 16, 40, 0]
    # a twin that saw nothing between the runs: the run's first line until it changes
    assert [shown(True, line) for line in (3, 3)] == [3, 3]  # still the same run
    assert shown(False, 41) == 41
    assert [shown(True, line) for line in (41, 41, 17)] == [None, None, 17]
    fresh = LinuxCncConnection(config(5007))
    values: dict[str, float] = {"program_line": 40.0}
    fresh._drop_stale_line(True, values, {})
    assert values == {}


def test_positions_follow_the_program_and_commands_reach_linuxcnc(
    sim: LinuxCncSim, operator: Operator
) -> None:
    async def scenario() -> None:
        async with LinuxCncConnection(config(sim.port)) as conn:
            assert conn.may_command
            first = await conn.read()
            assert first.values["run_state"] == RunState.IDLE
            operator.run(sim.program)
            operator.wait_status("RUNNING", 10.0)
            start = await conn.read()  # the run's first line is held back until it changes
            assert start.values["run_state"] == RunState.RUNNING
            assert "program_line" in start.rejected
            await asyncio.sleep(1.5)  # down to Z-1 and into the first pass
            reading = await conn.read()
            x, y, z = operator.position()
            assert reading.values["run_state"] == RunState.RUNNING
            assert reading.values["tool_number"] == 1
            assert reading.values["program_line"] >= 17
            for name, theirs in zip(("x_mm", "y_mm", "z_mm"), (x, y, z), strict=True):
                # read within ~50 ms of each other at <= 1000 mm/min: within 2 mm
                assert abs(reading.values[name] - theirs) < 2.0, (name, reading.values, theirs)
            assert -0.8 <= reading.values["x_mm"] <= 20.8 and -0.8 <= reading.values["y_mm"] <= 20.8
            assert (
                reading.source_time_s is not None and abs(reading.source_time_s - time.time()) < 5
            )

            await conn.write("feed_override_pct", 50.0)
            assert operator.get("feed_override") == ["50"]
            assert await conn.read_signal("feed_override_pct") == 50.0
            await conn.write("spindle_override_pct", 80.0)
            assert operator.get("spindle_override 0") == ["0", "80"]
            # garbage is refused before anything is sent; LinuxCNC keeps its value
            for name, value in (
                ("feed_override_pct", 500.0),
                ("feed_override_pct", float("nan")),
                ("spindle_override_pct", 10.0),
                ("feed_hold", 0.5),
                ("emergency_stop", 0.0),
                ("tool_length_wear_mm", 0.01),
            ):
                with pytest.raises(CommandRejected):
                    await conn.write(name, value)
            assert operator.get("feed_override") == ["50"]

            await conn.write("feed_hold", 1.0)
            operator.wait_status("PAUSED", 5.0)
            held = operator.position()
            await asyncio.sleep(0.4)
            assert operator.position() == held
            assert (await conn.read()).values["feed_hold"] == 1.0
            await conn.write("feed_hold", 0.0)
            operator.wait_status("RUNNING", 5.0)
            await asyncio.sleep(0.3)
            assert operator.position() != held

            await conn.write("stop", 1.0)  # abort
            operator.wait_status("IDLE", 5.0)
            stopped = operator.position()
            await asyncio.sleep(0.4)
            assert operator.position() == stopped
            assert (await conn.read()).values["run_state"] == RunState.STOPPED
            assert conn.sent.count("set abort") == 1

    asyncio.run(scenario())


def test_a_session_without_the_enable_password_only_reads(
    sim: LinuxCncSim, operator: Operator, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("CNCTWIN_LINUXCNC_ENABLE", raising=False)

    async def scenario() -> None:
        async with LinuxCncConnection(config(sim.port, enable=None)) as conn:
            assert not conn.may_command
            assert (await conn.read()).values["feed_override_pct"] == 100.0
            with pytest.raises(CommandRejected, match="not enabled"):
                await conn.write("feed_override_pct", 40.0)
            assert conn.sent == []
        async with LinuxCncConnection(config(sim.port, enable="wrong")) as conn:
            with pytest.raises(CommandRejected, match="refused the enable password"):
                await conn.write("feed_override_pct", 40.0)

    asyncio.run(scenario())
    assert operator.get("feed_override") == ["100"]


def test_cnctwin_run_mirrors_linuxcnc_and_slows_the_last_pass(
    sim: LinuxCncSim, operator: Operator, tmp_path: Path, shared_data: Path
) -> None:
    """The issue's proof: ``cnctwin run`` against LinuxCNC running a real program; the
    twin's rule lowers the feed override on the last pass, and LinuxCNC's own program lines
    show that pass taking twice as long as the first."""
    text = EXAMPLE.read_text()
    text = text.replace("linuxcncrsh://127.0.0.1:5007", f"linuxcncrsh://127.0.0.1:{sim.port}")
    text = text.replace(
        '"../../../shared/data/gcode/fusion360_grbl_shooshx/1024_block_14bit.nc"',
        json.dumps(str(shared_data / PROGRAM)),
    )
    assert tomllib.loads(text)["twin"]["program"] == str(shared_data / PROGRAM)
    (tmp_path / "twin.toml").write_text(text)
    # a run aborted in its first pass: at the start of the next one LinuxCNC shows lines of
    # this one for a while (line 40, where its interpreter had read to), which the twin's rule
    # on program_line >= 34 must not take for the new run's
    operator.run(sim.program)
    operator.wait_status("RUNNING", 10.0)
    time.sleep(1.0)
    operator.set("abort")
    operator.wait_status("IDLE", 10.0)
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    twin = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "cnctwin",
            "run",
            "--config",
            str(tmp_path / "twin.toml"),
            "--db",
            str(tmp_path / "history.sqlite"),
            "--json",
            "--connect-timeout",
            "60",
            "--duration",
            "120",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    watch: subprocess.Popen[str] | None = None
    overrides: list[dict[str, float]] = []
    try:
        # the program starts once the twin cycles (its first samples are in the historian):
        # building the twin compiles its kernels, minutes on a loaded machine without cache
        ready = time.monotonic() + 300.0
        while not _recorded_samples(tmp_path / "history.sqlite"):
            assert twin.poll() is None, twin.communicate()[1].decode()[-3000:]
            assert time.monotonic() < ready, "the twin did not start cycling within 300 s"
            time.sleep(0.2)
        # LinuxCNC runs the program and says which line motion executes through its own Python
        # interface: the twin keeps the only linuxcncrsh session while it runs (a second
        # session polling beside it has made linuxcncrsh 2.9, and LinuxCNC with it, exit)
        watch = sim.run_through_nml(sim.program, timeout_s=90.0)
        watched, watch_err = watch.communicate(timeout=120.0)
        events = [json.loads(line) for line in watched.splitlines()]
        assert events and events[-1].get("end") == "idle", (events[-3:], watch_err[-2000:])
        overrides = [e for e in events if "feed_override_pct" in e and "end" not in e]
        events = [e for e in events if "feed_override_pct" not in e or "end" in e]
        first_seen: dict[int, float] = {}
        for event in events[:-1]:
            if first_seen and event["line"] < max(first_seen):
                first_seen.clear()  # the line of an earlier run, shown until this one starts
            first_seen.setdefault(event["line"], event["t"])
        out, err = twin.communicate(timeout=60.0)
    finally:
        for child in (twin, watch):
            if child is not None and child.poll() is None:
                child.kill()
                child.communicate()
    assert twin.returncode == 0, err.decode()[-3000:]
    summary = json.loads(out)
    assert summary["ended"] == "finished"
    assert summary["feed_override_min"] == 50.0
    assert summary["decisions"] >= 1 and summary["samples_recorded"] > 50
    assert events[-1]["feed_override_pct"] == 50.0  # LinuxCNC's own word, through NML
    assert operator.get("feed_override") == ["50"]  # and through linuxcncrsh

    def took(span: tuple[int, int]) -> float:
        return first_seen[span[1]] - first_seen[span[0]]

    ratio = took(LAST_PASS) / took(FIRST_PASS)
    # 85.6 mm at 1000 mm/min, then at 50 %: twice as long (blending and the seen lines: 20 %)
    assert 1.6 < ratio < 2.4, (ratio, first_seen, overrides)


def _recorded_samples(db: Path) -> int:
    """Sample frames the twin has written to its historian so far (0 before the file)."""
    if not db.exists():
        return 0
    try:
        with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True)) as con:
            return int(con.execute("SELECT count(*) FROM hist_frames").fetchone()[0])
    except sqlite3.Error:
        return 0


def test_a_restarted_linuxcnc_is_reconnected_and_nothing_is_replayed(
    sim: LinuxCncSim,
) -> None:
    sim.ensure_running()

    async def scenario() -> None:
        person = Operator(sim)
        person.machine_ready()
        person.close()
        async with LinuxCncConnection(config(sim.port)) as conn:
            await conn.write("feed_override_pct", 60.0)
            sim.kill()
            with pytest.raises(ConnectionLost):
                await conn.read()
            assert conn.state is ConnectionState.RECONNECTING
            lost = time.monotonic()
            await asyncio.to_thread(sim.restart)
            while conn.state is not ConnectionState.CONNECTED:
                assert time.monotonic() - lost < 60.0, "no reconnection within 60 s"
                await asyncio.sleep(0.1)
            assert conn.reconnects == 1
            reading = await conn.read()
            # a fresh LinuxCNC: E-stop on, override 100 %; the 60 % was not sent again
            assert reading.values["emergency_stop"] == 1.0
            assert reading.values["feed_override_pct"] == 100.0
            assert conn.sent.count("set feed_override 60") == 1
            with pytest.raises(CommandRejected, match="refused"):
                await conn.write("feed_override_pct", 70.0)  # LinuxCNC: NAK in E-stop

    asyncio.run(scenario())
