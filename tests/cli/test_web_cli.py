"""``cnctwin web``: bad options end in one line and exit 2 before anything is served; good
ones serve the historian's runs at the address printed."""

import json
import subprocess
import sys
import urllib.request

from cnctwin.cli import run as cli_run
from cnctwin.store import Historian


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
