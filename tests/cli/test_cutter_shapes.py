"""Every cutter shape through every path: ``cnctwin simulate``, ``cnctwin signals``, the twin's
physics stage and the virtual machine, against closed forms and against each other.

One tool of each kind (flat, ball, bull, conical, snub; 10 mm, 3 flutes) cuts the same full
slot, 3 mm deep, along X through a 60 mm block. Independent references:

* Removed volume: the slot's cross-section, the tool's profile below ``ap`` (its envelope,
  closed form per shape), times the 60 mm the tool crosses.
* Mean cutting torque of the steady slot, per revolution (Altintas 2012, ch. 2, with the chip
  ``h = f_z sin(phi) sin(kappa)`` over a width ``ds`` along the profile, Lee & Altintas 1996):
  every slice cuts over ``0 < phi < pi``, so

      T = N Ktc f_z A / (2 pi) + N Kte / 2 * integral of r ds,

  ``A`` the cross-section (``sin(kappa) ds = dz``, so the shear part is ``Ktc`` times the
  removal rate over ``omega``) and ``integral of r ds`` the profile's first moment below ``ap``
  (closed form per shape).

The twin's physics fed the positions of the offline prediction gives the same forces; the
virtual machine, which follows the path with its own ticks and acceleration limits, gives the
same steady forces and torque.
"""

from __future__ import annotations

import csv
import json
import math
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from cnctwin.cli import app
from cnctwin.config import load_config
from cnctwin.mechanics.materials import milling_material
from cnctwin.twin.physics import TwinPhysics
from cnctwin.virtual import NoiseConfig, VirtualMachine, VirtualMachineConfig

RPM = 8000.0
FEED_MM_MIN = 600.0
AP_MM = 3.0
FLUTES = 3
RADIUS_MM = 5.0
SLOT_LENGTH_MM = 60.0
# A 3 mm deep full slot along X at Y10 through the 60 mm block, after a 1 s spindle start.
SLOT = (
    "G21 G90 G94\nT1 M6\nS8000 M3\nG0 X-10 Y10 Z5\nG4 P1\nG1 Z-3 F300\n"
    "G1 X70 F600\nG0 Z5\nM5\nM30\n"
)
SLOT_LINE = 7
#: The tool's centre well inside the block: a steady full slot (mm).
STEADY_X_MM = (15.0, 45.0)

#: Each shape's [[tools]] keys. Bull: corner 2 mm; V-bit: 60 degrees (cone 8.66 mm high);
#: snub: 4 mm tip, 60 degrees (cone 5.20 mm high): ap = 3 mm lies on the corner or the cone.
SHAPES: dict[str, str] = {
    "flat": 'kind = "flat"',
    "ball": 'kind = "ball"',
    "bull": 'kind = "bull"\ncorner_radius_mm = 2.0',
    "conical": 'kind = "conical"\ntip_angle_deg = 60.0',
    "snub": 'kind = "snub"\ntip_diameter_mm = 4.0\ntip_angle_deg = 60.0',
}

CONFIG = """\
[machine]
rapid_mm_min = 6000.0

[machine.axes.x]
min_mm = -500.0
max_mm = 500.0
max_velocity_mm_min = 12000.0
max_accel_mm_s2 = 2000.0

[machine.axes.y]
min_mm = -500.0
max_mm = 500.0
max_velocity_mm_min = 12000.0
max_accel_mm_s2 = 2000.0

[machine.axes.z]
min_mm = -500.0
max_mm = 500.0
max_velocity_mm_min = 12000.0
max_accel_mm_s2 = 1500.0

[[tools]]
number = 1
diameter_mm = 10.0
flutes = 3
helix_deg = 30.0
flute_length_mm = 22.0
{shape}

[stock]
min_mm = [0.0, 0.0, -10.0]
max_mm = [60.0, 20.0, 0.0]

[material]
name = "AA6060-T6"

[simulation]
density_per_mm = 10.0
"""


