"""The dexel study (Heide 2025, Sec. 2.3): score, optimum, T* fit, and small runs of the cut."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.errors import ConfigError
from cnctwin.studies import (
    PAPER_CYCLES_S,
    PAPER_DENSITIES_PER_MM,
    PAPER_FEEDS_MM_MIN,
    DexelStudy,
    RunResult,
    RunSpec,
    SideMillingCut,
    constrained_optimum,
    fit_t_star,
    min_max,
    optimum,
    run_one,
    run_study,
    score,
    settings,
)


def test_paper_grid_is_table_2() -> None:
    # Heide 2025, Table 2: 5 densities x 8 cycle times x 6 feeds = 240 runs.
    study = DexelStudy.paper()
    assert len(study.runs()) == 240
    assert study.densities_per_mm == (5.0, 10.0, 13.0, 16.0, 20.0) == PAPER_DENSITIES_PER_MM
    assert PAPER_CYCLES_S == (0.00625, 0.0125, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2)
    assert PAPER_FEEDS_MM_MIN == (480.0, 960.0, 1440.0, 1920.0, 2400.0, 2880.0)
    # The six passes together take the paper's 328 s: l * 60 * sum(1 / vf) = 328 s.
    pass_mm = study.cut.pass_length_mm
    assert pass_mm * 60.0 * sum(1.0 / f for f in PAPER_FEEDS_MM_MIN) == pytest.approx(328.0)
    assert pass_mm == pytest.approx(
        328.0 / (60.0 / 480.0 * (1 + 1 / 2 + 1 / 3 + 1 / 4 + 1 / 5 + 1 / 6))
    )


def test_min_max_by_hand() -> None:
    # Eq. 2: (A - min) / (max - min).
    np.testing.assert_allclose(min_max([2.0, 4.0, 6.0, 10.0]), [0.0, 0.25, 0.5, 1.0])
    np.testing.assert_allclose(min_max([-1.0, 1.0]), [0.0, 1.0])
    # A spread at or below the resolution carries no information: all 0, not noise / noise.
    np.testing.assert_array_equal(min_max([1e-13, 3e-13, 2e-13], resolution=1e-6), [0, 0, 0])
    np.testing.assert_array_equal(min_max([5.0, 5.0]), [0.0, 0.0])
    with pytest.raises(ConfigError, match="finite"):
        min_max([1.0, math.nan])


def test_score_by_hand() -> None:
    # Three settings; by hand: ae* = (0, 1, 0.5), vf* = (1/3, 0, 1), T* = (0, 1/3, 1),
    # S = 0.4 ae* + 0.4 vf* + 0.2 T* (Eq. 3).
    s = score([0.1, 0.3, 0.2], [1.0, 0.5, 2.0], [10.0, 20.0, 40.0])
    np.testing.assert_allclose(s, [0.4 / 3, 0.4 + 0.2 / 3, 0.2 + 0.4 + 0.2], rtol=1e-12)
    # Feed errors at float-rounding level (1e-12 %) do not count.
    s = score([0.1, 0.3], [1e-12, 3e-12], [10.0, 20.0])
    np.testing.assert_allclose(s, [0.0, 0.4 + 0.2])
    with pytest.raises(ConfigError, match="weights"):
        score([1.0], [1.0], [1.0], weights=(0.5, 0.5))


def _result(
    rho: float, cycle: float, feed: float, ae: float, vf: float, cpu: float, volume: float = 0.0
) -> RunResult:
    return RunResult(
        spec=RunSpec(rho, cycle, feed),
        delta_ae_mm=ae,
        delta_ae_max_mm=ae,
        feed_deviation_pct=vf,
        volume_deviation_pct=volume,
        runtime_s=cpu,
        cpu_s=cpu,
        process_s=10.0,
        steps=100,
        steady_steps=50,
    )


def test_settings_aggregate_over_feeds_and_optimum() -> None:
    results = [
        # (5 /mm, 10 ms): accurate at one feed only.
        _result(5.0, 0.01, 480.0, 0.10, 1.0, 1.0),
        _result(5.0, 0.01, 960.0, 0.30, 3.0, 1.0),
        # (10 /mm, 10 ms): accurate, slower.
        _result(10.0, 0.01, 480.0, 0.02, 0.2, 3.0),
        _result(10.0, 0.01, 960.0, 0.02, 0.4, 3.0),
        # (10 /mm, 50 ms): accurate, fast, but leaves 20 % of the volume at one feed.
        _result(10.0, 0.05, 480.0, 0.01, 0.1, 1.5, volume=-0.5),
        _result(10.0, 0.05, 960.0, 0.03, 0.5, 1.5, volume=-20.0),
    ]
    scored = {(s.density_per_mm, s.cycle_s): s for s in settings(results)}
    a, b, c = scored[(5.0, 0.01)], scored[(10.0, 0.01)], scored[(10.0, 0.05)]
    # Means over the feeds, runtimes summed.
    assert (a.delta_ae_mm, a.feed_deviation_pct, a.cpu_s) == pytest.approx((0.2, 2.0, 2.0))
    assert (b.delta_ae_mm, b.feed_deviation_pct, b.cpu_s) == pytest.approx((0.02, 0.3, 6.0))
    assert (c.delta_ae_mm, c.feed_deviation_pct, c.cpu_s) == pytest.approx((0.02, 0.3, 3.0))
    assert c.volume_deviation_pct == 20.0
    # By hand: ae* = (1, 0, 0), vf* = (1, 0, 0), T* = (0, 1, 0.25).
    assert (a.score, b.score, c.score) == pytest.approx((0.8, 0.2, 0.05))
    assert optimum(list(scored.values())) is c
    # Within 1 % of the volume, (10 /mm, 50 ms) is out (test_constrained_optimum.py).
    choice = constrained_optimum(list(scored.values()))
    assert choice.optimum is b and choice.score_optimum is c
    assert constrained_optimum([c]).optimum is None


def test_optimum_breaks_ties_by_cost() -> None:
    results = [
        _result(10.0, 0.01, 480.0, 0.0, 0.0, 1.0),
        _result(5.0, 0.01, 480.0, 0.0, 0.0, 1.0),
    ]
    # Equal scores (0): the cheaper rho^2 / t_cycle wins.
    assert optimum(settings(results)).density_per_mm == 5.0


def test_t_star_fit_recovers_known_exponents() -> None:
    rng = np.random.default_rng(7)
    rho, cycle = np.meshgrid(PAPER_DENSITIES_PER_MM, PAPER_CYCLES_S)
    effort = rho**2 / cycle
    # Exactly T*^0.8: k = 0.8, R^2 = 1; free exponents 1.6 and -0.8.
    fit = fit_t_star(rho, cycle, 1e-4 * effort**0.8)
    assert fit.exponent == pytest.approx(0.8, abs=1e-9)
    assert fit.prefactor_s == pytest.approx(1e-4, rel=1e-9)
    assert fit.r2 == pytest.approx(1.0)
    assert (fit.density_exponent, fit.cycle_exponent) == pytest.approx((1.6, -0.8), abs=1e-9)
    # With 5 % log-normal noise the exponent stays within a few hundredths (40 points
    # spanning 3 decades of T*: standard error ~0.05 / (sqrt(40) * 0.9) ~ 0.01).
    noisy = 2e-3 * effort * np.exp(rng.normal(0.0, 0.05, effort.shape))
    fit = fit_t_star(rho, cycle, noisy)
    assert fit.exponent == pytest.approx(1.0, abs=0.04)
    assert fit.r2 > 0.98
    # Runtime that ignores the density does not follow T*: a = 0, b = -1.
    fit = fit_t_star(rho, cycle, 1.0 / cycle)
    assert (fit.density_exponent, fit.cycle_exponent) == pytest.approx((0.0, -1.0), abs=1e-9)
    assert fit.r2 < 0.9
    with pytest.raises(ConfigError, match="2 of each"):
        fit_t_star([5.0, 5.0, 5.0], [0.01, 0.02, 0.03], [1.0, 2.0, 3.0])


def test_tiny_study_delta_ae_shrinks_with_density() -> None:
    # 2 densities x 2 cycle times x 1 feed on a 20 mm block. At 480 mm/min a step is 0.05 or
    # 0.1 mm, shorter than the dexel pitch p: the sliver each step takes off the side face is
    # then missed by the rays across the feed at some steps, and ae ends at the slab centre of
    # the rays along z and x, half a pitch inside the face; the wall end comes from the ray
    # across the feed nearest the tool axis, at most a pitch off it (error p^2 / 2R). So
    # |delta ae| <= p / 2 + p^2 / 2R, and it shrinks with the pitch.
    study = DexelStudy((5.0, 10.0), (0.00625, 0.0125), (480.0,), SideMillingCut(20.0))
    results = {(r.spec.density_per_mm, r.spec.cycle_s): r for r in run_study(study, workers=1)}
    assert len(results) == 4
    for cycle in (0.00625, 0.0125):
        coarse, fine = results[(5.0, cycle)], results[(10.0, cycle)]
        assert fine.delta_ae_mm < coarse.delta_ae_mm
        for r in (coarse, fine):
            pitch = 1.0 / r.spec.density_per_mm
            assert r.delta_ae_max_mm <= pitch / 2.0 + pitch**2 / 6.0
    for r in results.values():
        # A straight line sampled exactly: the reconstructed feed is the programmed one up
        # to float rounding.
        assert r.feed_deviation_pct < 1e-6
        assert r.cpu_s > 0.0 and r.steady_steps > 0
        # The program: a 10.07 mm rapid at 10 m/min (0.060 s), then 30 mm at 480 mm/min
        # (3.75 s); the process ends with the cycle after the last sample.
        rapid_s = math.hypot(1.2, 10.0) / 10000.0 * 60.0
        assert r.process_s == pytest.approx(3.75 + rapid_s, abs=r.spec.cycle_s)


def _scallop_loss(step_mm: float, radius_mm: float = 3.0, ae_mm: float = 1.8) -> float:
    """Fraction of a continuous cut's volume that discrete positions leave, side milling."""
    s, r, d = step_mm, radius_mm, radius_mm - ae_mm
    if s <= 2.0 * math.sqrt(r * r - d * d):  # scallop below the side face
        area = s * r - 0.5 * s * math.sqrt(r * r - s * s / 4.0) - r * r * math.asin(s / (2 * r))
        return area / (s * ae_mm)
    # Steps beyond the engaged chord: each position takes a circular segment only.
    segment = r * r * math.acos(d / r) - d * math.sqrt(r * r - d * d)
    return 1.0 - segment / (s * ae_mm)


