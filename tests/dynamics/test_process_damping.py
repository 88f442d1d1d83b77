"""Process-damping calibration (Royandi 2026, Sec. 2.4 and 6.4): synthetic recovery, then the
paper's own numbers (Table 2, Sec. 4.2, Table 3, Eq. 17-19 and the C_pd and C_eff ranges of
Sec. 6.4), checked for what they allow and for where they contradict each other.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.dynamics.process_damping import (
    CalibrationSetup,
    GammaFit,
    ProcessDampingModel,
    calibrate_cpd,
    fit_gamma,
    fit_process_damping_model,
    match_cpd,
    relative_error,
)
from cnctwin.dynamics.stability import (
    MillingProcess,
    ProcessDamping,
    ToolDynamics,
    ToolMode,
    floquet_multipliers,
)
from cnctwin.errors import ConfigError, DataError, InputError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import CuttingCoefficients

RPM = math.pi / 30.0
G = 9.80665  # m/s^2 per g
DIAMETER_MM = 12.0  # Sec. 4.1: 12 mm solid carbide end mill, 4 flutes (Sec. 5)
FLUTE_LENGTH_MM = 30.0  # not given; the time-domain model does not read it

# Table 2 means: k 8028 N/mm, c 118 N s/m, m 0.241 kg (918.6 Hz, zeta 0.0424, 1.47 um/N at
# resonance: the 920 Hz and 1.45 um/N of Sec. 4.1), the same in x and y (Eq. 7).
MODE = ToolMode(math.sqrt(8028e3 / 0.241), 118.0 / (2.0 * math.sqrt(8028e3 * 0.241)), 8028e3)
TOOL = ToolDynamics.from_xy(x=[MODE], y=[MODE])
# Sec. 4.2: Ktc 745.1, Krc 360.98 N/mm^2, Kte 31.49, Kre 21.85 N/mm; full-immersion slots.
SLOT = MillingProcess.from_immersion(4, CuttingCoefficients(745.1e6, 360.98e6), 1.0)
# The paper gives no helix angle: 30 deg, common for 4-flute carbide end mills for aluminium
# (docs/_validation_chatter.md shows 0 and 45 deg). Edge terms per helical edge length, Eq. 10-11.
SETUP = CalibrationSetup(
    TOOL,
    SLOT,
    Cutter.flat(DIAMETER_MM, FLUTE_LENGTH_MM, flutes=4, helix_rad=math.radians(30.0)),
    edge_tangential_n_m=31.49e3,
    edge_radial_n_m=21.85e3,
    helical_edge=True,
    duration_s=0.2,
)

# Royandi 2026, Table 3: a_p (mm), spindle speed (rpm), f_z (mm/tooth), measured vibration (g).
TABLE_3 = np.array(
    [
        [1.5, 5500, 0.100, 1.949], [2.5, 5500, 0.100, 3.422], [3.5, 5500, 0.100, 3.595],
        [1.5, 5500, 0.075, 1.920], [2.5, 5500, 0.075, 3.210], [3.5, 5500, 0.075, 3.638],
        [1.5, 5500, 0.050, 2.080], [2.5, 5500, 0.050, 3.330], [3.5, 5500, 0.050, 4.260],
        [1.5, 7500, 0.100, 2.573], [2.5, 7500, 0.100, 3.487], [3.5, 7500, 0.100, 3.312],
        [1.5, 7500, 0.075, 2.762], [2.5, 7500, 0.075, 4.260], [3.5, 7500, 0.075, 4.560],
        [1.5, 7500, 0.050, 2.786], [2.5, 7500, 0.050, 4.183], [3.5, 7500, 0.050, 4.893],
        [1.5, 9500, 0.100, 2.579], [2.5, 9500, 0.100, 4.079], [3.5, 9500, 0.100, 4.799],
        [1.5, 9500, 0.075, 2.532], [2.5, 9500, 0.075, 3.658], [3.5, 9500, 0.075, 3.927],
        [1.5, 9500, 0.050, 1.830], [2.5, 9500, 0.050, 3.745], [3.5, 9500, 0.050, 4.325],
    ]
)  # fmt: skip
DEPTH_M = TABLE_3[:, 0] * 1e-3
SPEED = TABLE_3[:, 1] * RPM
FEED_M = TABLE_3[:, 2] * 1e-3
MEASURED_M_S2 = TABLE_3[:, 3] * G


def cutting_speed(spindle_rad_s: float) -> float:
    """V_c = Omega D / 2 in m/s at a spindle speed in rad/s."""
    return float(spindle_rad_s) * SETUP.cutter.radius_m


# ----------------------------------------------------------------------------------------
# Synthetic: known answers


def test_match_cpd_finds_the_root_of_a_known_curve() -> None:
    # rms(C) = 5 / (1 + C / 2e10): the measured 2 is reached at C = 3e10 exactly.
    def rms(c: float) -> float:
        return 5.0 / (1.0 + c / 2e10)

    found = match_cpd(rms, 2.0)
    assert found.status == "matched"
    assert found.cpd_pa == pytest.approx(3e10, rel=3e-3)  # log10 tolerance 1e-3: 0.23 %
    assert found.relative_error < 3e-3
    assert found.evaluations < 15
    # A root below the lowest bound is found between 0 and it, in linear C.
    low = match_cpd(rms, 4.9, bounds_pa=(1e9, 1e13))
    assert low.status == "matched" and low.cpd_pa == pytest.approx(2e10 * (5 / 4.9 - 1), rel=1e-3)
    # Less vibration than measured even without damping: C_pd = 0 minimises Eq. 14.
    none = match_cpd(rms, 6.0)
    assert (none.status, none.cpd_pa, none.simulated_rms) == ("no_damping_needed", 0.0, 5.0)
    assert none.relative_error == pytest.approx(1.0 / 6.0)
    top = match_cpd(rms, 1e-6, bounds_pa=(1e7, 1e12))
    assert (top.status, top.cpd_pa) == ("upper_bound", pytest.approx(1e12))


def test_calibrate_recovers_a_known_cpd_from_simulated_rms() -> None:
    # The "measurement" is the model's own RMS at a known C_pd; the calibration must return
    # that C_pd (RMS falls by ~0.7 % per 1 % of C_pd here: 0.5 % tolerance on C_pd).
    for rpm, depth, feed, true in ((7500, 2.5e-3, 1e-4, 1.2e11), (5500, 1.5e-3, 5e-5, 2e11)):
        measured = SETUP.acceleration_rms(rpm * RPM, depth, feed, true)
        found = calibrate_cpd(
            SETUP, spindle_rad_s=rpm * RPM, depth_m=depth, feed_per_tooth_m=feed,
            measured_rms_m_s2=measured,
        )  # fmt: skip
        assert found.status == "matched"
        assert found.cpd_pa == pytest.approx(true, rel=5e-3)
        assert found.simulated_rms == pytest.approx(measured, rel=5e-3)


def test_fit_gamma_recovers_a_known_saturation_curve() -> None:
    truth = GammaFit(7500 * RPM, 6.2e3, 1.25e5, 0.5e-3)
    depth = np.repeat(np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.5]) * 1e-3, 3)
    feed = np.tile(np.array([0.05, 0.075, 0.1]) * 1e-3, 6)
    cpd = truth.gamma_n(depth) / (depth * feed)  # Eq. 15 inverted
    fit = fit_gamma(7500 * RPM, depth, feed, cpd)
    assert fit.asymptote_n == pytest.approx(6.2e3, rel=1e-6)
    assert fit.amplitude_n == pytest.approx(1.25e5, rel=1e-6)
    assert fit.depth_scale_m == pytest.approx(0.5e-3, rel=1e-6)
    assert fit.mape_percent < 1e-6
    # With +-3 % scatter on C_pd (a fixed pattern) the parameters stay within 10 % and the
    # MAPE is about the scatter.
    scatter = 1.0 + 0.03 * np.sin(np.arange(depth.size) * 2.4)
    noisy = fit_gamma(7500 * RPM, depth, feed, cpd * scatter)
    assert noisy.asymptote_n == pytest.approx(6.2e3, rel=0.1)
    assert noisy.amplitude_n == pytest.approx(1.25e5, rel=0.1)
    assert noisy.depth_scale_m == pytest.approx(0.5e-3, rel=0.1)
    assert 1.0 < noisy.mape_percent < 3.0


def test_model_interpolates_between_speeds_and_holds_outside() -> None:
    model = ProcessDampingModel.royandi2026()
    assert [f.spindle_rad_s / RPM for f in model.fits] == pytest.approx([5500, 7500, 9500])
    # Eq. 20-21: linear interpolation of A, B, a0 between the nodes (Sec. 6.4).
    assert model.parameters(6500 * RPM) == pytest.approx((4.15e3, 3.675e5, 0.46e-3))
    assert model.parameters(3000 * RPM) == pytest.approx((2.10e3, 6.10e5, 0.42e-3))
    assert model.parameters(12000 * RPM) == pytest.approx((1.20e4, 3.10e5, 0.46e-3))
    # Eq. 17 at a_p = 1.5 mm, and C_pd by Eq. 20 at f_z = 0.1 mm.
    gamma = 2.10e3 + 6.10e5 * math.exp(-1.5 / 0.42)
    assert model.gamma_n(1.5e-3, 5500 * RPM) == pytest.approx(gamma)
    assert model.cpd_pa(1.5e-3, 1e-4, 5500 * RPM) == pytest.approx(gamma / 1.5e-7)
    damping = model.process_damping(1.5e-3, 1e-4, 5500 * RPM, SETUP.cutter.diameter_m)
    assert damping.effective_damping(1.5e-3, 5500 * RPM) == pytest.approx(
        gamma / cutting_speed(5500 * RPM)
    )


def test_fit_process_damping_model_groups_cuts_by_speed() -> None:
    truth = ProcessDampingModel.royandi2026()
    cpd = np.array([truth.cpd_pa(a, f, n) for a, f, n in zip(DEPTH_M, FEED_M, SPEED, strict=True)])
    model = fit_process_damping_model(SPEED, DEPTH_M, FEED_M, cpd)
    assert len(model.fits) == 3
    for fit, expected in zip(model.fits, truth.fits, strict=True):
        assert fit.spindle_rad_s == pytest.approx(expected.spindle_rad_s)
        assert fit.gamma_n(DEPTH_M) == pytest.approx(expected.gamma_n(DEPTH_M), rel=1e-6)


@pytest.mark.parametrize(
    ("call", "error"),
    [
        (lambda: relative_error(1.0, 0.0), DataError),
        (lambda: match_cpd(lambda c: 1.0, 1.0, bounds_pa=(1e9, 1e8)), InputError),
        (lambda: match_cpd(lambda c: math.nan, 1.0), DataError),
        (lambda: fit_gamma(1.0, [1e-3, 2e-3], [1e-4, 1e-4], [1e10, 1e10]), DataError),
        (lambda: fit_gamma(1.0, [1e-3, 2e-3, 3e-3], [1e-4] * 3, [1e10, -1.0, 1e10]), DataError),
        (lambda: ProcessDampingModel(()), ConfigError),
        (lambda: ProcessDampingModel.royandi2026().cpd_pa(0.0, 1e-4, 600.0), InputError),
    ],
)
def test_invalid_input(call: object, error: type[Exception]) -> None:
    with pytest.raises(error):
        call()  # type: ignore[operator]


# ----------------------------------------------------------------------------------------
# The paper's numbers


def test_paper_cpd_range_follows_from_eq_17_to_20_at_the_top_not_the_bottom() -> None:
    # Sec. 6.4 quotes calibrated C_pd of 4.7e9 ... 2.9e11 N/m^2. Eq. 17-19 with Eq. 20 in SI
    # (Gamma in N) over the 27 cuts of Table 3 give 6.42e9 ... 3.19e11: the top within the
    # 11 % MAPE reported at 9500 rpm, where it lies. The bottom belongs to 5500 rpm, 3.5 mm,
    # 0.1 mm/tooth, where the fit's MAPE is 1.05 % over 9 cuts: no single cut can then be
    # off by more than 9 x 1.05 = 9.5 %, yet 4.7e9 is 27 % below the fit. Not reproducible.
    model = ProcessDampingModel.royandi2026()
    cpd = np.array([model.cpd_pa(a, f, n) for a, f, n in zip(DEPTH_M, FEED_M, SPEED, strict=True)])
    assert cpd.max() == pytest.approx(3.19e11, rel=5e-3)
    assert cpd.max() == pytest.approx(2.9e11, rel=0.11)
    lowest = int(np.argmin(cpd))
    assert TABLE_3[lowest, :3].tolist() == [3.5, 5500, 0.1]
    assert cpd[lowest] == pytest.approx(6.42e9, rel=5e-3)
    assert 4.7e9 < cpd[lowest] * (1.0 - 9 * 0.0105)


def test_paper_effective_damping_ranges_do_not_follow_from_its_cpd() -> None:
    # Sec. 6.4 computes C_eff = C_pd a_p f_z / V_c (Eq. 3) = Gamma / V_c and quotes 120-720,
    # 180-900 and 250-1100 N s/m at 5500, 7500 and 9500 rpm. Its own Eq. 17-19 give
    # 650-5571, 1340-2636 and 2036-4004 N s/m (V_c = pi D n / 60 with D = 12 mm): 2.9 to 8
    # times more. V_c in m/min instead would give 60 times less: no unit slip explains it.
    model = ProcessDampingModel.royandi2026()
    quoted = {5500: (120.0, 720.0), 7500: (180.0, 900.0), 9500: (250.0, 1100.0)}
    for rpm, (low, high) in quoted.items():
        ceff = [model.gamma_n(a, rpm * RPM) / cutting_speed(rpm * RPM) for a in (3.5e-3, 1.5e-3)]
        assert ceff[0] / low > 5.0 and ceff[1] / high > 2.5, (rpm, ceff)


def test_quoted_effective_damping_lets_the_deep_slots_chatter() -> None:
    # Independent of the time-domain code: the semi-discretization with the paper's tool and
    # coefficients. Without process damping every Table 3 cut is unstable (critical depth
    # 0.45-0.76 mm at these speeds); a 3.5 mm slot needs C_eff of 784, 692 and 762 N s/m at
    # 5500, 7500, 9500 rpm. Gamma falls with depth (Eq. 16-19), so the low ends of the quoted
    # C_eff ranges belong to the 3.5 mm cuts: they chatter, and so does Eq. 17 itself at 5500
    # rpm (650 N s/m), though the paper reports every cut stable (Sec. 6.1).
    def radius(rpm: float, depth: float, ceff: float) -> float:
        speed = rpm * RPM
        cpd = ceff * cutting_speed(speed) / (depth * 1e-4)  # C_eff = C_pd a h / V_c
        damping = ProcessDamping(cpd, 1e-4, SETUP.cutter.diameter_m)
        return float(abs(floquet_multipliers(TOOL, SLOT, speed, depth, damping=damping)[0]))

    for rpm in (5500, 7500, 9500):
        assert radius(rpm, 1.5e-3, 0.0) > 1.4
    for rpm, ceff in ((5500, 120.0), (7500, 180.0), (9500, 250.0), (5500, 650.0)):
        assert radius(rpm, 3.5e-3, ceff) > 1.0, (rpm, ceff)
    for rpm, critical in ((5500, 784.0), (7500, 692.0), (9500, 762.0)):
        assert radius(rpm, 3.5e-3, 0.98 * critical) > 1.0 > radius(rpm, 3.5e-3, 1.02 * critical)


@pytest.fixture(scope="module")
def calibrated() -> list:
    """C_pd of each Table 3 cut calibrated on its measured RMS (x acceleration, Eq. 14)."""
    return [
        calibrate_cpd(SETUP, spindle_rad_s=n, depth_m=a, feed_per_tooth_m=f, measured_rms_m_s2=v)
        for n, a, f, v in zip(SPEED, DEPTH_M, FEED_M, MEASURED_M_S2, strict=True)
    ]


def test_table_3_calibration_matches_every_cut_and_keeps_it_stable(calibrated: list) -> None:
    # Sec. 2.4 aims at Eq. 14 below 5-10 %; the root finder reaches 1 %.
    assert all(found.status == "matched" for found in calibrated)
    assert max(found.relative_error for found in calibrated) < 0.01
    # Every calibrated cut is stable by the SDM (forced vibration, as the paper reports):
    # the measured levels are well below the chatter of the undamped model (250-1200 g).
    for found, n, a, f in zip(calibrated, SPEED, DEPTH_M, FEED_M, strict=True):
        damping = ProcessDamping(found.cpd_pa, f, SETUP.cutter.diameter_m)
        assert abs(floquet_multipliers(TOOL, SLOT, n, a, damping=damping)[0]) < 1.0


def test_table_3_calibration_shows_the_trends_of_figure_11(calibrated: list) -> None:
    # Sec. 6.4, Fig. 11: C_pd falls with depth at every speed and feed, and the smallest feed
    # needs the largest C_pd; Gamma = C_pd a_p f_z (Eq. 15) removes most of the feed effect:
    # the spread across feeds (max / min, per speed and depth) shrinks from 1.4-3.2 to
    # 1.1-1.6 for C_pd, on average (in log) by more than half, yet not at every point.
    cpd = np.array([found.cpd_pa for found in calibrated]).reshape(3, 3, 3)  # speed, feed, depth
    assert np.all(np.diff(cpd, axis=2) < 0.0)
    assert np.all(cpd[:, 2, :] > cpd[:, 0, :])  # 0.05 vs 0.1 mm/tooth
    gamma = cpd * (DEPTH_M * FEED_M).reshape(3, 3, 3)
    spread = gamma.max(axis=1) / gamma.min(axis=1)  # across feeds, per speed and depth
    raw = cpd.max(axis=1) / cpd.min(axis=1)
    assert np.mean(np.log(spread)) < 0.5 * np.mean(np.log(raw))
    assert spread.max() < 2.0


def test_table_3_gamma_fit_is_as_good_as_the_papers(calibrated: list) -> None:
    # The decaying saturation of Eq. 16-19 describes the calibrated C_pd with a MAPE per
    # speed within the paper's overall ~12 % (it reports 1.05, 11.36 and 11.11 %).
    cpd = np.array([found.cpd_pa for found in calibrated])
    model = fit_process_damping_model(SPEED, DEPTH_M, FEED_M, cpd)
    assert [fit.spindle_rad_s / RPM for fit in model.fits] == pytest.approx([5500, 7500, 9500])
    assert all(fit.mape_percent < 12.0 for fit in model.fits)
    assert all(fit.asymptote_n > 0.0 for fit in model.fits)
