"""Machine signals along a simulated cut, checked against closed forms.

A straight full slot at constant feed through a dexel block: the per-step mean forces must be
Altintas' closed form for a flat end mill (a full slot is immersed from 0 to pi), the cutting
power ``Ktc MRR`` plus the edge terms, and the spindle current in steady cutting the drive's
closed form ``(T_cut + B w) / K_T``. Out of contact every force is zero.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.config.spindle import SpeedControllerConfig, SpindleConfig, SpindleMotorConfig
from cnctwin.drives import RAD_S_PER_RPM, spindle_preset
from cnctwin.errors import ConfigError
from cnctwin.geometry import Cutter, DexelStock, cut
from cnctwin.geometry import Engagement as DexelEngagement
from cnctwin.mechanics import ImmersionIntervals, flat_end_mill_mean_forces
from cnctwin.mechanics.materials import milling_material
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.setup import NCSetup
from cnctwin.simulation.signals import (
    SIGNAL_COLUMNS,
    MachineSignals,
    immersion_intervals,
    simulate_signals,
    spindle_drive_parameters,
)

D_MM, AP_MM, TEETH = 6.0, 3.0, 2
RPM, FEED_MM_MIN = 10_000.0, 600.0
FZ_MM = FEED_MM_MIN / (RPM * TEETH)
OMEGA = RPM * RAD_S_PER_RPM
# The Kistler-identified coefficients: all six terms non-zero, so Fz is checked too.
MATERIAL = milling_material("kistler-slot-6000rpm")
PRESET = "machining-centre-15kw"


def _slot(direction: str) -> MachineSignals:
    """A 3 mm deep full slot through a 40 x 40 x 10 mm block, along +X or +Y at 600 mm/min.

    The spindle starts 1.5 s before the cut (G4), so that the drive has settled.
    """
    move = (
        "G0 X-5 Y20\nG0 Z-3\nG1 X45 F600" if direction == "x" else "G0 X20 Y-5\nG0 Z-3\nG1 Y45 F600"
    )
    program = f"G21 G90 G17\nT1 M6\nS{RPM:.0f} M3\nG4 P1.5\n{move}\nG0 Z5\nM5\nM30\n"
    cutter = Cutter.flat(diameter_mm=D_MM, flute_length_mm=15.0, flutes=TEETH, helix_rad=0.5)
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 40.0, 0.0), density_per_mm=10.0)
    segments = Interpreter(NCSetup()).run_text(program)
    return simulate_signals(
        segments,
        stock,
        {1: cutter},
        MATERIAL.coefficients,
        spindle_preset(PRESET),
        rapid_mm_min=6000.0,
        drive_name=PRESET,
    )


@pytest.fixture(scope="module")
def slot_x() -> MachineSignals:
    return _slot("x")


def _steady(signals: MachineSignals, axis: str) -> np.ndarray:
    """Rows in full contact: the tool's centre more than a radius inside the block."""
    c = signals.columns
    along = c[f"{axis}_mm"]
    return (c["contact"] > 0) & (along > 3.5) & (along < 36.5)


def _closed_form() -> tuple[float, float, float, float, float]:
    mean = flat_end_mill_mean_forces(
        MATERIAL.coefficients, TEETH, D_MM / 2e3, 0.0, math.pi, AP_MM * 1e-3, FZ_MM * 1e-3, OMEGA
    )
    return mean.fx_n, mean.fy_n, mean.fz_n, mean.torque_nm, mean.power_w


def test_columns_and_rows(slot_x: MachineSignals) -> None:
    assert set(slot_x.columns) == set(SIGNAL_COLUMNS)
    assert slot_x.table().shape == (len(slot_x), len(SIGNAL_COLUMNS))
    assert np.count_nonzero(_steady(slot_x, "x")) > 200  # 33 mm at 10 mm/s, 12.5 ms cycles


def test_full_slot_forces_match_the_closed_form(slot_x: MachineSignals) -> None:
    c = slot_x.columns
    steady = _steady(slot_x, "x")
    fx, fy, fz, torque, power = _closed_form()
    # Feed along +X: the tool frame is the machine frame. The dexel engagement's intervals
    # cover 0..pi here (widened past its ends, which cut nothing) on three steps in four; on
    # the fourth (the tool's centre in the same place relative to the 0.1 mm grid, every
    # 0.5 mm) two strips of 0.039 rad are missing where the front arc runs diagonal to the
    # grid, which takes 2.6 % off Fy and 2.5 % off the torque on that step. Hence: the mean
    # within 1 %, every step within 3 % of the force scale (and of torque and power).
    scale = math.hypot(fx, fy)
    for name, expected in (
        ("fx_n", fx), ("fy_n", fy), ("fz_n", fz), ("f_feed_n", fx), ("f_normal_n", fy)
    ):  # fmt: skip
        values = c[name][steady]
        assert abs(values.mean() - expected) < 0.01 * scale, name
        assert np.all(np.abs(values - expected) < 0.03 * scale), name
    for name, expected in (("cutting_torque_nm", torque), ("cutting_power_w", power)):
        values = c[name][steady]
        assert values.mean() == pytest.approx(expected, rel=0.01), name
        assert np.allclose(values, expected, rtol=0.03), name
    # The peak over the revolution is at least the mean force.
    assert np.all(c["f_peak_n"][steady] >= c["f_mean_n"][steady])


