"""``cnctwin web`` and ``--web`` on ``run``/``demo``: bad options end in one line and exit 2
before anything is served or opened; good ones serve the historian's runs at the address
printed."""

import json
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest

from cnctwin.cli import run as cli_run
from cnctwin.store import Historian

REPO = Path(__file__).resolve().parents[2]
DEMO_CONFIG = REPO / "src" / "cnctwin" / "examples" / "demo_twin.toml"


def test_cli_refuses_bad_input_in_one_line(tmp_path, capsys) -> None:
    assert cli_run(["web", "--db", str(tmp_path / "none.sqlite")]) == 2
    assert "no historian database at" in capsys.readouterr().err
    assert cli_run(["web", "--host", "0.0.0.0"]) == 2
    err = capsys.readouterr().err
    assert "--insecure" in err and err.count("\n") == 1
    assert cli_run(["web", "--port", "70000"]) == 2
    assert "--port 70000" in capsys.readouterr().err


def test_serves_the_historian_at_the_printed_address(tmp_path) -> None:
    db = tmp_path / "runs.sqlite"
    with Historian.open(db) as h:
        run = h.start_run({"program": "pocket.nc", "machine": "mill-1"})
        for i in range(50):
            h.record_samples(run, i * 0.0125, {"force_x_n": float(i)})
        h.end_run(run, "finished", {})
    server = subprocess.Popen(
        [sys.executable, "-m", "cnctwin", "web", "--db", str(db), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = server.stdout.readline()
        assert line.startswith(f"run browser of {db} at http://127.0.0.1:"), line
        address = line.split(" at ")[1].split()[0]
        assert address.endswith("/runs") and "token" not in line  # loopback: no token
        with urllib.request.urlopen(address.removesuffix("runs") + "api/runs", timeout=20) as r:
            runs = json.loads(r.read())["runs"]
        assert [(r["program"], r["machine"], r["status"], r["frames"]) for r in runs] == [
            ("pocket.nc", "mill-1", "finished", 50)
        ]
        with urllib.request.urlopen(address, timeout=20) as r:
            assert b"cnctwin: recorded runs" in r.read()
    finally:
        server.terminate()
        server.wait(20)


def test_cli_refuses_a_non_loopback_host_in_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    argv = ["run", "--config", str(DEMO_CONFIG), "--db", str(tmp_path / "h.sqlite")]
    code = cli_run([*argv, "--web", "--host", "0.0.0.0", "--port", "0"])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and "--host '0.0.0.0'" in err and "--insecure" in err
    assert not (tmp_path / "h.sqlite").exists()  # refused before the historian is opened


def test_a_port_in_use_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        argv = ["demo", "--web", "--port", str(port), "--db", str(tmp_path / "h.sqlite")]
        code = cli_run(argv)
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and f"--port {port}: cannot listen" in err


def test_web_on_a_port_in_use_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    db = tmp_path / "h.sqlite"
    with Historian.open(db):
        pass
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        code = cli_run(["web", "--db", str(db), "--port", str(port)])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and f"--port {port}: cannot listen" in err
