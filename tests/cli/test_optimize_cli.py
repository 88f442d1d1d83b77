"""``cnctwin optimize`` end to end: the program written, the report, the re-simulation's
verdict, and bad options refused in one line (exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from cnctwin.config import load_config
from cnctwin.nc import Interpreter, MotionKind
from cnctwin.simulation import predict_program_signals

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "cnctwin" / "examples"
DEMO, DEMO_CONFIG = EXAMPLES / "demo.ngc", EXAMPLES / "demo.toml"
TIMEOUT_S = 600


def _cnctwin(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cnctwin", *args], capture_output=True, text=True,
        timeout=TIMEOUT_S,
    )  # fmt: skip


def test_demo_is_optimised_and_signals_confirm_the_limits(tmp_path: Path) -> None:
    out, report = tmp_path / "demo_opt.ngc", tmp_path / "demo_opt.json"
    done = _cnctwin(
        "optimize", str(DEMO), "--config", str(DEMO_CONFIG), "--max-force-n", "150",
        "--max-power-w", "800", "--out", str(out), "--report", str(report), "--json",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    printed = json.loads(done.stdout)
    assert printed["limits_hold"] is True
    assert json.loads(report.read_text())["cycle_time_after_s"] == printed["cycle_time_after_s"]
    assert printed["before"]["max_force_n"] > 150.0 >= printed["after"]["max_force_n"]
    assert printed["after"]["max_power_w"] <= 800.0
    limits = {row["limit"] for row in printed["blocks"]}
    assert {"force", "kept"} <= limits
    # What cnctwin signals predicts for the written program (its own run) respects the limits.
    config = load_config(DEMO_CONFIG)
    signals = predict_program_signals(out, config, density_per_mm=10.0, cycle_s=0.0125)
    summary = signals.summary()
    assert summary["max_force_n"] <= 150.0
    assert summary["max_power_w"] <= 800.0
    assert abs(summary["process_time_s"] - printed["cycle_time_after_s"]) < 1e-6


def test_bad_options_are_one_line_and_exit_2(tmp_path: Path) -> None:
    out = tmp_path / "o.ngc"
    for args, needle in (
        (["--out", str(out)], "no limit given"),
        (["--out", str(out), "--max-force-n", "-5"], "max_force_n=-5.0"),
        (["--out", str(out), "--max-chip-mm", "0.05", "--force-metric", "rms"], "--force-metric"),
        (["--out", str(DEMO), "--max-chip-mm", "0.05"], "--out"),
        (["--out", str(out), "--max-chip-mm", "0.05", "--max-factor", "0.5"], "--max-factor"),
    ):
        done = _cnctwin("optimize", str(DEMO), "--config", str(DEMO_CONFIG), *args)
        assert done.returncode == 2, (args, done.stderr)
        assert needle in done.stderr
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert "Traceback" not in done.stderr


def test_stability_file_schedules_speeds_and_the_limits_still_hold(tmp_path: Path) -> None:
    out = tmp_path / "demo_stab.ngc"
    stability = Path(__file__).resolve().parents[2] / "examples" / "stability"
    done = _cnctwin(
        "optimize", str(DEMO), "--config", str(DEMO_CONFIG), "--max-force-n", "150",
        "--stability", str(stability / "ubc_two_mode.toml"), "--out", str(out), "--json",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    printed = json.loads(done.stdout)
    assert printed["limits_hold"] is True
    moved = {
        row["line"]: row["new_rpm"] for row in printed["blocks"] if row["new_rpm"] != row["rpm"]
    }
    assert moved  # the roadmap moves some blocks off the programmed 8000 rpm
    # The interpreter reads the scheduled speed on every such block, the programmed one
    # (8000 rpm) back on the blocks after them.
    config = load_config(DEMO_CONFIG)
    segments = list(Interpreter(config.nc_setup()).run_file(out))
    source = {seg.line: seg for seg in segments}
    lines = out.read_text().splitlines()
    for number, seg in source.items():
        if seg.kind != MotionKind.LINEAR or seg.spindle_rpm == 3000.0:
            continue
        assert seg.spindle_rpm in {8000.0, *moved.values()}, lines[number - 1]
    assert {seg.spindle_rpm for seg in segments} >= set(moved.values())