def test_cutting_power_is_ktc_mrr_plus_edge_power(slot_x: MachineSignals) -> None:
    # Hand formula, independent of the force kernels: in a slot the shear power is Ktc times
    # the removal rate D ap vf, and each tooth's edge rubs Kte per unit width over half a turn,
    # N ap (pi / 2 pi) Kte R w in all.
    k = MATERIAL.coefficients
    mrr_m3_s = (D_MM * 1e-3) * (AP_MM * 1e-3) * (FEED_MM_MIN * 1e-3 / 60.0)
    edge_w = TEETH * AP_MM * 1e-3 * 0.5 * k.kte * (D_MM / 2e3) * OMEGA
    expected = k.ktc * mrr_m3_s + edge_w
    power = slot_x.columns["cutting_power_w"][_steady(slot_x, "x")]
    assert np.median(power) == pytest.approx(expected, rel=0.02)


def test_spindle_current_in_steady_cutting_is_the_drive_closed_form(
    slot_x: MachineSignals,
) -> None:
    c = slot_x.columns
    motor = spindle_preset(PRESET).motor
    steady = _steady(slot_x, "x")
    # Leave the first 0.5 s of the cut for the speed loop to settle (slowest pole -20 1/s).
    settled = steady & (c["t_s"] > c["t_s"][np.argmax(steady)] + 0.5)
    assert np.count_nonzero(settled) > 100
    # The dexel engagement repeats every fourth step (see above), so the load is periodic:
    # over whole periods the rotor neither gains nor loses speed, and the mean current is the
    # closed form of the mean load (Christiand 2024, Eq. 10-12 with dw/dt = di/dt = 0).
    settled &= np.cumsum(settled) <= 4 * (np.count_nonzero(settled) // 4)
    current = c["spindle_current_a"][settled]
    load = c["cutting_torque_nm"][settled]
    expected = (load + motor.viscous_friction * OMEGA) / motor.torque_constant
    assert current.mean() == pytest.approx(expected.mean(), rel=1e-3)
    assert np.allclose(current, expected, rtol=0.01)  # the loop follows the 2.5 % ripple
    assert np.allclose(c["spindle_speed_rpm"][settled], RPM, rtol=1e-3)
    assert np.allclose(c["motor_torque_nm"][settled], motor.torque_constant * current)


def test_forces_are_zero_out_of_contact(slot_x: MachineSignals) -> None:
    c = slot_x.columns
    off = c["contact"] == 0
    assert np.count_nonzero(off) > 100
    for name in ("fx_n", "fy_n", "fz_n", "f_peak_n", "cutting_torque_nm", "cutting_power_w"):
        assert np.all(c[name][off] == 0.0), name
    # Idle at speed before the cut: the current holds the viscous friction, B w / K_T.
    motor = spindle_preset(PRESET).motor
    idle = off & (c["t_s"] > 1.0) & (c["t_s"] < 1.5)
    assert np.allclose(
        c["spindle_current_a"][idle], motor.viscous_friction * OMEGA / motor.torque_constant,
        rtol=1e-3,
    )  # fmt: skip


def test_feed_along_y_rotates_the_forces_into_the_machine_frame() -> None:
    signals = _slot("y")
    c = signals.columns
    steady = _steady(signals, "y")
    fx, fy, fz, _, _ = _closed_form()
    # Feed f = +Y, left normal n = -X: F_X = -F_y(tool), F_Y = +F_x(tool).
    scale = math.hypot(fx, fy)
    assert np.all(np.abs(c["fx_n"][steady] + fy) < 0.03 * scale)
    assert np.all(np.abs(c["fy_n"][steady] - fx) < 0.03 * scale)
    assert np.all(np.abs(c["f_feed_n"][steady] - fx) < 0.03 * scale)
    assert np.all(np.abs(c["fz_n"][steady] - fz) < 0.03 * scale)


def test_overload_against_the_rating() -> None:
    cutter = Cutter.flat(diameter_mm=D_MM, flute_length_mm=15.0, flutes=TEETH)
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 40.0, 0.0), density_per_mm=5.0)
    program = "T1 M6\nS10000 M3\nG0 X-5 Y20\nG0 Z-3\nG1 X45 F600\nM30\n"
    _, _, _, torque, _ = _closed_form()
    signals = simulate_signals(
        Interpreter(NCSetup()).run_text(program),
        stock,
        {1: cutter},
        MATERIAL.coefficients,
        spindle_preset(PRESET),
        rapid_mm_min=6000.0,
        rated_power_w=0.5 * torque * OMEGA,  # half the slot's power at 10,000 rpm
    )
    summary = signals.summary()
    assert summary["overload_steps"] > 200
    assert len(signals.warnings) == 1 and "more than the spindle's rating" in signals.warnings[0]


