"""``cnctwin wear ekf`` from the command line."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path


def _cnctwin(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cnctwin", *args], capture_output=True, text=True, timeout=120
    )


def test_synthetic_run_reports_errors_and_writes_files(tmp_path: Path) -> None:
    out, png = tmp_path / "estimate.csv", tmp_path / "ekf.png"
    done = _cnctwin(
        "wear", "ekf", "--synthetic", "--seed", "3", "--json", "--out", str(out), "--plot", str(png)
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["steps"] == 14000
    assert report["mean_abs_error_mm"] < 0.038  # Christiand 2024, Table 7
    assert [e["stage"] for e in report["stage_events"]] == [2, 3, 4]
    assert out.read_text().splitlines()[0].startswith("time_s,vb_mm,sd_mm")
    assert png.stat().st_size > 10_000


def test_csv_with_truth_and_missed_samples(tmp_path: Path) -> None:
    data = tmp_path / "run.csv"
    rows = ["time_s,torque_nm,material_removed_mm3,vb_mm"]
    for k in range(1, 201):
        torque = "" if k % 10 == 0 else "0.0035"
        rows.append(f"{k * 0.01:.2f},{torque},0.0004,0.1")
    data.write_text("\n".join(rows) + "\n")
    done = _cnctwin("wear", "ekf", "--data", str(data), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["steps"] == 200 and math.isfinite(report["max_abs_error_mm"])


def test_bad_input_is_one_line_with_the_place(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,torque_nm,material_removed_mm3\n0.01,0.003,0.0004\n0.02,abc,0.0004\n")
    done = _cnctwin("wear", "ekf", "--data", str(bad))
    assert done.returncode == 2
    assert done.stderr.strip() == f"{bad}:3: column torque_nm: 'abc' is not a number"
    missing = tmp_path / "missing.csv"
    missing.write_text("time_s,torque_nm\n0.01,0.003\n")
    done = _cnctwin("wear", "ekf", "--data", str(missing))
    assert done.returncode == 2 and "material_removed_mm3" in done.stderr
    both = _cnctwin("wear", "ekf", "--data", str(bad), "--synthetic")
    assert both.returncode == 2 and "exactly one" in both.stderr
