"""The spindle drive: a DC armature motor under PID speed control, loaded by the cutting torque.

Christiand et al. 2024 (J. Manuf. Mater. Process. 8, 108), section 3.2:

* Eq. 10 and 15, rotor:      ``J dw/dt + B w = T - kappa psi phi T_cut`` (here plus ``T_c sign w``);
* Eq. 11, armature circuit:  ``L di/dt + R i = V - K_e w``;
* Eq. 12, torque:            ``T = K_T i``;
* Eq. 13-14, speed control:  ``V = K_p e + K_i int e dt + K_d de/dt``, ``e = w_ref - w``;
* Eq. 16-18, the event signals: spindle ``phi``, feed ``psi``, contact ``kappa``
  (:mod:`cnctwin.drives.events`).

Additions to the paper, all neutral with their defaults: a Coulomb friction torque ``T_c``
(default 0; the paper has viscous friction only), a symmetric limit on the armature voltage with
conditional-integration anti-windup (default none), and these event semantics, which the paper
leaves implicit: with the spindle off the drive is disabled (no voltage, open armature: ``i = 0``)
and the rotor coasts on its friction; switching it on starts the PID from a zero integrator.
The derivative acts on the measured speed only (``de/dt = -dw/dt``): a step of the reference
gives no derivative kick.

Integration: exact discretisation. Between steps the drive is linear in one of a few modes
(off, on, on with the voltage clamped, integrator frozen, rotor stuck by Coulomb friction), so a
step is ``x <- Phi x + Gamma u`` with matrix exponentials computed once per step size, and the
result is exact for inputs held over each step; the only discretisation error comes from the
mode chosen at the start of a step (voltage limit reached, rotor stopping) holding to its end.

Units are SI: A, V, rad/s, N m, s. Speeds enter and leave in rpm only where names say so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm

from cnctwin.drives import _spindle_kernel as _k
from cnctwin.drives.events import EventState, MachiningEvents
from cnctwin.errors import ConfigError, DataError, InputError

__all__ = [
    "RAD_S_PER_RPM",
    "SpeedController",
    "SpindleDrive",
    "SpindleDriveParameters",
    "SpindleMotor",
    "SpindleResult",
    "SpindleSample",
    "SpindleState",
    "SteadyState",
]

RAD_S_PER_RPM = 2.0 * math.pi / 60.0
"""Conversion factor from rpm to rad/s."""

_DEFAULT_STEP_S = 1e-4


def _check(name: str, value: float, *, positive: bool) -> None:
    bound = "> 0" if positive else ">= 0"
    ok = math.isfinite(value) and (value > 0.0 if positive else value >= 0.0)
    if not ok:
        raise ConfigError(f"{name}={value!r}; it must be a finite number {bound}")


class SteadyState(NamedTuple):
    """Closed-form operating point of the motor at constant speed and load.

    Attributes
    ----------
    current
        Armature current ``i = (T_L + B w + T_c sign w) / K_T``, A.
    voltage
        Armature voltage ``V = R i + K_e w``, V.
    torque
        Motor torque ``T = K_T i``, N m.
    """

    current: float
    voltage: float
    torque: float


@dataclass(frozen=True, slots=True)
class SpindleMotor:
    """Electrical and mechanical parameters of the spindle motor (Christiand 2024, Eq. 10-12).

    Parameters
    ----------
    resistance
        Armature resistance ``R``, ohm (> 0).
    inductance
        Armature inductance ``L``, H (> 0).
    torque_constant
        Torque constant ``K_T``, N m/A (> 0).
    back_emf_constant
        Back-EMF constant ``K_e``, V s/rad (> 0). An ideal machine has ``K_e = K_T`` in SI
        units; the paper's fitted values differ (see docs/drives.md), so both are kept.
    inertia
        Rotor (and tool) inertia ``J``, kg m^2 (> 0).
    viscous_friction
        Viscous friction coefficient ``B``, N m s/rad (>= 0).
    coulomb_friction
        Coulomb friction torque ``T_c``, N m (>= 0); 0 in the paper.
    """

    resistance: float
    inductance: float
    torque_constant: float
    back_emf_constant: float
    inertia: float
    viscous_friction: float
    coulomb_friction: float = 0.0

    def __post_init__(self) -> None:
        for name in ("resistance", "inductance", "torque_constant", "back_emf_constant", "inertia"):
            _check(name, getattr(self, name), positive=True)
        _check("viscous_friction", self.viscous_friction, positive=False)
        _check("coulomb_friction", self.coulomb_friction, positive=False)

    @property
    def electrical_time_constant(self) -> float:
        """Armature time constant ``L / R``, s."""
        return self.inductance / self.resistance

    @property
    def mechanical_time_constant(self) -> float:
        """Coast-down time constant ``J / B``, s (``inf`` without viscous friction)."""
        if self.viscous_friction == 0.0:
            return math.inf
        return self.inertia / self.viscous_friction

    def steady_state(self, speed: float, load_torque: float = 0.0) -> SteadyState:
        """Current, voltage and torque that hold a constant speed against a constant load.

        Setting ``dw/dt = di/dt = 0`` in Christiand 2024, Eq. 10-12.

        Parameters
        ----------
        speed
            Rotor speed ``w``, rad/s.
        load_torque
            Load torque ``T_L``, N m, opposing positive rotation.

        Returns
        -------
        SteadyState
            Current (A), voltage (V) and motor torque (N m).
        """
        friction = self.coulomb_friction * float(np.sign(speed))
        torque = load_torque + self.viscous_friction * speed + friction
        current = torque / self.torque_constant
        voltage = self.resistance * current + self.back_emf_constant * speed
        return SteadyState(current, voltage, torque)


@dataclass(frozen=True, slots=True)
class SpeedController:
    """PID speed controller whose output is the armature voltage (Christiand 2024, Eq. 13-14).

    Parameters
    ----------
    kp
        Proportional gain ``K_p``, V s/rad (>= 0).
    ki
        Integral gain ``K_i``, V/rad (>= 0).
    kd
        Derivative gain ``K_d``, V s^2/rad (>= 0), applied to the measured speed.
    voltage_limit
        Symmetric limit of the armature voltage, V (> 0), or ``None`` for none (the paper's
        case). With a limit, the integrator stops while the output is clamped and the error
        pushes it further (anti-windup).
    """

    kp: float
    ki: float
    kd: float
    voltage_limit: float | None = None

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd"):
            _check(name, getattr(self, name), positive=False)
        if self.voltage_limit is not None:
            _check("voltage_limit", self.voltage_limit, positive=True)


@dataclass(frozen=True, slots=True)
class SpindleDriveParameters:
    """A spindle motor with its speed controller."""

    motor: SpindleMotor
    controller: SpeedController


@dataclass(frozen=True, slots=True)
class SpindleState:
    """The drive's internal state.

    Attributes
    ----------
    current
        Armature current, A.
    speed
        Rotor speed, rad/s.
    speed_error_integral
        PID integrator ``int (w_ref - w) dt``, rad.
    spindle_on
        Whether the spindle was on (``phi = 1``); switching it on resets the integrator.
    """

    current: float = 0.0
    speed: float = 0.0
    speed_error_integral: float = 0.0
    spindle_on: bool = False


@dataclass(frozen=True, slots=True)
class SpindleSample:
    """The drive's outputs at one instant.

    Attributes
    ----------
    t_s
        Time, s.
    speed
        Rotor speed, rad/s.
    current
        Armature current, A.
    torque
        Motor torque ``K_T i``, N m.
    voltage
        Armature voltage applied from this instant, V.
    """

    t_s: float
    speed: float
    current: float
    torque: float
    voltage: float

    @property
    def speed_rpm(self) -> float:
        """Rotor speed, rpm."""
        return self.speed / RAD_S_PER_RPM


@dataclass(frozen=True, slots=True)
class SpindleResult:
    """Time series of a drive simulation, one value per input sample.

    Attributes
    ----------
    t_s
        Sample times, s.
    speed
        Rotor speed, rad/s.
    current
        Armature current, A.
    torque
        Motor torque ``K_T i``, N m (Christiand 2024, Eq. 12).
    voltage
        Armature voltage applied from each sample on, V.
    load_torque
        Load torque after the event gate ``kappa psi phi``, N m (Eq. 15).
    """

    t_s: NDArray[np.float64]
    speed: NDArray[np.float64]
    current: NDArray[np.float64]
    torque: NDArray[np.float64]
    voltage: NDArray[np.float64]
    load_torque: NDArray[np.float64]

    @property
    def speed_rpm(self) -> NDArray[np.float64]:
        """Rotor speed, rpm."""
        return self.speed / RAD_S_PER_RPM


def _continuous_mode(
    motor: SpindleMotor, ctrl: SpeedController, mode: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """State and input matrices ``(A, B_u)`` of one mode, ``dx/dt = A x + B_u u``."""
    a = np.zeros((3, 3))
    b = np.zeros((3, _k.N_INPUTS))
    on = mode >= _k.MODE_ON
    stuck = mode % 2 == _k.STUCK
    if not stuck:
        # Eq. 15 with Eq. 12: J dw/dt = K_T i - B w - T_c sign w - T_L.
        a[1, 1] = -motor.viscous_friction / motor.inertia
        b[1, _k.U_FRICTION] = -1.0 / motor.inertia
        if on:
            a[1, 0] = motor.torque_constant / motor.inertia
            b[1, _k.U_LOAD] = -1.0 / motor.inertia
    if not on:
        return a, b
    k = mode - _k.MODE_ON
    saturated, frozen = k >= 4, (k // 2) % 2 == 1
    if saturated:
        v_x = np.zeros(3)
        v_u = np.zeros(_k.N_INPUTS)
        v_u[_k.U_VOLTAGE] = 1.0
    else:
        # Eq. 13-14 with de/dt = -dw/dt for a reference held over the step.
        v_x = np.array([0.0, -ctrl.kp, ctrl.ki]) - ctrl.kd * a[1]
        v_u = -ctrl.kd * b[1]
        v_u[_k.U_REF] += ctrl.kp
    # Eq. 11: L di/dt = V - R i - K_e w.
    a[0] = (v_x - np.array([motor.resistance, motor.back_emf_constant, 0.0])) / motor.inductance
    b[0] = v_u / motor.inductance
    if not frozen:
        a[2, 1] = -1.0
        b[2, _k.U_REF] = 1.0
    return a, b


def _discretise(params: SpindleDriveParameters, step_s: float) -> NDArray[np.float64]:
    """Exact one-step transition of every mode for a step of ``step_s`` (s).

    Row ``mode`` holds ``Phi.ravel()`` then ``Gamma.ravel()``, where ``[Phi, Gamma]`` is the top
    of ``expm([[A, B_u], [0, 0]] step_s)`` (zero-order hold of the inputs).
    """
    n = 3 + _k.N_INPUTS
    rows = np.empty((_k.N_MODES, 3 * n))
    for mode in range(_k.N_MODES):
        a, b = _continuous_mode(params.motor, params.controller, mode)
        block = np.zeros((n, n))
        block[:3, :3] = a
        block[:3, 3:] = b
        e = expm(block * step_s)
        rows[mode, :9] = e[:3, :3].ravel()
        rows[mode, 9:] = e[:3, 3:].ravel()
    return rows


def _param_vector(params: SpindleDriveParameters) -> NDArray[np.float64]:
    m, c = params.motor, params.controller
    p = np.empty(_k.N_PARAMS)
    p[_k.P_KT] = m.torque_constant
    p[_k.P_B] = m.viscous_friction
    p[_k.P_TC] = m.coulomb_friction
    p[_k.P_J] = m.inertia
    p[_k.P_KP] = c.kp
    p[_k.P_KI] = c.ki
    p[_k.P_KD] = c.kd
    p[_k.P_VMAX] = math.inf if c.voltage_limit is None else c.voltage_limit
    return p


def _series(name: str, value: ArrayLike, n: int) -> NDArray[np.float64]:
    """``value`` as a finite float array of length ``n`` (a scalar is repeated)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise DataError(f"{name} has shape {arr.shape}; it must be a scalar or have shape ({n},)")
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{name} has non-finite values; every value must be a finite number")
    return arr


