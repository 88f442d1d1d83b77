"""Runs of the time-domain milling model on a stability configuration.

:func:`run_milling` simulates one cut of a :class:`~cnctwin.dynamics.config.StabilityConfig`
(:func:`~cnctwin.dynamics.time_domain.simulate_milling`), summarises it (RMS, chatter verdict,
mean force, peak-to-peak motion) and checks it against the semi-discretization's Floquet
multiplier at the same speed, depth and process damping (Insperger & Stépán 2004).
:func:`calibrate_damping_cuts` finds the process-damping coefficient of each measured cut
(Royandi 2026, Eq. 14) and fits the Gamma model per spindle speed (Eq. 15-19).

Both fill in what the configuration gives: the cutter diameter and default process damping
from ``[process_damping]``, the edge coefficients from the ``[cut]`` material. SI units
(rad/s, m, s, N, N/m, N/m^2) except where a name says mm: the cutter diameter (the unit of
:class:`cnctwin.geometry.Cutter` and of ``[process_damping].diameter_mm``) and the depths
and feeds of measured cuts (those of Royandi 2026's tables).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from cnctwin.dynamics.config import StabilityConfig
from cnctwin.dynamics.process_damping import (
    CalibrationSetup,
    GammaFit,
    MatchStatus,
    ProcessDampingModel,
    calibrate_cpd,
    cut_process_damping,
    fit_process_damping_model,
)
from cnctwin.dynamics.stability import MillingProcess, floquet_multipliers
from cnctwin.dynamics.time_domain import (
    ChatterVerdict,
    MillingVibration,
    VibrationRms,
    simulate_milling,
)
from cnctwin.errors import ConfigError, InputError
from cnctwin.geometry import Cutter

__all__ = [
    "CalibratedCut",
    "DampingCalibration",
    "MillingRun",
    "calibrate_damping_cuts",
    "run_milling",
]

#: Least distinct depths per spindle speed for a Gamma fit (three parameters, Eq. 16-19).
MIN_FIT_DEPTHS = 3


@dataclass(frozen=True)
class MillingRun:
    """One simulated cut of a stability configuration and its summary.

    Attributes
    ----------
    vibration
        The simulation: tool-tip motion and cutting force over time.
    feed_per_tooth_m
        Feed per tooth used, m.
    cpd_pa
        Process-damping coefficient C_pd used, N/m^2; None without process damping.
    simulated_s, transient_s
        Time simulated (whole tooth periods) and the part of it left out of the summary, s.
    rms
        RMS about the mean over the steady part (displacement m, velocity m/s, acceleration
        m/s^2 and g, force N; x and y).
    mean_force_n, peak_to_peak_m
        Mean cutting force on the tool, N, and peak-to-peak displacement, m, over the steady
        part ([x, y]).
    verdict
        The time-domain chatter verdict over the steady part.
    sdm_spectral_radius
        ``|mu|`` of the largest Floquet multiplier by semi-discretization (stable below 1).
    wall_s
        Wall time of the simulation and its summary, s.
    """

    vibration: MillingVibration
    feed_per_tooth_m: float
    cpd_pa: float | None
    simulated_s: float
    transient_s: float
    rms: VibrationRms
    mean_force_n: np.ndarray
    peak_to_peak_m: np.ndarray
    verdict: ChatterVerdict
    sdm_spectral_radius: float
    wall_s: float

    @property
    def sdm_stable(self) -> bool:
        """True when the semi-discretization finds the cut stable (``|mu| < 1``)."""
        return self.sdm_spectral_radius < 1.0


@dataclass(frozen=True)
class CalibratedCut:
    """The process damping that reproduces one measured cut (Royandi 2026, Eq. 14-15).

    Attributes
    ----------
    cpd_pa
        C_pd, N/m^2.
    simulated_rms_m_s2
        The model's RMS acceleration at ``cpd_pa``, m/s^2.
    relative_error
        Eq. 14 at ``cpd_pa``.
    status
        ``"matched"``, ``"no_damping_needed"`` or ``"upper_bound"``
        (:class:`~cnctwin.dynamics.process_damping.CpdMatch`).
    evaluations
        Simulations run.
    gamma_n
        ``Gamma = C_pd a_p f_z``, N (Eq. 15).
    effective_damping_n_s_m
        ``C_eff = Gamma / V_c``, N s/m (Eq. 3, ``V_c`` the cutting speed at the radius).
    """

    cpd_pa: float
    simulated_rms_m_s2: float
    relative_error: float
    status: MatchStatus
    evaluations: int
    gamma_n: float
    effective_damping_n_s_m: float


@dataclass(frozen=True)
class DampingCalibration:
    """Process damping per measured cut and the Gamma model per spindle speed.

    Attributes
    ----------
    cuts
        One :class:`CalibratedCut` per measured cut, in the given order.
    fits
        One :class:`~cnctwin.dynamics.process_damping.GammaFit` per spindle speed with at least
        three distinct matched depths, by rising speed; each fit's ``spindle_rad_s`` is the
        given speed.
    unfitted_rad_s
        The given speeds (rad/s) without a fit, rising.
    wall_s
        Wall time of the calibration, s.
    """

    cuts: tuple[CalibratedCut, ...]
    fits: tuple[GammaFit, ...]
    unfitted_rad_s: tuple[float, ...]
    wall_s: float

    def model(self) -> ProcessDampingModel:
        """The fits as a model of C_pd over depth, feed and speed (Royandi 2026, Eq. 20)."""
        return ProcessDampingModel(self.fits)


def run_milling(
    config: StabilityConfig,
    *,
    spindle_rad_s: float,
    depth_m: float,
    feed_per_tooth_m: float | None = None,
    duration_s: float = 0.3,
    transient_s: float | None = None,
    diameter_mm: float | None = None,
    helix_rad: float = 0.0,
    edge_tangential_n_m: float | None = None,
    edge_radial_n_m: float | None = None,
    helical_edge: bool = False,
    cpd_pa: float | None = None,
    damping_model: ProcessDampingModel | None = None,
    steps_per_tooth: int | None = None,
    max_duration_s: float | None = None,
) -> MillingRun:
    """Simulate one cut of a stability configuration and summarise it.

    While the chatter verdict is ``"undecided"`` (the growth rate of the vibration off the
    tooth period is not distinguishable from 0: a cut near the boundary, or saturated
    chatter; :meth:`~cnctwin.dynamics.time_domain.MillingVibration.chatter`), the cut is
    simulated again for twice the time, up to ``max_duration_s``, where the energy off the
    harmonics decides.

    Parameters
    ----------
    config
        A stability configuration with a milling cut: modes, teeth, immersion, coefficients.
    spindle_rad_s, depth_m
        Spindle speed, rad/s, and axial depth of cut, m.
    feed_per_tooth_m
        Feed per tooth, m; default ``[process_damping].chip_thickness_mm``.
    duration_s, transient_s
        Simulated time and the part of it left out of the summary (default half), s.
    diameter_mm, helix_rad
        Cutter diameter, mm (default ``[process_damping].diameter_mm``; None: straight flutes
        without a cutter), and helix angle, rad (0 <= helix < pi/2; > 0 needs a diameter).
    edge_tangential_n_m, edge_radial_n_m
        Edge coefficients Kte, Kre, N/m; default the ``[cut]`` material's, else 0.
    helical_edge
        Edge force per helical edge length (Royandi 2026, Eq. 10-11).
    cpd_pa, damping_model
        Process damping: C_pd in N/m^2 (0 turns it off; default ``[process_damping].cpd_n_m2``)
        or a fitted Gamma model (Eq. 20); they exclude each other.
    steps_per_tooth
        Steps per tooth period (None: the simulation's default).
    max_duration_s
        Longest simulated time of an undecided verdict, s (default 4 x ``duration_s``;
        ``duration_s`` or less: no second run). A given ``transient_s`` stays as given;
        the default stays half the time simulated.

    Raises
    ------
    ConfigError
        When the configuration's cut is orthogonal.
    InputError
        For a helix out of range or without a diameter, no feed, a process damping without
        a diameter, and what :func:`~cnctwin.dynamics.time_domain.simulate_milling` refuses.
    """
    process = _milling(config)
    section = config.process_damping
    if feed_per_tooth_m is None:
        if section is None:
            raise InputError(
                "feed_per_tooth_m: give it (m) or a [process_damping] chip_thickness_mm"
            )
        feed_per_tooth_m = section.chip_thickness_mm * 1e-3
    diameter = _diameter(config, diameter_mm)
    cutter = _cutter(process.teeth, diameter, helix_rad, depth_m * 1e3)
    kte, kre = _edges(config, edge_tangential_n_m, edge_radial_n_m)
    damping = cut_process_damping(
        depth_m=depth_m,
        feed_per_tooth_m=feed_per_tooth_m,
        spindle_rad_s=spindle_rad_s,
        diameter_m=None if cutter is None else cutter.diameter_m,
        cpd_pa=cpd_pa,
        model=damping_model,
        default_cpd_pa=None if section is None else section.cpd_n_m2,
    )
    cap = 4.0 * duration_s if max_duration_s is None else max_duration_s
    started = time.perf_counter()
    while True:
        result = simulate_milling(
            config.tool_dynamics(),
            process,
            spindle_rad_s=spindle_rad_s,
            depth_m=depth_m,
            feed_per_tooth_m=feed_per_tooth_m,
            duration_s=duration_s,
            cutter=cutter,
            edge_tangential_n_m=kte,
            edge_radial_n_m=kre,
            helical_edge=helical_edge,
            damping=damping,
            steps_per_tooth=steps_per_tooth,
        )
        longer = 2.0 * duration_s <= cap * (1.0 + 1e-9)
        verdict = result.chatter(transient_s=transient_s, final=not longer)
        if verdict.decision != "undecided":
            break
        duration_s *= 2.0
    rms = result.rms(transient_s)
    wall = time.perf_counter() - started
    window = result.steady_window(transient_s)
    multipliers = floquet_multipliers(
        config.tool_dynamics(), process, spindle_rad_s, depth_m, damping=damping
    )
    return MillingRun(
        vibration=result,
        feed_per_tooth_m=feed_per_tooth_m,
        cpd_pa=None if damping is None else damping.coefficient_pa,
        simulated_s=float(result.time_s.size * result.tooth_period_s / result.steps_per_tooth),
        transient_s=float(window.start * result.tooth_period_s / result.steps_per_tooth),
        rms=rms,
        mean_force_n=result.force_n[window].mean(axis=0),
        peak_to_peak_m=np.ptp(result.displacement_m[window], axis=0),
        verdict=verdict,
        sdm_spectral_radius=float(abs(multipliers[0])),
        wall_s=wall,
    )


def calibrate_damping_cuts(
    config: StabilityConfig,
    *,
    depth_mm: Sequence[float],
    spindle_rad_s: Sequence[float],
    feed_per_tooth_mm: Sequence[float],
    measured_rms_m_s2: Sequence[float],
    diameter_mm: float | None = None,
    helix_rad: float = 0.0,
    edge_tangential_n_m: float | None = None,
    edge_radial_n_m: float | None = None,
    helical_edge: bool = False,
    axis: Literal["x", "y"] = "x",
    duration_s: float = 0.2,
    steps_per_tooth: int | None = None,
) -> DampingCalibration:
    """Calibrate C_pd per measured cut (Royandi 2026, Eq. 14) and fit Gamma per speed (Eq. 15-19).

    Each cut is simulated with the configuration's modes and immersion, C_pd adjusted until
    the RMS acceleration along ``axis`` over the second half of ``duration_s`` matches the
    measured one (:func:`~cnctwin.dynamics.process_damping.calibrate_cpd`). Speeds with at
    least three distinct matched depths get a fit ``Gamma = A + B exp(-a_p / a0)``.

    Parameters
    ----------
    config
        A stability configuration with a milling cut.
    depth_mm, spindle_rad_s, feed_per_tooth_mm, measured_rms_m_s2
        Per cut: axial depth, mm; spindle speed, rad/s; feed per tooth, mm; measured RMS
        acceleration along ``axis``, m/s^2. Equal lengths, at least one cut.
    diameter_mm, helix_rad, edge_tangential_n_m, edge_radial_n_m, helical_edge
        As for :func:`run_milling`; a diameter is required (the cutting speed of Eq. 3).
    axis
        ``"x"`` (feed) or ``"y"``.
    duration_s
        Simulated time per run, s.
    steps_per_tooth
        Steps per tooth period (None: the simulation's default).

    Raises
    ------
    ConfigError
        When the configuration's cut is orthogonal.
    InputError
        For no cuts, columns of different lengths, an axis other than x or y, no diameter,
        and what :func:`~cnctwin.dynamics.process_damping.calibrate_cpd` refuses.
    """
    if axis not in ("x", "y"):
        raise InputError(f"axis {axis!r}; give 'x' or 'y'")
    columns = (depth_mm, spindle_rad_s, feed_per_tooth_mm, measured_rms_m_s2)
    if len({len(column) for column in columns}) != 1:
        raise InputError(
            "depth_mm, spindle_rad_s, feed_per_tooth_mm and measured_rms_m_s2 have lengths "
            f"{[len(column) for column in columns]}; give one value per cut in each"
        )
    if not depth_mm:
        raise InputError("no cuts; give at least one (depth, speed, feed, measured RMS)")
    process = _milling(config)
    diameter = _diameter(config, diameter_mm)
    if diameter is None:
        raise InputError(
            "the cutting speed of Eq. 3 needs the cutter diameter: give diameter_mm or "
            "[process_damping].diameter_mm"
        )
    cutter = _end_mill(process.teeth, diameter, helix_rad, max(depth_mm))
    kte, kre = _edges(config, edge_tangential_n_m, edge_radial_n_m)
    setup = CalibrationSetup(
        config.tool_dynamics(),
        process,
        cutter,
        kte,
        kre,
        helical_edge,
        duration_s,
        steps_per_tooth,
        axis,
    )
    started = time.perf_counter()
    cuts = []
    for ap, speed, fz, measured in zip(*columns, strict=True):
        found = calibrate_cpd(
            setup,
            spindle_rad_s=speed,
            depth_m=ap * 1e-3,
            feed_per_tooth_m=fz * 1e-3,
            measured_rms_m_s2=measured,
        )
        gamma = found.cpd_pa * ap * fz * 1e-6  # Eq. 15, N (mm * mm = 1e-6 m^2)
        cuts.append(
            CalibratedCut(
                cpd_pa=found.cpd_pa,
                simulated_rms_m_s2=found.simulated_rms,
                relative_error=found.relative_error,
                status=found.status,
                evaluations=found.evaluations,
                gamma_n=gamma,
                effective_damping_n_s_m=gamma / (speed * cutter.radius_m),  # Eq. 3
            )
        )
    fits, unfitted = [], []
    for speed in sorted(set(spindle_rad_s)):
        group = [
            index
            for index, cut in enumerate(cuts)
            if spindle_rad_s[index] == speed and cut.status == "matched"
        ]
        if len({depth_mm[index] for index in group}) < MIN_FIT_DEPTHS:
            unfitted.append(speed)
            continue
        model = fit_process_damping_model(
            [spindle_rad_s[index] for index in group],
            [depth_mm[index] * 1e-3 for index in group],
            [feed_per_tooth_mm[index] * 1e-3 for index in group],
            [cuts[index].cpd_pa for index in group],
        )
        fits.append(model.fits[0])
    return DampingCalibration(
        cuts=tuple(cuts),
        fits=tuple(fits),
        unfitted_rad_s=tuple(unfitted),
        wall_s=time.perf_counter() - started,
    )


def _milling(config: StabilityConfig) -> MillingProcess:
    """The configuration's cut, which must be milling."""
    process = config.process()
    if not isinstance(process, MillingProcess):
        raise ConfigError("cut.operation is 'orthogonal'; the time-domain model simulates milling")
    return process


def _diameter(config: StabilityConfig, given: float | None) -> float | None:
    """Cutter diameter in mm: the given one, else ``[process_damping].diameter_mm``, else None."""
    if given is not None:
        return given
    if config.process_damping is not None:
        return config.process_damping.diameter_mm
    return None


def _edges(config: StabilityConfig, kte: float | None, kre: float | None) -> tuple[float, float]:
    """Edge coefficients in N/m: the given ones, else the configuration's material, else 0."""
    base = config.coefficients()
    return (base.kte if kte is None else kte, base.kre if kre is None else kre)


def _end_mill(teeth: int, diameter_mm: float, helix_rad: float, depth_mm: float) -> Cutter:
    """A flat end mill with flutes as long as the (deepest) cut, mm: the time-domain model
    reads only its flutes, helix and diameter."""
    if not (math.isfinite(helix_rad) and 0.0 <= helix_rad < 0.5 * math.pi):
        raise InputError(f"helix_rad {helix_rad!r}; give 0 <= helix < pi/2 rad")
    return Cutter.flat(diameter_mm, depth_mm, flutes=teeth, helix_rad=helix_rad)


def _cutter(
    teeth: int, diameter_mm: float | None, helix_rad: float, depth_mm: float
) -> Cutter | None:
    """The cutter, or None (straight flutes) when no diameter is known."""
    if diameter_mm is None:
        if helix_rad != 0.0:
            raise InputError(
                f"helix_rad {helix_rad!r} needs the cutter diameter: give diameter_mm or "
                "[process_damping].diameter_mm"
            )
        return None
    return _end_mill(teeth, diameter_mm, helix_rad, depth_mm)
