"""The wear EKF (Christiand 2024, section 4) against closed forms and synthetic truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.wear.ekf import (
    CHRISTIAND2024,
    LogisticWear,
    WearEKF,
    WearTorque,
    material_removed_mm3,
)
from cnctwin.wear.stages import StageMonitor, remaining_life
from cnctwin.wear.torque_series import run_filter, synthetic_session

LAW = CHRISTIAND2024.propagation
TORQUE = CHRISTIAND2024.wear_torque


def test_logistic_step_and_jacobian_match_eq_32_33() -> None:
    law = LogisticWear(q_per_mm3=2.0, vb_max_mm=0.5)
    # By hand: 0.1 + 2 * 0.05 * 0.1 * (1 - 0.2) = 0.108; d/dVB = 1 + 0.1 * (1 - 0.4) = 1.06.
    assert law.propagate(0.1, 0.05) == pytest.approx(0.108, abs=1e-15)
    assert law.jacobian(0.1, 0.05) == pytest.approx(1.06, abs=1e-15)
    # The Jacobian is the derivative: central difference.
    h = 1e-7
    numeric = (law.propagate(0.1 + h, 0.05) - law.propagate(0.1 - h, 0.05)) / (2 * h)
    assert law.jacobian(0.1, 0.05) == pytest.approx(numeric, rel=1e-7)


def test_small_steps_converge_to_the_continuous_logistic_material() -> None:
    law = LogisticWear(q_per_mm3=1.43, vb_max_mm=0.663)
    vb, removed = 0.01, 0.0
    while vb < 0.3:
        vb = law.propagate(vb, 1e-4)
        removed += 1e-4
    # Closed form of dVB/dMR = q VB (1 - VB/VBmax) from 0.01 to the wear reached.
    assert removed == pytest.approx(law.material_to_reach_mm3(0.01, vb), rel=1e-3)


def test_wear_torque_slope_is_eq_34_and_the_derivative() -> None:
    wt = WearTorque(p0_nm=2e-3, p1_per_mm=10.0, p2=0.5, p3_per_mm=1.0, p4_nm=0.01)
    vb = 0.2
    # Eq. 34 by hand: p0 p2 / (VB (p2 - p3 VB)) = 2e-3 * 0.5 / (0.2 * 0.3).
    assert wt.slope_nm_per_mm(vb) == pytest.approx(2e-3 * 0.5 / (0.2 * 0.3), rel=1e-12)
    h = 1e-7
    numeric = (wt.torque_nm(vb + h) - wt.torque_nm(vb - h)) / (2 * h)
    assert wt.slope_nm_per_mm(vb) == pytest.approx(numeric, rel=1e-6)
    # Tw = p0 ln(p1 VB / (p2 - p3 VB)) + p4 = 2e-3 ln(2 / 0.3) + 0.01.
    assert wt.torque_nm(vb) == pytest.approx(2e-3 * math.log(2.0 / 0.3) + 0.01, rel=1e-12)


def test_preset_domain_and_torque_levels() -> None:
    # The recovered exponents make the model defined up to VBmax and the wear torque positive.
    assert TORQUE.vb_limit_mm > LAW.vb_max_mm
    for vb in (0.005, 0.1, 0.3, 0.6):
        assert 1e-3 < TORQUE.torque_nm(vb) < 5e-3


def test_material_removed_generalises_eq_30() -> None:
    # Eq. 30 for the paper's tool (Z = 2, D = 1 mm): dMR = 2 fT dn a.
    assert material_removed_mm3(0.006, 2, 1.0, 0.01, 3.0) == pytest.approx(2 * 0.006 * 3 * 0.01)
    # A full slot removes feed per revolution x width x depth.
    assert material_removed_mm3(0.05, 4, 10.0, 2.0, 1.0) == pytest.approx(0.2 * 10.0 * 2.0)


def test_linear_measurement_update_equals_the_kalman_closed_form() -> None:
    # One update from a known prior: K = P H / (H P H + R); x = x- + K (z - h); P = (1-KH) P.
    ekf = WearEKF(
        LAW, TORQUE, process_var_mm2=0.0, measurement_var_nm2=4e-6, vb0_mm=0.1, var0_mm2=1e-3
    )
    prior = LAW.propagate(0.1, 1e-3)
    prior_var = LAW.jacobian(0.1, 1e-3) ** 2 * 1e-3
    h = TORQUE.slope_nm_per_mm(prior)
    z = TORQUE.torque_nm(prior) + 0.002
    step = ekf.step(1e-3, z, 0.0)
    gain = prior_var * h / (h * prior_var * h + 4e-6)
    assert step.prior_vb_mm == pytest.approx(prior)
    assert step.gain_mm_per_nm == pytest.approx(gain)
    assert step.vb_mm == pytest.approx(prior + gain * 0.002)
    assert step.var_mm2 == pytest.approx((1 - gain * h) * prior_var)  # Joseph = simple form
    assert step.innovation_nm == pytest.approx(0.002)


def test_missed_samples_and_idle_steps_keep_the_prediction() -> None:
    ekf = CHRISTIAND2024.filter(vb0_mm=0.1, var0_mm2=1e-4)
    step = ekf.step(1e-3, math.nan)
    assert step.vb_mm == step.prior_vb_mm and math.isnan(step.gain_mm_per_nm)
    idle = ekf.step(0.0, 0.01)
    assert idle.vb_mm == pytest.approx(step.vb_mm) and idle.var_mm2 == step.var_mm2


def test_synthetic_tracking_beats_the_paper() -> None:
    # Christiand 2024, Table 7: mean absolute EKF errors of 0.022-0.038 mm on real data.
    # Sessions like the paper's (section 5) at 100 samples/s with a torque noise of 0.5 mN m
    # (the filter assumes the paper's noisier eps_u); the filter starts at 0.05 mm for a
    # tool at 0.02 mm.
    means = []
    for seed in range(1, 6):
        series = synthetic_session(CHRISTIAND2024, seed=seed, noise_nm=5e-4, vb0_mm=0.02)
        assert series.vb_mm is not None and series.vb_mm[-1] > 0.6  # all four stages
        run = run_filter(CHRISTIAND2024.filter(vb0_mm=0.05, var0_mm2=1e-3), series)
        error = np.abs(run.vb_mm - series.vb_mm)
        assert error.mean() < 0.038
        assert error[len(error) // 2 :].max() < 0.038
        means.append(error.mean())
    assert float(np.mean(means)) < 0.015


def test_synthetic_session_follows_the_experiment() -> None:
    series = synthetic_session(CHRISTIAND2024, seed=0, rate_hz=10.0, slots=2, noise_nm=0.0)
    # 2 slots x 3.5 s at 10 samples/s; 20,000 rpm, fz = 4/(2*333.3) mm, 0.01 mm deep:
    # dMR per sample = 2 fz (rev per sample) a = 2 * 0.006 * 33.33 * 0.01 mm^3.
    assert series.time_s.size == 70
    assert series.material_removed_mm3[0] == pytest.approx(2 * 0.006 * (20000 / 60 / 10) * 0.01)
    assert series.torque_nm[0] == pytest.approx(
        series.torque_base_nm[0] + TORQUE.torque_nm(series.vb_mm[0])
    )


def test_stage_notifications_and_early_flag() -> None:
    monitor = StageMonitor((0.1, 0.2, 0.5), expected_entry_s=(10.0, 20.0, 30.0))
    assert monitor.update(5.0, 0.05) == []
    events = monitor.update(8.0, 0.25)  # jumps over two boundaries at once
    assert [(e.stage, e.early) for e in events] == [(2, True), (3, True)]
    assert "earlier than normal" in events[0].message
    late = monitor.update(31.0, 0.55)
    assert [(e.stage, e.early) for e in late] == [(4, False)]
    with pytest.raises(ValueError, match="increasing"):
        StageMonitor((0.2, 0.1, 0.5))


def test_remaining_life_matches_the_logistic_closed_form() -> None:
    law = LogisticWear(q_per_mm3=1.0, vb_max_mm=1.0)
    life = remaining_life(law, 0.1, 0.0, 0.5, removal_rate_mm3_s=0.5)
    # ln(0.5 * 0.9 / (0.1 * 0.5)) = ln 9 mm^3, at 0.5 mm^3/s.
    assert life.material_mm3 == pytest.approx(math.log(9.0))
    assert life.time_s == pytest.approx(2 * math.log(9.0))
    banded = remaining_life(law, 0.1, 0.02**2, 0.5)
    assert banded.material_low_mm3 < banded.material_mm3 < banded.material_high_mm3
    assert math.isnan(banded.time_s)
