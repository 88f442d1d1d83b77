"""``cnctwin demo``: the twin against the packaged virtual machine over OPC UA (and Modbus).

The JSON summary is checked against the historian the run wrote (another reader of the
same facts) and against the demo's design: the form-error rule lowers the feed override in
the heavy pass, the hole in the blank stops the machine.
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from cnctwin.cli import run

REPO = Path(__file__).resolve().parents[2]
KEYS = (
    "cycles",
    "cycle_p50_ms",
    "cycle_p99_ms",
    "overruns",
    "stop_reaction_ms",
    "feed_override_min",
    "events",
    "samples_recorded",
    "database",
)


def _demo(tmp_path: Path, *extra: str) -> tuple[dict, str, Path]:
    db = tmp_path / "demo.sqlite"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "cnctwin",
            "demo",
            "--json",
            "--db",
            str(db),
            # the demo's own speed (2x): at 4x a loaded computer reads the machine half as
            # often per mm cut (docs/benchmarks.md, "The twin under CPU load", is measured at 2x)
            "--speed",
            "2",
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1  # one JSON object, nothing else on stdout
    return json.loads(lines[0]), result.stderr, db


def test_demo_adapts_the_feed_then_stops_on_the_hole(tmp_path: Path) -> None:
    report, err, db = _demo(tmp_path)
    assert list(report)[: len(KEYS)] == list(KEYS)
    assert f"history: {db}" in err  # the history path is printed at the start
    assert report["ended"] == "stopped"
    assert report["stop_reaction_ms"] is not None and report["stop_reaction_ms"] > 0
    # the form-error rule lowers the feed, unless an overloaded twin shed the form-error
    # prediction (docs/twin.md, "Overload": the last stage shed, the stop is never shed)
    adapted = "form_error" not in report["shed"]
    assert report["feed_override_min"] < 90.0 or not adapted
    assert report["database"] == str(db)
    with sqlite3.connect(db) as conn:
        (frames,) = conn.execute("SELECT COUNT(*) FROM hist_frames WHERE kind = 0").fetchone()
        decisions = conn.execute(
            "SELECT rule, action, accepted FROM hist_decisions ORDER BY seq"
        ).fetchall()
        status, summary = conn.execute("SELECT status, summary FROM hist_runs").fetchone()
    # a cycle records only a new sample, and an overloaded twin keeps fewer (it sheds the
    # historian's detail; docs/twin.md, "Overload")
    assert 0 < frames == report["samples_recorded"] <= report["cycles"]
    # one stop, on the hole; cycles until the axes are seen at rest may add feed decisions
    assert [d for d in decisions if d[1] == "stop"] == [("force_out_of_band", "stop", 1)]
    fed = any(r == "form_error" and a == "feed_override_pct" and ok for r, a, ok in decisions)
    assert fed or not adapted
    assert status == "stopped"
    assert json.loads(summary)["stop_reaction_ms"] == report["stop_reaction_ms"]


def test_demo_over_modbus(tmp_path: Path) -> None:
    report, _, _ = _demo(tmp_path, "--transport", "modbus")
    assert report["transport"] == "modbus"
    assert report["ended"] == "stopped"
    assert report["feed_override_min"] < 90.0 or "form_error" in report["shed"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--speed", "-1"], "--speed -1"),
        (["--duration", "0"], "--duration 0"),
        (["--transport", "ads"], "--transport 'ads'"),
    ],
)
def test_demo_bad_input_is_one_line_and_exit_2(capsys, argv: list[str], message: str) -> None:
    code = run(["demo", *argv])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and message in err


def test_demo_config_runs_the_wear_example_to_its_tool_change(tmp_path: Path) -> None:
    """``--config``: the wear example's own virtual machine wears its tool by its own law (the
    accelerated-wear fault, not the twin's EKF); the twin asks for a tool change at stage IV
    and stops, and its estimate then is near the machine's true wear."""
    config = "examples/wear/wear_twin.toml"
    report, _, db = _demo(tmp_path, "--config", config)
    assert report["ended"] == "stopped"
    tool = report["stage_results"]["wear"]["1"]
    assert tool["stage"] == 4
    entry = tool["stage_entries"]["4"]
    assert entry["vb_mm"] >= 0.4  # stage IV begins at 0.4 mm ([twin.wear] stages_mm)
    true_vb = report["machine_tool_wear_mm"]
    # the machine's law reaches 0.4 mm in about 20 s of cutting; the twin's estimate within
    # 0.1 mm of it (docs/benchmarks.md, "Wear live": mean abs error 0.01-0.03 mm in lockstep)
    assert 0.25 < true_vb < 0.55
    assert abs(entry["vb_mm"] - true_vb) < 0.1
    with sqlite3.connect(db) as conn:
        decisions = conn.execute("SELECT rule, action, reason FROM hist_decisions").fetchall()
        (meta,) = conn.execute("SELECT meta FROM hist_runs").fetchone()
    # a tool change writes no signal: the request is recorded (docs/control.md)
    requests = [r for rule, action, r in decisions if action == "tool_change"]
    assert len(requests) == 1 and "tool change requested" in requests[0]
    assert ("worn_out", "stop") in [(rule, action) for rule, action, _ in decisions]
    assert json.loads(meta)["command"] == f"cnctwin demo --config {config}"


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ("examples/opcua/heidenhain_tnc.toml", "no [virtual] table"),
        ("examples/nowhere.toml", "nowhere.toml"),
    ],
)
def test_demo_bad_config_is_one_line_and_exit_2(capsys, config: str, message: str) -> None:
    code = run(["demo", "--config", str(REPO / config)])
    _, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and message in err


