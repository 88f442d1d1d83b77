"""Drilling and tapping end to end: the shipped peck-drilling example through the signals
prediction, the virtual machine and the twin's physics give the thrust and torque of the
closed form (cnctwin.mechanics.drilling_load, itself checked against published references in
test_drilling.py) at the steady bottom of the hole; bad drill and tap configurations are one
line naming the value."""

from __future__ import annotations

import math
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from cnctwin.config import MachiningConfig, load_config
from cnctwin.errors import ConfigError
from cnctwin.mechanics import drilling_load, drilling_material, tapping_torque
from cnctwin.simulation import predict_program_signals, step_durations
from cnctwin.twin import TwinPhysics
from cnctwin.virtual import NoiseConfig, VirtualMachine, VirtualMachineConfig

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "drilling"
PROGRAM = EXAMPLES / "peck.ngc"
CONFIG = EXAMPLES / "drilling.toml"
RAD_S_PER_RPM = 2.0 * math.pi / 60.0

#: The example's drill: 8.5 mm, 118 deg, 1.2 mm web, 2 lips, at 2000 rpm and 300 mm/min.
DRILL_RPM = 2000.0
DRILL_FEED_MM_REV = 300.0 / DRILL_RPM


def _steady_drill() -> tuple[float, float]:
    """Closed-form thrust (N) and torque (N m) of the example's drill at full depth."""
    load = drilling_load(
        drilling_material("AA6060-T6"),
        8.5e-3,
        DRILL_FEED_MM_REV * 1e-3,
        point_angle_rad=math.radians(118.0),
        web_m=1.2e-3,
        lips=2,
    )
    return load.thrust_n, load.torque_nm


@pytest.fixture(scope="module")
def config() -> MachiningConfig:
    return load_config(CONFIG)


def test_peck_example_signals_match_the_closed_form(config: MachiningConfig) -> None:
    """G83 peck drilling: most drilling steps are at the steady bottom, where Fz, the torque and
    the power are the closed form's; the G84 tap gives the tapping torque and no warning."""
    result = predict_program_signals(PROGRAM, config, density_per_mm=10.0, cycle_s=0.0125)
    columns = result.signals.columns
    tool = columns["tool"]
    cutting = columns["contact"] > 0
    drill = cutting & (tool == 1)
    thrust, torque = _steady_drill()
    steady = np.isclose(columns["fz_n"], thrust, rtol=1e-9) & drill
    # The hole's steady bottom is most of the drill's cutting (pecks re-enter at full depth).
    assert steady.sum() > 0.6 * drill.sum() > 0
    assert columns["cutting_torque_nm"][steady] == pytest.approx(torque, rel=1e-9)
    assert columns["cutting_power_w"][steady] == pytest.approx(
        torque * DRILL_RPM * RAD_S_PER_RPM, rel=1e-9
    )
    assert np.all(columns["fz_n"][drill] <= thrust * (1 + 1e-9))
    assert np.all(columns["fx_n"][drill] == 0.0)
    # Entering, the point engages from the centre out: some steps carry a partial load.
    assert np.any((columns["fz_n"][drill] > 0) & (columns["fz_n"][drill] < 0.99 * thrust))
    # Several pecks per hole: the drill enters material in separate runs of contact steps.
    starts = np.flatnonzero(np.diff(drill.astype(int)) == 1)
    assert len(starts) >= 6  # two holes, 14 mm deep in 4 mm pecks
    tap = cutting & (tool == 2)
    expected_tap = tapping_torque(drilling_material("AA6060-T6"), 10e-3, 1.5e-3)
    assert tap.sum() > 0
    assert Counter(np.round(columns["cutting_torque_nm"][tap], 9)).most_common(1)[0][0] == (
        pytest.approx(expected_tap, rel=1e-9)
    )
    assert np.all(columns["fz_n"][tap] == 0.0)
    assert not any("tap" in w for w in result.warnings)
    assert result.summary()["max_force_n"] == pytest.approx(thrust, rel=1e-9)
    assert "Yamawa" in result.summary()["drilling_coefficients_source"]
    # The material removed is the holes' closed-form volume: two 8.5 mm holes with a 118 deg
    # point at 14 mm depth (cylinder to the point's top plus the cone) and the taps' annulus
    # from 8.5 to 10 mm over 10 mm (the tap's envelope is its nominal cylinder).
    cone_h = 4.25 / math.tan(math.radians(59.0))
    hole = math.pi * 4.25**2 * (14.0 - cone_h) + math.pi * 4.25**2 * cone_h / 3.0
    thread = math.pi * (5.0**2 - 4.25**2) * 10.0
    removed = float(np.sum(columns["mrr_mm3_s"] * step_durations(columns["t_s"])))
    assert removed == pytest.approx(2.0 * (hole + thread), rel=0.02)


def test_tap_feed_off_its_pitch_is_warned(tmp_path: Path, config: MachiningConfig) -> None:
    text = PROGRAM.read_text().replace("F750", "F700")
    program = tmp_path / "peck.ngc"
    program.write_text(text)
    line = next(n for n, t in enumerate(text.splitlines(), 1) if "F700" in t)
    result = predict_program_signals(program, config, density_per_mm=5.0, cycle_s=0.0125)
    warned = [w for w in result.warnings if "tap T2" in w]
    assert warned and f"line {line}:" in warned[0] and "1.4 mm per revolution" in warned[0]


_PLUNGE = """G21 G90 G94 G54
T1 M6
G43 H1
S2000 M3
G4 P1
G0 X12 Y15 Z2
G1 Z-8 F300
G0 Z10
M30
"""


