"""``cnctwin signals`` end to end: a small slot program, its CSV, plot, JSON and errors."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cnctwin.mechanics import flat_end_mill_mean_forces
from cnctwin.mechanics.materials import milling_material
from cnctwin.simulation.signals import SIGNAL_COLUMNS

REPO = Path(__file__).resolve().parents[2]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _cnctwin(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cnctwin", *args], capture_output=True, text=True, timeout=300
    )


CONFIG = """
[machine]
rapid_mm_min = 6000.0

[machine.spindle]
preset = "machining-centre-15kw"
rated_power_kw = 15.0

[[tools]]
number = 1
kind = "flat"
diameter_mm = 6.0
flute_length_mm = 15.0
flutes = 2
helix_deg = 30.0

[stock]
min_mm = [0.0, 0.0, -10.0]
max_mm = [40.0, 20.0, 0.0]

[material]
name = "AA6060-T6"

[simulation]
density_per_mm = 5.0
"""

# A 3 mm deep full slot along y = 10 from x = -5 to x = 45 at 600 mm/min, 10,000 rpm.
PROGRAM = """G21 G90 G17
T1 M6
S10000 M3
G0 X-5 Y10 Z5
G0 Z-3
G1 X45 F600
G0 Z5
M5
M30
"""


def _files(tmp_path: Path, config: str = CONFIG, program: str = PROGRAM) -> tuple[Path, Path]:
    cfg, prog = tmp_path / "cell.toml", tmp_path / "slot.ngc"
    cfg.write_text(config)
    prog.write_text(program)
    return cfg, prog


def test_slot_csv_plot_and_json(tmp_path: Path) -> None:
    config, program = _files(tmp_path)
    out, plot = tmp_path / "run", tmp_path / "elsewhere.png"
    done = _cnctwin("signals", str(program), "--config", str(config), "--out", str(out), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    for key in ("max_force_n", "mean_power_w", "max_spindle_torque_nm", "process_time_s"):
        assert isinstance(report[key], float) and report[key] > 0.0, key
    assert report["spindle_drive"] == "machining-centre-15kw"
    assert report["material"] == "AA6060-T6" and report["overload_steps"] == 0
    assert json.loads((out / "summary.json").read_text()) == report
    with (out / "signals.csv").open() as handle:
        rows = list(csv.reader(handle))
    assert tuple(rows[0]) == SIGNAL_COLUMNS
    assert len(rows) - 1 == report["steps"]
    # The program's duration: rapids at 100 mm/s (sqrt(150), 8 and 8 mm), 50 mm at 10 mm/s.
    assert report["process_time_s"] == pytest.approx((math.sqrt(150.0) + 16.0) / 100.0 + 5.0)
    assert (out / "signals.png").read_bytes()[:8] == PNG_MAGIC
    # The steady slot: Altintas' closed form (tests/simulation/test_signals.py checks it per step).
    data = np.array(rows[1:], dtype=float)
    c = {name: data[:, k] for k, name in enumerate(SIGNAL_COLUMNS)}
    steady = (c["contact"] > 0) & (c["x_mm"] > 3.5) & (c["x_mm"] < 36.5)
    mean = flat_end_mill_mean_forces(
        milling_material("AA6060-T6").coefficients, 2, 3e-3, 0.0, math.pi, 3e-3,
        600.0 / (10_000.0 * 2) * 1e-3, 10_000.0 * math.pi / 30.0,
    )  # fmt: skip
    assert np.median(c["cutting_torque_nm"][steady]) == pytest.approx(mean.torque_nm, rel=0.01)
    assert np.median(c["fy_n"][steady]) == pytest.approx(mean.fy_n, rel=0.02)
    assert report["max_spindle_torque_nm"] == pytest.approx(mean.torque_nm, rel=0.05)
    # --plot puts the plot where it is asked for.
    done = _cnctwin("signals", str(program), "--config", str(config), "--plot", str(plot))
    assert done.returncode == 0, done.stderr
    assert plot.read_bytes()[:8] == PNG_MAGIC
    assert "max cutting torque" in done.stdout


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            ('name = "AA6060-T6"', 'name = "unobtainium"'),
            "material.name: no milling material 'unobtainium'; valid: AA6060-T6",
        ),
        (("flute_length_mm = 15.0\n", ""), "tool 1 has no flute_length_mm"),
        (
            ('preset = "machining-centre-15kw"', 'preset = "nakanishi"'),
            "machine.spindle.preset: spindle preset 'nakanishi' is unknown",
        ),
    ],
)
def test_config_errors_are_one_line(tmp_path: Path, change: tuple[str, str], message: str) -> None:
    config, program = _files(tmp_path, CONFIG.replace(*change))
    done = _cnctwin("signals", str(program), "--config", str(config), "--json")
    assert done.returncode == 2
    assert done.stdout == ""
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message), done.stderr


def test_tool_without_geometry_names_the_line(tmp_path: Path) -> None:
    config, program = _files(tmp_path, program=PROGRAM.replace("T1 M6", "T2 M6"))
    done = _cnctwin("signals", str(program), "--config", str(config))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{program}:4: tool T2 has no geometry")


@pytest.mark.validation
def test_kit_notch_program(shared_data: Path, tmp_path: Path) -> None:
    """The KIT DMC 60H notch program (aluminium, F350 S3800, 10 mm 4-flute tool assumed).

    Its first pass opens with a 6 mm deep full slot (line 16) whose steady cut must give
    Altintas' closed form, and whose cutting power is Ktc MRR plus the edge power.
    """
    program = shared_data / "gcode" / "siemens_kit_dmc60h" / "AL_2007_T4_Notch_Normal.mpf"
    out = tmp_path / "notch"
    done = _cnctwin(
        "signals", str(program), "--config", str(REPO / "examples" / "kit_dmc60h_al2007.toml"),
        "--out", str(out), "--json", "--density", "5",  # 0.2 mm: the 6 mm passes on grid planes
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    data = np.genfromtxt(out / "signals.csv", delimiter=",", names=True)
    slot = data[(data["line"] == 16) & (data["contact"] > 0) & (data["x_mm"] > 5.5)]
    assert slot.size > 300
    fz_m = 350.0 / (3800.0 * 4) * 1e-3
    omega = 3800.0 * math.pi / 30.0
    k = milling_material("AA6060-T6").coefficients
    mean = flat_end_mill_mean_forces(k, 4, 5e-3, 0.0, math.pi, 6e-3, fz_m, omega)
    assert np.median(slot["cutting_torque_nm"]) == pytest.approx(mean.torque_nm, rel=0.01)
    mrr_m3_s = 10e-3 * 6e-3 * 350e-3 / 60.0  # 350 mm^3/s
    edge_w = 4 * 6e-3 * 0.5 * k.kte * 5e-3 * omega
    assert np.median(slot["cutting_power_w"]) == pytest.approx(k.ktc * mrr_m3_s + edge_w, rel=0.01)
    assert report["overload_steps"] == 0
    assert report["min_cutting_speed_rpm"] > 0.99 * 3800.0


def test_a_cut_through_the_stock_bottom_runs(tmp_path: Path) -> None:
    # The demo cell (a 10 mm, 3 flute end mill in a 20 mm block of AA6060-T6) slotting with
    # its tip 4.5 mm under the block's bottom: the cut from a raster pocket's deep layers that
    # stopped with exit 2 ("z_bounds_m from 0.0045...; give increasing heights"). The full
    # slot's mean force is Altintas' closed form at ap = 17.5 mm (the block's 20 mm less the
    # 2.5 mm above the flutes' end at 22 mm).
    program = tmp_path / "through.ngc"
    program.write_text(
        "G21 G17 G90 G94 G40 G49 G80\nG54\nG53 G0 Z0\nT1 M6\nG43 H1\nS8000 M3\n"
        "G0 X-8 Y30\nG0 Z-24.5\nG1 X10 F800\nG0 Z5\nM5\nM30\n"
    )
    demo = REPO / "src" / "cnctwin" / "examples" / "demo.toml"
    done = _cnctwin("signals", str(program), "-c", str(demo), "--json")
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    mean = flat_end_mill_mean_forces(
        milling_material("AA6060-T6").coefficients, 3, 5e-3, 0.0, math.pi, 17.5e-3,
        800.0 / (8000.0 * 3) * 1e-3, 8000.0 * math.pi / 30.0,
    )  # fmt: skip
    assert report["max_mean_force_n"] == pytest.approx(mean.resultant_n, rel=0.02)
    assert report["max_spindle_torque_nm"] == pytest.approx(mean.torque_nm, rel=0.05)
