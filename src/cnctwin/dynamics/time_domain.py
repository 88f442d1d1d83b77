"""Time-domain simulation of milling vibration: regeneration, process damping, forced response.

Royandi 2026, Eq. 1-12 with the 2-DOF form Eq. 6-7, generalised to any set of tool-tip modes
(:class:`~cnctwin.dynamics.stability.ToolDynamics`): each mode ``i`` (natural frequency
``wn_i``, damping ratio ``zeta_i``, stiffness ``k_i``, direction ``d_i`` in the x-y plane)
obeys

    q_i'' + 2 zeta_i wn_i q_i' + wn_i^2 q_i = (wn_i^2 / k_i) d_i . (F_c(t) - C_eff v(t)),

the tool tip moves by ``r = sum_i d_i q_i`` (velocity ``v``), ``F_c`` is the cutting force on the
tool and ``C_eff v`` the process-damping force of Royandi 2026, Eq. 3 (``C_eff = C_pd a_p f_z /
V_c``, :class:`~cnctwin.dynamics.stability.ProcessDamping`; it acts in x and y at all times, as
in the semi-discretization of :mod:`cnctwin.dynamics.stability`).

The cutting force sums axial slices (helix lag ``psi = z tan(beta) / R``) and teeth: a tooth
at immersion ``phi`` inside the immersion interval with a chip ``h > 0`` adds, per slice width
``dz`` (Royandi 2026, Eq. 8-11 in the frame of :mod:`cnctwin.mechanics.engagement`: x along the
feed, phi clockwise from +y),

    dFx = -(Ktc h + Kte) cos(phi) - (Krc h + Kre) sin(phi),
    dFy = +(Ktc h + Kte) sin(phi) - (Krc h + Kre) cos(phi),

with the regenerative chip (Royandi 2026, Eq. 12 in this frame)
``h = f_z sin(phi) + (r(t) - r(t - T)) . (sin phi, cos phi)``, measured against the surface the
last cutting tooth left: a tooth whose chip is ``h <= 0`` has left the cut and feels no force
(shear nor edge), and the next tooth meets the older surface (see
:mod:`cnctwin.dynamics._time_domain_kernels`). ``regenerative=False`` takes the nominal chip
``f_z sin(phi)``: the forced response alone.

Integration: a fixed step ``dt = T / m`` with ``m`` steps per tooth period T, so the delayed
surface falls exactly on a step. Each step is exact for the linear modal dynamics under a
force linear over the step (Van Loan's block exponential); the force at the step's end is
predicted, then the step taken with it (Heun), second order in dt. Each sample stands for the
cell of angles a tooth sweeps around it; a cell that straddles the entry or exit angle counts
with the part inside the cut, at that part's middle, so entry and exit are integrated exactly.
Default resolution: ``m`` = the larger of 200 and 200 steps per cycle of the highest natural
frequency: the RMS acceleration then changes by less than 0.1 % when ``m`` doubles, and the
Floquet multipliers seen in a transient match the semi-discretization's to 1e-3
(tests/dynamics/test_time_domain.py; docs/chatter.md, Accuracy). The default number
of slices keeps the lag between neighbouring slices below 1/20 of the highest mode's period.

The cutter engages the full depth at rest at t = 0 (zero displacement, the surface cut by an
undeflected tool); the step of the mean force starts the transient, which also seeds chatter
where the cut is unstable. Vibration levels are taken after that transient, over whole tooth
periods (:meth:`MillingVibration.rms`, :meth:`MillingVibration.spectrum`); a spectrum's
energy outside the tooth-passing harmonics measures chatter
(:meth:`MillingVibration.chatter`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np
from scipy.linalg import expm

from cnctwin.dynamics import _time_domain_kernels as _k
from cnctwin.dynamics.stability import MillingProcess, ProcessDamping, ToolDynamics
from cnctwin.errors import InputError
from cnctwin.geometry import Cutter

__all__ = [
    "ChatterVerdict",
    "MillingVibration",
    "Spectrum",
    "VibrationRms",
    "simulate_milling",
]

logger = logging.getLogger(__name__)

Quantity = Literal["displacement", "velocity", "acceleration", "force"]
#: The time-domain chatter decision (:meth:`MillingVibration.chatter`).
Decision = Literal["stable", "chatter", "undecided"]

_TWO_PI = 2.0 * math.pi
_GRAVITY = 9.80665  # m/s^2 per g (standard gravity)
_STEPS_PER_TOOTH = 200  # least steps per tooth period
_STEPS_PER_CYCLE = 200  # least steps per cycle of the highest natural frequency
_SLICES_PER_CYCLE = 20  # slice lag at most 1/20 of the highest mode's period
_MAX_STEPS = 10_000_000  # 640 MB of output (8 float64 per step)
_CHATTER_RATIO = 1e-3  # default threshold of the non-synchronous energy fraction
#: A vibration off the tooth period dies out (a stable cut) when even its growth rate's
#: upper bound (rate + 2 sigma) shrinks it below this fraction over the steady window: a
#: saturated chatter drifts down by a few per cent and is not called stable.
_DECAYED = 0.8
_COLUMNS = {"displacement": 0, "velocity": 2, "acceleration": 4, "force": 6}


@dataclass(frozen=True)
class VibrationRms:
    """RMS values about the mean over the steady part of a simulation, per axis (x, y).

    Attributes
    ----------
    displacement_m
        Tool-tip displacement RMS in m, shape (2,).
    velocity_m_s
        Tool-tip velocity RMS in m/s, shape (2,).
    acceleration_m_s2
        Tool-tip acceleration RMS in m/s^2, shape (2,).
    force_n
        Cutting-force RMS in N, shape (2,).
    """

    displacement_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    force_n: np.ndarray

    @property
    def acceleration_g(self) -> np.ndarray:
        """Acceleration RMS in g (standard gravity 9.80665 m/s^2), shape (2,)."""
        return self.acceleration_m_s2 / _GRAVITY


@dataclass(frozen=True, eq=False)
class Spectrum:
    """Single-sided amplitude spectrum of a steady window of whole tooth periods.

    Attributes
    ----------
    frequency_hz
        Bin frequencies in Hz, from 0 in steps of ``1 / window``.
    amplitude
        Amplitude of each component in the signal's unit (the mean at 0 Hz).
    tooth_passing_hz
        Tooth-passing frequency ``N Omega / (2 pi)`` in Hz.
    harmonic
        True at the bins of 0 and the tooth-passing harmonics (exact bins: the window holds
        whole tooth periods).
    """

    frequency_hz: np.ndarray
    amplitude: np.ndarray
    tooth_passing_hz: float
    harmonic: np.ndarray

    @property
    def nonsynchronous_ratio(self) -> float:
        """Fraction of the signal's energy (its mean left out) off the tooth-passing harmonics.

        0 for a periodic response at the tooth period (a stable cut); near 1 when chatter
        dominates.
        """
        power = self.amplitude[1:] ** 2
        total = float(power.sum())
        if total <= 0.0:
            return 0.0
        return float(power[~self.harmonic[1:]].sum() / total)

    @property
    def chatter_frequency_hz(self) -> float:
        """Frequency in Hz of the strongest component off the harmonics (NaN if none)."""
        off = np.where(self.harmonic, 0.0, self.amplitude)
        if not np.any(off > 0.0):
            return math.nan
        return float(self.frequency_hz[int(np.argmax(off))])


@dataclass(frozen=True)
class ChatterVerdict:
    """Chatter detected from the energy off the tooth-passing harmonics and its trend.

    Attributes
    ----------
    chatter
        True if the non-synchronous energy fraction exceeds the threshold and does not decay
        (``growth > 0.5``).
    nonsynchronous_ratio
        Fraction of the energy (the mean left out) off the tooth-passing harmonics, 0 ... 1,
        x and y together.
    growth
        RMS of the change over one tooth period, ``r(t) - r(t - T)``, in the last quarter of
        the steady window over that in its first quarter: < 1 while a transient dies out
        (about ``|mu|^(3K/4)`` for K periods and the largest Floquet multiplier mu), about 1
        for saturated chatter, > 1 while chatter grows. NaN for a window under 5 periods.
    frequency_hz
        Frequency in Hz of the strongest non-synchronous component (NaN if none).
    threshold
        The threshold of ``nonsynchronous_ratio`` used.
    decision
        ``"stable"``, ``"chatter"`` or ``"undecided"`` (:meth:`MillingVibration.chatter`).
    growth_rate_per_s
        Exponential growth rate of the vibration's change over one tooth period, 1/s: the
        slope of its log per-period RMS over the steady window (``ln|mu| / T`` near the
        boundary, mu the largest Floquet multiplier); NaN for a window under 5 periods,
        ``-inf`` where it has settled to rounding.
    growth_rate_sigma_per_s
        Standard error of that slope, 1/s.
    """

    chatter: bool
    nonsynchronous_ratio: float
    growth: float
    frequency_hz: float
    threshold: float
    decision: Decision = "undecided"
    growth_rate_per_s: float = math.nan
    growth_rate_sigma_per_s: float = math.nan


@dataclass(frozen=True, eq=False)
class MillingVibration:
    """The result of :func:`simulate_milling`: tool-tip motion and cutting force over time.

    Attributes
    ----------
    time_s
        Sample times in s, from 0 in steps of ``tooth_period_s / steps_per_tooth``.
    displacement_m
        Tool-tip displacement (x, y) in m, shape (steps, 2).
    velocity_m_s
        Tool-tip velocity in m/s, shape (steps, 2).
    acceleration_m_s2
        Tool-tip acceleration in m/s^2, shape (steps, 2).
    force_n
        Cutting force on the tool in N, shape (steps, 2) (process damping excluded).
    tooth_period_s
        Tooth period T in s.
    steps_per_tooth
        Steps per tooth period m.
    slices
        Axial slices.
    process_damping_n_s_m
        Effective process damping ``C_eff`` used, in N s/m (0 without).
    """

    time_s: np.ndarray
    displacement_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    force_n: np.ndarray
    tooth_period_s: float
    steps_per_tooth: int
    slices: int
    process_damping_n_s_m: float

    @property
    def tooth_passing_hz(self) -> float:
        """Tooth-passing frequency ``1 / T`` in Hz."""
        return 1.0 / self.tooth_period_s

    def steady_window(self, transient_s: float | None = None) -> slice:
        """The samples after the transient: whole tooth periods ending at the last sample.

        Parameters
        ----------
        transient_s
            Time in s to leave out at the start; default half the simulated time.

        Raises
        ------
        InputError
            If less than one tooth period remains.
        """
        total = self.time_s.size
        duration = total * self.tooth_period_s / self.steps_per_tooth
        skip = 0.5 * duration if transient_s is None else float(transient_s)
        if not (math.isfinite(skip) and skip >= 0.0):
            raise InputError(f"transient_s={transient_s!r}; give a time >= 0 s")
        start = math.ceil(skip / self.tooth_period_s * self.steps_per_tooth - 1e-9)
        periods = (total - start) // self.steps_per_tooth
        if periods < 1:
            raise InputError(
                f"transient_s={skip:g} s leaves less than one tooth period of the "
                f"{duration:g} s simulated; simulate longer or give a shorter transient"
            )
        return slice(total - periods * self.steps_per_tooth, total)

    def rms(self, transient_s: float | None = None) -> VibrationRms:
        """RMS about the mean of each signal and axis after the transient (Royandi 2026, Sec. 5).

        Parameters
        ----------
        transient_s
            Time in s left out at the start; default half the simulated time.
        """
        window = self.steady_window(transient_s)
        return VibrationRms(*(np.std(a[window], axis=0) for a in self._signals()))

    def spectrum(
        self,
        quantity: Quantity = "acceleration",
        axis: Literal["x", "y"] = "x",
        transient_s: float | None = None,
    ) -> Spectrum:
        """Amplitude spectrum (numpy FFT, rectangular window) of one signal after the transient.

        Parameters
        ----------
        quantity
            ``"displacement"`` (m), ``"velocity"`` (m/s), ``"acceleration"`` (m/s^2) or
            ``"force"`` (N).
        axis
            ``"x"`` or ``"y"``.
        transient_s
            Time in s left out at the start; default half the simulated time.
        """
        column = _column(quantity) + _axis(axis)
        return self._spectra(transient_s, (column,))[0]

    def chatter(
        self,
        quantity: Quantity = "displacement",
        transient_s: float | None = None,
        threshold: float = _CHATTER_RATIO,
        final: bool = True,
    ) -> ChatterVerdict:
        """Chatter from the energy off the tooth-passing harmonics, x and y together.

        A stable cut settles to a motion periodic at the tooth period, whose spectrum holds
        only the tooth-passing harmonics; regenerative chatter adds a component near a natural
        frequency (Hopf) or at odd multiples of half the tooth-passing frequency (period
        doubling). The decision rests on the growth rate of ``s(t) - s(t - T)`` (which the
        periodic forced motion does not have), fitted over the steady window with its
        standard error sigma (:meth:`growth_rate`): ``"stable"`` when ``rate + 2 sigma``
        shrinks it below :data:`_DECAYED` (0.8) of itself over the steady window (it dies out,
        however much energy it still holds; a saturated chatter drifting down by a few per
        cent is not) or it has settled to rounding;
        ``"chatter"`` when ``rate - 2 sigma > 0`` (it grows); otherwise ``"undecided"``
        unless ``final``, in which case: ``"stable"`` when ``rate + 2 sigma < 0`` and the
        vibration off the tooth period never grew since the cut began (a slow decay near the
        boundary); else the non-synchronous energy decides: ``"chatter"`` above
        ``threshold`` (chatter saturated by the tool leaving the cut neither grows nor decays,
        or drifts), else ``"stable"``. :func:`cnctwin.dynamics.run_milling` asks with
        ``final=False`` and doubles the simulated time while undecided, up to a cap.
        ``chatter`` is the decision ``"chatter"`` (docs/chatter.md).

        Parameters
        ----------
        quantity
            The signal: ``"displacement"`` (default), ``"velocity"``, ``"acceleration"`` or
            ``"force"``.
        transient_s
            Time in s left out at the start; default half the simulated time.
        threshold
            Fraction of the energy off the harmonics above which a cut that does not settle
            chatters, 0 < threshold < 1 (default 1e-3).
        final
            False: ``"undecided"`` where the growth rate's interval straddles 0.
        """
        if not (0.0 < threshold < 1.0):
            raise InputError(f"threshold={threshold!r}; give 0 < threshold < 1")
        first = _column(quantity)
        spectra = self._spectra(transient_s, (first, first + 1))
        power = spectra[0].amplitude[1:] ** 2 + spectra[1].amplitude[1:] ** 2
        off = ~spectra[0].harmonic[1:]
        total = float(power.sum())
        ratio = float(power[off].sum() / total) if total > 0.0 else 0.0
        if np.any(power[off] > 0.0):
            frequency = float(spectra[0].frequency_hz[1:][int(np.argmax(np.where(off, power, 0)))])
        else:
            frequency = math.nan
        window = self.steady_window(transient_s)
        signal = self._signals()[first // 2]
        growth = self._growth(signal, window)
        rate, sigma = self._growth_rate(signal, window)
        decision: Decision
        seconds = (window.stop - window.start) * self.tooth_period_s / self.steps_per_tooth
        if math.exp((rate + 2.0 * sigma) * seconds) < _DECAYED:
            decision = "stable"
        elif rate - 2.0 * sigma > 0.0:
            decision = "chatter"
        elif not final:
            decision = "undecided"
        elif rate + 2.0 * sigma < 0.0 and self._overall_growth(signal) < 1.0:
            decision = "stable"  # dying out slowly, and never grew since the cut began
        else:
            decision = "chatter" if ratio > threshold else "stable"
        return ChatterVerdict(decision == "chatter", ratio, growth, frequency, threshold,
                              decision, rate, sigma)  # fmt: skip

    def growth_rate(
        self, quantity: Quantity = "displacement", transient_s: float | None = None
    ) -> tuple[float, float]:
        """Growth rate of the vibration off the tooth period and its standard error, 1/s.

        The per-period RMS ``r_k`` of ``s(t) - s(t - T)`` (x and y together) over the tooth
        periods of the steady window; the least-squares slope of ``ln r_k`` over time and its
        standard error. Periods whose ``r_k`` has fallen below 1e-9 of the signal's RMS (a
        transient decayed to rounding) are left out; with fewer than 5 periods left the rate
        is ``-inf`` (settled), NaN for a window under 5 periods.

        Parameters
        ----------
        quantity
            The signal (as :meth:`chatter`).
        transient_s
            Time in s left out at the start; default half the simulated time.
        """
        signal = self._signals()[_column(quantity) // 2]
        return self._growth_rate(signal, self.steady_window(transient_s))

    def _overall_growth(self, signal: np.ndarray) -> float:
        """Per-period RMS of ``s(t) - s(t - T)`` over the run's last tenth of periods over
        that of its first tenth after the second period (the forced motion's build-up): how
        far the vibration off the tooth period grew since the cut began."""
        m = self.steps_per_tooth
        periods = signal.shape[0] // m - 1
        change = signal[m : (periods + 1) * m] - signal[: periods * m]
        rms = np.sqrt(np.mean(change.reshape(periods, m, -1) ** 2, axis=(1, 2)))
        tenth = max(1, periods // 10)
        early = float(rms[2 : 2 + tenth].mean()) if periods > 2 + tenth else float(rms[0])
        late = float(rms[-tenth:].mean())
        return late / early if early > 0.0 else math.inf

    def _growth_rate(self, signal: np.ndarray, window: slice) -> tuple[float, float]:
        m = self.steps_per_tooth
        periods = (window.stop - window.start) // m
        if periods < 6:
            return math.nan, math.nan
        start = window.stop - periods * m
        change = signal[start + m : window.stop] - signal[start : window.stop - m]
        per_period = np.sqrt(np.mean(change.reshape(periods - 1, m, -1) ** 2, axis=(1, 2)))
        scale = float(np.sqrt(np.mean(signal[window] ** 2)))
        keep = per_period > 1e-9 * scale
        if keep.sum() < 5:
            return -math.inf, 0.0
        t = (np.arange(periods - 1) + 0.5) * self.tooth_period_s
        x, y = t[keep], np.log(per_period[keep])
        fit = np.polyfit(x, y, 1, full=False, cov=True)
        slope, variance = float(fit[0][0]), float(fit[1][0, 0])
        return slope, math.sqrt(max(variance, 0.0))

    def _growth(self, signal: np.ndarray, window: slice) -> float:
        """RMS of ``s(t) - s(t - T)`` over the window's last quarter over its first quarter."""
        m = self.steps_per_tooth
        periods = (window.stop - window.start) // m
        if periods < 5:
            return math.nan
        change = signal[window.start + m : window.stop] - signal[window.start : window.stop - m]
        quarter = (periods - 1) // 4 * m
        early = float(np.sqrt(np.mean(change[:quarter] ** 2)))
        late = float(np.sqrt(np.mean(change[-quarter:] ** 2)))
        if early == 0.0:
            return math.nan if late == 0.0 else math.inf
        return late / early

    def _signals(self) -> tuple[np.ndarray, ...]:
        return (self.displacement_m, self.velocity_m_s, self.acceleration_m_s2, self.force_n)

    def _spectra(self, transient_s: float | None, columns: tuple[int, ...]) -> list[Spectrum]:
        window = self.steady_window(transient_s)
        signals = np.hstack(self._signals())
        count = window.stop - window.start
        periods = count // self.steps_per_tooth
        frequency = np.fft.rfftfreq(count, self.tooth_period_s / self.steps_per_tooth)
        harmonic = np.arange(frequency.size) % periods == 0
        out = []
        for column in columns:
            amplitude = np.abs(np.fft.rfft(signals[window, column])) * (2.0 / count)
            amplitude[0] *= 0.5
            if count % 2 == 0:
                amplitude[-1] *= 0.5
            out.append(Spectrum(frequency, amplitude, self.tooth_passing_hz, harmonic))
        return out


def simulate_milling(
    tool: ToolDynamics,
    process: MillingProcess,
    *,
    spindle_rad_s: float,
    depth_m: float,
    feed_per_tooth_m: float,
    duration_s: float,
    cutter: Cutter | None = None,
    edge_tangential_n_m: float = 0.0,
    edge_radial_n_m: float = 0.0,
    helical_edge: bool = False,
    damping: ProcessDamping | None = None,
    steps_per_tooth: int | None = None,
    slices: int | None = None,
    regenerative: bool = True,
) -> MillingVibration:
    """Simulate the tool-tip vibration and cutting force of a milling cut over time.

    Royandi 2026, Eq. 1-12 (2-DOF Eq. 6-7 for any set of modes; process damping Eq. 3); the
    model, the integration and its accuracy are in the module notes.

    Parameters
    ----------
    tool
        Tool-tip modes (SI).
    process
        Teeth, shear coefficients Ktc, Krc (Pa) and immersion interval of the cut.
    spindle_rad_s
        Spindle speed Omega in rad/s, > 0.
    depth_m
        Axial depth of cut a_p in m, >= 0.
    feed_per_tooth_m
        Feed per tooth f_z in m, >= 0.
    duration_s
        Time to simulate in s, > 0; rounded up to whole tooth periods.
    cutter
        A flat end mill (its helix angle and diameter give the lag of the slices; its flutes
        must match the teeth of ``process``); ``None``: straight flutes.
    edge_tangential_n_m, edge_radial_n_m
        Edge coefficients Kte, Kre in N/m (Royandi 2026, Eq. 10-11).
    helical_edge
        Charge the edge terms per unit helical edge length, ``K dz / cos(beta)`` (Royandi
        2026, Eq. 10-11); default per unit axial width (as :mod:`cnctwin.mechanics.milling`).
    damping
        Optional process damping (Royandi 2026, Eq. 3), ``C_eff`` at this depth and speed.
    steps_per_tooth
        Steps per tooth period m, >= 20; default: the larger of 200 and 200 steps per cycle
        of the highest natural frequency.
    slices
        Axial slices, >= 1; default: 1 for straight flutes, else enough for a lag between
        neighbouring slices below 1/20 of the highest mode's period.
    regenerative
        False: the chip is the nominal ``f_z sin(phi)`` (forced vibration only).

    Returns
    -------
    MillingVibration
        Displacement, velocity, acceleration and cutting force at every step.

    Raises
    ------
    InputError
        For a value out of range, a cutter that does not match the process, or more than
        10 million steps.
    """
    speed = _positive("spindle_rad_s", spindle_rad_s)
    depth = _non_negative("depth_m", depth_m)
    feed = _non_negative("feed_per_tooth_m", feed_per_tooth_m)
    duration = _positive("duration_s", duration_s)
    kte = _finite("edge_tangential_n_m", edge_tangential_n_m)
    kre = _finite("edge_radial_n_m", edge_radial_n_m)
    helix, radius = _cutter_geometry(cutter, process)
    period = float(process.delay_s(speed))
    highest = max(mode.frequency_rad_s for mode in tool.modes) / _TWO_PI
    m = _steps(steps_per_tooth, highest * period)
    lag = depth * math.tan(helix) / radius if radius > 0.0 else 0.0
    count = _slices(slices, lag, speed, highest)
    periods = math.ceil(duration / period - 1e-9)
    total = periods * m
    if total > _MAX_STEPS:
        raise InputError(
            f"duration_s={duration:g} s needs {total} steps at {m} per tooth period; "
            f"give at most {_MAX_STEPS * period / m:.3g} s"
        )
    dt = period / m
    c_eff = 0.0 if damping is None else damping.effective_damping(depth, speed)
    matrices = _modal_matrices(tool, c_eff, dt)
    tables = _angle_tables(process, m, count, depth, lag, kte, kre, helix, helical_edge)
    grid_steps = np.arange(process.teeth * m) % m
    surface = feed * tables.sin * (grid_steps / m - 1.0)[:, None]
    state = np.zeros(2 * len(tool.modes))
    out = np.empty((total, 8))
    logger.debug("time-domain milling: %d steps, %d per tooth, %d slices", total, m, count)
    _k.simulate(
        matrices.transition,
        matrices.hold,
        matrices.ramp,
        matrices.tip,
        matrices.accel_state,
        matrices.accel_force,
        state,
        m,
        feed,
        tables.inside,
        tables.sin,
        tables.cos,
        tables.cut_x,
        tables.cut_y,
        tables.edge_x,
        tables.edge_y,
        surface,
        bool(regenerative),
        out,
    )
    return MillingVibration(
        time_s=np.arange(total) * dt,
        displacement_m=out[:, 0:2],
        velocity_m_s=out[:, 2:4],
        acceleration_m_s2=out[:, 4:6],
        force_n=out[:, 6:8],
        tooth_period_s=period,
        steps_per_tooth=m,
        slices=count,
        process_damping_n_s_m=c_eff,
    )


class _Modal(NamedTuple):
    """Step matrices of the modal state and the maps to the tool tip (see the kernel)."""

    transition: np.ndarray  # (2n, 2n)
    hold: np.ndarray  # (2n, 2): response to a force held over the step, m/N and s/kg
    ramp: np.ndarray  # (2n, 2): response to a force rising linearly over the step
    tip: np.ndarray  # (2, n): mode directions
    accel_state: np.ndarray  # (2, 2n) 1/s^2 and 1/s
    accel_force: np.ndarray  # (2, 2) 1/kg


class _Tables(NamedTuple):
    """Per grid angle and slice, shape (N m, slices): the kernel's angle tables."""

    inside: np.ndarray  # bool: the cell overlaps the immersion interval
    sin: np.ndarray
    cos: np.ndarray
    cut_x: np.ndarray  # N per m of chip
    cut_y: np.ndarray
    edge_x: np.ndarray  # N
    edge_y: np.ndarray


def _modal_matrices(tool: ToolDynamics, c_eff: float, dt: float) -> _Modal:
    """Step matrices of the modal state ``[q, q']`` and the tip maps (see the kernel).

    ``A = [[0, I], [-W^2, -(2 zeta W + C_eff M^-1 Phi^T Phi)]]``, ``B = [0; M^-1 Phi^T]``;
    ``exp([[A, B, 0], [0, 0, I], [0, 0, 0]] dt)`` holds the transition matrix and the responses
    to a force held constant and to one rising linearly over the step (Van Loan 1978).
    """
    wn = np.array([mode.frequency_rad_s for mode in tool.modes])
    zeta = np.array([mode.damping_ratio for mode in tool.modes])
    k = np.array([mode.stiffness_n_m for mode in tool.modes])
    phi = tool.directions  # (2, n)
    n = wn.size
    inverse_mass = wn * wn / k
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -np.diag(wn * wn)
    a[n:, n:] = -np.diag(2.0 * zeta * wn) - c_eff * (inverse_mass[:, None] * (phi.T @ phi))
    b = np.zeros((2 * n, 2))
    b[n:, :] = inverse_mass[:, None] * phi.T
    block = np.zeros((2 * n + 4, 2 * n + 4))
    block[: 2 * n, : 2 * n] = a * dt
    block[: 2 * n, 2 * n : 2 * n + 2] = b * dt
    block[2 * n : 2 * n + 2, 2 * n + 2 :] = np.eye(2)
    e = expm(block)
    transition = e[: 2 * n, : 2 * n]
    hold = e[: 2 * n, 2 * n : 2 * n + 2]
    ramp = e[: 2 * n, 2 * n + 2 :]
    arrays = (transition, hold, ramp, phi, phi @ a[n:, :], phi @ b[n:, :])
    return _Modal(*(np.ascontiguousarray(x) for x in arrays))


def _angle_tables(
    process: MillingProcess,
    steps: int,
    slices: int,
    depth: float,
    lag: float,
    kte: float,
    kre: float,
    helix: float,
    helical_edge: bool,
) -> _Tables:
    """Per grid angle and slice: inside, sin, cos, shear force per unit chip, edge force.

    A grid angle stands for its cell ``phi +- dtheta / 2``: its force is weighted by the part
    of the cell inside the immersion interval and taken at the middle of that part (chip and
    direction alike), so that a tooth's entry and exit are integrated exactly.
    """
    grid = process.teeth * steps
    dtheta = _TWO_PI / grid
    width = depth / slices
    psi = (np.arange(slices) + 0.5) / slices * lag
    phi = np.arange(grid)[None, :] * dtheta - psi[:, None]
    overlap = np.zeros_like(phi)
    moment = np.zeros_like(phi)
    # a shifted interval clear of every cell adds only zeros (exactly): it is skipped
    first = float(phi.min()) - 0.5 * dtheta
    last = float(phi.max()) + 0.5 * dtheta
    for shift in (-_TWO_PI, 0.0, _TWO_PI, 2.0 * _TWO_PI):
        if process.exit_rad + shift <= first or process.entry_rad + shift >= last:
            continue
        lo = np.maximum(phi - 0.5 * dtheta, process.entry_rad + shift)
        hi = np.minimum(phi + 0.5 * dtheta, process.exit_rad + shift)
        part = np.clip(hi - lo, 0.0, None)
        overlap += part
        moment += part * (0.5 * (lo + hi) - phi)
    inside = overlap > 0.0
    phi = phi + np.where(inside, moment / np.where(inside, overlap, 1.0), 0.0)
    weight = overlap / dtheta * width
    s, c = np.sin(phi), np.cos(phi)
    kt, kr = process.tangential_pa, process.radial_pa
    edge = 1.0 / math.cos(helix) if helical_edge else 1.0
    arrays = (
        inside,
        s,
        c,
        -(kt * c + kr * s) * weight,
        (kt * s - kr * c) * weight,
        -(kte * c + kre * s) * weight * edge,
        (kte * s - kre * c) * weight * edge,
    )
    return _Tables(*(np.ascontiguousarray(x.T) for x in arrays))


def _cutter_geometry(cutter: Cutter | None, process: MillingProcess) -> tuple[float, float]:
    """Helix angle (rad) and radius (m) of the cutter; (0, 0) for straight flutes."""
    if cutter is None:
        return 0.0, 0.0
    if cutter.kind != "flat":
        raise InputError(
            f"cutter kind {cutter.kind!r}; the time-domain model takes a flat end mill"
        )
    if cutter.runout_mm != 0.0:
        raise InputError(
            f"runout_mm={cutter.runout_mm!r}; the time-domain model takes no runout (0)"
        )
    if cutter.flutes != process.teeth:
        raise InputError(
            f"cutter flutes={cutter.flutes} but the process has {process.teeth} teeth; give the "
            "same"
        )
    return cutter.helix_rad, cutter.radius_m


def _steps(given: int | None, cycles_per_tooth: float) -> int:
    if given is None:
        return max(_STEPS_PER_TOOTH, math.ceil(_STEPS_PER_CYCLE * cycles_per_tooth))
    if isinstance(given, bool) or not isinstance(given, (int, np.integer)) or given < 20:
        raise InputError(f"steps_per_tooth={given!r}; give an integer >= 20")
    per_cycle = given / cycles_per_tooth
    if per_cycle < 50.0:
        logger.warning(
            "time-domain milling: %d steps per tooth period are %.0f steps per cycle of the "
            "highest mode; the response may be off by a few %% (default: 200 per cycle)",
            given,
            per_cycle,
        )
    return int(given)


def _slices(given: int | None, lag: float, speed: float, highest_hz: float) -> int:
    if given is None:
        return max(1, math.ceil(lag * _SLICES_PER_CYCLE * highest_hz / speed))
    if isinstance(given, bool) or not isinstance(given, (int, np.integer)) or given < 1:
        raise InputError(f"slices={given!r}; give an integer >= 1")
    return int(given)


def _column(quantity: str) -> int:
    if quantity not in _COLUMNS:
        raise InputError(f"quantity={quantity!r}; give one of {', '.join(_COLUMNS)}")
    return _COLUMNS[quantity]


def _axis(axis: str) -> int:
    if axis not in ("x", "y"):
        raise InputError(f"axis={axis!r}; give 'x' or 'y'")
    return 0 if axis == "x" else 1


def _finite(name: str, value: float) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if not math.isfinite(number):
        raise InputError(f"{name}={value!r}; give a finite number")
    return number


def _positive(name: str, value: float) -> float:
    number = _finite(name, value)
    if number <= 0.0:
        raise InputError(f"{name}={value!r}; give a finite number > 0")
    return number


def _non_negative(name: str, value: float) -> float:
    number = _finite(name, value)
    if number < 0.0:
        raise InputError(f"{name}={value!r}; give a finite number >= 0")
    return number
