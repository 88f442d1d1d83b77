"""The virtual machine's axes: the interpreter's path, feed, override, hold and stop.

Reference: the trapezoidal speed profile of a straight move from rest to rest, in closed form
(time ``L / v + v / a`` when the move reaches its feed ``v`` under acceleration ``a``), and the
interpreter's own segments for the path.
"""

from __future__ import annotations

import math

import pytest
from vm_helpers import ACCEL_MM_S2, MakeVM, physics, run_to_end

from cnctwin.nc import AxisLimits, TrajectorySampler, interpret_text
from cnctwin.thread.signals import RunState
from cnctwin.virtual import VirtualMachine

TICK_S = 0.005
# A straight move along X from the machine's start (the origin), rest to rest: 60 mm at
# 600 mm/min, far from the stock.
LINE = "G21 G90 G94\nG1 X60 F600\nM30\n"
AWAY = physics(min_mm=[0.0, 100.0, -10.0], max_mm=[60.0, 120.0, 0.0])


def _finish_s(vm: VirtualMachine) -> float:
    """Run to the end; the machine time at the tick the program finished, s."""
    run_to_end(vm)
    return vm.time_s


def _trapezoid_s(length_mm: float, v_mm_s: float, a_mm_s2: float) -> float:
    """Rest-to-rest time of a straight move (s) with feed v and acceleration a."""
    if length_mm >= v_mm_s**2 / a_mm_s2:
        return length_mm / v_mm_s + v_mm_s / a_mm_s2
    return 2.0 * math.sqrt(length_mm / a_mm_s2)


def test_straight_move_takes_length_over_feed(make_vm: MakeVM) -> None:
    vm = make_vm(LINE, AWAY)
    snapshots = run_to_end(vm)
    expected = _trapezoid_s(60.0, 10.0, ACCEL_MM_S2[0])  # 6.005 s
    assert -1e-9 <= vm.time_s - expected < TICK_S  # finished at the first tick after the end
    assert (snapshots[-1]["x_mm"], snapshots[-1]["y_mm"], snapshots[-1]["z_mm"]) == pytest.approx(
        (60.0, 0.0, 0.0), abs=1e-9
    )
    assert snapshots[-1]["run_state"] == RunState.FINISHED
    # Cruise speed is the programmed feed.
    assert max(s["feed_mm_min"] for s in snapshots) == pytest.approx(600.0, rel=1e-9)


def test_feed_override_50_percent_doubles_the_cutting_time(make_vm: MakeVM) -> None:
    full = _finish_s(make_vm(LINE, AWAY))
    vm = make_vm(LINE, AWAY)
    vm.command("feed_override_pct", 50.0)
    half = _finish_s(vm)
    assert -1e-9 <= half - _trapezoid_s(60.0, 5.0, ACCEL_MM_S2[0]) < TICK_S
    assert half / full == pytest.approx(2.0, abs=0.002)


def test_override_change_ramps_within_the_acceleration_limit(make_vm: MakeVM) -> None:
    vm = make_vm(LINE, AWAY)
    while vm.snapshot()["feed_mm_min"] < 599.0:
        vm.step(TICK_S)
    vm.command("feed_override_pct", 20.0)
    assert vm.snapshot()["feed_override_pct"] == 20.0  # read back at once
    speeds = []
    for _ in range(10):
        vm.step(TICK_S)
        speeds.append(vm.snapshot()["feed_mm_min"] / 60.0)
    # Mean speed over a tick drops by at most a * tick per tick (2000 mm/s^2 * 5 ms = 10 mm/s).
    drops = [a - b for a, b in zip([10.0, *speeds], speeds, strict=False)]
    assert max(drops) <= ACCEL_MM_S2[0] * TICK_S + 1e-9
    assert speeds[-1] == pytest.approx(2.0, rel=1e-9)


def test_path_follows_the_interpreter(make_vm: MakeVM) -> None:
    text = (
        "G21 G90 G94 G17\nG0 X30 Y10 Z20\nG1 X40 F900\nG3 X30 Y20 I-10 J0\n"
        "G2 X20 Y10 I0 J-10\nG1 X25 Y5 Z15\nM30\n"
    )
    vm = make_vm(text, AWAY)
    segments = list(interpret_text(text))
    arcs = {seg.line: seg for seg in segments if seg.center_mm is not None}
    snapshots = run_to_end(vm)
    for s in snapshots:
        seg = arcs.get(int(s["program_line"]))
        if seg is not None and seg.center_mm is not None:
            radius = math.hypot(s["x_mm"] - seg.center_mm[0], s["y_mm"] - seg.center_mm[1])
            assert radius == pytest.approx(10.0, abs=1e-9)
    end = segments[-1].end_mm
    last = snapshots[-1]
    assert (last["x_mm"], last["y_mm"], last["z_mm"]) == pytest.approx(end, abs=1e-9)
    # Each arc: a quarter and a half turn of radius 10 at 900 mm/min, plus ramps.
    lines = [int(s["program_line"]) for s in snapshots]
    assert lines == sorted(lines)


