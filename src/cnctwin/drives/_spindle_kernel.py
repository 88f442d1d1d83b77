"""Numba kernel of the spindle drive (private; see :mod:`cnctwin.drives.spindle`).

The drive's state is ``x = [i, omega, z]``: armature current (A), rotor speed (rad/s) and the
PID integrator ``z = integral of (omega_ref - omega) dt`` (rad). Between two steps the drive is
linear and time-invariant in one of :data:`N_MODES` modes, so each step is exact:
``x <- Phi[mode] @ x + Gamma[mode] @ u`` with the inputs ``u`` held over the step (zero-order hold).
The kernel takes both as one row per mode, ``step_matrix[mode] = [Phi.ravel(), Gamma.ravel()]``
(``3 * 3 + 3 * N_INPUTS`` values), which keeps the inner loop at about 10 ns a step.

Inputs ``u`` (columns of ``Gamma``):

* ``U_REF``: speed reference omega_ref, rad/s;
* ``U_LOAD``: load (cutting) torque after the event gate, N m, opposing positive rotation;
* ``U_FRICTION``: signed Coulomb friction torque ``T_c sign(omega)``, N m;
* ``U_VOLTAGE``: constant armature voltage while the controller output is saturated, V.

Modes: ``MODE_OFF`` (spindle off: open armature, ``i = z = 0``, the rotor coasts) and the
spindle-on modes ``MODE_ON + 4 * saturated + 2 * frozen_integrator``, each plus ``STUCK`` when
Coulomb friction holds the rotor at rest.

Parameter vector ``p``: ``[K_T, B, T_c, J, K_p, K_i, K_d, V_max]`` in N m/A, N m s/rad, N m,
kg m^2, V s/rad, V/rad, V s^2/rad, V (``V_max = inf`` without a limit).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

U_REF = 0
U_LOAD = 1
U_FRICTION = 2
U_VOLTAGE = 3
N_INPUTS = 4

MODE_OFF = 0
MODE_ON = 2
STUCK = 1
N_MODES = 10

P_KT = 0
P_B = 1
P_TC = 2
P_J = 3
P_KP = 4
P_KI = 5
P_KD = 6
P_VMAX = 7
N_PARAMS = 8


_G = 9  # offset of Gamma in a row of the step matrix


@njit(cache=True)
def select_mode(
    current: float, omega: float, integral: float, on: bool, omega_ref: float, load: float,
    p: np.ndarray,
) -> tuple[int, float, float, float]:  # fmt: skip
    """Mode, signed friction torque (N m), held voltage input (V) and applied voltage (V).

    The friction direction is the direction of motion, or at rest the direction the net drive
    torque pushes; at rest a net torque within the Coulomb level leaves the rotor stuck
    (Karnopp's stick condition). The PID output is clamped at ``+-V_max``; while it is clamped
    the integrator stops when the speed error would drive it further into the limit
    (conditional-integration anti-windup).
    """
    coulomb = p[P_TC]
    motor_torque = p[P_KT] * current if on else 0.0
    direction = 0.0
    stuck = 0
    if coulomb > 0.0:
        if omega > 0.0:
            direction = 1.0
        elif omega < 0.0:
            direction = -1.0
        else:
            net = motor_torque - load
            if abs(net) <= coulomb:
                stuck = 1
            else:
                direction = 1.0 if net > 0.0 else -1.0
    friction = coulomb * direction
    if not on:
        return MODE_OFF + stuck, friction, 0.0, 0.0
    accel = 0.0
    if not stuck:
        accel = (motor_torque - p[P_B] * omega - friction - load) / p[P_J]
    error = omega_ref - omega
    v_pid = p[P_KP] * error + p[P_KI] * integral - p[P_KD] * accel
    if abs(v_pid) <= p[P_VMAX]:
        return MODE_ON + stuck, friction, 0.0, v_pid
    v_held = math.copysign(p[P_VMAX], v_pid)
    frozen = 0 if error * v_pid < 0.0 else 1
    return MODE_ON + 4 + 2 * frozen + stuck, friction, v_held, v_held


@njit(cache=True)
def run(
    step_matrix: np.ndarray,
    x: np.ndarray,
    was_on: bool,
    n_sub: int,
    omega_ref: np.ndarray,
    load: np.ndarray,
    spindle_on: np.ndarray,
    p: np.ndarray,
    out_speed: np.ndarray,
    out_current: np.ndarray,
    out_voltage: np.ndarray,
) -> bool:
    """Simulate ``len(omega_ref)`` samples of ``n_sub`` steps each; return the last spindle state.

    ``x`` (current A, speed rad/s, integral rad) is updated in place. Sample ``k`` records the
    state at its start and the voltage applied then; its inputs are held for its ``n_sub``
    steps. Switching the spindle on resets the integrator; switching it off opens the armature
    (``i = 0``). Coulomb friction cannot reverse the motion: a step that would do so ends at rest.
    """
    i, w, z = x[0], x[1], x[2]
    for k in range(omega_ref.shape[0]):
        on = spindle_on[k]
        ref = omega_ref[k]
        tl = load[k]
        if not on:
            i = 0.0
            z = 0.0
        elif not was_on:
            z = 0.0
        out_speed[k] = w
        out_current[k] = i
        for s in range(n_sub):
            mode, fr, vh, v = select_mode(i, w, z, on, ref, tl, p)
            if s == 0:
                out_voltage[k] = v
            m = step_matrix[mode]
            i_new = (
                m[0] * i
                + m[1] * w
                + m[2] * z
                + m[_G] * ref
                + m[_G + 1] * tl
                + m[_G + 2] * fr
                + m[_G + 3] * vh
            )
            w_new = (
                m[3] * i
                + m[4] * w
                + m[5] * z
                + m[_G + 4] * ref
                + m[_G + 5] * tl
                + m[_G + 6] * fr
                + m[_G + 7] * vh
            )
            z_new = (
                m[6] * i
                + m[7] * w
                + m[8] * z
                + m[_G + 8] * ref
                + m[_G + 9] * tl
                + m[_G + 10] * fr
                + m[_G + 11] * vh
            )
            if mode % 2 == STUCK or w_new * fr < 0.0:
                w_new = 0.0
            if not on:
                i_new = 0.0
                z_new = 0.0
            i, w, z = i_new, w_new, z_new
        was_on = on
    x[0] = i
    x[1] = w
    x[2] = z
    return was_on
