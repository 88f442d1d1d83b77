"""The lathe simulator of Bolyn 2023 section IV: Tables 2-3, closed forms, reported figures.

The paper reports one run per test without its random draws, so its figures are compared with
the distribution of ours over 200 seeds: the paper's value must be a plausible draw (inside our
central 90 %), and the relations it states (about twice the parts with the coarser gauge, under
5 um with heritage, no scrap in Test 6) must hold for the distribution.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

from cnctwin.errors import InputError
from cnctwin.wear import TESTS, LatheRun, LatheTwin, run_test, simulate
from cnctwin.wear.lathe_simulator import DEFAULT_PARTS, scenario

UM = 1e-6
SEEDS = range(200)
Runs = dict[int, list[LatheRun]]


@pytest.fixture(scope="module")
def runs() -> Runs:
    """Each of Tests 1-6 over 200 seeds (about 0.5 s)."""
    return {test: [run_test(test, seed) for seed in SEEDS] for test in TESTS}


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values, dtype=float), q))


def parts_before_trusted(runs: list[LatheRun]) -> list[float]:
    """Each run's parts before its slope is trusted for good; every run must get there."""
    counts = [r.parts_before_trusted for r in runs]
    assert None not in counts
    return [float(c) for c in counts if c is not None]


# -- Tables 2 and 3 -------------------------------------------------------------------------


def test_scenarios_are_tables_2_and_3() -> None:
    # Slope 3 um/part and lathe accuracy 5 um in all tests; standard deviation 1 um (Tests
    # 1-4) and 5 um (5-6); measurement accuracy exact (1-2) and 10 um (3-6); heritage in the
    # even tests; intervals 13.43 +0.07 -0.03 mm (1-4) and 13.45 +-0.05 mm (5-6).
    table = {
        1: (1, 0, False, 13.40, 13.50),
        2: (1, 0, True, 13.40, 13.50),
        3: (1, 10, False, 13.40, 13.50),
        4: (1, 10, True, 13.40, 13.50),
        5: (5, 10, False, 13.40, 13.50),
        6: (5, 10, True, 13.40, 13.50),
    }
    for test, (sigma_um, gauge_um, heritage, low_mm, high_mm) in table.items():
        case = TESTS[test]
        assert case.drift == pytest.approx(3 * UM)
        assert case.lathe_resolution == pytest.approx(5 * UM)
        assert case.scatter == pytest.approx(sigma_um * UM)
        assert case.measuring_resolution == pytest.approx(gauge_um * UM)
        assert case.heritage is heritage
        assert case.lower == pytest.approx(low_mm * 1e-3)
        assert case.upper == pytest.approx(high_mm * 1e-3)
        assert case.target == pytest.approx(13.45e-3)  # "the middle of range as the target"


def test_unknown_test_and_bad_arguments_are_refused() -> None:
    with pytest.raises(InputError, match="Tests 1-6"):
        scenario(7)
    with pytest.raises(InputError, match="parts"):
        run_test(1, parts=0)
    with pytest.raises(InputError, match="seed"):
        run_test(1, seed=-1)
    with pytest.raises(InputError, match="resolution"):
        simulate(TESTS[1], np.random.default_rng(0), lathe=LatheTwin(resolution=1 * UM))


# -- the simulator's physics ----------------------------------------------------------------


def test_parts_follow_drift_offset_and_scatter() -> None:
    run = run_test(3, seed=1)
    case = run.scenario
    i = np.arange(1, run.parts + 1)
    expected = case.target + case.drift * i + run.offset + run.noise
    np.testing.assert_allclose(run.true_dimension, expected, rtol=0, atol=1e-15)
    # A 10 um gauge reports the nearest multiple of 10 um.
    steps = run.measured_dimension / (10 * UM)
    np.testing.assert_allclose(steps, np.round(steps), rtol=0, atol=1e-6)
    assert np.max(np.abs(run.measured_dimension - run.true_dimension)) <= 5 * UM + 1e-15
    # The lathe applies offsets in steps of 5 um only.
    offsets = run.offset / (5 * UM)
    np.testing.assert_allclose(offsets, np.round(offsets), rtol=0, atol=1e-6)
    assert np.std(run_test(5, seed=1, parts=2000).noise) == pytest.approx(5 * UM, rel=0.05)


def test_twin_slope_is_the_closed_form_on_the_drawn_scatter() -> None:
    # Test 1 measures exactly, so the uncorrected deviations are 3 i + e_i whatever the
    # corrections: b_n = sum(i (3 i + e_i)) / sum(i^2) from the drawn e_i alone.
    run = run_test(1, seed=3)
    i = np.arange(1, run.parts + 1)
    d = 3 * UM * i + run.noise
    expected = np.cumsum(i * d) / np.cumsum(i * i)
    np.testing.assert_allclose([o.slope for o in run.observations], expected, rtol=1e-10)
    assert any(o.correction for o in run.observations)


def _trust_probability(n: int, drift: float, sigma: float, criterion: float) -> float:
    """P(|b_n - b_(n-1)| < criterion |b_n|) for d_i = drift i + N(0, sigma^2).

    With S_n = sum(i^2): b_n ~ N(drift, sigma^2 / S_n), and b_n - b_(n-1) ~ N(0, sigma^2 n^2 /
    (S_n S_(n-1))) uncorrelated with b_n (their covariance sigma^2 (n^2/S_n^2 - n^2/S_n^2)
    vanishes), hence independent.
    """
    s_n, s_prev = n * (n + 1) * (2 * n + 1) / 6, (n - 1) * n * (2 * n - 1) / 6
    spread_b = sigma / math.sqrt(s_n)
    spread_change = sigma * n / math.sqrt(s_n * s_prev)

    def integrand(b: float) -> float:
        inside = 2 * stats.norm.cdf(criterion * abs(b) / spread_change) - 1
        return float(stats.norm.pdf(b, drift, spread_b) * inside)

    lo, hi = drift - 10 * spread_b, drift + 10 * spread_b
    return float(integrate.quad(integrand, lo, hi, points=[0.0] if lo < 0 < hi else None)[0])


