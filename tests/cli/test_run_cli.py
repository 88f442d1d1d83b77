"""``cnctwin run``: the twin of a configuration file against a machine on loopback.

The machine is the packaged virtual machine served by OPC UA from a child process (as a real
control would be: another process, reached only through the protocol).
"""

from __future__ import annotations

import json
import shutil
import socket
import sqlite3
import subprocess
import sys
import time
from importlib.resources import files
from pathlib import Path

import pytest
from timeouts import CHILD_START_S

from cnctwin.cli import run
from cnctwin.twin.config import load_run_config
from cnctwin.twin.host import MachineProcess

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def twin_toml(tmp_path: Path) -> Path:
    """The demo's twin configuration and program copied to a folder of their own."""
    examples = files("cnctwin.examples")
    for name in ("demo_twin.toml", "demo_twin.ngc"):
        shutil.copyfile(str(examples / name), tmp_path / name)
    return tmp_path / "demo_twin.toml"


def test_run_mirrors_the_machine_and_records_the_run(twin_toml: Path, tmp_path: Path) -> None:
    config = load_run_config(twin_toml)
    clean = config.model_copy(update={"virtual": config.virtual.model_copy(update={"faults": []})})
    db = tmp_path / "run.sqlite"
    with MachineProcess(clean, "opcua", speed=2.0) as machine:
        twin = subprocess.Popen(
            [sys.executable, "-m", "cnctwin", "run", "--config", str(twin_toml),
             "--endpoint", machine.endpoint, "--db", str(db), "--duration", "4", "--json",
             "--connect-timeout", str(CHILD_START_S)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
        )  # fmt: skip
        try:
            # the program starts once the twin is connected, so the twin sees the whole blank
            # (a twin attached mid-program would not know what was already cut)
            _wait_for_event(db, "reached", twin)
            machine.go()
            out, err = twin.communicate(timeout=CHILD_START_S)
        finally:
            if twin.poll() is None:
                twin.kill()
                twin.wait()
        state = machine.state()
    assert twin.returncode == 0, err
    report = json.loads(out)
    assert report["ended"] == "duration"
    # 4 s at 12.5 ms is 320 cycles on a quiet machine, fewer on a loaded one (cycle figures are
    # benchmarked in bench_twin_cycle.py); a cycle records only a new sample of the machine
    assert 0 < report["samples_recorded"] <= report["cycles"]
    assert report["stop_reaction_ms"] is None
    assert state is not None and state["run_state"] == 1  # the machine still runs
    with sqlite3.connect(db) as conn:
        meta, status = conn.execute("SELECT meta, status FROM hist_runs").fetchone()
        (x_max,) = conn.execute("SELECT COUNT(*) FROM hist_frames WHERE kind = 1").fetchone()
    assert json.loads(meta)["command"] == "cnctwin run"
    assert status == "duration"
    assert x_max == report["samples_recorded"]  # predictions recorded with every sample


def test_unreachable_machine_is_one_line_and_exit_2(capsys, twin_toml: Path, tmp_path) -> None:
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code = run(
        ["run", "--config", str(twin_toml), "--endpoint", f"opc.tcp://127.0.0.1:{port}/x",
         "--db", str(tmp_path / "x.sqlite"), "--connect-timeout", "1"]
    )  # fmt: skip
    _, err = capsys.readouterr()
    assert code == 2
    last = err.strip().splitlines()[-1]
    assert "cannot reach the machine" in last and str(port) in last


def test_bad_config_is_one_line_and_exit_2(capsys, tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[twin]\ncycle_s = 0.0125\nspeedy = true\n")
    code = run(["run", "--config", str(bad)])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1
    assert "twin.speedy: unknown key" in err


def _wait_for_event(db: Path, kind: str, process: subprocess.Popen[str]) -> None:
    """Wait until ``process`` records an event of ``kind`` in ``db``; fail at once if it ends."""
    deadline = time.monotonic() + CHILD_START_S
    while time.monotonic() < deadline:
        if process.poll() is not None:
            _, err = process.communicate()
            raise AssertionError(f"exit {process.returncode} before a {kind!r} event: {err}")
        if db.exists():
            try:
                with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0) as conn:
                    row = conn.execute(
                        "SELECT 1 FROM hist_events WHERE kind = ?", (kind,)
                    ).fetchone()
                if row:
                    return
            except sqlite3.Error:
                pass
        time.sleep(0.05)
    raise AssertionError(f"no {kind!r} event in {db} within {CHILD_START_S} s")
