"""The tool twin and lathe twin of Bolyn 2023 against closed forms.

Every expected value is computed here independently of the code under test: least squares by
numpy, rounding by hand, offsets from the drift, test sizes and powers from Student's and
Fisher's distributions.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats

from cnctwin.errors import ConfigError, DataError, InputError
from cnctwin.wear import (
    STABILITY_CRITERION,
    LatheTwin,
    ManufacturingParameters,
    ToolTwin,
    drift_fit,
    round_to_resolution,
)

UM = 1e-6
CONDITIONS = ManufacturingParameters("C45", "CNMG 120408", 3.3, 0.2e-3, 1.0e-3)


def feed(twin: ToolTwin, drift: np.ndarray) -> None:
    """Measure parts whose uncorrected deviations are ``drift`` (m), under the twin's offsets."""
    for value in drift:
        twin.observe(float(value) + twin.offset)


# -- rounding and Table 1 ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value_um", "expected_um"),
    [(2.0, 0.0), (3.0, 5.0), (-2.0, 0.0), (-3.0, -5.0), (7.4, 5.0), (7.6, 10.0), (-12.6, -15.0)],
)
def test_rounding_to_the_lathe_resolution(value_um: float, expected_um: float) -> None:
    # Bolyn 2023 section IV: "if the correction proposed is 2 um, it will not be applied by
    # the lathe since it only applies corrections in multiples of 5 um".
    assert round_to_resolution(value_um * UM, 5 * UM) == pytest.approx(expected_um * UM, abs=1e-15)


def test_zero_resolution_leaves_the_value_and_negative_is_refused() -> None:
    assert round_to_resolution(1.234e-6, 0.0) == 1.234e-6
    with pytest.raises(InputError, match="resolution"):
        round_to_resolution(1e-6, -5e-6)
    with pytest.raises(InputError, match="value nan"):
        round_to_resolution(math.nan, 5e-6)


def test_drift_fit_is_least_squares_through_the_origin() -> None:
    rng = np.random.default_rng(4)
    parts = np.arange(1, 21, dtype=float)
    deviations = 3 * UM * parts + rng.normal(0, 1 * UM, parts.size)
    slope, sigma = drift_fit(parts.tolist(), deviations.tolist())
    # Independent closed form: numpy's least squares on the one-column design [i].
    (expected,), residual, _, _ = np.linalg.lstsq(parts[:, None], deviations, rcond=None)
    assert slope == pytest.approx(expected, rel=1e-12)
    # Table 1's scatter divides the residual sum of squares by n - 2.
    assert sigma == pytest.approx(math.sqrt(residual[0] / (parts.size - 2)), rel=1e-9)


def test_drift_fit_scatter_needs_three_parts_and_matching_lengths() -> None:
    slope, sigma = drift_fit([1, 2], [3e-6, 6e-6])
    assert slope == pytest.approx(3e-6)
    assert sigma is None
    with pytest.raises(DataError, match="as many deviations as parts"):
        drift_fit([1, 2, 3], [1e-6])


def test_table1_scatter_overestimates_the_variance_by_n_minus_1_over_n_minus_2() -> None:
    # The fit has one parameter, so E[RSS] = (n - 1) sigma^2 and E[sigma_hat^2] =
    # sigma^2 (n - 1) / (n - 2). 4000 fits of 6 points: the mean of sigma_hat^2 / sigma^2
    # has a standard error of sqrt(2 / 4) * 5 / 4 / sqrt(4000) = 0.014; 4 of them allowed.
    rng = np.random.default_rng(11)
    n, trials = 6, 4000
    parts = list(range(1, n + 1))
    ratios = []
    for _ in range(trials):
        _, sigma = drift_fit(parts, list(2e-6 * np.arange(1, n + 1) + rng.normal(0, 1e-6, n)))
        assert sigma is not None
        ratios.append(sigma**2 / 1e-12)
    assert np.mean(ratios) == pytest.approx((n - 1) / (n - 2), abs=4 * 0.014)


# -- the tool twin ------------------------------------------------------------------------


def test_deviations_are_corrected_by_the_cumulative_correction() -> None:
    # Whatever corrections the twin applies, its regression sees the drift without them:
    # slope and scatter equal Table 1 on the uncorrected deviations.
    rng = np.random.default_rng(2)
    drift = 3 * UM * np.arange(1, 31) + rng.normal(0, 1 * UM, 30)
    twin = LatheTwin(resolution=5 * UM).mount("T1")
    feed(twin, drift)
    assert any(twin.corrections)
    np.testing.assert_allclose(twin.deviations, drift, rtol=0, atol=1e-18)
    parts = np.arange(1, 31)
    for n in (3, 10, 30):
        expected = np.sum(parts[:n] * drift[:n]) / np.sum(parts[:n] ** 2)
        assert twin.slopes[n - 1] == pytest.approx(expected, rel=1e-12)
    assert twin.slope is not None
    residual = drift - twin.slope * parts
    assert twin.sigma == pytest.approx(math.sqrt(np.sum(residual**2) / 28), rel=1e-9)


