"""program_roadmap: an NC file's stability roadmap, against the same steps taken by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cnctwin.config import load_config
from cnctwin.dynamics import load_stability_config, program_roadmap, stability_roadmap
from cnctwin.errors import ConfigError, NCError
from cnctwin.geometry import Cutter, DexelStock, EngagementMap
from cnctwin.nc import Interpreter

SLOT = Path(__file__).parents[2] / "examples" / "stability" / "insperger_slot.toml"
CELL = """
[machine]
name = "test mill"
max_spindle_rpm = 24000.0

[[tools]]
number = 1
kind = "flat"
diameter_mm = 10.0
flutes = 2
helix_deg = 0.0
flute_length_mm = 20.0

[stock]
kind = "box"
min_mm = [0.0, 0.0, -10.0]
max_mm = [60.0, 40.0, 0.0]

[simulation]
density_per_mm = 5.0
"""
# Two full slots, 0.5 and 2 mm deep, at S10000.
PASSES = """G21 G90 G17 G94
T1 M6
S10000 M3
G0 X-10 Y10 Z5
G0 Z-0.5
G1 X70 F1000
G0 Z5
G0 X-10 Y30
G0 Z-2.0
G1 X70 F1000
G0 Z5
M30
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("roadmap")
    (folder / "cell.toml").write_text(CELL)
    (folder / "passes.ngc").write_text(PASSES)
    return folder / "passes.ngc", folder / "cell.toml"


def test_same_roadmap_as_the_steps_by_hand(files: tuple[Path, Path]) -> None:
    program, cell = files
    config, stability = load_config(cell), load_stability_config(SLOT)
    grid = np.linspace(8000.0, 12000.0, 81)
    found = program_roadmap(program, config, stability, grid, margin=1.5, step_mm=0.5)
    # The same pipeline written out: stock, cutters, interpreter, map, roadmap.
    stock = DexelStock.box((0.0, 0.0, -10.0), (60.0, 40.0, 0.0), 5.0)
    cutter = Cutter.flat(diameter_mm=10.0, flute_length_mm=20.0, flutes=2)
    speeds: dict[int, float] = {}
    segments = []
    for segment in Interpreter().run_file(program):
        speeds[segment.line] = segment.spindle_rpm
        segments.append(segment)
    emap = EngagementMap.build(segments, stock, {1: cutter}, step_mm=0.5)
    expected = stability_roadmap(
        emap, speeds, stability.tool_dynamics(), stability.coefficients(), {1: 2}, grid,
        margin=1.5, method=stability.lobes.method, max_depth_mm=stability.lobes.max_depth_mm,
        steps=stability.lobes.steps,
    )  # fmt: skip
    assert found.segments == expected.segments and len(found.segments) == 2
    assert np.array_equal(found.spindle_rpm, grid) and found.margin == 1.5
    for a, b in zip(found.lobes, expected.lobes, strict=True):
        assert np.array_equal(a.critical_depth_mm, b.critical_depth_mm)


def test_default_grid_is_the_files_range_every_10_rpm_capped_by_the_machine(
    files: tuple[Path, Path],
) -> None:
    program, cell = files
    stability = load_stability_config(SLOT)
    found = program_roadmap(program, load_config(cell), stability, step_mm=1.0)
    # [lobes] rpm = [5000, 25000]: 2001 speeds every 10 rpm, 1901 up to 24000 rpm.
    assert np.array_equal(found.spindle_rpm, np.arange(5000.0, 24000.1, 10.0))


def test_a_grid_above_the_machine_and_a_bad_program_are_refused(
    files: tuple[Path, Path], tmp_path: Path
) -> None:
    program, cell = files
    config, stability = load_config(cell), load_stability_config(SLOT)
    with pytest.raises(ConfigError, match=r"max_spindle_rpm=24000 is below .*\(25000 rpm\)"):
        program_roadmap(program, config, stability, np.array([25000.0, 26000.0]))
    bad = tmp_path / "bad.ngc"
    bad.write_text("G21 G90\nG1 X10 F100 Q\nM30\n")
    with pytest.raises(NCError) as caught:
        program_roadmap(bad, config, stability)
    assert caught.value.file == str(bad) and caught.value.line == 2