@pytest.mark.parametrize("cycle_s", [0.05, 0.1, 0.2])
def test_removed_volume_matches_scallop_closed_form(cycle_s: float) -> None:
    # 2880 mm/min: steps of 2.4, 4.8 and 9.6 mm. At 10 /mm, ae = 1.8 mm is 18 pitches, so the
    # tri-dexel volume itself is unbiased; the loss is the scallops (islands for 9.6 mm)
    # between positions. Closed form by integration of the circle. Tolerance 0.25 points: the
    # few steady steps (3 at 9.6 mm) each carry the ray families' pitch-sized error at the
    # round ends of the piece they remove (measured 0.02-0.09 points).
    step = 2880.0 / 60.0 * cycle_s
    result = run_one(SideMillingCut(45.0), RunSpec(10.0, cycle_s, 2880.0))
    expected = -100.0 * _scallop_loss(step)
    assert result.volume_deviation_pct == pytest.approx(expected, abs=0.25)


def test_cut_and_study_reject_bad_settings() -> None:
    with pytest.raises(ConfigError, match="ae_mm"):
        SideMillingCut(30.0, ae_mm=7.0)
    with pytest.raises(ConfigError, match="block_length_mm"):
        SideMillingCut(10.0)
    with pytest.raises(ConfigError, match="cycles_s"):
        DexelStudy((5.0,), (0.01, 0.01), (480.0,), SideMillingCut(30.0))
    with pytest.raises(ConfigError, match="workers"):
        run_study(DexelStudy.quick(), workers=0)
    # A 1 s cycle at 2880 mm/min steps 48 mm: no step in the steady part of a 20 mm block.
    with pytest.raises(ConfigError, match="steady part"):
        run_one(SideMillingCut(20.0), RunSpec(5.0, 1.0, 2880.0))