def test_stability_criterion_at_five_percent() -> None:
    # Part 1 deviates 3 um, so b1 = 3 um; part 2 is chosen so that b2 = 3 / (1 - x) and the
    # relative change |b2 - b1| / b2 is x (b2 = (d1 + 2 d2) / 5, Table 1).
    assert STABILITY_CRITERION == 0.05
    for change, trusted in ((0.04, True), (0.06, False)):
        twin = ToolTwin("T1")
        b2 = 3 * UM / (1 - change)
        twin.observe(3 * UM)
        seen = twin.observe((5 * b2 - 3 * UM) / 2)
        assert seen.relative_change == pytest.approx(change, rel=1e-9)
        assert seen.trusted is trusted
    assert ToolTwin("T1").observe(3 * UM).trusted is False  # one part: no change yet


def test_corrections_put_the_next_part_on_target_in_lathe_steps() -> None:
    # A noiseless 3 um/part drift: the slope is exact and trusted from part 2 on, and the
    # offset in force for part n + 1 is -3 (n + 1) um rounded to the 5 um step.
    twin = LatheTwin(resolution=5 * UM).mount("T1")
    feed(twin, 3 * UM * np.arange(1, 21))
    offsets = np.cumsum(twin.corrections)
    for n in range(2, 21):
        expected = -5 * UM * math.floor(3 * (n + 1) / 5 + 0.5)
        assert offsets[n - 1] == pytest.approx(expected, abs=1e-15)
    assert offsets[0] == 0.0  # untrusted after part 1, no heritage: no correction
    steps = np.asarray(twin.corrections) / (5 * UM)
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)


def test_untrusted_slope_without_heritage_changes_nothing() -> None:
    twin = ToolTwin("T1", resolution=5 * UM)
    seen = [twin.observe(d * UM) for d in (3.0, 9.0, 4.0)]
    assert [o.trusted for o in seen] == [False, False, False]
    assert [o.source for o in seen] == ["none"] * 3
    assert twin.offset == 0.0


def test_bad_measurements_are_refused_and_not_recorded() -> None:
    twin = ToolTwin("T1")
    twin.observe(1e-6)
    for bad in (math.nan, math.inf, "12", None, True):
        with pytest.raises(DataError, match="finite number"):
            twin.observe(bad)  # type: ignore[arg-type]
    with pytest.raises(DataError, match="above 1"):
        twin.observe(2e-6, part=1)
    assert twin.count == 1
    twin.observe(4e-6, part=np.int64(4))  # parts may be skipped; numpy integers are fine
    assert twin.parts == [1, 4]


# -- end-of-life signs ------------------------------------------------------------------------


def _life(seed: int, *, accelerate: float = 0.0, scatter_factor: float = 1.0) -> ToolTwin:
    """40 parts at 3 um/part and 1 um scatter; the last 10 with extra drift or scatter."""
    rng = np.random.default_rng(seed)
    parts = np.arange(1, 41)
    late = np.clip(parts - 30, 0, None)
    sigma = np.where(late > 0, scatter_factor, 1.0) * UM
    twin = LatheTwin(resolution=5 * UM).mount("T1")
    feed(twin, 3 * UM * parts + accelerate * UM * late**2 + rng.normal(0, 1, 40) * sigma)
    return twin


def test_end_of_life_false_alarms_match_the_confidence() -> None:
    # Constant drift: the slope test is Student's t and the scatter test Fisher's F exactly,
    # so each fires with probability 1 - 0.99 = 1 %. Over 400 tools: 4 expected, sd 2.
    signs = [_life(seed).end_of_life(window=10, confidence=0.99) for seed in range(400)]
    assert all(s is not None for s in signs)
    assert sum(s.accelerating for s in signs if s) <= 4 + 4 * 2
    assert sum(s.scatter_growing for s in signs if s) <= 4 + 4 * 2


def test_growing_scatter_is_found_with_fishers_power() -> None:
    # Scatter tripled over the last 10 parts: the variance ratio over 9 follows F(8, 29), so
    # the detection rate is F.sf(F.ppf(0.99) / 9). Binomial sd over 300 tools <= 0.029.
    found = [_life(seed, scatter_factor=3.0).end_of_life() for seed in range(300)]
    rate = np.mean([s.scatter_growing for s in found if s])
    power = stats.f.sf(stats.f.ppf(0.99, 8, 29) / 9.0, 8, 29)
    assert rate == pytest.approx(power, abs=4 * math.sqrt(power * (1 - power) / 300) + 0.005)


def test_accelerating_wear_is_found() -> None:
    # 0.05 um/part^2 after part 30 adds 0.5 um/part of slope by part 40 on average, about
    # 9 standard errors of the window slope (1 um / sqrt(82.5) = 0.11 um/part).
    found = [_life(seed, accelerate=0.05).end_of_life() for seed in range(100)]
    assert np.mean([s.accelerating for s in found if s]) >= 0.97