def _check_state(state: SpindleState) -> None:
    values = (state.current, state.speed, state.speed_error_integral)
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"initial state {state!r}; current, speed and integral must be finite")


class SpindleDrive:
    """Spindle motor plus PID speed control, loaded by the event-gated cutting torque.

    Christiand 2024, Eq. 10-18 (see the module docstring for the additions and event semantics).

    Parameters
    ----------
    params
        Motor and controller, e.g. ``spindle_preset("christiand2024")``.
    step_s
        Largest integration step, s (default 1e-4, a 10 kHz step). :meth:`simulate` splits each
        sample interval into equal steps no longer than this; :meth:`step` advances in steps of
        exactly this length.

    Examples
    --------
    >>> import numpy as np
    >>> from cnctwin.drives import SpindleDrive, spindle_preset
    >>> drive = SpindleDrive(spindle_preset("christiand2024"))
    >>> result = drive.simulate(np.arange(0.0, 5.0, 1e-4), 20000.0)
    >>> round(float(result.speed_rpm[-1]))
    20000
    """

    def __init__(self, params: SpindleDriveParameters, step_s: float = _DEFAULT_STEP_S) -> None:
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise InputError(f"step_s={step_s!r}; the integration step must be a number > 0 s")
        self._params = params
        self._step_s = step_s
        self._p = _param_vector(params)
        self._matrices: dict[float, NDArray[np.float64]] = {}
        self._x = np.zeros(3)
        self._on = False
        self._t_s = 0.0
        self._pending_s = 0.0
        # One-sample buffers for step(), reused to keep a live call cheap.
        self._ref1 = np.empty(1)
        self._load1 = np.empty(1)
        self._on1 = np.empty(1, dtype=np.bool_)
        self._out1 = np.empty((3, 1))

    @property
    def params(self) -> SpindleDriveParameters:
        """Motor and controller parameters."""
        return self._params

    @property
    def step_s(self) -> float:
        """Largest integration step, s."""
        return self._step_s

    @property
    def state(self) -> SpindleState:
        """Live state after the last :meth:`step` (or :meth:`reset`)."""
        return SpindleState(float(self._x[0]), float(self._x[1]), float(self._x[2]), self._on)

    @property
    def t_s(self) -> float:
        """Live time, s: the sum of the steps taken since :meth:`reset`."""
        return self._t_s

    def reset(self, state: SpindleState | None = None, t_s: float = 0.0) -> None:
        """Set the live state (default: at rest, spindle off) and clock (s)."""
        state = state or SpindleState()
        _check_state(state)
        self._x[:] = (state.current, state.speed, state.speed_error_integral)
        self._on = state.spindle_on
        self._t_s = float(t_s)
        self._pending_s = 0.0

    def _matrices_for(self, h: float) -> NDArray[np.float64]:
        if h not in self._matrices:
            self._matrices[h] = _discretise(self._params, h)
        return self._matrices[h]

    def simulate(
        self,
        t_s: ArrayLike,
        speed_ref_rpm: ArrayLike,
        load_torque_nm: ArrayLike = 0.0,
        events: MachiningEvents | None = None,
        initial: SpindleState | None = None,
    ) -> SpindleResult:
        """Simulate the drive over a uniform time grid (the live state is not touched).

        Parameters
        ----------
        t_s
            Sample times, s: at least two, uniformly spaced, increasing.
        speed_ref_rpm
            Speed reference, rpm (negative: reverse), a scalar or one value per sample, held
            until the next sample.
        load_torque_nm
            Cutting torque, N m, opposing positive rotation; a scalar or one value per sample.
            It acts only while spindle, feed and contact are all on (Eq. 15).
        events
            Spindle, feed and contact signals per sample; ``None`` means all on throughout.
        initial
            State at ``t_s[0]``; default at rest with the spindle off.

        Returns
        -------
        SpindleResult
            Speed (rad/s), current (A), torque (N m), voltage (V) and gated load (N m) per sample.
        """
        t = np.asarray(t_s, dtype=np.float64)
        if t.ndim != 1 or t.size < 2:
            raise DataError(f"t_s has shape {t.shape}; it must be 1-D with at least two samples")
        dt = float(t[1] - t[0])
        spacing = np.diff(t)
        if not (dt > 0.0 and np.all(np.abs(spacing - dt) <= 1e-6 * dt)):
            raise DataError(
                f"t_s is not uniformly increasing (steps from {spacing.min()!r} to "
                f"{spacing.max()!r} s); it must have one constant step > 0"
            )
        n = t.size
        omega_ref = _series("speed_ref_rpm", speed_ref_rpm, n) * RAD_S_PER_RPM
        load = _series("load_torque_nm", load_torque_nm, n)
        if events is None:
            events = MachiningEvents.constant(n)
        if len(events) != n:
            raise DataError(f"events has {len(events)} samples; it must have {n}, like t_s")
        load = load * events.load_gate()
        spindle_on = np.ascontiguousarray(events.spindle_on, dtype=np.bool_)

        state = initial or SpindleState()
        _check_state(state)
        x = np.array([state.current, state.speed, state.speed_error_integral])
        n_sub = max(1, math.ceil(dt / self._step_s * (1.0 - 1e-9)))
        step_matrix = self._matrices_for(dt / n_sub)
        speed = np.empty(n)
        current = np.empty(n)
        voltage = np.empty(n)
        _k.run(
            step_matrix, x, state.spindle_on, n_sub, omega_ref, load, spindle_on, self._p,
            speed, current, voltage,
        )  # fmt: skip
        torque = self._params.motor.torque_constant * current
        return SpindleResult(t, speed, current, torque, voltage, load)

    def step(
        self,
        duration_s: float,
        speed_ref_rpm: float,
        load_torque_nm: float = 0.0,
        events: EventState | None = None,
    ) -> SpindleSample:
        """Advance the live drive with inputs held for ``duration_s``; return its new outputs.

        The drive advances in whole steps of :attr:`step_s`; a remainder shorter than a step is
        carried to the next call, so the drive's clock never runs ahead of the caller's.

        Parameters
        ----------
        duration_s
            Time to advance, s (>= 0), e.g. the twin's cycle time.
        speed_ref_rpm
            Speed reference, rpm.
        load_torque_nm
            Cutting torque, N m, opposing positive rotation (gated by ``events``).
        events
            Spindle, feed and contact signals; ``None`` means all on.

        Returns
        -------
        SpindleSample
            Speed (rad/s), current (A), torque (N m) and voltage (V) at the new time.
        """
        values = (duration_s, speed_ref_rpm, load_torque_nm)
        if not all(math.isfinite(v) for v in values) or duration_s < 0.0:
            raise DataError(
                f"step(duration_s={duration_s!r}, speed_ref_rpm={speed_ref_rpm!r}, "
                f"load_torque_nm={load_torque_nm!r}); all must be finite and duration_s >= 0"
            )
        events = events or EventState()
        on = events.spindle_on
        omega_ref = speed_ref_rpm * RAD_S_PER_RPM
        load = load_torque_nm * events.load_gate
        h = self._step_s
        self._pending_s += duration_s
        n_steps = math.floor(self._pending_s / h + 1e-9)
        if n_steps > 0:
            self._ref1[0], self._load1[0], self._on1[0] = omega_ref, load, on
            out = self._out1
            self._on = _k.run(
                self._matrices_for(h), self._x, self._on, n_steps, self._ref1, self._load1,
                self._on1, self._p, out[0], out[1], out[2],
            )  # fmt: skip
            self._pending_s = max(0.0, self._pending_s - n_steps * h)
            self._t_s += n_steps * h
        if not on:
            self._x[0] = 0.0
            self._x[2] = 0.0
        elif not self._on:
            self._x[2] = 0.0
        self._on = on
        current, speed, integral = (float(v) for v in self._x)
        voltage = _k.select_mode(current, speed, integral, on, omega_ref, load, self._p)[3]
        return SpindleSample(
            self._t_s,
            speed,
            current,
            self._params.motor.torque_constant * current,
            float(voltage),
        )
