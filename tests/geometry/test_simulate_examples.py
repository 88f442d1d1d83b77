"""Real programs through the stock (``cnctwin simulate``): removed volumes against independent
computations.

The programs are in ``../shared/data/gcode`` (Fusion 360 and CAMotics examples); the Fusion 360
program runs with its configuration in ``examples/fusion360`` (the tool its comment states),
the CAMotics one with its project. Both run at 10 dexels/mm and 12.5 ms, as by default.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cnctwin.config import load_config
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.segments import MotionKind
from cnctwin.simulation import simulate_program

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
DENSITY = 10.0  # /mm
CYCLE_S = 0.0125


@pytest.mark.validation
def test_fusion_block_contour(shared_data: Path) -> None:
    # 1024_block_14bit.nc: a 1.4 mm flat end mill contours a 20 x 20 mm block in three 1 mm
    # layers, its axis on the square from -0.7 to 20.7 mm. The stock (its configuration) spans
    # -1.4 to 21.4 mm, 3 mm deep: the cut leaves the block and the stock's four corners the
    # tool's round side does not reach, (4 - pi) r^2 each.
    program = shared_data / "gcode" / "fusion360_grbl_shooshx" / "1024_block_14bit.nc"
    config = load_config(EXAMPLES / "fusion360" / "1024_block_14bit.toml")
    cut = simulate_program(program, config, density_per_mm=DENSITY, cycle_s=CYCLE_S)
    report = cut.summary()
    r = 0.7
    expected = 3.0 * (22.8**2 - 20.0**2 - (4.0 - math.pi) * r * r)
    # The discrete positions (steps s = 1000 mm/min x 12.5 ms) leave scallops at most
    # s^2 / 8r deep on the block's 240 mm^2 of wall; the block's faces lie on cell boundaries.
    step = 1000.0 / 60.0 * CYCLE_S
    assert report["removed_volume_mm3"] == pytest.approx(expected, abs=step**2 / (8 * r) * 240)
    assert abs(report["volume_balance_mm3"]) < 1e-6
    assert report["max_ae_mm"] <= 1.4 + 1e-6
    # The program's time: 282.8 mm at 1000 or 333.3 mm/min and 11 mm of rapids, 18.0 s.
    assert report["process_time_s"] == pytest.approx(18.0, abs=CYCLE_S)
    ap_mm = cut.table.column("ap_mm")
    cutting = ap_mm[
        (cut.table.column("contact") > 0) & (cut.table.column("path_speed_mm_min") > 999.0)
    ]
    # Each layer cuts 1 mm along the walls the layer above left: ap is the layer's 1 mm, not
    # the wall's height (only the short first steps after a corner, where the layer above
    # left a cusp deeper than such a step's thin-material threshold, see more: 2 of 1242).
    assert np.median(cutting) == pytest.approx(1.0, abs=1e-4)
    assert np.mean(np.abs(cutting - 1.0) < 1e-4) > 0.99


def _swept_area_mm2(points: np.ndarray, radius: float, pixel: float) -> float:
    """Area (mm^2) swept by a disc of ``radius`` moving continuously along a polyline (n, 2):
    the pixels (of side ``pixel``) within ``radius`` of any of its segments, counted once."""
    low = points.min(axis=0) - radius - pixel
    high = points.max(axis=0) + radius + pixel
    nx, ny = np.ceil((high - low) / pixel).astype(int)
    covered = np.zeros((ny, nx), dtype=bool)
    for p, q in zip(points[:-1], points[1:], strict=True):
        i0, j0 = np.floor((np.minimum(p, q) - radius - low) / pixel).astype(int)
        i1, j1 = np.ceil((np.maximum(p, q) + radius - low) / pixel).astype(int)
        x, y = np.meshgrid(
            low[0] + (np.arange(i0, i1) + 0.5) * pixel, low[1] + (np.arange(j0, j1) + 0.5) * pixel
        )
        d = q - p
        length2 = float(d @ d)
        t = np.clip(((x - p[0]) * d[0] + (y - p[1]) * d[1]) / length2, 0.0, 1.0) if length2 else 0
        near = (x - p[0] - t * d[0]) ** 2 + (y - p[1] - t * d[1]) ** 2 <= radius * radius
        covered[j0:j1, i0:i1] |= near
    return float(covered.sum()) * pixel * pixel


@pytest.mark.validation
def test_camotics_scorpion_engraving(shared_data: Path) -> None:
    # scorpion.nc: one contour of straight moves, 3 mm deep (the stock's full depth) with a
    # 1 mm flat end mill at 1800 mm/min. The continuous cut is the area a 1 mm disc sweeps
    # along the path times 3 mm, rasterised here at 0.025 mm.
    folder = shared_data / "gcode" / "camotics" / "scorpion"
    config = load_config(folder / "scorpion.camotics")
    report = simulate_program(
        folder / "scorpion.nc", config, density_per_mm=DENSITY, cycle_s=CYCLE_S
    ).summary()
    segments = list(Interpreter(config.nc_setup()).run_file(folder / "scorpion.nc"))
    assert all(s.kind in (MotionKind.LINEAR, MotionKind.RAPID) for s in segments)
    cut = [s for s in segments if s.kind == MotionKind.LINEAR and s.tcp_end_mm[2] <= -3.0 + 1e-9]
    path = np.array([cut[0].tcp_start_mm[:2]] + [s.tcp_end_mm[:2] for s in cut])
    radius = 0.5
    continuous = 3.0 * _swept_area_mm2(path, radius, 0.025)
    # Discrete positions a step s apart take pi r^2 less the lens two discs s apart share per
    # step, instead of 2 r s (Heide 2025, Fig. 7a): 97.6 % at s = 0.375 mm; slower steps (the
    # corners, the plunge) lose less. 1 % more either way for the dexel and pixel grids.
    s = 1800.0 / 60.0 * CYCLE_S
    lens = 2 * radius**2 * math.acos(s / (2 * radius)) - s / 2 * math.sqrt(4 * radius**2 - s * s)
    ratio = (math.pi * radius**2 - lens) / (2 * radius * s)
    removed = report["removed_volume_mm3"]
    assert continuous * ratio * 0.99 <= removed <= continuous * 1.01
    assert abs(report["volume_balance_mm3"]) < 1e-6
    assert report["max_ae_mm"] <= 1.0 + 1e-6 and report["max_ap_mm"] <= 3.0 + 1e-4