def test_end_of_life_needs_two_windows_of_parts() -> None:
    twin = ToolTwin("T1")
    for part in range(1, 20):
        twin.observe(3e-6 * part)
    assert twin.end_of_life(window=10) is None
    with pytest.raises(InputError, match="window"):
        twin.end_of_life(window=2)


# -- the lathe twin and heritage --------------------------------------------------------------


def _retired(
    lathe: LatheTwin,
    tool_id: str,
    slope_um: float,
    parameters: ManufacturingParameters = CONDITIONS,
) -> None:
    twin = lathe.mount(tool_id, parameters)
    feed(twin, slope_um * UM * np.arange(1, 11))
    lathe.retire(tool_id)


def test_heritage_corrects_the_first_part() -> None:
    lathe = LatheTwin(resolution=5 * UM)
    _retired(lathe, "old", 3.0)
    new = lathe.mount("new", CONDITIONS)
    assert new.heritage is not None and new.heritage.tool_id == "old"
    assert new.heritage.slope == pytest.approx(3 * UM, rel=1e-12)
    # Before part 1: -3 um rounded to the 5 um step.
    assert new.offset == pytest.approx(-5 * UM, abs=1e-15)
    # Untrusted own slope after part 1: the heritage drives the correction for part 2
    # (-6 um, rounded -5 um: nothing more to apply).
    seen = new.observe(3 * UM + new.offset)
    assert (seen.trusted, seen.source, seen.correction) == (False, "heritage", 0.0)


def test_heritage_chooses_the_most_similar_conditions() -> None:
    lathe = LatheTwin(resolution=5 * UM)
    faster = ManufacturingParameters("C45", "CNMG 120408", 3.6, 0.2e-3, 1.0e-3)  # 8.3 % faster
    close = ManufacturingParameters("C45", "CNMG 120408", 3.4, 0.2e-3, 1.0e-3)  # 2.9 % faster
    steel = ManufacturingParameters("42CrMo4", "CNMG 120408", 3.3, 0.2e-3, 1.0e-3)
    far = ManufacturingParameters("C45", "CNMG 120408", 5.0, 0.2e-3, 1.0e-3)  # 34 % faster
    _retired(lathe, "faster", 4.0, faster)
    _retired(lathe, "close", 3.5, close)
    _retired(lathe, "steel", 2.0, steel)
    _retired(lathe, "far", 6.0, far)
    chosen = lathe.select_heritage(CONDITIONS)
    assert chosen is not None and chosen.tool_id == "close"
    assert chosen.distance == pytest.approx(0.1 / 3.4)
    assert lathe.select_heritage(ManufacturingParameters("C45", "DNMG", 3.3, 2e-4, 1e-3)) is None
    assert lathe.mount("T9", CONDITIONS, inherit=False).heritage is None


def test_heritage_is_the_last_trusted_slope_and_needs_one() -> None:
    lathe = LatheTwin(resolution=5 * UM)
    never = lathe.mount("never", CONDITIONS)
    for d in (3.0, 9.0, 4.0):  # never stable
        never.observe(d * UM)
    lathe.retire("never")
    assert lathe.select_heritage(CONDITIONS) is None
    worn = lathe.mount("worn", CONDITIONS)
    feed(worn, 3 * UM * np.arange(1, 11))
    worn.observe(60 * UM + worn.offset)  # a jump at the end of life: slope no longer trusted
    assert not worn.is_trusted
    lathe.retire("worn")
    chosen = lathe.select_heritage(CONDITIONS)
    assert chosen is not None and chosen.slope == pytest.approx(3 * UM, rel=1e-12)
    assert chosen.parts == 11


def test_lathe_refuses_unknown_and_duplicate_tools() -> None:
    lathe = LatheTwin(resolution=5 * UM)
    lathe.mount("T1", CONDITIONS)
    with pytest.raises(InputError, match="already mounted"):
        lathe.mount("T1", CONDITIONS)
    with pytest.raises(DataError, match="not mounted"):
        lathe.measure("T2", 1e-6)
    with pytest.raises(ConfigError, match="cutting_speed"):
        ManufacturingParameters("C45", "CNMG", -1.0, 2e-4, 1e-3)


def test_state_survives_a_json_round_trip() -> None:
    lathe = LatheTwin(resolution=5 * UM)
    _retired(lathe, "old", 3.0)
    current = lathe.mount("new", CONDITIONS)
    rng = np.random.default_rng(5)
    feed(current, 3 * UM * np.arange(1, 8) + rng.normal(0, 1 * UM, 7))
    restored = LatheTwin.from_dict(json.loads(json.dumps(lathe.to_dict())))
    assert restored.to_dict() == lathe.to_dict()
    copy = restored.active["new"]
    assert copy.offset == current.offset and copy.deviations == current.deviations
    # The restored twin carries on exactly as the original.
    assert copy.observe(25 * UM) == current.observe(25 * UM)
    with pytest.raises(ConfigError, match="missing keys"):
        ToolTwin.from_dict({"tool_id": "T1"})
