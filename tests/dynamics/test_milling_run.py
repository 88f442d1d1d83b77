"""Runs of the time-domain model on a stability file: :func:`run_milling` against the SDM's
lobe and the closed-form mean slot forces, its defaults from the file; and
:func:`calibrate_damping_cuts` recovering a known Gamma model (Royandi 2026, Eq. 15-20)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from cnctwin.dynamics import (
    GammaFit,
    ProcessDampingModel,
    StabilityConfig,
    calibrate_damping_cuts,
    load_stability_config,
    run_milling,
    sdm_lobes,
)
from cnctwin.errors import CnctwinError, ConfigError, InputError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
RPM = math.pi / 30.0  # rad/s per rpm


@pytest.fixture(scope="module")
def slot() -> StabilityConfig:
    """Insperger's 1-DOF slot: 2 teeth, Ktc 600, Krc 200 N/mm^2, no [process_damping]."""
    return load_stability_config(EXAMPLES / "stability" / "insperger_slot.toml")


@pytest.fixture(scope="module")
def royandi() -> StabilityConfig:
    """Royandi 2026's slot: 4 teeth, AA6060-T6, C_pd 2e10 N/m^2, f_z 0.1 mm, D 12 mm."""
    return load_stability_config(EXAMPLES / "chatter" / "royandi2026.toml")


@pytest.mark.parametrize("ratio", [0.75, 1.25])
def test_run_agrees_with_the_sdm_lobe(slot: StabilityConfig, ratio: float) -> None:
    speed = 10000 * RPM
    lobes = sdm_lobes(slot.tool_dynamics(), slot.process(), [speed], max_depth_m=0.01)
    critical = float(lobes.critical_depth_m[0])
    run = run_milling(
        slot,
        spindle_rad_s=speed,
        depth_m=ratio * critical,
        feed_per_tooth_m=1e-4,
        duration_s=0.6,
    )
    unstable = ratio > 1.0
    assert run.verdict.chatter is unstable
    assert run.sdm_stable is not unstable
    assert (run.sdm_spectral_radius > 1.0) is unstable
    if unstable:
        assert run.verdict.frequency_hz == pytest.approx(lobes.chatter_frequency_hz[0], rel=0.02)
    assert run.cpd_pa is None and run.vibration.process_damping_n_s_m == 0.0
    assert run.simulated_s >= 0.6 and run.transient_s == pytest.approx(0.3, abs=1e-3)


def test_mean_force_is_the_closed_form_slot_average(slot: StabilityConfig) -> None:
    """Altintas 2000, Sec. 2.3: over a full slot (0 to pi), the mean forces of N straight
    teeth are Fx = -N a (c Krc / 4 + Kre / pi) and Fy = N a (c Ktc / 4 + Kte / pi); the
    regenerative terms average out in a stable periodic cut."""
    teeth, depth, feed = 2, 0.2e-3, 1e-4
    ktc, krc, kte, kre = 600e6, 200e6, 20e3, 15e3
    run = run_milling(
        slot,
        spindle_rad_s=10000 * RPM,
        depth_m=depth,
        feed_per_tooth_m=feed,
        duration_s=0.3,
        edge_tangential_n_m=kte,
        edge_radial_n_m=kre,
    )
    assert not run.verdict.chatter and run.sdm_stable
    fx = -teeth * depth * (feed * krc / 4.0 + kre / math.pi)
    fy = teeth * depth * (feed * ktc / 4.0 + kte / math.pi)
    assert run.mean_force_n.tolist() == pytest.approx([fx, fy], rel=1e-4)
    assert run.peak_to_peak_m[0] > 0.0 and run.peak_to_peak_m[1] == 0.0  # no mode in y


def test_defaults_come_from_the_file(royandi: StabilityConfig) -> None:
    speed, depth = 7500 * RPM, 1.5e-3
    run = run_milling(royandi, spindle_rad_s=speed, depth_m=depth, duration_s=0.1)
    assert run.feed_per_tooth_m == pytest.approx(1e-4)  # chip_thickness_mm
    assert run.cpd_pa == 2e10
    # Royandi 2026, Eq. 3: C_eff = C_pd a_p f_z / V_c with V_c = omega D / 2.
    assert run.vibration.process_damping_n_s_m == pytest.approx(
        2e10 * depth * 1e-4 / (speed * 0.006)
    )
    # The material's edge coefficients (Sec. 4.2: Kte 31.49, Kre 21.85 N/mm) are the default.
    explicit = run_milling(
        royandi,
        spindle_rad_s=speed,
        depth_m=depth,
        duration_s=0.1,
        edge_tangential_n_m=31.49e3,
        edge_radial_n_m=21.85e3,
    )
    assert explicit.rms.acceleration_m_s2.tolist() == run.rms.acceleration_m_s2.tolist()
    off = run_milling(royandi, spindle_rad_s=speed, depth_m=depth, duration_s=0.1, cpd_pa=0.0)
    assert off.cpd_pa is None and off.vibration.process_damping_n_s_m == 0.0
    assert off.rms.acceleration_m_s2[0] > run.rms.acceleration_m_s2[0]  # less damping


