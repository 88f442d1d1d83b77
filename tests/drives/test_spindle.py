"""Spindle drive (Christiand 2024, Eq. 10-18) against closed forms and independent integrations.

References used here, none of them the drive's own output:
* the steady state of Eq. 10-12 solved by hand (dw/dt = di/dt = 0);
* the closed-loop transfer functions of Eq. 10-14, simulated by scipy.signal.lsim;
* the free coast-down of Eq. 10 (exponential, with Coulomb friction an exponential offset);
* the power balances of Eq. 10 and 11, integrated from the outputs;
* an adaptive Runge-Kutta integration (scipy.integrate.solve_ivp) of the saturated PID loop.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import solve_ivp, trapezoid

from cnctwin.drives import (
    EventState,
    MachiningEvents,
    SpeedController,
    SpindleDrive,
    SpindleDriveParameters,
    SpindleState,
    spindle_preset,
)
from cnctwin.errors import ConfigError, DataError, InputError

PRESET = spindle_preset("christiand2024")
MOTOR = PRESET.motor
CTRL = PRESET.controller
REF_RPM = 20000.0  # the paper's spindle speed (section 5.1)
W_REF = REF_RPM * 2.0 * math.pi / 60.0  # rad/s


def plant_den() -> np.ndarray:
    """``L J s^2 + (L B + R J) s + R B + K_T K_e`` (Eq. 10-12 with i eliminated)."""
    m = MOTOR
    return np.array(
        [
            m.inductance * m.inertia,
            m.inductance * m.viscous_friction + m.resistance * m.inertia,
            m.resistance * m.viscous_friction + m.torque_constant * m.back_emf_constant,
        ]
    )


def closed_loop_den() -> np.ndarray:
    """``s * plant_den + K_T (K_d s^2 + K_p s + K_i)``: Eq. 13-14 closed around the plant."""
    return np.polyadd(np.polymul([1.0, 0.0], plant_den()), MOTOR.torque_constant * np.array(
        [CTRL.kd, CTRL.kp, CTRL.ki]))  # fmt: skip


def test_steady_state_matches_closed_form() -> None:
    # Constant speed w and load T_L in Eq. 10-12: i = (T_L + B w + T_c) / K_T, V = R i + K_e w.
    motor = dataclasses.replace(MOTOR, coulomb_friction=2e-4)
    drive = SpindleDrive(SpindleDriveParameters(motor, CTRL))
    load = 1e-3  # N m, about the idle torque (B w = 1.26e-3 N m)
    t = np.arange(0.0, 20.0, 1e-3)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 20)], feed_s=[(0, 20)],
                                            contact_s=[(4, 20)])  # fmt: skip
    r = drive.simulate(t, REF_RPM, load, events)
    i_expected = (load + motor.viscous_friction * W_REF + 2e-4) / motor.torque_constant
    v_expected = motor.resistance * i_expected + motor.back_emf_constant * W_REF
    # The slowest closed-loop pole is -3.66 1/s: after 16 s the transient is ~1e-25 of the step.
    assert r.speed[-1] == pytest.approx(W_REF, rel=1e-9)
    assert r.current[-1] == pytest.approx(i_expected, rel=1e-9)
    assert r.voltage[-1] == pytest.approx(v_expected, rel=1e-9)
    assert r.torque[-1] == pytest.approx(motor.torque_constant * i_expected, rel=1e-9)
    ss = motor.steady_state(W_REF, load)
    assert (ss.current, ss.voltage) == pytest.approx((i_expected, v_expected), rel=1e-12)


def test_startup_matches_closed_loop_transfer_function() -> None:
    # Speed and torque after switching the spindle on at 20,000 rpm, from rest.
    t = np.arange(0.0, 3.0, 1e-4)
    r = SpindleDrive(PRESET).simulate(t, REF_RPM)
    kt = MOTOR.torque_constant
    num_w = kt * np.array([CTRL.kp, CTRL.ki])  # derivative on the measurement: no K_d s term
    den = closed_loop_den()
    _, w_ref, _ = signal.lsim((num_w, den), np.full(t.size, W_REF), t)
    # Motor torque T = J dw/dt + B w without load (Eq. 10).
    num_t = np.polymul([MOTOR.inertia, MOTOR.viscous_friction], num_w)
    _, torque_ref, _ = signal.lsim((num_t, den), np.full(t.size, W_REF), t)
    # Exact discretisation vs lsim's own matrix exponential: agreement to round-off.
    assert np.max(np.abs(r.speed - w_ref)) < 1e-7 * W_REF
    assert np.max(np.abs(r.torque - torque_ref)) < 1e-7 * np.max(torque_ref)


def test_startup_torque_overshoot_idle_torque_and_settling() -> None:
    # Christiand 2024, Fig. 6d: a torque overshoot right after the spindle is switched on, then
    # the idle "no-load" torque at the reference speed.
    t = np.arange(0.0, 8.0, 1e-4)
    r = SpindleDrive(PRESET).simulate(t, REF_RPM)
    idle_torque = MOTOR.viscous_friction * W_REF  # B w_ref, closed form
    peak = int(np.argmax(r.torque))
    assert r.torque[peak] > 10.0 * idle_torque  # the rotor's inertia dominates the start
    assert t[peak] < 0.5
    assert r.torque[-1] == pytest.approx(idle_torque, rel=1e-6)
    assert r.current[-1] == pytest.approx(idle_torque / MOTOR.torque_constant, rel=1e-6)
    # Reaches and holds the reference: within 2 % after 1.5 s, within 1e-6 after 6 s.
    assert np.all(np.abs(r.speed[t >= 1.5] - W_REF) < 0.02 * W_REF)
    assert np.all(np.abs(r.speed[t >= 6.0] - W_REF) < 1e-6 * W_REF)


def test_cutting_torque_step_matches_disturbance_response() -> None:
    # Idle at the reference, then the tool enters the cut (load step T_L) and leaves it.
    load = 1e-3  # N m
    t = np.arange(0.0, 14.0, 1e-4)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 14)], feed_s=[(0, 14)],
                                            contact_s=[(8, 11)])  # fmt: skip
    r = SpindleDrive(PRESET).simulate(t, REF_RPM, load, events)
    idle = MOTOR.viscous_friction * W_REF
    before = np.searchsorted(t, 8.0) - 1
    end_cut = np.searchsorted(t, 11.0) - 1
    assert r.torque[before] == pytest.approx(idle, rel=1e-6)
    # Integral action: torque rises by exactly T_L and the speed returns to the reference.
    assert r.torque[end_cut] - idle == pytest.approx(load, rel=1e-5)
    assert r.speed[end_cut] == pytest.approx(W_REF, rel=1e-6)
    # The speed dip follows the disturbance transfer function of Eq. 10-14:
    # w / T_L = -(L s + R) s / closed_loop_den.
    m = MOTOR
    num = -np.polymul([m.inductance, m.resistance], [1.0, 0.0])
    k0 = np.searchsorted(t, 8.0)
    tt = t[k0:end_cut] - t[k0]
    _, dip, _ = signal.lsim((num, closed_loop_den()), np.full(tt.size, load), tt)
    assert np.min(dip) < -5e-3 * W_REF  # a visible dip (13.3 rad/s, 127 rpm)
    assert np.max(np.abs((r.speed[k0:end_cut] - W_REF) - dip)) < 1e-8 * np.max(np.abs(dip))


def test_power_balances() -> None:
    # Eq. 11 times i: V i = R i^2 + d(L i^2 / 2)/dt + K_e w i.
    # Eq. 10 times w: K_T i w = B w^2 + T_c |w| + T_L w + d(J w^2 / 2)/dt.
    motor = dataclasses.replace(MOTOR, coulomb_friction=1e-4)
    t = np.arange(0.0, 3.0, 1e-5)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 3)], feed_s=[(0, 3)],
                                            contact_s=[(1.5, 3)])  # fmt: skip
    r = SpindleDrive(SpindleDriveParameters(motor, CTRL)).simulate(t, REF_RPM, 1e-3, events)
    i, w = r.current, r.speed
    e_in = trapezoid(r.voltage * i, t)
    e_el = trapezoid(
        motor.resistance * i**2 + motor.back_emf_constant * w * i, t
    ) + 0.5 * motor.inductance * (i[-1] ** 2 - i[0] ** 2)
    assert e_el == pytest.approx(e_in, rel=1e-9)
    e_shaft = trapezoid(motor.torque_constant * i * w, t)
    e_mech = trapezoid(
        motor.viscous_friction * w**2 + motor.coulomb_friction * np.abs(w) + r.load_torque * w, t
    ) + 0.5 * motor.inertia * (w[-1] ** 2 - w[0] ** 2)
    assert e_mech == pytest.approx(e_shaft, rel=1e-5)  # trapezoidal rule on the kinks


def test_spindle_off_no_current_and_coast_down() -> None:
    t = np.arange(0.0, 40.0, 1e-3)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 6)], feed_s=[(0, 40)],
                                            contact_s=[(0, 40)])  # fmt: skip
    tc = 5e-5  # N m
    motor = dataclasses.replace(MOTOR, coulomb_friction=tc)
    r = SpindleDrive(SpindleDriveParameters(motor, CTRL)).simulate(t, REF_RPM, 1e-3, events)
    off = t >= 6.0
    assert np.all(r.current[off] == 0.0)
    assert np.all(r.voltage[off] == 0.0)
    assert np.all(r.torque[off] == 0.0)
    assert np.all(r.load_torque[off] == 0.0)
    # Free rotor, Eq. 10 with T = 0: J dw/dt = -B w - T_c, so
    # w(t) = (w0 + T_c / B) exp(-B t / J) - T_c / B until it stops at t* = J/B ln(1 + B w0 / T_c).
    k0 = np.searchsorted(t, 6.0)
    w0 = r.speed[k0]
    b, j = motor.viscous_friction, motor.inertia
    tau = t[k0:] - t[k0]
    expected = np.maximum((w0 + tc / b) * np.exp(-b * tau / j) - tc / b, 0.0)
    assert np.max(np.abs(r.speed[k0:] - expected)) < 1e-9 * w0
    t_stop = j / b * math.log(1.0 + b * w0 / tc)
    assert t_stop < 39.0  # about 33 s: the rotor stops within the run
    assert np.all(r.speed[k0:][tau > t_stop + 1e-3] == 0.0)


def test_load_acts_only_with_spindle_feed_and_contact() -> None:
    t = np.arange(0.0, 6.0, 1e-3)
    drive = SpindleDrive(PRESET)
    free = drive.simulate(t, REF_RPM, 0.0)
    for feed, contact in ((False, True), (True, False)):
        events = MachiningEvents.constant(t.size, feed_on=feed, in_contact=contact)
        r = drive.simulate(t, REF_RPM, 2e-3, events)
        assert np.array_equal(r.speed, free.speed)
        assert np.array_equal(r.current, free.current)
    loaded = drive.simulate(t, REF_RPM, 2e-3)
    assert loaded.torque[-1] > free.torque[-1] + 1.9e-3


def test_restart_from_rest_repeats_the_startup() -> None:
    # Switching on resets the integrator: a second start from rest is the first one again.
    # Coulomb friction stops the coasting rotor (after ~33 s), so the restart is from rest.
    t = np.arange(0.0, 50.0, 1e-3)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 5), (45, 50)])
    params = SpindleDriveParameters(dataclasses.replace(MOTOR, coulomb_friction=5e-5), CTRL)
    r = SpindleDrive(params).simulate(t, REF_RPM, 0.0, events)
    k = np.searchsorted(t, 45.0)
    assert r.speed[k] == 0.0
    n = 5000
    assert np.allclose(r.speed[k : k + n], r.speed[:n], rtol=0, atol=1e-9 * W_REF)


def saturating_params(coulomb: float = 0.0) -> SpindleDriveParameters:
    """The preset motor under a stiffer PI that hits a 24 V limit on every start."""
    motor = dataclasses.replace(MOTOR, coulomb_friction=coulomb)
    return SpindleDriveParameters(motor, SpeedController(kp=0.05, ki=0.5, kd=0.0,
                                                         voltage_limit=24.0))  # fmt: skip


def reference_ivp(params: SpindleDriveParameters, t: np.ndarray, windup: bool) -> np.ndarray:
    """Speed from an adaptive RK integration of Eq. 10-14 with the voltage clamp (T_c = 0)."""
    m, c = params.motor, params.controller
    vmax = c.voltage_limit
    assert vmax is not None

    def rhs(_t: float, x: np.ndarray) -> list[float]:
        i, w, z = x
        e = W_REF - w
        v_pid = c.kp * e + c.ki * z
        v = min(max(v_pid, -vmax), vmax)
        clamped = v != v_pid and e * v_pid > 0.0
        dz = 0.0 if clamped and not windup else e
        return [
            (v - m.resistance * i - m.back_emf_constant * w) / m.inductance,
            (m.torque_constant * i - m.viscous_friction * w) / m.inertia,
            dz,
        ]

    sol = solve_ivp(rhs, (t[0], t[-1]), [0.0, 0.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-10,
                    max_step=1e-3, method="LSODA")  # fmt: skip
    return sol.y[1]


def test_voltage_limit_and_anti_windup_match_rk_reference() -> None:
    params = saturating_params()
    t = np.arange(0.0, 1.5, 1e-4)
    r = SpindleDrive(params).simulate(t, REF_RPM)
    assert np.max(r.voltage) == pytest.approx(24.0)  # the limit is reached ...
    assert np.all(np.abs(r.voltage) <= 24.0)
    assert r.speed[-1] == pytest.approx(W_REF, rel=1e-3)  # ... and the speed still settles
    w_ivp = reference_ivp(params, t, windup=False)
    # Mode switches at step starts cost ~1.5e-4 of the speed at 10 kHz (first order in the step).
    assert np.max(np.abs(r.speed - w_ivp)) < 5e-4 * W_REF
    # Without anti-windup the integrator would overshoot far more: the clamp matters.
    w_windup = reference_ivp(params, t, windup=True)
    overshoot, overshoot_windup = np.max(r.speed) - W_REF, np.max(w_windup) - W_REF
    assert overshoot_windup > 2.0 * max(overshoot, 0.0) + 0.01 * W_REF


def test_converges_with_step_size() -> None:
    # Mode switches (voltage clamp, Coulomb stick/slip, spindle off/on) are the only
    # discretisation error: 10 kHz must be close to 100 kHz and closer than 1 kHz.
    params = saturating_params(coulomb=1e-4)
    t_end = 12.0

    def run(step: float) -> np.ndarray:
        t = np.arange(0.0, t_end, step)
        events = MachiningEvents.from_intervals(t, spindle_s=[(0, 3), (8, 12)], feed_s=[(0, 12)],
                                                contact_s=[(1.5, 2.5)])  # fmt: skip
        r = SpindleDrive(params, step_s=step).simulate(t, REF_RPM, 2e-3, events)
        return r.speed[:: round(1e-2 / step)]  # common 100 Hz grid

    fine, mid, coarse = run(1e-5), run(1e-4), run(1e-3)
    err_mid = np.max(np.abs(mid - fine))
    err_coarse = np.max(np.abs(coarse - fine))
    assert err_mid < 5e-4 * W_REF  # 1.6e-4 measured
    assert err_mid < 0.2 * err_coarse


def test_live_step_equals_batch_simulation() -> None:
    t = np.arange(0.0, 4.0, 1e-3)
    events = MachiningEvents.from_intervals(t, spindle_s=[(0, 3)], feed_s=[(1, 3)],
                                            contact_s=[(1.5, 2.5)])  # fmt: skip
    ref = np.where(t < 2.0, REF_RPM, 15000.0)
    batch = SpindleDrive(PRESET).simulate(t, ref, 1e-3, events)
    live = SpindleDrive(PRESET)
    samples = [live.step(1e-3, float(ref[k]), 1e-3, events.at(k)) for k in range(t.size - 1)]
    speed = np.array([s.speed for s in samples])
    current = np.array([s.current for s in samples])
    np.testing.assert_allclose(speed, batch.speed[1:], rtol=0, atol=1e-9 * W_REF)
    # A step returns the state reached under its own events; the batch sample at the same time
    # already shows the next sample's events (the current drops to 0 when the spindle goes off).
    same_events = events.spindle_on[1:] == events.spindle_on[:-1]
    assert np.count_nonzero(~same_events) == 1
    np.testing.assert_allclose(current[same_events], batch.current[1:][same_events], atol=1e-9)
    assert samples[-1].t_s == pytest.approx(t[-1])


def test_live_step_carries_partial_steps() -> None:
    drive = SpindleDrive(PRESET, step_s=1e-4)
    drive.step(0.00025, REF_RPM)  # two steps, 0.5 step carried
    assert drive.t_s == pytest.approx(2e-4)
    drive.step(0.00025, REF_RPM)
    assert drive.t_s == pytest.approx(5e-4)
    drive.reset(SpindleState(speed=W_REF, spindle_on=True))
    sample = drive.step(0.0, REF_RPM, 0.0, EventState(spindle_on=False))
    assert sample.current == 0.0 and sample.voltage == 0.0 and sample.speed == W_REF


def test_bad_inputs_raise_one_line_errors() -> None:
    drive = SpindleDrive(PRESET)
    with pytest.raises(DataError, match="uniformly"):
        drive.simulate([0.0, 0.1, 0.3], REF_RPM)
    with pytest.raises(DataError, match="shape"):
        drive.simulate([0.0, 0.1, 0.2], [1.0, 2.0])
    with pytest.raises(DataError, match="non-finite"):
        drive.simulate([0.0, 0.1], [1.0, math.nan])
    with pytest.raises(DataError, match="events"):
        drive.simulate([0.0, 0.1], REF_RPM, 0.0, MachiningEvents.constant(3))
    with pytest.raises(DataError, match="duration_s"):
        drive.step(-1.0, REF_RPM)
    with pytest.raises(ConfigError, match="inductance"):
        dataclasses.replace(MOTOR, inductance=0.0)
    with pytest.raises(ConfigError, match="voltage_limit"):
        SpeedController(kp=1.0, ki=1.0, kd=0.0, voltage_limit=-5.0)
    with pytest.raises(InputError, match="step_s"):
        SpindleDrive(PRESET, step_s=0.0)
