"""Time-domain milling simulation against the semi-discretization, closed forms and physics.

Benchmarks: ../shared/data/stability/NOTES.md section 1 (Insperger & Stépán: 2 teeth, 922 Hz,
zeta 0.011, k 1340049.648 N/m, Kt 600, Kn 200 N/mm^2; slot with a 1-DOF tool and a/D = 0.05
down-milling with a symmetric 2-DOF tool) and section 2 (UBC tool, two modes per direction).
The SDM (cnctwin.dynamics.stability, another algorithm on the linearised equation) is the
independent reference for stability; closed forms for the forced response.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.dynamics import _time_domain_kernels as kernels
from cnctwin.dynamics.stability import (
    MillingProcess,
    ProcessDamping,
    ToolDynamics,
    ToolMode,
    floquet_multipliers,
    sdm_lobes,
)
from cnctwin.dynamics.time_domain import MillingVibration, _angle_tables, simulate_milling
from cnctwin.errors import InputError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import (
    CuttingCoefficients,
    ImmersionIntervals,
    flat_end_mill_mean_forces,
    milling_forces,
)

RPM = math.pi / 30.0
INSPERGER_MODE = ToolMode.from_hz(922.0, 0.011, stiffness_n_m=1340049.648)
ONE_DOF = ToolDynamics.from_xy(x=[INSPERGER_MODE])
TWO_DOF = ToolDynamics.from_xy(x=[INSPERGER_MODE], y=[INSPERGER_MODE])
INSPERGER = CuttingCoefficients(6e8, 2e8)
SLOT = MillingProcess.from_immersion(2, INSPERGER, 1.0)
AD005 = MillingProcess.from_immersion(2, INSPERGER, 0.05, down_milling=True)
UBC = ToolDynamics.from_xy(
    x=[
        ToolMode.from_hz(456.780, 0.111705, stiffness_n_m=7933097.2),
        ToolMode.from_hz(1448.889, 0.017037, stiffness_n_m=14691778.4),
    ],
    y=[
        ToolMode.from_hz(516.518, 0.024580, stiffness_n_m=9374613.8),
        ToolMode.from_hz(1408.448, 0.031358, stiffness_n_m=12406389.7),
    ],
)
UBC_CUT = MillingProcess.from_immersion(2, CuttingCoefficients(1319.4e6, 788.8e6), 0.5)
# Royandi 2026, Table 2 means (k 8028 N/mm, c 118 N s/m, m 0.241 kg) in x and y, and the
# AA6060-T6 coefficients of Sec. 4.2 (4 teeth, slot).
ROYANDI_MODE = ToolMode(math.sqrt(8028e3 / 0.241), 118.0 / (2 * math.sqrt(8028e3 * 0.241)), 8028e3)
ROYANDI = ToolDynamics.from_xy(x=[ROYANDI_MODE], y=[ROYANDI_MODE])
ROYANDI_SLOT = MillingProcess.from_immersion(4, CuttingCoefficients(745.1e6, 360.98e6), 1.0)
ROYANDI_PD = ProcessDamping(3e9, 1e-4, 0.012)  # the paper's initial C_pd (Sec. 4.2)

CASES = {
    "slot 1-DOF": (ONE_DOF, SLOT, None),
    "a/D 0.05 2-DOF": (TWO_DOF, AD005, None),
    "UBC two modes per axis": (UBC, UBC_CUT, None),
    "Royandi slot with process damping": (ROYANDI, ROYANDI_SLOT, ROYANDI_PD),
}


@pytest.mark.parametrize(
    ("case", "rpm"),
    [
        ("slot 1-DOF", 5000.0),  # Hopf
        ("slot 1-DOF", 10000.0),  # Hopf
        ("slot 1-DOF", 20000.0),  # flip (period doubling)
        ("slot 1-DOF", 24000.0),  # Hopf, saturating at a small share of the energy
        ("a/D 0.05 2-DOF", 8000.0),
        ("a/D 0.05 2-DOF", 15000.0),
        ("a/D 0.05 2-DOF", 20000.0),  # flip
        ("UBC two modes per axis", 3000.0),
        ("UBC two modes per axis", 9000.0),
        ("Royandi slot with process damping", 5500.0),
        ("Royandi slot with process damping", 9500.0),
    ],
)
def test_stable_and_chatter_agree_with_the_semi_discretization(case: str, rpm: float) -> None:
    tool, process, damping = CASES[case]
    lobes = sdm_lobes(tool, process, [rpm * RPM], max_depth_m=0.02, damping=damping)
    critical = float(lobes.critical_depth_m[0])
    assert math.isfinite(critical)
    for factor in (0.8, 1.2):
        result = simulate_milling(
            tool,
            process,
            spindle_rad_s=rpm * RPM,
            depth_m=factor * critical,
            feed_per_tooth_m=1e-4,
            duration_s=0.3,
            damping=damping,
        )
        verdict = result.chatter()
        assert verdict.chatter == (factor > 1.0), (factor, verdict)
        if factor > 1.0 and lobes.bifurcation[0] == "hopf":
            # The chatter frequency of the nonlinear (saturated) motion stays within 2 % of the
            # linear one at the boundary (the window resolves 1 / 0.15 s = 6.7 Hz).
            expected = float(lobes.chatter_frequency_hz[0])
            assert verdict.frequency_hz == pytest.approx(expected, rel=0.02)
        if factor > 1.0 and lobes.bifurcation[0] == "flip":
            # Period doubling: the chatter sits at odd multiples of half the tooth frequency.
            half = 0.5 * result.tooth_passing_hz
            assert verdict.frequency_hz / half == pytest.approx(
                round(verdict.frequency_hz / half), abs=0.02
            )
            assert round(verdict.frequency_hz / half) % 2 == 1


def _dominant_multipliers(result: MillingVibration) -> np.ndarray:
    """The dominant pair of Floquet multipliers seen in a simulated transient (Prony).

    The change over one tooth period, ``d_k = x(t0 + kT) - x(t0 + (k-1)T)``, is free of the
    periodic forced motion and, once the faster multipliers have died out, obeys
    ``d_(k+2) = c1 d_(k+1) + c0 d_k`` with ``mu`` the roots of ``z^2 - c1 z - c0``; fitted by
    least squares over all phases t0 of the middle half of the record.
    """
    m = result.steps_per_tooth
    x = result.displacement_m[:, 0]
    periods = x.size // m
    change = np.diff(x[: periods * m].reshape(periods, m), axis=0)
    change = change[(periods - 1) // 4 : 3 * (periods - 1) // 4]
    design = np.column_stack((change[1:-1].ravel(), change[:-2].ravel()))
    (c1, c0), *_ = np.linalg.lstsq(design, change[2:].ravel(), rcond=None)
    return np.sort_complex(np.roots([1.0, -c1, -c0]))


@pytest.mark.parametrize(
    ("rpm", "depth_mm"), [(5000.0, 0.30), (10000.0, 0.25), (20000.0, 1.2), (24000.0, 3.0)]
)
def test_transient_decays_with_the_floquet_multipliers(rpm: float, depth_mm: float) -> None:
    # A stable cut's deviation from its periodic motion dies out as mu^k, mu the dominant
    # Floquet multipliers of the SDM. The time domain finds them, complex, within 2e-3
    # (seen: 2e-5 to 8e-4, the largest at 5000 rpm where the SDM's 200 steps per period
    # are 36 per cycle of the mode: its own error there, 6e-4 against 400 steps).
    mu = floquet_multipliers(ONE_DOF, SLOT, rpm * RPM, depth_mm * 1e-3, steps=200)[:2]
    result = simulate_milling(
        ONE_DOF, SLOT, spindle_rad_s=rpm * RPM, depth_m=depth_mm * 1e-3,
        feed_per_tooth_m=1e-4, duration_s=0.2,
    )  # fmt: skip
    found = _dominant_multipliers(result)
    assert np.abs(found - np.sort_complex(mu)).max() < 2e-3


def _forced(cutter: Cutter | None = None, **options: object) -> MillingVibration:
    """Half-immersion down-milling, 3 teeth, x and y modes of different frequencies."""
    tool = ToolDynamics.from_xy(
        x=[ToolMode.from_hz(700.0, 0.03, stiffness_n_m=5e6)],
        y=[ToolMode.from_hz(1100.0, 0.02, stiffness_n_m=8e6)],
    )
    process = MillingProcess.from_immersion(3, CuttingCoefficients(7e8, 2.5e8), 0.5)
    return simulate_milling(
        tool,
        process,
        spindle_rad_s=6000.0 * RPM,
        depth_m=2e-3,
        feed_per_tooth_m=8e-5,
        duration_s=0.25,
        cutter=cutter,
        edge_tangential_n_m=2.5e4,
        edge_radial_n_m=1.5e4,
        regenerative=False,
        **options,  # type: ignore[arg-type]
    )


def test_forced_response_mean_is_the_static_deflection_under_the_mean_force() -> None:
    cutter = Cutter.flat(12.0, 20.0, flutes=3, helix_rad=math.radians(30.0))
    result = _forced(cutter)
    window = result.steady_window()
    entry, exit_ = math.pi / 2, math.pi  # a/D = 0.5, down-milling
    mean = flat_end_mill_mean_forces(
        CuttingCoefficients(7e8, 2.5e8, 0.0, 2.5e4, 1.5e4), 3, 0.006, entry, exit_,
        2e-3, 8e-5, 6000.0 * RPM,
    )  # fmt: skip
    # Altintas' closed form of the mean force (the helix does not change a mean); the
    # angular cells are integrated exactly at the entry and exit, the rest by the midpoint
    # rule: 1e-4 relative.
    force = result.force_n[window].mean(axis=0)
    assert force == pytest.approx([mean.fx_n, mean.fy_n], rel=1e-4)
    # The linear system's steady state under the mean force: F / k per axis.
    displacement = result.displacement_m[window].mean(axis=0)
    assert displacement == pytest.approx([mean.fx_n / 5e6, mean.fy_n / 8e6], rel=1e-4)
    assert result.chatter().nonsynchronous_ratio < 1e-12


def test_forced_response_harmonics_follow_the_frf() -> None:
    # Each tooth-passing harmonic of the displacement is the FRF times the force harmonic
    # (x and y modes are uncoupled): |X_k| = |G(i w_k)| |F_k|. The integrator treats the force
    # as linear between samples: error of order (w_k dt)^2 / 12, below 1e-4 for these k.
    result = _forced()
    modes = (ToolMode.from_hz(700.0, 0.03, stiffness_n_m=5e6),
             ToolMode.from_hz(1100.0, 0.02, stiffness_n_m=8e6))  # fmt: skip
    for axis, mode in (("x", modes[0]), ("y", modes[1])):
        x = result.spectrum("displacement", "x" if axis == "x" else "y")
        f = result.spectrum("force", "x" if axis == "x" else "y")
        bins = np.flatnonzero(x.harmonic)[1:6]
        receptance = np.abs(mode.receptance(2 * math.pi * x.frequency_hz[bins]))
        assert x.amplitude[bins] == pytest.approx(receptance * f.amplitude[bins], rel=1e-3)
        assert x.frequency_hz[bins] == pytest.approx(result.tooth_passing_hz * np.arange(1, 6))


def test_force_waveform_matches_the_mechanics_model() -> None:
    # The non-regenerative force over a revolution is the mechanistic force of
    # cnctwin.mechanics.milling (another implementation: same slices, pointwise angles)
    # everywhere but the few cells a tooth of a slice enters or leaves, which the time
    # domain averages over the cell.
    cutter = Cutter.flat(12.0, 20.0, flutes=3, helix_rad=math.radians(30.0))
    result = _forced(cutter)
    m = result.steps_per_tooth
    revolution = slice(result.time_s.size - 3 * m, result.time_s.size)
    start = result.time_s.size - 3 * m  # a whole number of revolutions from t = 0
    assert start % (3 * m) == 0
    cut = ImmersionIntervals.from_depths(
        cutter, 0.006, 2e-3, down_milling=True, slices=result.slices
    )
    wave = milling_forces(
        cutter, CuttingCoefficients(7e8, 2.5e8, 0.0, 2.5e4, 1.5e4), cut, 8e-5, 6000.0 * RPM,
        steps=3 * m,
    )  # fmt: skip
    expected = np.column_stack((wave.fx_n, wave.fy_n))
    error = np.abs(result.force_n[revolution] - expected).max(axis=1)
    scale = np.abs(expected).max()
    boundary_cells = 2 * 3 * result.slices  # entry and exit of each tooth in each slice
    assert np.count_nonzero(error > 1e-9 * scale) <= boundary_cells
    assert np.median(error) < 1e-12 * scale


def test_power_balance_in_the_periodic_steady_state() -> None:
    # In a periodic steady state the cutting force's mean power into the tool equals the
    # mean power dissipated by the structural and process damping (x and y modes: c = 2
    # zeta k / wn). A stable regenerative cut with process damping, Royandi's tool.
    damping = ProcessDamping(2e10, 1e-4, 0.012)
    result = simulate_milling(
        ROYANDI, ROYANDI_SLOT, spindle_rad_s=7500 * RPM, depth_m=1.5e-3,
        feed_per_tooth_m=1e-4, duration_s=0.2,
        cutter=Cutter.flat(12.0, 20.0, flutes=4, helix_rad=math.radians(30)),
        edge_tangential_n_m=31.49e3, edge_radial_n_m=21.85e3, damping=damping,
    )  # fmt: skip
    window = result.steady_window()
    v = result.velocity_m_s[window]
    power_in = float(np.mean(np.sum(result.force_n[window] * v, axis=1)))
    c = 2.0 * ROYANDI_MODE.damping_ratio * ROYANDI_MODE.stiffness_n_m / ROYANDI_MODE.frequency_rad_s
    dissipated = float(np.mean((c + result.process_damping_n_s_m) * np.sum(v * v, axis=1)))
    assert result.process_damping_n_s_m == pytest.approx(
        2e10 * 1.5e-3 * 1e-4 / (7500 * RPM * 0.006)
    )
    assert power_in == pytest.approx(dissipated, rel=2e-3)


def test_step_size_convergence_is_second_order() -> None:
    # Heun's predictor-corrector on exact modal steps: the RMS acceleration's error falls as
    # dt^2 (an observed order near 2), and the default resolution (200 steps per cycle of
    # the mode, here 1107 per tooth period) is converged to 0.1 %.
    def rms(m: int | None) -> float:
        result = simulate_milling(
            ONE_DOF, SLOT, spindle_rad_s=5000 * RPM, depth_m=0.3e-3, feed_per_tooth_m=1e-4,
            duration_s=0.15, steps_per_tooth=m,
        )  # fmt: skip
        return float(result.rms().acceleration_m_s2[0])

    coarse, middle, fine = rms(100), rms(200), rms(400)
    order = math.log2(abs(middle - coarse) / abs(fine - middle))
    assert 1.8 < order < 2.2
    assert rms(None) == pytest.approx(rms(2214), rel=1e-3)


def test_default_resolution() -> None:
    result = simulate_milling(
        ROYANDI, ROYANDI_SLOT, spindle_rad_s=5500 * RPM, depth_m=3.5e-3, feed_per_tooth_m=1e-4,
        duration_s=0.01, cutter=Cutter.flat(12.0, 20.0, flutes=4, helix_rad=math.radians(30.0)),
    )  # fmt: skip
    # 918.6 Hz mode, tooth period 60 / (4 * 5500) s: 2.505 cycles per period, 200 per cycle.
    assert result.steps_per_tooth == 502
    # Helix lag 3.5 tan(30 deg) / 6 = 0.3368 rad, turned in 0.585 ms = 0.537 cycles of the
    # mode: 20 slices per cycle -> 11 slices.
    assert result.slices == 11
    fast = simulate_milling(
        ONE_DOF, SLOT, spindle_rad_s=25000 * RPM, depth_m=1e-3, feed_per_tooth_m=1e-4,
        duration_s=0.01,
    )  # fmt: skip
    assert (fast.steps_per_tooth, fast.slices) == (222, 1)


def test_a_tooth_out_of_the_cut_leaves_the_surface_to_the_next() -> None:
    # One slice, 2 teeth, 4 steps per tooth period: grid angles k pi / 4. At step 2 tooth 0
    # is at 90 deg (h = f sin 90 = f). With the tool pulled back by more than f along x it
    # misses: no force, the surface stays; one period later (step 6, tooth 1 at the same
    # angle) the tool is back at 0 and cuts two feeds' worth.
    feed, m = 1e-4, 4
    angles = np.arange(8)[:, None] * (math.pi / 4)
    inside = (angles > 0) & (angles < math.pi)
    sin_t, cos_t = np.sin(angles), np.cos(angles)
    ones = np.where(inside, 1.0, 0.0)
    zeros = np.zeros_like(ones)
    surface = feed * sin_t * ((np.arange(8) % m) / m - 1.0)[:, None]
    args = (m, feed, inside, sin_t, cos_t, ones, zeros, zeros, zeros)

    def force(step: int, rx: float) -> float:
        advance = feed * step / m + rx  # the feed advanced so far plus the tip's x
        return kernels.cutting_force(step, advance, 0.0, *args, surface, True, True)[0]

    assert force(2, 0.0) == pytest.approx(feed)
    assert force(6, -1.5 * feed) == 0.0
    assert force(10, 0.0) == pytest.approx(2 * feed)
    assert force(14, 0.0) == pytest.approx(feed)


def test_chatter_saturates_when_the_teeth_leave_the_cut() -> None:
    # Linear theory grows without bound above the boundary; with the teeth leaving the cut
    # the chatter settles to a bounded motion (growth about 1) with force-free instants.
    critical = float(sdm_lobes(ONE_DOF, SLOT, [10000 * RPM], max_depth_m=0.01).critical_depth_m[0])
    result = simulate_milling(
        ONE_DOF, SLOT, spindle_rad_s=10000 * RPM, depth_m=1.5 * critical, feed_per_tooth_m=1e-4,
        duration_s=0.6,
    )  # fmt: skip
    verdict = result.chatter()
    assert verdict.chatter and verdict.growth == pytest.approx(1.0, abs=0.3)
    # A 1-DOF tool moves along x only: the x spectrum alone tells the same.
    spectrum = result.spectrum("displacement", "x")
    assert spectrum.nonsynchronous_ratio == pytest.approx(verdict.nonsynchronous_ratio)
    assert spectrum.chatter_frequency_hz == verdict.frequency_hz
    assert spectrum.chatter_frequency_hz == pytest.approx(930.4, rel=0.02)  # SDM at 10000 rpm
    window = result.steady_window()
    free = np.all(result.force_n[window] == 0.0, axis=1)
    assert 0.05 < free.mean() < 0.9
    assert np.abs(result.displacement_m[window, 0]).max() < 1e-3


def test_rms_and_spectrum_of_the_outputs() -> None:
    result = _forced()
    rms = result.rms()
    window = result.steady_window()
    assert rms.acceleration_m_s2 == pytest.approx(np.std(result.acceleration_m_s2[window], axis=0))
    assert rms.acceleration_g == pytest.approx(rms.acceleration_m_s2 / 9.80665)
    # Parseval: the spectrum's energy (single-sided amplitudes) is the signal's variance.
    s = result.spectrum("velocity", "y")
    assert np.sum(s.amplitude[1:] ** 2) / 2 == pytest.approx(rms.velocity_m_s[1] ** 2, rel=1e-6)
    # Velocity and acceleration are the derivatives of displacement and velocity: each
    # step's change is the trapezoidal integral of the derivative, to O(dt^3) (a few 1e-5
    # relative here) except where a tooth enters and the force jumps within the step (5e-3).
    dt = result.time_s[1]
    for value, rate in ((result.displacement_m, result.velocity_m_s),
                        (result.velocity_m_s, result.acceleration_m_s2)):  # fmt: skip
        change = np.diff(value[window], axis=0)
        integral = 0.5 * dt * (rate[window][1:] + rate[window][:-1])
        assert change == pytest.approx(integral, abs=1e-2 * np.abs(change).max())
    assert result.time_s.size % result.steps_per_tooth == 0


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"depth_m": -1e-3}, "depth_m"),
        ({"duration_s": 0.0}, "duration_s"),
        ({"steps_per_tooth": 10}, "steps_per_tooth"),
        ({"slices": 0}, "slices"),
        ({"cutter": Cutter.flat(12.0, 20.0, flutes=4)}, "teeth"),
        ({"cutter": Cutter.ball(12.0, 20.0)}, "flat end mill"),
        ({"cutter": Cutter("flat", 12.0, 20.0, runout_mm=0.01)}, "runout"),
        ({"duration_s": 100.0}, "at most"),
    ],
)
def test_invalid_input_is_an_input_error(options: dict[str, object], message: str) -> None:
    arguments: dict[str, object] = {
        "spindle_rad_s": 10000 * RPM,
        "depth_m": 1e-3,
        "feed_per_tooth_m": 1e-4,
        "duration_s": 0.01,
    }
    arguments.update(options)
    with pytest.raises(InputError, match=message):
        simulate_milling(ONE_DOF, SLOT, **arguments)  # type: ignore[arg-type]


def test_analysis_options_are_checked() -> None:
    result = simulate_milling(
        ONE_DOF, SLOT, spindle_rad_s=10000 * RPM, depth_m=1e-4, feed_per_tooth_m=1e-4,
        duration_s=0.01,
    )  # fmt: skip
    with pytest.raises(InputError, match="transient_s"):
        result.rms(transient_s=1.0)
    with pytest.raises(InputError, match="threshold"):
        result.chatter(threshold=1.5)
    with pytest.raises(InputError, match="quantity"):
        result.spectrum("jerk")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="axis"):
        result.spectrum("force", "z")  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------------
# Near the boundary: 0.9x and 1.1x (issue 16, item 7)


@pytest.mark.parametrize("rpm", [10000.0, 16000.0])
@pytest.mark.parametrize("factor", [0.9, 1.1])
def test_run_milling_decides_like_the_sdm_at_ten_percent_from_the_boundary(
    rpm: float, factor: float
) -> None:
    # The shipped Insperger slot example (1-DOF, 2 teeth; NOTES.md section 1). At 0.9x the
    # largest Floquet multiplier is about 0.985-0.99 per tooth period: a 0.3 s run has not
    # died out (the old rule, late/early change RMS > 0.5, called it chatter), but its growth
    # rate is clearly negative. The time-domain integration (its own steps, no SDM) must
    # decide as the semi-discretization does, and its growth rate must be the SDM's
    # ln|mu| / T within 25 %.
    from pathlib import Path

    from cnctwin.dynamics import load_stability_config, run_milling

    example = Path(__file__).resolve().parents[2] / "examples/stability/insperger_slot.toml"
    config = load_stability_config(example)
    speed = rpm * RPM
    critical = float(sdm_lobes(ONE_DOF, SLOT, [speed], max_depth_m=0.01).critical_depth_m[0])
    run = run_milling(config, spindle_rad_s=speed, depth_m=factor * critical,
                      feed_per_tooth_m=5e-5, duration_s=0.3)  # fmt: skip
    verdict = run.verdict
    assert verdict.decision == ("chatter" if factor > 1.0 else "stable"), verdict
    assert verdict.chatter == (factor > 1.0)
    assert run.sdm_stable == (factor < 1.0)
    period = 2 * math.pi / (2 * speed)
    expected = math.log(run.sdm_spectral_radius) / period
    assert verdict.growth_rate_per_s == pytest.approx(expected, rel=0.25)
    assert abs(verdict.growth_rate_per_s) > 2 * verdict.growth_rate_sigma_per_s
    if factor < 1.0:
        assert verdict.growth > 0.5  # what the old rule would have called chatter


def test_an_undecided_short_run_is_run_longer_until_decided() -> None:
    # 0.97x the boundary at 10000 rpm: 0.03 s (10 tooth periods, a steady window of 5) cannot
    # tell the decay from 0; run_milling doubles the time until it can.
    from pathlib import Path

    from cnctwin.dynamics import load_stability_config, run_milling

    example = Path(__file__).resolve().parents[2] / "examples/stability/insperger_slot.toml"
    config = load_stability_config(example)
    speed = 10000.0 * RPM
    critical = float(sdm_lobes(ONE_DOF, SLOT, [speed], max_depth_m=0.01).critical_depth_m[0])
    short = simulate_milling(ONE_DOF, SLOT, spindle_rad_s=speed, depth_m=0.97 * critical,
                             feed_per_tooth_m=5e-5, duration_s=0.03)  # fmt: skip
    assert short.chatter(final=False).decision == "undecided"
    run = run_milling(config, spindle_rad_s=speed, depth_m=0.97 * critical,
                      feed_per_tooth_m=5e-5, duration_s=0.03)  # fmt: skip
    assert run.simulated_s > 0.05
    assert run.verdict.decision == "stable"


def test_angle_tables_skip_only_shifts_that_add_nothing() -> None:
    # the immersion interval is tried at four turns; one clear of every cell is skipped, which
    # must leave the tables bit for bit those of all four (the sums below)
    rng = np.random.default_rng(5)
    for k in range(60):
        entry = float(rng.uniform(0.0, math.pi))
        exit_ = float(rng.uniform(entry, math.pi if k % 3 else 2.0 * math.pi))
        teeth, steps, slices = int(rng.integers(2, 6)), int(rng.integers(20, 200)), 1 + k % 12
        lag = float(rng.uniform(0.0, 1.0))
        tables = _angle_tables(
            MillingProcess(teeth, 7e8, 2e8, entry, exit_), steps, slices, 2e-3, lag, 2e4, 1e4,
            0.5, False,
        )  # fmt: skip
        dtheta = 2.0 * math.pi / (teeth * steps)
        psi = (np.arange(slices) + 0.5) / slices * lag
        phi = np.arange(teeth * steps)[None, :] * dtheta - psi[:, None]
        overlap, moment = np.zeros_like(phi), np.zeros_like(phi)
        for shift in (-2.0 * math.pi, 0.0, 2.0 * math.pi, 4.0 * math.pi):
            lo = np.maximum(phi - 0.5 * dtheta, entry + shift)
            hi = np.minimum(phi + 0.5 * dtheta, exit_ + shift)
            part = np.clip(hi - lo, 0.0, None)
            overlap += part
            moment += part * (0.5 * (lo + hi) - phi)
        inside = overlap > 0.0
        phi = phi + np.where(inside, moment / np.where(inside, overlap, 1.0), 0.0)
        weight = overlap / dtheta * (2e-3 / slices)
        np.testing.assert_array_equal(tables.inside, inside.T)
        np.testing.assert_array_equal(tables.sin, np.sin(phi).T)
        np.testing.assert_array_equal(tables.cos, np.cos(phi).T)
        np.testing.assert_array_equal(
            tables.cut_x, (-(7e8 * np.cos(phi) + 2e8 * np.sin(phi)) * weight).T
        )
