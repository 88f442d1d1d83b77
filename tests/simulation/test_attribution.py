"""Attribution of a cut to the move that did it: no false collisions, every real one named.

A step that crossed a segment boundary used to be booked to the next segment: the material a
feed move left between its last cycle and its end point was "cut" by the first cycle of the
following rapid, so a straight retract after a cut was reported as a collision and its cut,
at the rapid rate's feed per tooth, became the headline force (issue 16). The sampler now
samples every segment's end; these tests check the shipped demo, a user's part with ramp
entry, arc slot and peck drilling at a 20 m/min rapid rate, and a planted collision, against
closed forms (the slot volume, Altintas' full-slot mean force).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from cnctwin.config import load_config
from cnctwin.drives import RAD_S_PER_RPM, spindle_preset
from cnctwin.geometry import Cutter, DexelStock
from cnctwin.mechanics import flat_end_mill_mean_forces, mean_forces
from cnctwin.mechanics.materials import milling_material
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.setup import NCSetup
from cnctwin.simulation import (
    COLUMNS,
    CutStep,
    StepTable,
    immersion_intervals,
    predict_program_signals,
    simulate_cut,
    simulate_program,
    simulate_signals,
    step_durations,
)
from cnctwin.simulation.signals import SPIKE_FACTOR, headline_warnings

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "cnctwin" / "examples"
DEMO, DEMO_CONFIG = EXAMPLES / "demo.ngc", EXAMPLES / "demo.toml"

# A user's part on the demo's machine and stock (G54 at the stock's top left corner, 80 x 60 x
# 20 mm), at a 20,000 mm/min rapid rate: a pocket entered on a ramp, an arc slot, and two peck
# drilled holes with the second tool. Every rapid runs above the stock or in what was cut.
PART = """G21 G17 G90 G94 G40 G49 G80
G54
G53 G0 Z0
T1 M6
G43 H1
S8000 M3
G4 P0.5
G0 X20 Y15
G0 Z2
G1 Z0 F300
(ramp entry)
G1 X40 Z-2 F400
G1 X20 Z-4
(pocket floor)
G1 X40 F800
G1 Y25
G1 X20
G1 Y15
G0 Z5
(arc slot)
G0 X60 Y30
G1 Z-2 F300
G2 X60 Y50 I0 J10 F600
G0 Z5
(peck drilling with T2)
G53 G0 Z0
T2 M6
G43 H2
S3000 M3
G0 X10 Y50
G0 Z5
G98 G83 X10 Y50 Z-12 R2 Q3 F200
X30
G80
G0 Z25
M5
G53 G0 Z0
M30
"""
# The planted collision: after the tool change, the second tool rapids down into the stock
# (line 32) and on through it (line 33) before it retracts (line 34, from inside the cut).
CRASH = PART.replace(
    "G0 X10 Y50\nG0 Z5\nG98 G83 X10 Y50 Z-12 R2 Q3 F200\nX30\nG80\n",
    "G0 X10 Y50\nG0 Z5\nG0 Z-5\nG0 X30\nG0 Z5\n",
)
CRASH_LINES = (32, 33)


@pytest.fixture(scope="module")
def part_config(tmp_path_factory: pytest.TempPathFactory) -> Path:
    text = DEMO_CONFIG.read_text()
    assert "rapid_mm_min = 12000.0" in text
    path = tmp_path_factory.mktemp("part") / "part.toml"
    path.write_text(text.replace("rapid_mm_min = 12000.0", "rapid_mm_min = 20000.0"))
    return path


def _program(tmp_path: Path, text: str, name: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _collisions(warnings: list[str]) -> list[str]:
    return [w for w in warnings if "collision" in w]


@pytest.mark.parametrize(("density", "cycle_s"), [(10.0, 0.0125), (20.0, 0.00625)])
def test_the_demo_has_no_collision(density: float, cycle_s: float) -> None:
    cut = simulate_program(DEMO, load_config(DEMO_CONFIG), density_per_mm=density, cycle_s=cycle_s)
    table = cut.table
    assert _collisions(cut.warnings) == []
    rapid = table.column("rapid") > 0
    assert not np.any(table.column("contact")[rapid] > 0)
    assert table.column("removed_mm3")[rapid].sum() == 0.0
    summary = cut.summary()
    assert abs(summary["volume_balance_mm3"]) < 1e-6
    # The last row is the program's end: the rows' durations add up to it.
    t = table.column("t_s")
    assert summary["process_time_s"] == t[-1] == pytest.approx(step_durations(t).sum())


def test_a_users_part_has_no_collision(tmp_path: Path, part_config: Path) -> None:
    config = load_config(part_config)
    program = _program(tmp_path, PART, "part.ngc")
    cut = simulate_program(program, config, density_per_mm=10.0, cycle_s=0.0125)
    assert _collisions(cut.warnings) == []
    predicted = predict_program_signals(program, config, density_per_mm=10.0, cycle_s=0.0125)
    assert predicted.signals.warnings == []
    # The largest force is a cut's: the ramp's and the floor's full slots at 800 mm/min give
    # about 250 N, not the 1,155 N the rapid retract gave when it was booked the cut.
    assert predicted.summary()["max_force_n"] < 300.0


def test_a_planted_collision_is_named_with_every_line(tmp_path: Path, part_config: Path) -> None:
    config = load_config(part_config)
    program = _program(tmp_path, CRASH, "crash.ngc")
    assert [CRASH.splitlines()[n - 1] for n in CRASH_LINES] == ["G0 Z-5", "G0 X30"]
    cut = simulate_program(program, config, density_per_mm=10.0, cycle_s=0.0125)
    (warning,) = _collisions(cut.warnings)
    assert warning.startswith(f"{program}:{CRASH_LINES[0]}: a rapid move cuts material")
    named = re.search(r"at lines ([\d, ]+)\)", warning)
    assert named is not None
    assert tuple(int(n) for n in named.group(1).split(", ")) == CRASH_LINES
    # The retract (line 34) rises through the hole the rapids cut: no contact of its own.
    table = cut.table
    hit = (table.column("rapid") > 0) & (table.column("contact") > 0)
    assert set(table.column("line")[hit].astype(int)) == set(CRASH_LINES)
    # The volume the warning names: the 6.8 mm tool's discs at the rapids' positions, 5 mm
    # deep (counted on a 0.02 mm pixel grid), below the continuous sweep from X10 to X30.
    x, y = table.column("x_mm")[hit], table.column("y_mm")[hit]
    gx, gy = np.meshgrid(np.arange(140.0, 190.0, 0.02), np.arange(140.0, 160.0, 0.02))
    inside = np.zeros(gx.shape, dtype=bool)
    for px, py in zip(x, y, strict=True):
        inside |= (gx - px) ** 2 + (gy - py) ** 2 <= 3.4**2
    discs = 5.0 * inside.sum() * 0.02**2
    volume = float(re.search(r"\(([\d.]+) mm\^3", warning).group(1))  # type: ignore[union-attr]
    assert volume == pytest.approx(discs, rel=0.02)
    assert volume < 5.0 * (6.8 * 20.0 + math.pi * 3.4**2)
    predicted = predict_program_signals(program, config, density_per_mm=10.0, cycle_s=0.0125)
    headline = [w for w in predicted.signals.warnings if "rapid move" in w]
    assert headline and "max_force_n" in headline[0]
    assert headline[0].startswith(f"line {CRASH_LINES[1]}:") or headline[0].startswith(
        f"line {CRASH_LINES[0]}:"
    )


def test_the_end_of_a_slot_belongs_to_its_feed_move() -> None:
    # A 6 mm flat end mill slots 3 mm deep from outside a block to x = 20.1 mm (a point off
    # the 0.125 mm cycle grid) and retracts at once. All the material is the G1's: a slot
    # 20.1 mm long plus the half disc at its end, within the dexel pitch.
    program = "G21 G90 G17\nT1 M6\nS10000 M3\nG0 X-5 Y10 Z5\nG0 Z-3\nG1 X20.1 F600\nG0 Z5\nM30\n"
    cutter = Cutter.flat(diameter_mm=6.0, flute_length_mm=15.0, flutes=2, helix_rad=0.5)
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), density_per_mm=10.0)
    before = stock.volume_mm3()
    table = StepTable()
    for rows in simulate_cut(
        Interpreter(NCSetup()).run_text(program), stock, {1: cutter}, rapid_mm_min=6000.0
    ):
        table.append(rows)
    line = table.column("line")
    removed = table.column("removed_mm3")
    assert set(line[removed > 0].astype(int)) == {6}
    expected = 3.0 * (6.0 * 20.1 + math.pi * 9.0 / 2.0)
    assert removed.sum() == pytest.approx(expected, rel=0.01)
    assert before - stock.volume_mm3() == pytest.approx(removed.sum(), abs=1e-6)
    # The slot's last row is its end point, between two cycle times; its rates are per its
    # own time, so the reconstructed feed is the programmed 600 mm/min.
    last = int(np.flatnonzero(line == 6)[-1])
    assert table.column("x_mm")[last] == pytest.approx(20.1)
    assert table.column("feed_mm_min")[last] == pytest.approx(600.0, rel=1e-6)
    assert len(COLUMNS) == len(table.columns)


def test_signals_of_the_demo_peak_in_a_feed_move() -> None:
    # The demo's hardest cut is the clearing loop's full slot: 10 mm, 3 flutes, ap 3 mm at
    # 800 mm/min and 8000 rpm; its mean force and power are Altintas' closed form.
    predicted = predict_program_signals(
        DEMO, load_config(DEMO_CONFIG), density_per_mm=10.0, cycle_s=0.0125
    )
    summary = predicted.summary()
    assert predicted.warnings == []
    coefficients = milling_material("AA6060-T6").coefficients
    fz_m = 800.0 / (8000.0 * 3) * 1e-3
    mean = flat_end_mill_mean_forces(
        coefficients, 3, 5e-3, 0.0, math.pi, 3e-3, fz_m, 8000.0 * RAD_S_PER_RPM
    )
    assert summary["max_mean_force_n"] == pytest.approx(math.hypot(mean.fx_n, mean.fy_n), rel=0.01)
    assert summary["max_power_w"] == pytest.approx(mean.power_w, rel=0.01)
    c = predicted.signals.columns
    k = int(np.argmax(c["f_peak_n"]))
    assert c["path_speed_mm_min"][k] == pytest.approx(800.0)


def _columns(values: list[float]) -> dict[str, np.ndarray]:
    n = len(values)
    columns = {name: np.zeros(n) for name in ("f_peak_n", "f_mean_n", "cutting_power_w")}
    columns["cutting_torque_nm"] = np.zeros(n)
    columns["f_peak_n"] = np.asarray(values, dtype=float)
    columns["t_s"] = np.arange(n) * 0.0125
    columns["line"] = np.arange(n) + 10.0
    return columns


def test_headline_from_a_single_step_spike_is_warned() -> None:
    columns = _columns([0.0, 100.0, 100.0, 3.0 * 100.0, 100.0, 0.0])
    (warning,) = headline_warnings(columns, np.zeros(6, dtype=bool))
    assert warning.startswith("line 13: max_force_n 300 N")
    assert "single-step spike" in warning
    # Just under the factor, and a plateau: no warning.
    columns = _columns([0.0, 100.0, 0.99 * SPIKE_FACTOR * 100.0, 100.0])
    assert headline_warnings(columns, np.zeros(4, dtype=bool)) == []
    columns = _columns([0.0, 250.0, 250.0, 250.0, 0.0])
    assert headline_warnings(columns, np.zeros(5, dtype=bool)) == []


def test_headline_from_a_rapid_is_warned() -> None:
    columns = _columns([0.0, 100.0, 120.0, 110.0])
    rapid = np.array([False, False, True, False])
    (warning,) = headline_warnings(columns, rapid)
    assert warning.startswith("line 12: max_force_n 120 N")
    assert "rapid move" in warning


def test_signals_of_a_slot_cut_by_a_rapid_warn() -> None:
    # A G0 along a slot the G1 cut, then on through the block: the rapid's own cut has the
    # rapid rate's feed per tooth, the largest force of the program, and is named.
    program = (
        "G21 G90 G17\nT1 M6\nS10000 M3\nG4 P0.2\nG0 X-5 Y10 Z5\nG0 Z-3\nG1 X10 F600\n"
        "G0 X45\nG0 Z5\nM30\n"
    )
    cutter = Cutter.flat(diameter_mm=6.0, flute_length_mm=15.0, flutes=2, helix_rad=0.5)
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), density_per_mm=5.0)
    signals = simulate_signals(
        Interpreter(NCSetup()).run_text(program),
        stock,
        {1: cutter},
        milling_material("AA6060-T6").coefficients,
        spindle_preset("machining-centre-15kw"),
        rapid_mm_min=6000.0,
    )
    assert any(w.startswith("line 8:") and "rapid move" in w for w in signals.warnings)
    # The time sums are weighted by each row's time: the program lasts what its moves take.
    duration = (math.sqrt(150.0) + 8.0 + 35.0 + 8.0) / 100.0 + 15.0 / 10.0 + 0.2
    summary = signals.summary()
    assert summary["process_time_s"] == pytest.approx(duration)
    assert summary["cutting_time_s"] <= summary["process_time_s"]


def test_a_later_layer_along_a_cornered_wall_cuts_only_its_own_layer() -> None:
    # Two 1 mm layers of an L-shaped slot (a 90 degree corner between two G1s), the second at
    # another feed, so its positions do not fall where the first layer's did. A step that
    # spanned the corner would cut the chord, leave a sliver of the corner's material on the
    # wall above the second layer, and the second layer would read that sliver as a cut of the
    # whole wall: ap 2 mm and up to twice the force for one step (issue 16, cnctwin optimize).
    # With the corner sampled, every step of the second layer cuts its own 1 mm: ap within a
    # pitch of 1 mm, and no step's mean force above Altintas' full-slot mean force at 1 mm.
    program = (
        "G21 G90 G17\nT1 M6\nS10000 M3\nG0 X-5 Y5 Z5\nG0 Z-1\nG1 X20 F610\nG1 Y30\nG0 Z5\n"
        "G0 X-5 Y5\nG0 Z-2\nG1 X20 F467\nG1 Y30\nG0 Z5\nM30\n"
    )
    cutter = Cutter.flat(diameter_mm=6.0, flute_length_mm=15.0, flutes=2, helix_rad=0.5)
    stock = DexelStock.box((0.0, 0.0, -10.0), (30.0, 30.0, 0.0), density_per_mm=10.0)
    coefficients = milling_material("AA6060-T6").coefficients
    omega = 10000.0 * RAD_S_PER_RPM
    means: list[float] = []

    def observe(step: CutStep) -> None:
        if step.line in (11, 12):
            cut = immersion_intervals(step.engagement, stock.grid.pitch_mm[2])
            if cut is not None:
                f = mean_forces(cutter, coefficients, cut, step.feed_per_tooth_mm * 1e-3, omega)
                means.append(math.hypot(f.fx_n, f.fy_n))

    table = StepTable()
    for rows in simulate_cut(
        Interpreter(NCSetup()).run_text(program),
        stock,
        {1: cutter},
        rapid_mm_min=6000.0,
        on_step=observe,
    ):
        table.append(rows)
    line = table.column("line").astype(int)
    contact = table.column("contact") > 0
    ap = table.column("ap_mm")
    second = contact & ((line == 11) | (line == 12))
    assert second.sum() > 100
    assert ap[second].max() <= 1.0 + 0.1 + 1e-6
    slot = flat_end_mill_mean_forces(
        coefficients, 2, 3e-3, 0.0, math.pi, 1e-3, 467.0 / (10000.0 * 2) * 1e-3, omega
    )
    assert max(means) <= 1.02 * math.hypot(slot.fx_n, slot.fy_n)
    # The first layer's corner is a step's end of its own.
    x, y = table.column("x_mm"), table.column("y_mm")
    at_corner = (np.abs(x - 20.0) < 1e-9) & (np.abs(y - 5.0) < 1e-9)
    assert at_corner.sum() == 2