def test_virtual_machine_drills_with_the_same_model(tmp_path: Path) -> None:
    """The virtual machine's dynamometer reads the drill's thrust on the workpiece (-Fz) and
    its spindle carries the drilling torque, at the closed form's values at full depth."""
    program = tmp_path / "plunge.ngc"
    program.write_text(_PLUNGE)
    quiet = NoiseConfig(
        position_mm=0.0, feed_mm_min=0.0, spindle_rpm=0.0, force_n=0.0, torque_nm=0.0,
        current_a=0.0, power_w=0.0, load_pct=0.0,
    )  # fmt: skip
    vm = VirtualMachine(VirtualMachineConfig(program=program, physics_config=CONFIG, noise=quiet))
    forces, torques, feeds = [], [], []
    while not vm.finished:
        vm.step(vm.tick_s)
        snapshot = vm.snapshot()
        forces.append(snapshot["force_z_n"])
        torques.append(snapshot["spindle_torque_nm"])
        feeds.append(snapshot["feed_mm_min"])
        assert vm.time_s < 60.0
    thrust, torque = _steady_drill()
    forces_n = -np.asarray(forces)
    # At 2000 rpm (the spindle is at speed after the dwell) the steady plunge is the closed form.
    steady = np.isclose(forces_n, thrust, rtol=0.01)
    assert steady.sum() > 50
    assert forces_n.max() <= thrust * 1.01
    # The spindle motor carries the drilling torque on top of its idle (friction) torque: the
    # idle torque is read while the spindle turns at speed before the plunge reaches the stock.
    torques_nm = np.asarray(torques)
    first_cut = int(np.argmax(forces_n > 0.0))
    idle = (np.arange(len(torques_nm)) < first_cut) & (np.asarray(feeds) > 0.0)
    extra = np.median(torques_nm[steady]) - np.median(torques_nm[idle])
    assert extra == pytest.approx(torque, rel=0.05)


def test_twin_physics_drills_with_the_same_model(config: MachiningConfig) -> None:
    physics = TwinPhysics(config, density_per_mm=10.0)
    thrust, torque = _steady_drill()
    feed_mm_min, dt = DRILL_FEED_MM_REV * DRILL_RPM, 0.0125
    lo = config.stock.min_mm
    hi = config.stock.max_mm
    x, y = lo[0] + 12.0, lo[1] + 15.0
    loads = []
    for z in np.arange(hi[2] + 1.0, hi[2] - 8.0, -feed_mm_min / 60.0 * dt):
        engagement, fz = physics.cut(np.array((x, y, z)), 1, DRILL_RPM, feed_mm_min, dt)
        if engagement is not None and engagement.contact:
            loads.append(physics.forces(engagement, 1, DRILL_RPM, fz))
    assert loads[-1].fz_n == pytest.approx(thrust, rel=1e-9)
    assert loads[-1].torque_nm == pytest.approx(torque, rel=1e-9)
    assert loads[0].fz_n < 0.5 * thrust  # the point entering


@pytest.mark.parametrize(
    ("tool", "fragment"),
    [
        ({"kind": "tap", "diameter_mm": 10.0}, "pitch"),
        ({"kind": "tap", "diameter_mm": 10.0, "pitch_mm": 6.0}, "pitch"),
        ({"kind": "drill", "diameter_mm": 8.0, "web_mm": 8.0}, "web"),
        ({"kind": "flat", "diameter_mm": 8.0, "web_mm": 1.0}, "web"),
        ({"kind": "flat", "diameter_mm": 8.0, "pitch_mm": 1.0}, "pitch"),
        ({"kind": "tap", "diameter_mm": 8.0, "pitch_mm": 1.25, "tip_angle_deg": 90.0}, "tip_angle"),
    ],
)
def test_bad_drill_and_tap_configurations_name_the_value(
    tmp_path: Path, tool: dict[str, object], fragment: str
) -> None:
    path = tmp_path / "bad.toml"
    entries = "\n".join(f"{k} = {v!r}".replace("'", '"') for k, v in tool.items())
    path.write_text(f"[[tools]]\nnumber = 1\nflute_length_mm = 20.0\n{entries}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    message = str(err.value)
    assert "\n" not in message and f"tools[0].{fragment}" in message


def test_drill_default_point_angle_and_envelope() -> None:
    from cnctwin.config import ToolConfig
    from cnctwin.geometry import Cutter

    tool = ToolConfig(number=1, kind="drill", diameter_mm=10.0, flute_length_mm=40.0)
    cutter = Cutter.from_tool_config(tool)
    assert tool.tip_angle_deg == 118.0
    # The point is a cone of the point angle: its height R / tan(59 deg).
    assert cutter.cone_height_mm == pytest.approx(5.0 / math.tan(math.radians(59.0)))
    assert float(cutter.radius_at(1.0)) == pytest.approx(math.tan(math.radians(59.0)))


def test_cli_exit_2_for_a_tap_without_pitch_and_a_material_without_drilling_data(
    tmp_path: Path,
) -> None:
    text = CONFIG.read_text()
    cases = {
        "nopitch.toml": (text.replace("pitch_mm = 1.5\n", ""), "pitch"),
        "nodata.toml": (
            text.replace('name = "AA6060-T6"', 'name = "kistler-slot-6000rpm"'),
            "no drilling coefficients for material 'kistler-slot-6000rpm'",
        ),
    }
    for name, (body, fragment) in cases.items():
        path = tmp_path / name
        path.write_text(body)
        run = subprocess.run(
            [sys.executable, "-m", "cnctwin", "signals", str(PROGRAM), "-c", str(path)],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        assert run.returncode == 2, run.stderr
        assert fragment in run.stderr and "Traceback" not in run.stderr
