"""The virtual machine's process signals and injected faults.

Reference for the forces: Altintas' closed-form mean forces of a flat end mill
(:func:`cnctwin.mechanics.flat_end_mill_mean_forces`, Manufacturing Automation 2012, ch. 2) for
a full slot, an independent path from the machine's dexel cut and engagement intervals. The
machine reports what a dynamometer under the workpiece measures: the opposite of the force on
the tool.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from vm_helpers import MakeVM, run_to_end

from cnctwin.mechanics import MeanForces, flat_end_mill_mean_forces
from cnctwin.mechanics.materials import milling_material
from cnctwin.thread.signals import RunState
from cnctwin.virtual import (
    ChatterFault,
    HoleFault,
    NoiseConfig,
    ToolBreakageFault,
    VirtualMachineConfig,
    WearFault,
)

RPM = 8000.0
FEED_MM_MIN = 600.0
AP_MM = 3.0
# A 3 mm deep full slot along X at Y10 through the 60 mm block, after a 1 s spindle start.
SLOT = (
    "G21 G90 G94\nT1 M6\nS8000 M3\nG0 X-10 Y10 Z5\nG4 P1\nG1 Z-3 F300\n"
    "G1 X70 F600\nG0 Z5\nM5\nM30\n"
)
SLOT_LINE = 7


def _slot_forces() -> MeanForces:
    """Mean forces on the tool of the full slot (tool frame: x = +X feed, y = +Y), N."""
    k = milling_material("AA6060-T6").coefficients
    fz_m = FEED_MM_MIN / (RPM * 3) * 1e-3
    return flat_end_mill_mean_forces(
        k, 3, 0.005, 0.0, math.pi, AP_MM * 1e-3, fz_m, RPM * 2 * math.pi / 60
    )


def _steady(snapshots: list[dict[str, float]], x0: float, x1: float) -> list[dict[str, float]]:
    """Snapshots of the slot with the tool centre between x0 and x1 (mm)."""
    return [s for s in snapshots if s["program_line"] == SLOT_LINE and x0 <= s["x_mm"] <= x1]


def test_full_slot_forces_match_the_mechanics(make_vm: MakeVM) -> None:
    snapshots = run_to_end(make_vm(SLOT))
    expected = _slot_forces()
    steady = _steady(snapshots, 10.0, 50.0)
    assert len(steady) > 700
    for s in steady:
        # Dexel engagement (10 /mm) vs the closed form: 1 % (measured 2e-5).
        assert s["force_x_n"] == pytest.approx(-expected.fx_n, rel=0.01)
        assert s["force_y_n"] == pytest.approx(-expected.fy_n, rel=0.01)
        assert s["force_z_n"] == pytest.approx(-expected.fz_n, abs=0.5)
    # The spindle motor carries the cutting torque on top of its idle torque.
    idle = [s["spindle_torque_nm"] for s in snapshots if s["program_line"] == 5][-1]
    loaded = np.mean([s["spindle_torque_nm"] for s in steady])
    assert loaded - idle == pytest.approx(expected.torque_nm, rel=0.01)
    assert np.mean([s["spindle_rpm"] for s in steady]) == pytest.approx(RPM, rel=1e-3)
    # Input power: the mechanical power plus the copper loss (under 1 % at this load).
    power = np.mean([s["spindle_power_w"] for s in steady])
    assert power == pytest.approx(loaded * RPM * math.pi / 30, rel=0.01)


def test_forces_with_noise_match_within_the_noise(make_vm: MakeVM) -> None:
    vm = make_vm(SLOT, noise=NoiseConfig(force_n=5.0), seed=3)
    steady = _steady(run_to_end(vm), 10.0, 50.0)
    expected = _slot_forces()
    fx = np.array([s["force_x_n"] for s in steady])
    # Mean within 4 standard errors; scatter is the configured 5 N.
    assert abs(fx.mean() + expected.fx_n) < 4 * 5.0 / math.sqrt(fx.size)
    assert fx.std() == pytest.approx(5.0, rel=0.1)


def test_hole_in_the_blank_drops_the_force(make_vm: MakeVM) -> None:
    hole = HoleFault(kind="hole", shape="box", min_mm=(25.0, -1.0, -11.0), max_mm=(40.0, 21.0, 1.0))
    vm = make_vm(SLOT, faults=[hole])
    snapshots = run_to_end(vm)
    full = -_slot_forces().fx_n
    before = _steady(snapshots, 10.0, 18.0)
    inside = _steady(snapshots, 31.0, 34.0)  # the tool (27.5..37.5 mm) wholly in the hole
    after = _steady(snapshots, 47.0, 53.0)
    assert all(s["force_x_n"] == pytest.approx(full, rel=0.01) for s in before)
    assert inside and all(abs(s["force_x_n"]) < 1e-9 for s in inside)
    assert all(abs(s["force_y_n"]) < 1e-9 for s in inside)
    assert all(s["force_x_n"] == pytest.approx(full, rel=0.01) for s in after)
    # The machine's blank lacks the hole's volume (15 x 20 x 10 mm inside the block).
    blank = make_vm(SLOT, faults=[hole]).stock.volume_mm3()
    assert blank == pytest.approx(60 * 20 * 10 - 15 * 20 * 10, rel=1e-6)


def test_cylindrical_hole(make_vm: MakeVM) -> None:
    hole = HoleFault(
        kind="hole", shape="cylinder", center_mm=(30.0, 10.0), radius_mm=8.0, z_mm=(-11.0, 1.0)
    )
    snapshots = run_to_end(make_vm(SLOT, faults=[hole]))
    inside = _steady(snapshots, 29.0, 31.0)  # tool (radius 5) inside the 8 mm hole
    assert inside and all(abs(s["force_x_n"]) < 1e-9 for s in inside)
    after = _steady(snapshots, 47.0, 53.0)
    assert all(s["force_x_n"] == pytest.approx(-_slot_forces().fx_n, rel=0.01) for s in after)


def test_tool_breakage_collapses_the_load_and_the_machine_goes_on(make_vm: MakeVM) -> None:
    vm = make_vm(SLOT, faults=[ToolBreakageFault(kind="breakage", at_s=6.0)])
    snapshots = run_to_end(vm)
    assert snapshots[-1]["run_state"] == RunState.FINISHED
    assert snapshots[-1]["x_mm"] == pytest.approx(70.0)
    before = [s for s in _steady(snapshots, 10.0, 50.0) if s["t_s"] < 6.0]
    after = [s for s in _steady(snapshots, 10.0, 50.0) if s["t_s"] > 6.0]
    assert before and after
    assert all(s["force_x_n"] == pytest.approx(-_slot_forces().fx_n, rel=0.01) for s in before)
    assert all(s["force_x_n"] == 0.0 and s["force_y_n"] == 0.0 for s in after)
    idle = [s["spindle_torque_nm"] for s in snapshots if s["program_line"] == 5][-1]
    assert after[-1]["spindle_torque_nm"] == pytest.approx(idle, rel=0.01)
    (event,) = vm.fault_events
    assert event.kind == "breakage" and event.t_s == pytest.approx(6.0, abs=0.005)


def test_breakage_at_a_line_and_partial_loss(make_vm: MakeVM) -> None:
    # 2 mm of the tip lost during the plunge: the 3 mm slot is cut 1 mm deep, a third of it.
    fault = ToolBreakageFault(kind="breakage", at_line=6, lost_length_mm=2.0)
    steady = _steady(run_to_end(make_vm(SLOT, faults=[fault])), 10.0, 50.0)
    assert all(s["force_x_n"] == pytest.approx(-_slot_forces().fx_n / 3, rel=0.02) for s in steady)


def test_accelerated_wear_scales_the_forces(make_vm: MakeVM) -> None:
    wear = WearFault(kind="wear", growth_per_min=6.0, max_scale=5.0)  # +10 % per second of cut
    snapshots = run_to_end(make_vm(SLOT, faults=[wear]))
    steady = _steady(snapshots, 10.0, 50.0)
    full = -_slot_forces().fx_n
    cutting = [s for s in snapshots if abs(s["force_x_n"]) > 0.0]
    for s in steady[::50]:
        cut_s = sum(1 for c in cutting if c["t_s"] < s["t_s"]) * 0.005  # before this tick
        assert s["force_x_n"] == pytest.approx(full * (1 + 0.1 * cut_s), rel=0.01)


def test_flank_wear_follows_its_law_and_adds_the_rubbing_torque(make_vm: MakeVM) -> None:
    # VB = VBref tan(atan(VB0/VBref) + r t / VBref) over the minutes in contact t; the wear
    # land's edge force k VB per mm of edge adds, in a full slot (contact angle pi at every
    # height), the mean torque Z k VB ap R / 2 (Altintas' edge-force term, closed form).
    wear = WearFault(kind="wear", vb_rate_mm_min=3.0, vb0_mm=0.05, edge_force_n_mm2=80.0)
    vm = make_vm(SLOT, faults=[wear])
    rows = []
    cut_s = 0.0
    while not vm.finished:
        vm.step(vm.tick_s)
        snap = vm.snapshot()
        rows.append((snap, vm.tool_wear_mm, cut_s))
        if abs(snap["force_x_n"]) > 0.0:
            cut_s += vm.tick_s  # the wear of this tick counted the time before it
    idle = [s["spindle_torque_nm"] for s, _, _ in rows if s["program_line"] == 5][-1]
    steady = [r for r in rows if r[0]["program_line"] == SLOT_LINE and 10.0 <= r[0]["x_mm"] <= 50]
    assert steady[-1][1] > 2 * steady[0][1]  # the tool wore during the slot
    cutting = _slot_forces().torque_nm
    for snap, vb, t_s in steady[::40]:
        expected_vb = 0.3 * math.tan(math.atan(0.05 / 0.3) + 3.0 * t_s / 60.0 / 0.3)
        assert vb == pytest.approx(expected_vb, rel=1e-9)
        rubbing = 3 * 80.0 * vb * AP_MM * 5.0 / 2 * 1e-3
        assert snap["spindle_torque_nm"] - idle == pytest.approx(cutting + rubbing, rel=0.01)
    # a flank-wear fault grows no load of its own (growth_per_min unset): the forces are
    # the clean tool's
    assert all(s["force_x_n"] == pytest.approx(-_slot_forces().fx_n, rel=0.01) for s, *_ in steady)


def test_chatter_adds_a_vibration(make_vm: MakeVM) -> None:
    chatter = ChatterFault(kind="chatter", frequency_hz=1237.0, amplitude_ratio=0.5)
    steady = _steady(run_to_end(make_vm(SLOT, faults=[chatter])), 10.0, 50.0)
    mean = _slot_forces()
    magnitude = math.sqrt(mean.fx_n**2 + mean.fy_n**2 + mean.fz_n**2)
    dx = np.array([s["force_x_n"] for s in steady]) + mean.fx_n
    dy = np.array([s["force_y_n"] for s in steady]) + mean.fy_n
    # A rotating force of amplitude 0.5 |F| (to the dexel model's 1e-5 of the mean):
    # |(dx, dy)| is constant, each component's RMS is the amplitude over sqrt(2).
    assert np.hypot(dx, dy) == pytest.approx(0.5 * magnitude, rel=1e-4)
    assert np.sqrt(np.mean(dx**2)) == pytest.approx(0.5 * magnitude / math.sqrt(2), rel=0.1)
    assert [s["force_z_n"] for s in steady] == pytest.approx([-mean.fz_n] * len(steady), abs=0.5)


def test_same_seed_same_signals(make_vm: MakeVM) -> None:
    noisy = NoiseConfig()
    runs = []
    for seed in (11, 11, 12):
        vm = make_vm(SLOT, noise=noisy, seed=seed)
        run = []
        for tick in range(1200):  # into the slot
            if tick == 100:
                vm.command("feed_override_pct", 80.0)
            vm.step(0.005)
            run.append(vm.snapshot())
        runs.append(run)
    assert runs[0] == runs[1]
    assert runs[0] != runs[2]
    assert runs[0][-1]["force_x_n"] != 0.0  # the runs cut


def test_config_defaults_run_the_packaged_demo() -> None:
    from cnctwin.virtual import VirtualMachine

    vm = VirtualMachine(VirtualMachineConfig(noise=NoiseConfig(force_n=0.0)))
    for _ in range(400):
        vm.step(vm.tick_s)
    s = vm.snapshot()
    assert s["tool_number"] == 1.0 and s["work_offset"] == 1.0
    assert s["spindle_rpm_command"] == 8000.0
    assert s["heartbeat"] == 400.0 and s["t_s"] == pytest.approx(2.0)
