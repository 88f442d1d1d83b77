"""The "machining-centre-15kw" spindle preset: each value follows from its rating by its rule.

The rating (docs/signals.md, "Spindle drive presets"): S1 15 kW from a base speed of 1,500 rpm,
12,000 rpm top speed, a 400 V three-phase supply. The checks recompute every derived value from
the rating with the stated rule, then check the drive's behaviour with closed forms: the
designed closed-loop poles, the voltage needed at top speed, the current at rated torque.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.drives import RAD_S_PER_RPM, MachiningEvents, SpindleDrive, spindle_preset

PRESET = spindle_preset("machining-centre-15kw")
P_S1_W = 15e3
W_BASE = 1500.0 * RAD_S_PER_RPM
W_MAX = 12_000.0 * RAD_S_PER_RPM
T_S1_NM = P_S1_W / W_BASE  # 95.5 N m
I_S1_A = P_S1_W / (math.sqrt(3.0) * 400.0 * 0.75)  # eta cos(phi) = 0.75: 28.9 A


def test_values_follow_from_the_rating() -> None:
    m, c = PRESET.motor, PRESET.controller
    assert m.torque_constant == pytest.approx(T_S1_NM / I_S1_A, rel=0.01)  # 3.30 N m/A
    assert c.voltage_limit is not None
    assert c.voltage_limit == pytest.approx(400.0 * math.sqrt(2.0), rel=0.02)  # DC link
    assert m.back_emf_constant == pytest.approx(0.9 * c.voltage_limit / W_MAX, rel=0.01)
    assert m.resistance * I_S1_A**2 == pytest.approx(0.04 * P_S1_W, rel=0.01)  # copper loss
    assert m.electrical_time_constant == pytest.approx(0.010)
    assert m.viscous_friction * W_MAX**2 == pytest.approx(1000.0, rel=0.01)  # idle power

    # Rotor, shaft, holder and tool as steel cylinders (7850 kg/m^3): J = m r^2 / 2.
    def cylinder(d_m: float, length_m: float) -> float:
        mass = 7850.0 * math.pi * (d_m / 2) ** 2 * length_m
        return mass * (d_m / 2) ** 2 / 2

    estimate = cylinder(0.100, 0.200) + cylinder(0.065, 0.500) + 1e-3
    assert m.inertia == pytest.approx(estimate, rel=0.1)
    assert (m.coulomb_friction, c.kd) == (0.0, 0.0)


def test_speed_loop_has_the_designed_poles() -> None:
    m, c = PRESET.motor, PRESET.controller
    # Closed loop of Eq. 10-14 (tests/drives/test_presets.py), designed as
    # (s + 20)(s^2 + 80 s + 6400): a real pole and a pair with zeta 0.5, wn 80 rad/s.
    poly = [
        m.inductance * m.inertia,
        m.inductance * m.viscous_friction + m.resistance * m.inertia + m.torque_constant * c.kd,
        m.resistance * m.viscous_friction + m.torque_constant * (m.back_emf_constant + c.kp),
        m.torque_constant * c.ki,
    ]
    poles = np.sort_complex(np.roots(poly))
    designed = np.sort_complex(np.roots([1.0, 100.0, 8000.0, 128000.0]))
    assert np.allclose(poles, designed, rtol=0.01)


def test_top_speed_is_reached_within_the_voltage_limit() -> None:
    m, c = PRESET.motor, PRESET.controller
    assert c.voltage_limit is not None
    idle = m.steady_state(W_MAX)
    assert idle.voltage < 0.95 * c.voltage_limit
    # Rated torque at top speed still fits (the DC model has no field weakening).
    assert m.steady_state(W_MAX, T_S1_NM * W_BASE / W_MAX).voltage < c.voltage_limit
    result = SpindleDrive(PRESET, step_s=1e-4).simulate(np.arange(0.0, 3.0, 1e-3), 12_000.0)
    assert result.speed_rpm[-1] == pytest.approx(12_000.0, rel=1e-4)
    assert np.max(np.abs(result.voltage)) <= c.voltage_limit + 1e-9


def test_rated_torque_draws_the_rated_current() -> None:
    # Rated torque at base speed: the rating's current, plus 0.03 A of friction (K_T rounded).
    state = PRESET.motor.steady_state(W_BASE, T_S1_NM)
    assert state.current == pytest.approx(I_S1_A, rel=0.01)
    assert state.current == pytest.approx(28.9, rel=0.01)


def test_start_and_load_step_at_3800_rpm() -> None:
    # The KIT notch program's speed: a start from rest and a 2.5 N m cutting load.
    t = np.arange(0.0, 4.0, 1e-3)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 4)], feed_s=[(0, 4)],
                                            contact_s=[(2, 4)])  # fmt: skip
    result = SpindleDrive(PRESET).simulate(t, 3800.0, 2.5, events)
    assert np.max(result.current) < 2.0 * I_S1_A  # the start-up stays within a drive's peak
    settled = result.speed_rpm[(t > 0.5) & (t < 2.0)]
    assert np.allclose(settled, 3800.0, rtol=1e-3)
    dip = 3800.0 - np.min(result.speed_rpm[t > 2.0])
    assert 0.0 < dip < 0.01 * 3800.0
    w = 3800.0 * RAD_S_PER_RPM
    m = PRESET.motor
    assert result.current[-1] == pytest.approx((2.5 + m.viscous_friction * w) / m.torque_constant)