def test_calibration_recovers_a_known_gamma_model(royandi: StabilityConfig) -> None:
    """Measured RMS made by the model at C_pd = Gamma / (a_p f_z) (Eq. 15) from a known
    Gamma = A + B exp(-a_p / a0); the calibration returns those C_pd and that Gamma."""
    truth = GammaFit(7500 * RPM, 2.0e4, 3.0e4, 1.0e-3)
    speed, feed_mm, depths_mm = 7500 * RPM, 0.1, [1.5, 2.5, 3.5]
    model = ProcessDampingModel((truth,))
    measured = [
        run_milling(
            royandi,
            spindle_rad_s=speed,
            depth_m=ap * 1e-3,
            feed_per_tooth_m=feed_mm * 1e-3,
            duration_s=0.1,
            max_duration_s=0.1,  # the calibration's own runs: 0.1 s
            damping_model=model,
        ).rms.acceleration_m_s2[0]
        for ap in depths_mm
    ]
    other = 6000 * RPM  # one depth only: no fit at this speed
    calibration = calibrate_damping_cuts(
        royandi,
        depth_mm=[*depths_mm, 2.0],
        spindle_rad_s=[speed, speed, speed, other],
        feed_per_tooth_mm=[feed_mm] * 4,
        measured_rms_m_s2=[*measured, measured[0]],
        duration_s=0.1,
    )
    for cut, ap in zip(calibration.cuts, depths_mm, strict=False):
        cpd = model.cpd_pa(ap * 1e-3, feed_mm * 1e-3, speed)
        assert cut.status == "matched"
        assert cut.cpd_pa == pytest.approx(cpd, rel=1e-3)
        assert cut.gamma_n == pytest.approx(cut.cpd_pa * ap * 1e-3 * feed_mm * 1e-3)
        assert cut.effective_damping_n_s_m == pytest.approx(cut.gamma_n / (speed * 0.006))
        assert cut.relative_error < 1e-3 and cut.evaluations >= 1
    assert calibration.unfitted_rad_s == (other,)
    (fit,) = calibration.fits
    assert fit.spindle_rad_s == speed
    assert fit.asymptote_n == pytest.approx(truth.asymptote_n, rel=0.01)
    assert fit.amplitude_n == pytest.approx(truth.amplitude_n, rel=0.01)
    assert fit.depth_scale_m == pytest.approx(truth.depth_scale_m, rel=0.01)
    assert calibration.model().cpd_pa(2e-3, 1e-4, speed) == pytest.approx(
        model.cpd_pa(2e-3, 1e-4, speed), rel=0.01
    )


MODEL = ProcessDampingModel((GammaFit(9000 * RPM, 2e4, 0.0, 1e-3),))
RUN = {"spindle_rad_s": 9000 * RPM, "depth_m": 1e-3, "duration_s": 0.05}
CUTS = {
    "depth_mm": [1.0],
    "spindle_rad_s": [7500 * RPM],
    "feed_per_tooth_mm": [0.1],
    "measured_rms_m_s2": [20.0],
}


@pytest.mark.parametrize(
    ("call", "file", "arguments", "error", "message"),
    [
        (run_milling, "stability/orthogonal_2dof.toml", {**RUN, "feed_per_tooth_m": 1e-4},
         ConfigError, "orthogonal"),
        (run_milling, "stability/insperger_slot.toml", RUN, InputError, "feed_per_tooth_m"),
        (run_milling, "stability/insperger_slot.toml",
         {**RUN, "feed_per_tooth_m": 1e-4, "helix_rad": 0.5}, InputError,
         "needs the cutter diameter"),
        (run_milling, "chatter/royandi2026.toml", {**RUN, "helix_rad": 2.0}, InputError,
         "helix_rad 2.0"),
        (run_milling, "stability/insperger_slot.toml",
         {**RUN, "feed_per_tooth_m": 1e-4, "cpd_pa": 1e10}, InputError, "diameter"),
        (run_milling, "chatter/royandi2026.toml",
         {**RUN, "cpd_pa": 1e10, "damping_model": MODEL}, InputError, "exclude"),
        (calibrate_damping_cuts, "stability/insperger_slot.toml", CUTS, InputError,
         "diameter_mm"),
        (calibrate_damping_cuts, "chatter/royandi2026.toml", {**CUTS, "axis": "z"}, InputError,
         "axis 'z'"),
        (calibrate_damping_cuts, "chatter/royandi2026.toml", {**CUTS, "depth_mm": [1.0, 2.0]},
         InputError, "lengths [2, 1, 1, 1]"),
        (calibrate_damping_cuts, "chatter/royandi2026.toml",
         {key: [] for key in CUTS}, InputError, "no cuts"),
        (calibrate_damping_cuts, "stability/orthogonal_2dof.toml", CUTS, ConfigError,
         "orthogonal"),
    ],
)  # fmt: skip
def test_refusals_name_the_argument(
    call: Any, file: str, arguments: dict[str, Any], error: type[CnctwinError], message: str
) -> None:
    config = load_stability_config(EXAMPLES / file)
    with pytest.raises(error) as raised:
        call(config, **arguments)
    assert message in str(raised.value)
    assert "\n" not in str(raised.value)