def _dexel_engagement(heights, dz, owner, start, end) -> DexelEngagement:
    return DexelEngagement(
        contact=True, removed_volume_mm3=1.0, mrr_mm3_s=80.0, ae_mm=6.0, ap_mm=1.0,
        feed_mm_min=600.0, feed_dir=(1.0, 0.0), h_mean_mm=0.02, h_max_mm=0.03,
        slice_height_mm=np.array(heights, float), slice_dz_mm=np.array(dz, float),
        slice_radius_mm=np.full(len(heights), 3.0), interval_slice=np.array(owner, np.int64),
        interval_start_rad=np.array(start, float), interval_end_rad=np.array(end, float),
        bottom_contact=False, above_flutes=False,
    )  # fmt: skip


def test_immersion_intervals_lowest_slice_when_the_tip_is_inside_a_level() -> None:
    # Pitch 0.1 mm, tip 0.07 mm above a level: the next level (the lowest slice, 0.08 mm
    # above the tip) stands for [tip, tip + 0.13 mm] (dz 0.13 mm); the next for [0.13, 0.23].
    pi = math.pi
    cut = immersion_intervals(
        _dexel_engagement([0.08, 0.18], [0.13, 0.1], [0, 1], [0, 0], [pi, pi]), 0.1
    )
    assert cut is not None
    assert np.allclose(cut.z_bounds_m, [0.0, 0.13e-3, 0.23e-3], rtol=0, atol=1e-15)
    assert np.allclose(cut.entry_rad, 0.0) and np.allclose(cut.exit_rad, pi)
    assert immersion_intervals(_dexel_engagement([0.05], [0.1], [], [], []), 0.1) is None


@pytest.mark.parametrize("below_mm", [0.02, 0.05, 0.07, 0.1, 0.5, 4.5, 5.03])
def test_immersion_intervals_of_a_tip_below_the_stock(below_mm: float) -> None:
    # A slot whose tip is below_mm under the bottom of a 10 mm block (a through cut): the
    # tool meets material from the block's bottom to its top, in slices of the 0.1 mm pitch.
    # Hand-computed: the bounds run from the bottom (below_mm above the tip; the tip itself
    # when it lies within half a pitch under the lowest level, 0.05 mm above the bottom) to
    # the block's top or the flutes' end (10 + below_mm or 15 mm), every 0.1 mm between, and
    # ap is the span from the first bound to the last.
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 40.0, 0.0), density_per_mm=10.0)
    cutter = Cutter.flat(diameter_mm=D_MM, flute_length_mm=15.0, flutes=TEETH, helix_rad=0.5)
    tip_z = -10.0 - below_mm
    engagement = cut(stock, cutter, (10.0, 20.0, tip_z), (9.9, 20.0, tip_z), FZ_MM, 0.0125)
    bounds_mm = immersion_intervals(engagement, 0.1).z_bounds_m * 1e3
    bottom = 0.0 if below_mm < 0.05 else below_mm
    assert bounds_mm[0] == pytest.approx(bottom, abs=1e-9)
    assert np.all(np.diff(bounds_mm) > 0.0)
    inner = bounds_mm[1:-1] - below_mm
    assert np.allclose(inner, np.round(inner, 1), rtol=0, atol=1e-9)
    top = min(10.0 + below_mm, 15.0)
    assert bounds_mm[-1] == pytest.approx(top, abs=1e-9)
    assert engagement.ap_mm == pytest.approx(top - bottom, abs=1e-6)