def test_the_summary_table_has_a_row_per_closed_loop() -> None:
    from rich.console import Console

    from cnctwin.cli.run import summary_report, summary_table
    from cnctwin.twin.runtime import RunSummary

    results = {
        "adaptive_feed": {
            "quantity": "force",
            "reference": 150.0,
            "peak_engaged": 166.2,
            "commands": 141,
            "lowest_override_pct": 20.0,
        },
        "chatter": {
            "detections": [
                {
                    "line": 14,
                    "window_end_s": 2.02,
                    "after_engagement_s": 0.125,
                    "frequency_hz": 935.0,
                    "energy_ratio": 0.99,
                    "spindle_rpm": 7995.6,
                }
            ],
            "avoidances": [
                {
                    "line": 14,
                    "machine_s": 2.05,
                    "programmed_rpm": 8000.0,
                    "stable_rpm": 7070.0,
                    "spindle_override_pct": 88.375,
                }
            ],
        },
        "wear": {
            "1": {
                "vb_mm": 0.401,
                "sd_mm": 0.013,
                "stage": 4,
                "cut_s": 14.8,
                "removed_mm3": 1.0,
                "stage_entries": {"4": {"cut_s": 14.7, "vb_mm": 0.401, "sd_mm": 0.013}},
            }
        },
    }
    report = summary_report(RunSummary(stage_results=results), machine_tool_wear_mm=0.366)
    console = Console(width=200, record=True)
    console.print(summary_table(report, title="t"))
    text = console.export_text()
    assert (
        "peak force 166 N while engaged (reference 150 N), 141 feed commands, lowest 20 %" in text
    )
    assert "detected 125 ms after the engagement began, at 935 Hz" in text
    assert "spindle 8000 -> 7070 rpm at 2.05 s machine time" in text
    assert "stage IV at VB 0.401 mm after 14.7 s cutting; machine's true VB 0.366 mm" in text
    # the packaged demo has none of these stages: no loop rows
    plain = Console(width=200, record=True)
    plain.print(summary_table(summary_report(RunSummary()), title="t"))
    assert "adaptive feed" not in plain.export_text()