def section_mm2(kind: str) -> float:
    """Cross-section of the slot, the tool's profile below ``AP_MM``: ``2 * integral of r dz``."""
    r, a = RADIUS_MM, AP_MM
    if kind == "flat":
        return 2.0 * r * a
    if kind == "ball":  # a circular segment of height a
        return r * r * math.acos((r - a) / r) - (r - a) * math.sqrt(2.0 * r * a - a * a)
    if kind == "bull":  # two quarter discs and the flat strip between them, then the cylinder
        rc = 2.0
        return 2.0 * (math.pi * rc * rc / 4.0 + (r - rc) * rc) + 2.0 * r * (a - rc)
    tip = 2.0 if kind == "snub" else 0.0
    slope = math.tan(math.radians(30.0))
    return 2.0 * (tip * a + 0.5 * slope * a * a)  # a trapezoid (a triangle for the V-bit)


def profile_moment_mm2(kind: str) -> float:
    """First moment of the cutting profile below ``AP_MM`` about the axis, ``integral of r ds``
    (mm^2), ``ds`` along the profile (the flat bottom has no side edge)."""
    r, a = RADIUS_MM, AP_MM
    if kind in ("flat", "ball"):  # the ball's zone: r ds = R dz (Archimedes' hat-box theorem)
        return r * a
    if kind == "bull":  # r = R - rc + rc sin(kappa), ds = rc d(kappa) over the quarter arc
        rc = 2.0
        return (r - rc) * rc * math.pi / 2.0 + rc * rc + r * (a - rc)
    tip = 2.0 if kind == "snub" else 0.0
    half = math.radians(30.0)  # r = r_t + z tan(theta/2), ds = dz / cos(theta/2)
    return (tip * a + 0.5 * math.tan(half) * a * a) / math.cos(half)


def slot_torque_nm(kind: str) -> float:
    """Mean cutting torque of the steady full slot (module notes), N m."""
    k = milling_material("AA6060-T6").coefficients
    fz_m = FEED_MM_MIN / (RPM * FLUTES) * 1e-3
    shear = FLUTES * k.ktc * fz_m * section_mm2(kind) * 1e-6 / (2.0 * math.pi)
    edge = FLUTES * k.kte / 2.0 * profile_moment_mm2(kind) * 1e-6
    return shear + edge


