"""Process-damping calibration from measured vibration: Royandi 2026, Sec. 2.4 and 6.4.

For each cut (spindle speed n, depth a_p, feed per tooth f_z) the process-damping coefficient
``C_pd`` (Eq. 3) is the one at which the simulated RMS acceleration of the tool tip
(:func:`cnctwin.dynamics.time_domain.simulate_milling`) equals the measured one, the relative
error of Eq. 14 ``eps = |a_sim - a_exp| / a_exp`` reaching its minimum, zero
(:func:`match_cpd`, :func:`calibrate_cpd`). The feed is normalised away by
``Gamma = C_pd a_p f_z`` (Eq. 15, in N), which per spindle speed follows an exponential
saturation in depth (:func:`fit_gamma`),

    Gamma(a_p | n_k) = A_k + B_k exp(-a_p / a0_k),

decaying from ``A_k + B_k`` toward ``A_k``. The paper prints Eq. 16 and Eq. 21 with
``exp(+a_p / a0)``, but its fitted Eq. 17-19 and its text ("A_k represents the asymptotic value
of Gamma at large cutting depths") are the decaying form, which is the one implemented. Between
the calibrated speeds A, B and a0 are interpolated linearly (Eq. 20-21,
:class:`ProcessDampingModel`), and ``C_pd = Gamma / (a_p f_z)``.

SI units: Pa (N/m^2) for C_pd, N for Gamma, m for depths and feeds, rad/s for speeds, m/s^2
for accelerations. The paper quotes a_p and a0 in mm.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from scipy.optimize import brentq, minimize_scalar, nnls

from cnctwin.dynamics.stability import MillingProcess, ProcessDamping, ToolDynamics
from cnctwin.dynamics.time_domain import simulate_milling
from cnctwin.errors import ConfigError, DataError, InputError
from cnctwin.geometry import Cutter

__all__ = [
    "CalibrationSetup",
    "CpdMatch",
    "GammaFit",
    "ProcessDampingModel",
    "calibrate_cpd",
    "cut_process_damping",
    "fit_gamma",
    "fit_process_damping_model",
    "match_cpd",
    "read_damping_model",
    "relative_error",
]

logger = logging.getLogger(__name__)

_RPM = math.pi / 30.0  # rad/s per rpm
_START_PA = 1e10  # first C_pd tried: the middle of Royandi 2026's 4.7e9 ... 2.9e11 N/m^2

MatchStatus = Literal["matched", "no_damping_needed", "upper_bound"]


def relative_error(simulated: float, measured: float) -> float:
    """Royandi 2026, Eq. 14: ``|a_sim - a_exp| / a_exp`` (dimensionless)."""
    if not (math.isfinite(measured) and measured > 0.0):
        raise DataError(f"measured RMS {measured!r}; give a finite value > 0")
    return abs(simulated - measured) / measured


@dataclass(frozen=True)
class CpdMatch:
    """The process-damping coefficient that reproduces a measured RMS vibration.

    Attributes
    ----------
    cpd_pa
        C_pd in N/m^2.
    simulated_rms
        The model's RMS at ``cpd_pa``, in the unit of the measured one.
    measured_rms
        The measured RMS.
    relative_error
        Eq. 14 at ``cpd_pa``.
    status
        ``"matched"`` (a root was found), ``"no_damping_needed"`` (the model without process
        damping already vibrates less than measured: C_pd = 0 minimises Eq. 14) or
        ``"upper_bound"`` (still too much vibration at the upper bound of C_pd).
    evaluations
        Number of simulations run.
    """

    cpd_pa: float
    simulated_rms: float
    measured_rms: float
    relative_error: float
    status: MatchStatus
    evaluations: int


def match_cpd(
    rms_of_cpd: Callable[[float], float],
    measured_rms: float,
    *,
    bounds_pa: tuple[float, float] = (1e7, 1e13),
    log10_tolerance: float = 1e-3,
) -> CpdMatch:
    """Find C_pd with ``rms_of_cpd(C_pd) = measured_rms`` (Royandi 2026, Eq. 14).

    More process damping lowers the vibration, so the root is bracketed by stepping a decade
    at a time from 1e10 N/m^2 (up while the model vibrates more than measured, down while
    less), then found by Brent's method in log10(C_pd). Where the RMS is not monotonic the
    root found is the one inside the first bracket.

    Parameters
    ----------
    rms_of_cpd
        The model's RMS vibration at a given C_pd (N/m^2), any unit.
    measured_rms
        The measured RMS in the same unit, > 0.
    bounds_pa
        Lowest positive and highest C_pd searched in N/m^2, ``0 < low < high``; below the
        lowest, C_pd = 0 is tried.
    log10_tolerance
        Tolerance of the root in log10(C_pd) (1e-3: 0.23 %).

    Returns
    -------
    CpdMatch
    """
    if not (math.isfinite(measured_rms) and measured_rms > 0.0):
        raise DataError(f"measured RMS {measured_rms!r}; give a finite value > 0")
    low, high = (float(b) for b in bounds_pa)
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low < high):
        raise InputError(f"bounds_pa={bounds_pa!r}; give 0 < low < high in N/m^2")
    calls = 0
    target = math.log(measured_rms)
    cache: dict[float, float] = {}

    def excess(log_c: float) -> float:
        nonlocal calls
        if log_c not in cache:
            calls += 1
            value = float(rms_of_cpd(10.0**log_c))
            if not (math.isfinite(value) and value > 0.0):
                raise DataError(f"the model's RMS at C_pd = {10.0**log_c:.3g} N/m^2 is {value!r}")
            cache[log_c] = math.log(value) - target
        return cache[log_c]

    def done(cpd: float, rms: float, status: MatchStatus) -> CpdMatch:
        error = relative_error(rms, measured_rms)
        return CpdMatch(cpd, rms, measured_rms, error, status, calls)

    lo_log, hi_log = math.log10(low), math.log10(high)
    start = min(max(math.log10(_START_PA), lo_log), hi_log)
    a = start
    fa = excess(a)
    step = 1.0 if fa > 0.0 else -1.0
    while True:
        b = min(max(a + step, lo_log), hi_log)
        if b == a:
            break
        fb = excess(b)
        if (fb > 0.0) != (fa > 0.0):
            left, right = sorted((a, b))
            root = brentq(excess, left, right, xtol=log10_tolerance)
            # The simulated RMS at the root itself (cached if Brent evaluated it last).
            return done(10.0**root, measured_rms * math.exp(excess(root)), "matched")
        a, fa = b, fb
    if fa > 0.0:
        return done(10.0**a, measured_rms * math.exp(fa), "upper_bound")
    calls += 1
    zero = float(rms_of_cpd(0.0))
    if zero > measured_rms:

        def linear(c: float) -> float:
            return float(rms_of_cpd(c)) - measured_rms if c > 0.0 else zero - measured_rms

        cpd = brentq(linear, 0.0, 10.0**a, xtol=low * 1e-3)
        calls += 1
        return done(cpd, float(rms_of_cpd(cpd)), "matched")
    return done(0.0, zero, "no_damping_needed")


@dataclass(frozen=True)
class CalibrationSetup:
    """The fixed part of Royandi 2026's digital twin: structure, cutter and force model.

    Attributes
    ----------
    tool
        Tool-tip modes.
    process
        Teeth, shear coefficients and immersion.
    cutter
        The flat end mill (its diameter gives the cutting speed of Eq. 3, its helix the
        slices).
    edge_tangential_n_m, edge_radial_n_m
        Edge coefficients Kte, Kre in N/m.
    helical_edge
        Edge terms per unit helical edge length (Royandi 2026, Eq. 10-11).
    duration_s
        Simulated time per cut in s; the RMS is taken over its second half.
    steps_per_tooth
        Steps per tooth period (``None``: the simulation's default).
    axis
        Direction of the RMS acceleration: ``"x"`` (feed; the paper's V_xDT) or ``"y"``.
    """

    tool: ToolDynamics
    process: MillingProcess
    cutter: Cutter
    edge_tangential_n_m: float = 0.0
    edge_radial_n_m: float = 0.0
    helical_edge: bool = False
    duration_s: float = 0.2
    steps_per_tooth: int | None = None
    axis: Literal["x", "y"] = "x"

    def acceleration_rms(
        self, spindle_rad_s: float, depth_m: float, feed_per_tooth_m: float, cpd_pa: float
    ) -> float:
        """Simulated RMS tool-tip acceleration in m/s^2 of one cut with process damping C_pd.

        ``C_eff = C_pd a_p f_z / V_c`` (Royandi 2026, Eq. 3 and Sec. 6.4).
        """
        damping = ProcessDamping(cpd_pa, feed_per_tooth_m, self.cutter.diameter_m)
        result = simulate_milling(
            self.tool,
            self.process,
            spindle_rad_s=spindle_rad_s,
            depth_m=depth_m,
            feed_per_tooth_m=feed_per_tooth_m,
            duration_s=self.duration_s,
            cutter=self.cutter,
            edge_tangential_n_m=self.edge_tangential_n_m,
            edge_radial_n_m=self.edge_radial_n_m,
            helical_edge=self.helical_edge,
            damping=damping,
            steps_per_tooth=self.steps_per_tooth,
        )
        return float(result.rms().acceleration_m_s2[0 if self.axis == "x" else 1])


def calibrate_cpd(
    setup: CalibrationSetup,
    *,
    spindle_rad_s: float,
    depth_m: float,
    feed_per_tooth_m: float,
    measured_rms_m_s2: float,
    bounds_pa: tuple[float, float] = (1e7, 1e13),
) -> CpdMatch:
    """C_pd of one cut from its measured RMS acceleration (Royandi 2026, Sec. 2.4, Eq. 14).

    Parameters
    ----------
    setup
        The model of the machine and cutter.
    spindle_rad_s, depth_m, feed_per_tooth_m
        The cut: spindle speed in rad/s, axial depth in m, feed per tooth in m (slotting with
        the setup's process).
    measured_rms_m_s2
        Measured RMS acceleration in m/s^2, > 0.
    bounds_pa
        C_pd search bounds in N/m^2 (see :func:`match_cpd`).

    Returns
    -------
    CpdMatch
        RMS values in m/s^2.
    """

    def rms(cpd: float) -> float:
        return setup.acceleration_rms(spindle_rad_s, depth_m, feed_per_tooth_m, cpd)

    found = match_cpd(rms, measured_rms_m_s2, bounds_pa=bounds_pa)
    logger.debug(
        "C_pd %.3g N/m^2 at %.0f rpm, a_p %.3g mm, f_z %.3g mm (%s, %d runs)",
        found.cpd_pa,
        spindle_rad_s / _RPM,
        depth_m * 1e3,
        feed_per_tooth_m * 1e3,
        found.status,
        found.evaluations,
    )
    return found


@dataclass(frozen=True)
class GammaFit:
    """Royandi 2026, Eq. 16-19 (decaying form): ``Gamma(a_p) = A + B exp(-a_p / a0)`` at one speed.

    Attributes
    ----------
    spindle_rad_s
        The spindle speed n_k in rad/s.
    asymptote_n
        A in N: Gamma at large depths.
    amplitude_n
        B in N: the extra Gamma at shallow depths.
    depth_scale_m
        a0 in m: the depth over which the extra part falls by e.
    mape_percent
        Mean absolute percentage error of the fitted C_pd (equal to that of Gamma) over the
        calibrated cuts, % (NaN for a model given, not fitted).
    rmse_pa
        Root mean square error of the fitted C_pd in N/m^2 (NaN likewise).
    """

    spindle_rad_s: float
    asymptote_n: float
    amplitude_n: float
    depth_scale_m: float
    mape_percent: float = math.nan
    rmse_pa: float = math.nan

    def gamma_n(self, depth_m: np.ndarray | float) -> np.ndarray:
        """Gamma in N at depths ``a_p`` in m."""
        a = np.asarray(depth_m, dtype=np.float64)
        return self.asymptote_n + self.amplitude_n * np.exp(-a / self.depth_scale_m)


def fit_gamma(
    spindle_rad_s: float,
    depth_m: Sequence[float] | np.ndarray,
    feed_per_tooth_m: Sequence[float] | np.ndarray,
    cpd_pa: Sequence[float] | np.ndarray,
    *,
    depth_scale_bounds_m: tuple[float, float] | None = None,
) -> GammaFit:
    """Fit ``Gamma = A + B exp(-a_p / a0)`` to calibrated C_pd of one spindle speed (Eq. 15-19).

    ``Gamma_i = C_pd,i a_p,i f_z,i`` (Eq. 15). The residuals are relative,
    ``(Gamma(a_p,i) - Gamma_i) / Gamma_i`` (the same as those of C_pd, whose MAPE the paper
    reports); for a fixed a0 the best ``A, B >= 0`` are a non-negative linear least-squares
    problem, and a0 is found by a bounded scalar search in log(a0) started from a grid
    (variable projection). At least three distinct depths are needed.

    Parameters
    ----------
    spindle_rad_s
        The speed the cuts share, rad/s.
    depth_m, feed_per_tooth_m, cpd_pa
        Per cut: depth in m, feed per tooth in m, calibrated C_pd in N/m^2 (> 0).
    depth_scale_bounds_m
        Range of a0 in m; default a tenth of the smallest depth to 10 times the largest
        (a0 below it puts all the saturation before the shallowest cut, where no data
        constrain it).

    Raises
    ------
    DataError
        For arrays of different lengths, non-positive values or fewer than 3 depths.
    """
    a = np.asarray(depth_m, dtype=np.float64)
    f = np.asarray(feed_per_tooth_m, dtype=np.float64)
    c = np.asarray(cpd_pa, dtype=np.float64)
    if not (a.ndim == f.ndim == c.ndim == 1 and a.size == f.size == c.size):
        raise DataError("depths, feeds and C_pd must be 1-D arrays of one length")
    for name, values in (("depth", a), ("feed per tooth", f), ("C_pd", c)):
        if not np.all(np.isfinite(values) & (values > 0.0)):
            raise DataError(f"{name} values {values.tolist()!r}; give finite values > 0")
    if np.unique(a).size < 3:
        raise DataError(f"depths {a.tolist()!r}; the fit of A, B, a0 needs 3 distinct depths")
    gamma = c * a * f
    if depth_scale_bounds_m is None:
        bounds = (0.1 * a.min(), 10.0 * a.max())
    else:
        bounds = (float(depth_scale_bounds_m[0]), float(depth_scale_bounds_m[1]))
        if not (0.0 < bounds[0] < bounds[1] and math.isfinite(bounds[1])):
            raise InputError(f"depth_scale_bounds_m={depth_scale_bounds_m!r}; give 0 < lo < hi")

    def solve(log_a0: float) -> tuple[float, np.ndarray]:
        design = np.column_stack((np.ones_like(a), np.exp(-a / math.exp(log_a0)))) / gamma[:, None]
        coefficients, residual = nnls(design, np.ones_like(a))
        return float(residual), coefficients

    grid = np.linspace(math.log(bounds[0]), math.log(bounds[1]), 41)
    costs = [solve(x)[0] for x in grid]
    best = int(np.argmin(costs))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
    found = minimize_scalar(lambda x: solve(x)[0], bounds=(lo, hi), method="bounded",
                            options={"xatol": 1e-8})  # fmt: skip
    log_a0 = float(found.x) if found.fun <= costs[best] else float(grid[best])
    _, (big_a, big_b) = solve(log_a0)
    fit = GammaFit(float(spindle_rad_s), float(big_a), float(big_b), math.exp(log_a0))
    model = fit.gamma_n(a) / (a * f)
    mape = float(np.mean(np.abs(model - c) / c) * 100.0)
    rmse = float(np.sqrt(np.mean((model - c) ** 2)))
    return GammaFit(fit.spindle_rad_s, fit.asymptote_n, fit.amplitude_n, fit.depth_scale_m,
                    mape, rmse)  # fmt: skip


@dataclass(frozen=True)
class ProcessDampingModel:
    """C_pd over depth, feed and speed: Royandi 2026, Eq. 20-21 (decaying form).

    ``C_pd(a_p, f_z, n) = (A(n) + B(n) exp(-a_p / a0(n))) / (a_p f_z)`` with A, B and a0
    interpolated linearly in spindle speed between the fits (Sec. 6.4) and held at the
    nearest fit outside them (the paper does not say; its 3000 rpm validation cuts lay there).

    Attributes
    ----------
    fits
        One :class:`GammaFit` per calibrated speed, in increasing speed.
    """

    fits: tuple[GammaFit, ...]

    def __post_init__(self) -> None:
        fits = tuple(sorted(self.fits, key=lambda fit: fit.spindle_rad_s))
        if not fits:
            raise ConfigError("a process-damping model needs at least one fitted speed")
        speeds = [fit.spindle_rad_s for fit in fits]
        if len(set(speeds)) != len(speeds):
            raise ConfigError(f"spindle speeds {speeds!r} rad/s repeat; give one fit per speed")
        object.__setattr__(self, "fits", fits)

    @classmethod
    def royandi2026(cls) -> ProcessDampingModel:
        """The paper's fitted Eq. 17-19 (AL6061 slotting, 12 mm 4-flute carbide end mill).

        ``Gamma(a_p | 5500) = 2.10e3 + 6.10e5 exp(-a_p / 0.42 mm)``,
        ``Gamma(a_p | 7500) = 6.20e3 + 1.25e5 exp(-a_p / 0.50 mm)``,
        ``Gamma(a_p | 9500) = 1.20e4 + 3.10e5 exp(-a_p / 0.46 mm)``, Gamma in N (the unit
        follows from Eq. 15 in SI: ``C_pd = Gamma / (a_p f_z)`` then spans 6.4e9 ... 3.2e11
        N/m^2 over the paper's Table 3 cuts, near the 4.7e9 ... 2.9e11 its text quotes; see
        docs/validation.md for what does not agree).
        """
        rows = ((5500.0, 2.10e3, 6.10e5, 0.42e-3), (7500.0, 6.20e3, 1.25e5, 0.50e-3),
                (9500.0, 1.20e4, 3.10e5, 0.46e-3))  # fmt: skip
        return cls(tuple(GammaFit(rpm * _RPM, a, b, a0) for rpm, a, b, a0 in rows))

    def parameters(self, spindle_rad_s: float) -> tuple[float, float, float]:
        """A (N), B (N) and a0 (m) at a spindle speed in rad/s."""
        speeds = np.array([fit.spindle_rad_s for fit in self.fits])
        columns = np.array([[f.asymptote_n, f.amplitude_n, f.depth_scale_m] for f in self.fits])
        values = [float(np.interp(spindle_rad_s, speeds, columns[:, i])) for i in range(3)]
        return values[0], values[1], values[2]

    def gamma_n(self, depth_m: float, spindle_rad_s: float) -> float:
        """Gamma in N at depth ``a_p`` (m) and spindle speed (rad/s)."""
        big_a, big_b, a0 = self.parameters(spindle_rad_s)
        return big_a + big_b * math.exp(-depth_m / a0)

    def cpd_pa(self, depth_m: float, feed_per_tooth_m: float, spindle_rad_s: float) -> float:
        """C_pd in N/m^2 (Eq. 20) at depth and feed per tooth in m, speed in rad/s (> 0)."""
        if not (depth_m > 0.0 and feed_per_tooth_m > 0.0):
            raise InputError(
                f"depth {depth_m!r} m, feed per tooth {feed_per_tooth_m!r} m; give both > 0"
            )
        return self.gamma_n(depth_m, spindle_rad_s) / (depth_m * feed_per_tooth_m)

    def process_damping(
        self, depth_m: float, feed_per_tooth_m: float, spindle_rad_s: float, diameter_m: float
    ) -> ProcessDamping:
        """The :class:`~cnctwin.dynamics.ProcessDamping` of one cut (diameter in m)."""
        cpd = self.cpd_pa(depth_m, feed_per_tooth_m, spindle_rad_s)
        return ProcessDamping(cpd, feed_per_tooth_m, diameter_m)


def read_damping_model(path: Path) -> ProcessDampingModel:
    """Read a :class:`ProcessDampingModel` from the JSON that ``cnctwin chatter
    calibrate-damping --json`` prints: its ``fits`` rows, each with ``spindle_rpm`` (rpm),
    ``a_n`` and ``b_n`` (A and B of Eq. 17-19, N) and ``a0_mm`` (mm); other keys are ignored.

    Raises
    ------
    cnctwin.errors.DataError
        ``"FILE: ..."`` for a file that is not such JSON.
    OSError
        If the file cannot be read.
    """
    try:
        document = json.loads(Path(path).read_text(encoding="utf-8"))
        fits = tuple(
            GammaFit(
                float(row["spindle_rpm"]) * _RPM,
                float(row["a_n"]),
                float(row["b_n"]),
                float(row["a0_mm"]) * 1e-3,
            )
            for row in document["fits"]
        )
    except (UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
        raise DataError(
            f"{path}: not a damping model ({type(err).__name__}: {err}); give the JSON of "
            "'chatter calibrate-damping --json'"
        ) from None
    try:
        return ProcessDampingModel(fits)
    except ConfigError as err:
        raise DataError(f"{path}: {err}") from None


def cut_process_damping(
    *,
    depth_m: float,
    feed_per_tooth_m: float,
    spindle_rad_s: float,
    diameter_m: float | None,
    cpd_pa: float | None = None,
    model: ProcessDampingModel | None = None,
    default_cpd_pa: float | None = None,
) -> ProcessDamping | None:
    """The process damping of one milling cut, or None when the cut has none.

    The coefficient ``C_pd`` comes from the first source given: a fitted Gamma ``model``
    (Royandi 2026, Eq. 20, at this depth, feed and speed), an explicit ``cpd_pa`` (0 turns
    process damping off), else ``default_cpd_pa`` (e.g. a stability file's
    ``[process_damping].cpd_n_m2``; None or 0 for none). The chip thickness is the feed per
    tooth (Royandi 2026, Sec. 6.4: ``C_eff = C_pd a_p f_z / V_c``).

    Parameters
    ----------
    depth_m, feed_per_tooth_m
        Axial depth of cut and feed per tooth, m (> 0).
    spindle_rad_s
        Spindle speed, rad/s (> 0).
    diameter_m
        Cutter diameter, m; None when unknown (then no source may give a C_pd > 0).
    cpd_pa, model, default_cpd_pa
        The sources of ``C_pd``, N/m^2; ``cpd_pa`` and ``model`` exclude each other.

    Raises
    ------
    InputError
        For both ``cpd_pa`` and ``model``, a ``cpd_pa`` that is negative or not finite, or a
        ``C_pd > 0`` without ``diameter_m``.
    """
    if cpd_pa is not None and model is not None:
        raise InputError("cpd_pa and model exclude each other; give one")
    if model is not None:
        cpd: float | None = model.cpd_pa(depth_m, feed_per_tooth_m, spindle_rad_s)
    elif cpd_pa is not None:
        if not (math.isfinite(cpd_pa) and cpd_pa >= 0.0):
            raise InputError(f"cpd_pa {cpd_pa!r}: give a value >= 0 N/m^2 (0: no damping)")
        cpd = cpd_pa or None
    else:
        cpd = default_cpd_pa if default_cpd_pa is not None and default_cpd_pa > 0.0 else None
    if cpd is None:
        return None
    if diameter_m is None:
        raise InputError(
            f"process damping (C_pd {cpd:.3g} N/m^2) needs the cutter diameter (diameter_m, m)"
        )
    return ProcessDamping(cpd, feed_per_tooth_m, diameter_m)


def fit_process_damping_model(
    spindle_rad_s: Sequence[float] | np.ndarray,
    depth_m: Sequence[float] | np.ndarray,
    feed_per_tooth_m: Sequence[float] | np.ndarray,
    cpd_pa: Sequence[float] | np.ndarray,
) -> ProcessDampingModel:
    """Fit :func:`fit_gamma` at each distinct spindle speed of calibrated cuts (Sec. 6.4).

    Parameters
    ----------
    spindle_rad_s, depth_m, feed_per_tooth_m, cpd_pa
        Per cut: speed in rad/s, depth in m, feed per tooth in m, C_pd in N/m^2 (> 0); cuts
        whose speeds agree within 1e-9 relative share a fit.
    """
    speeds = np.asarray(spindle_rad_s, dtype=np.float64)
    a = np.asarray(depth_m, dtype=np.float64)
    f = np.asarray(feed_per_tooth_m, dtype=np.float64)
    c = np.asarray(cpd_pa, dtype=np.float64)
    if not (speeds.ndim == 1 and speeds.shape == a.shape == f.shape == c.shape):
        raise DataError("speeds, depths, feeds and C_pd must be 1-D arrays of one length")
    if not np.all(np.isfinite(speeds) & (speeds > 0.0)):
        raise DataError(f"spindle speeds {speeds.tolist()!r}; give finite values > 0")
    fits = []
    remaining = np.ones(speeds.size, dtype=bool)
    while remaining.any():
        node = speeds[remaining][0]
        group = remaining & np.isclose(speeds, node, rtol=1e-9, atol=0.0)
        fits.append(fit_gamma(float(node), a[group], f[group], c[group]))
        remaining &= ~group
    return ProcessDampingModel(tuple(fits))