def test_through_slot_forces_match_the_closed_form() -> None:
    # A full slot with the tip 2 mm under the bottom of a 10 mm block: the whole block's
    # height cuts, the closed form at ap = 10 mm (it stopped on "z_bounds_m ... give
    # increasing heights" before the lowest slice stood only for the tool within the block).
    program = "G21 G90 G17\nT1 M6\nS10000 M3\nG4 P1.5\nG0 X-5 Y20\nG0 Z-12\nG1 X45 F600\nM30\n"
    cutter = Cutter.flat(diameter_mm=D_MM, flute_length_mm=15.0, flutes=TEETH, helix_rad=0.5)
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 40.0, 0.0), density_per_mm=10.0)
    signals = simulate_signals(
        Interpreter(NCSetup()).run_text(program),
        stock,
        {1: cutter},
        MATERIAL.coefficients,
        spindle_preset(PRESET),
        rapid_mm_min=6000.0,
    )
    mean = flat_end_mill_mean_forces(
        MATERIAL.coefficients, TEETH, D_MM / 2e3, 0.0, math.pi, 10e-3, FZ_MM * 1e-3, OMEGA
    )
    steady = _steady(signals, "x")
    assert np.count_nonzero(steady) > 200
    fy = signals.columns["fy_n"][steady]
    torque = signals.columns["cutting_torque_nm"][steady]
    assert fy.mean() == pytest.approx(mean.fy_n, rel=0.01)
    assert torque.mean() == pytest.approx(mean.torque_nm, rel=0.01)


def test_immersion_intervals_agree_with_from_slices() -> None:
    # Two runs of slices with a gap (0.2 to 0.5 mm above the tip), several intervals a slice,
    # one slice without intervals: the array construction against the force model's own
    # slice-by-slice reader.
    heights = [0.05, 0.15, 0.25, 0.55, 0.65]
    dz = [0.1, 0.1, 0.1, 0.1, 0.1]
    owner = [0, 0, 1, 3, 3, 3, 4]
    start = [0.0, 2.0, 0.5, 0.1, 1.0, 6.0, 0.2]
    end = [1.5, 3.1, 2.5, 0.9, 2.0, 6.2831, 3.0]
    cut = immersion_intervals(_dexel_engagement(heights, dz, owner, start, end), 0.1)
    reference = ImmersionIntervals.from_slices(
        np.array(heights) * 1e-3, np.array(dz) * 1e-3, np.array(owner),
        np.array(start), np.array(end),
    )  # fmt: skip
    assert cut is not None
    assert np.allclose(cut.z_bounds_m, reference.z_bounds_m, rtol=0, atol=1e-15)
    assert np.array_equal(cut.offsets, reference.offsets)
    assert np.array_equal(cut.entry_rad, reference.entry_rad)
    assert np.array_equal(cut.exit_rad, reference.exit_rad)


def test_spindle_drive_parameters_from_the_config() -> None:
    assert spindle_drive_parameters(SpindleConfig()) == spindle_preset(PRESET)
    micro = spindle_drive_parameters(SpindleConfig(preset="christiand2024"))
    assert micro == spindle_preset("christiand2024")
    custom = spindle_drive_parameters(
        SpindleConfig(
            motor=SpindleMotorConfig(
                resistance_ohm=1.0, inductance_h=0.01, torque_constant_nm_a=2.0,
                back_emf_constant_v_s_rad=2.0, inertia_kg_m2=0.02,
                viscous_friction_nm_s_rad=1e-3, coulomb_friction_nm=0.5,
            ),
            controller=SpeedControllerConfig(kp_v_s_rad=0.1, ki_v_rad=5.0),
        )
    )  # fmt: skip
    assert custom.motor.torque_constant == 2.0 and custom.motor.coulomb_friction == 0.5
    assert custom.controller.ki == 5.0 and custom.controller.voltage_limit is None
    with pytest.raises(ConfigError, match="machine.spindle.preset.*christiand2024"):
        spindle_drive_parameters(SpindleConfig(preset="nakanishi"))


def test_a_step_whose_forces_fail_names_its_line() -> None:
    # A drill without the workpiece's drilling coefficients: the error names the program's
    # line (5, the G1 that drills), the tool and where its tip was.
    program = "G21 G90 G17\nT1 M6\nS3000 M3\nG0 X20 Y20 Z2\nG1 Z-3 F200\nM30\n"
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 40.0, 0.0), density_per_mm=5.0)
    with pytest.raises(ConfigError, match=r"^line 5 \(T1, tip at X20 Y20 Z-?[0-9.]+ mm"):
        simulate_signals(
            Interpreter(NCSetup()).run_text(program),
            stock,
            {1: Cutter.drill(6.8, 30.0)},
            MATERIAL.coefficients,
            spindle_preset(PRESET),
            rapid_mm_min=6000.0,
        )
