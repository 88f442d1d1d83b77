"""``cnctwin simulate`` end to end on small programs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest


def _cnctwin(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cnctwin", *args], capture_output=True, text=True, timeout=300
    )


CONFIG = """
[machine]
rapid_mm_min = 6000.0

[[tools]]
number = 1
kind = "flat"
diameter_mm = 6.0
flute_length_mm = 15.0
flutes = 2

[stock]
min_mm = [0.0, 0.0, -10.0]
max_mm = [40.0, 20.0, 0.0]

[simulation]
density_per_mm = 5.0
cycle_ms = 12.5
"""

# A 3 mm deep full slot along y = 10 from x = -5 to x = 45 at 600 mm/min.
PROGRAM = """G21 G90 G17
T1 M6
S10000 M3
G0 X-5 Y10 Z5
G0 Z-3
G1 X45 F600
G0 Z5
M30
"""


def test_slot_volume_and_engagement(tmp_path: Path) -> None:
    config, program, out = tmp_path / "cell.toml", tmp_path / "slot.ngc", tmp_path / "run"
    config.write_text(CONFIG)
    program.write_text(PROGRAM)
    done = _cnctwin("simulate", str(program), "--config", str(config), "--json", "--out", str(out))
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    # The slot through the 40 mm block: width 6 x depth 3 x length 40 mm = 720 mm^3 (the
    # dexel pitch of 0.2 mm blurs the round ends, which lie outside the block here).
    assert report["removed_volume_mm3"] == pytest.approx(720.0, rel=0.03)
    assert abs(report["volume_balance_mm3"]) < 1e-6
    assert report["max_ap_mm"] == pytest.approx(3.0, abs=0.21)
    assert report["max_ae_mm"] == pytest.approx(6.0, abs=0.21)
    rows = np.genfromtxt(out / "engagement.csv", delimiter=",", names=True)
    assert rows.size == report["steps"]
    cutting = rows[rows["contact"] > 0]
    # Full slot at 600 mm/min: MRR = 6 x 3 x 10 mm/s = 180 mm^3/s (per-step values scatter
    # with the 0.2 mm pitch against the 0.125 mm step; their median is the steady state).
    assert np.median(cutting["mrr_mm3_s"]) == pytest.approx(180.0, rel=0.05)
    assert np.median(cutting["feed_per_tooth_mm"]) == pytest.approx(600 / (10000 * 2))
    stl = (out / "stock.stl").read_bytes()
    triangles = int.from_bytes(stl[80:84], "little")
    # The default 0.5 mm: cells of two 0.2 mm dexels, 100 x 50 of them on the 40 x 20 mm block,
    # 2 (100 + 1)(50 + 1) + 6 (100 + 50 + 2) triangles.
    assert len(stl) == 84 + 50 * triangles and triangles == 2 * 101 * 51 + 6 * 152


def test_stl_options(tmp_path: Path) -> None:
    config, program, out = tmp_path / "cell.toml", tmp_path / "slot.ngc", tmp_path / "run"
    config.write_text(CONFIG)
    program.write_text(PROGRAM)
    args = ["simulate", str(program), "--config", str(config), "--out", str(out), "--json"]
    done = _cnctwin(*args, "--stl-resolution-mm", "2", "--stl-ascii")
    assert done.returncode == 0, done.stderr
    text = (out / "stock.stl").read_text()
    # 2 mm cells: 20 x 10 of them.
    assert text.startswith("solid cnctwin stock after slot.ngc\n")
    assert text.count("endfacet") == 2 * 21 * 11 + 6 * 32
    done = _cnctwin(*args, "--stl-resolution-mm", "0")
    assert done.returncode == 2
    assert done.stderr.strip() == (
        "--stl-resolution-mm 0.0: give a resolution > 0 mm (below the dexel pitch: the pitch)"
    )


def test_missing_tool_geometry_names_the_line(tmp_path: Path) -> None:
    config, program = tmp_path / "cell.toml", tmp_path / "slot.ngc"
    config.write_text(CONFIG)
    program.write_text(PROGRAM.replace("T1 M6", "T2 M6"))
    done = _cnctwin("simulate", str(program), "--config", str(config))
    assert done.returncode == 2
    assert done.stderr.strip().startswith(f"{program}:4: tool T2 has no geometry")


@pytest.mark.validation
def test_camotics_project(shared_data: Path) -> None:
    folder = shared_data / "gcode" / "camotics" / "scorpion"
    done = _cnctwin(
        "simulate",
        str(folder / "scorpion.nc"),
        "--config",
        str(folder / "scorpion.camotics"),
        "--json",
        "--density",
        "5",
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["removed_volume_mm3"] > 0 and abs(report["volume_balance_mm3"]) < 1e-6