def test_feed_hold_stops_the_axes_and_resumes(make_vm: MakeVM) -> None:
    undisturbed = run_to_end(make_vm(LINE, AWAY))
    vm = make_vm(LINE, AWAY)
    while vm.snapshot()["x_mm"] < 20.0:
        vm.step(TICK_S)
    vm.command("feed_hold", 1)
    assert vm.snapshot()["run_state"] == RunState.FEED_HOLD
    for _ in range(20):  # decelerates within 5 ms at 2000 mm/s^2
        vm.step(TICK_S)
    held_x = vm.snapshot()["x_mm"]
    for _ in range(200):  # one second on hold
        vm.step(TICK_S)
        assert vm.snapshot()["x_mm"] == held_x
        assert vm.snapshot()["feed_mm_min"] == 0.0
    vm.command("feed_hold", 0)
    assert vm.snapshot()["run_state"] == RunState.RUNNING
    rest = run_to_end(vm)
    assert rest[-1]["x_mm"] == pytest.approx(60.0, abs=1e-9)
    # Held 1.1 s, plus one stop and one restart (v / a = 5 ms), to a tick.
    extra = vm.time_s - undisturbed[-1]["t_s"]
    assert extra == pytest.approx(1.1 + 10.0 / ACCEL_MM_S2[0], abs=2 * TICK_S)


def test_stop_latches_until_restart(make_vm: MakeVM) -> None:
    vm = make_vm("G21 G90\nS8000 M3\nG4 P1\n" + LINE, AWAY)
    while vm.snapshot()["x_mm"] < 20.0:
        vm.step(TICK_S)
    vm.command("stop", 1)
    assert vm.snapshot()["stop"] == 1.0
    assert vm.snapshot()["run_state"] == RunState.STOPPED
    vm.command("stop", 0)  # does not unlatch
    assert vm.snapshot()["stop"] == 1.0
    for _ in range(400):
        vm.step(TICK_S)
    s = vm.snapshot()
    assert s["run_state"] == RunState.STOPPED
    assert vm.finished
    assert s["feed_mm_min"] == 0.0
    assert 20.0 < s["x_mm"] < 21.0
    assert s["spindle_rpm_command"] == 0.0
    assert s["spindle_rpm"] < 8000.0  # coasting down
    vm.restart()
    assert vm.snapshot()["run_state"] == RunState.RUNNING
    assert vm.snapshot()["stop"] == 0.0
    assert run_to_end(vm)[-1]["x_mm"] == pytest.approx(60.0, abs=1e-9)


def test_rapid_moves_run_at_the_rapid_rate(make_vm: MakeVM) -> None:
    vm = make_vm("G21 G90\nG0 X200\nM30\n", AWAY)
    snapshots = run_to_end(vm)
    assert max(s["feed_mm_min"] for s in snapshots) == pytest.approx(6000.0, rel=1e-9)
    assert -1e-9 <= vm.time_s - _trapezoid_s(200.0, 100.0, ACCEL_MM_S2[0]) < TICK_S


def test_duration_matches_the_offline_sampler(make_vm: MakeVM) -> None:
    """Another implementation of the same motion model: cnctwin.nc.sampler (128-segment
    lookahead) with the machine's axis limits. Long segments, so lookahead does not matter."""
    text = (
        "G21 G90 G94 G17\nG1 X40 F1200\nG1 Y40\nG3 X0 Y40 I-20 J0\nG1 Y0 F900\n"
        "G0 X50 Z10\nG1 X60 Y10 Z0 F600\nM30\n"
    )
    vm = make_vm(text, AWAY)
    run_to_end(vm)
    sampler = TrajectorySampler(
        interpret_text(text),
        rapid_mm_min=6000.0,
        cycle_s=TICK_S,
        limits=AxisLimits(
            accel_mm_s2=ACCEL_MM_S2,
            velocity_mm_s=(200.0, 200.0, 200.0),
            junction_deviation_mm=0.01,
        ),
    )
    for _ in sampler:
        pass
    assert sampler.duration_s is not None
    assert -1e-9 <= vm.time_s - sampler.duration_s < TICK_S