@pytest.fixture(scope="module", params=list(SHAPES))
def shape(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The shape's files and the outputs of ``cnctwin simulate`` and ``cnctwin signals``."""
    kind = request.param
    folder = tmp_path_factory.mktemp(kind)
    config = folder / "cell.toml"
    config.write_text(CONFIG.format(shape=SHAPES[kind]))
    program = folder / "slot.ngc"
    program.write_text(SLOT)
    runner = CliRunner()
    simulated = runner.invoke(app, ["simulate", str(program), "-c", str(config), "--json"])
    assert simulated.exit_code == 0, simulated.output
    out = folder / "signals"
    predicted = runner.invoke(
        app, ["signals", str(program), "-c", str(config), "--json", "--out", str(out)]
    )
    assert predicted.exit_code == 0, predicted.output
    with (out / "signals.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    signals = {name: np.array([float(row[name]) for row in rows]) for name in rows[0]}
    return {
        "kind": kind,
        "config": config,
        "program": program,
        "simulate": json.loads(simulated.output),
        "signals": signals,
    }


def _steady(signals: dict[str, np.ndarray]) -> np.ndarray:
    x = signals["x_mm"]
    return (signals["line"] == SLOT_LINE) & (x >= STEADY_X_MM[0]) & (x <= STEADY_X_MM[1])


def test_simulate_removes_the_slot_cross_section_times_its_length(shape: dict) -> None:
    report = shape["simulate"]
    expected = section_mm2(shape["kind"]) * SLOT_LENGTH_MM
    # Tri-dexels at 10 /mm against the closed-form section: 1 %.
    assert report["removed_volume_mm3"] == pytest.approx(expected, rel=0.01)
    assert report["max_ap_mm"] == pytest.approx(AP_MM, abs=0.1)
    assert report["warnings"] == []


def test_signals_torque_is_the_closed_form_of_the_slot(shape: dict) -> None:
    signals = shape["signals"]
    steady = _steady(signals)
    assert steady.sum() > 200
    torque = signals["cutting_torque_nm"][steady]
    # Dexel engagement (10 /mm) against the closed form: 2 % on every step.
    np.testing.assert_allclose(torque, slot_torque_nm(shape["kind"]), rtol=0.02)


def test_twin_physics_predicts_the_signals_of_the_same_positions(shape: dict) -> None:
    # The twin's physics stage cuts its own blank at the positions the offline prediction
    # sampled (as a machine would report them) and predicts the same forces step by step.
    signals = shape["signals"]
    twin = TwinPhysics(load_config(shape["config"]))
    forces = np.zeros((signals["t_s"].size, 3))
    dt_s = float(np.diff(signals["t_s"][:2])[0])
    for i in range(signals["t_s"].size):
        position = np.array([signals["x_mm"][i], signals["y_mm"][i], signals["z_mm"][i]])
        engagement, fz = twin.cut(
            position,
            int(signals["tool"][i]),
            signals["spindle_cmd_rpm"][i],
            signals["path_speed_mm_min"][i],
            dt_s,
        )
        if engagement is not None:
            load = twin.forces(
                engagement, int(signals["tool"][i]), signals["spindle_cmd_rpm"][i], fz
            )
            forces[i] = (load.fx_n, load.fy_n, load.torque_nm)
    steady = _steady(signals)
    expected = np.column_stack([signals[name] for name in ("fx_n", "fy_n", "cutting_torque_nm")])
    # signals.csv keeps 6 significant digits of each position: 0.2 % in the steady slot.
    np.testing.assert_allclose(forces[steady], expected[steady], rtol=0.002, atol=0.05)
    assert forces[steady, 2].mean() == pytest.approx(slot_torque_nm(shape["kind"]), rel=0.02)


def test_virtual_machine_measures_the_predicted_slot(shape: dict) -> None:
    quiet = NoiseConfig(
        position_mm=0.0, feed_mm_min=0.0, spindle_rpm=0.0, force_n=0.0, torque_nm=0.0,
        current_a=0.0, power_w=0.0, load_pct=0.0,
    )  # fmt: skip
    vm = VirtualMachine(
        VirtualMachineConfig(program=shape["program"], noise=quiet), load_config(shape["config"])
    )
    snapshots: list[dict[str, Any]] = []
    while not vm.finished:
        vm.step(vm.tick_s)
        snapshots.append(vm.snapshot())
        assert vm.time_s < 60.0, "the program did not finish"
    steady = [
        s
        for s in snapshots
        if s["program_line"] == SLOT_LINE and STEADY_X_MM[0] <= s["x_mm"] <= STEADY_X_MM[1]
    ]
    assert len(steady) > 500
    signals = shape["signals"]
    predicted = _steady(signals)
    # The machine's dynamometer reads the force on the workpiece, minus the force on the tool.
    # Its mean agrees within 2 %; each tick within 4 %: the machine's ticks fall on the
    # dexel grid (10 /mm) at alternating phases, which a sloped flank (the cone) turns into
    # a tick-to-tick ripple of up to 2 % about the mean.
    for name, column in (("force_x_n", "fx_n"), ("force_y_n", "fy_n")):
        measured = np.array([s[name] for s in steady])
        expected = signals[column][predicted].mean()
        assert -measured.mean() == pytest.approx(expected, rel=0.02)
        np.testing.assert_allclose(-measured, expected, rtol=0.04)
    # The spindle motor carries the cutting torque on top of its idle torque.
    idle = [s["spindle_torque_nm"] for s in snapshots if s["program_line"] == 5][-1]
    loaded = np.mean([s["spindle_torque_nm"] for s in steady])
    assert loaded - idle == pytest.approx(slot_torque_nm(shape["kind"]), rel=0.02)