def test_trust_rate_per_part_matches_the_closed_form() -> None:
    # Test 1 over 1000 seeds: the fraction of tools whose slope is trusted after part n
    # against the exact probability; 4 binomial standard deviations (<= 0.064).
    trusted = np.array([run_test(1, seed, parts=12).trusted for seed in range(1000)])
    for n in range(2, 13):
        p = _trust_probability(n, 3 * UM, 1 * UM, 0.05)
        tolerance = 4 * math.sqrt(max(p * (1 - p), 0.0025) / 1000)
        assert trusted[:, n - 1].mean() == pytest.approx(p, abs=tolerance), n


def test_heritage_is_what_the_previous_test_learnt() -> None:
    # The paper's Test 2 inherits "the last value obtained during Test 1".
    previous = run_test(1, seed=9)
    run = run_test(2, seed=9)
    assert run.heritage is not None
    assert run.heritage.slope == pytest.approx(previous.observations[-1].slope, rel=1e-12)
    # Corrections start before the first part: -3 um rounded to the 5 um step.
    assert run.offset[0] == pytest.approx(-5 * UM, abs=1e-15)
    assert run_test(1, seed=9).offset[0] == 0.0


# -- the paper's reported figures, over 200 seeds ---------------------------------------------


def test_test1_trusts_its_slope_after_about_six_parts(runs: Runs) -> None:
    # "For Test 1, it is after the 6th part produced that the digital twin definitively applies
    # the slope it computes." Our 200 seeds: median 5, central 90 % 3-7 parts; 6 lies inside.
    before = parts_before_trusted(runs[1])
    assert percentile(before, 5) <= 6 <= percentile(before, 95)
    assert 4 <= np.median(before) <= 7


def test_coarse_gauge_doubles_the_parts_before_trust(runs: Runs) -> None:
    # "the required number of parts before the digital twin trusts its slope is about two
    # times more than in the first tests" (Tests 3 and 4, 10 um gauge). The medians over 200
    # seeds move by at most half a part between seed sets; ratio 1.4-3 is "about two".
    first = np.median(parts_before_trusted(runs[1]))
    for test in (3, 4):
        coarse = np.median(parts_before_trusted(runs[test]))
        assert 1.4 <= coarse / first <= 3.0, (test, coarse, first)


def test_heritage_halves_the_largest_deviation(runs: Runs) -> None:
    # "the maximum deviation without heritage is about 10 um whereas the heritage provides
    # deviations below 5 um" (Tests 1-2). Ours: Test 1 median 11 um, central 90 % 6-16 um;
    # Test 2 below 5 um in 94 % of seeds (process scatter of 1 um plus half a lathe step
    # reaches 5 um now and then), never above 6 um.
    without = [r.max_abs_deviation / UM for r in runs[1]]
    heritage = [r.max_abs_deviation / UM for r in runs[2]]
    assert percentile(without, 5) <= 10 <= percentile(without, 95)
    assert 8 <= np.median(without) <= 13
    assert np.mean(np.less(heritage, 5)) >= 0.9
    assert max(heritage) < 6
    assert all(r.heritage is not None for r in runs[2])


def test_heritage_keeps_the_coarse_gauge_on_target(runs: Runs) -> None:
    # Test 4: "almost every dimension measured on target" although the own slope is trusted
    # as late as in Test 3. With a 10 um gauge, on target is within one gauge step.
    for run in runs[4]:
        assert np.max(np.abs(run.measured_deviation)) <= 10 * UM + 1e-12
    assert np.median([r.max_abs_deviation for r in runs[3]]) > 2.5 * np.median(
        [r.max_abs_deviation for r in runs[4]]
    )


def test_no_scrap_with_heritage_where_test5_drifts_towards_the_limit(runs: Runs) -> None:
    # Tests 5-6 (5 um scatter, tolerance +-50 um). Test 5: "the digital tool managed to find a
    # wear law before the dimensions reached the upper limit": the drift goes well past the
    # process's own +-15 um (3 sigma) before correction, yet stays inside. Test 6: "the only
    # deviations seen are due to the standard deviation": no scrap in any seed.
    assert sum(r.out_of_tolerance for r in runs[6]) == 0
    drift5 = [r.max_abs_deviation / UM for r in runs[5]]
    drift6 = [r.max_abs_deviation / UM for r in runs[6]]
    assert np.median(drift5) > 15 and percentile(drift5, 95) > 30
    assert np.median(drift5) > 1.5 * np.median(drift6)
    assert np.mean([r.out_of_tolerance > 0 for r in runs[5]]) <= 0.02


def test_scatter_estimate_with_a_coarse_gauge_is_higher(runs: Runs) -> None:
    # "If this accuracy is greater or equal to the standard deviation of the process ... the
    # standard deviation computed by the digital twin will be higher than the real one."
    exact = np.median([r.observations[-1].sigma for r in runs[1]])
    coarse = np.median([r.observations[-1].sigma for r in runs[3]])
    # Test 1: Table 1 on 30 parts estimates 1 um (times sqrt(29/28), less the c4 bias).
    assert exact == pytest.approx(1 * UM, rel=0.1)
    assert coarse > 2 * UM
    assert DEFAULT_PARTS == 30
