"""The MIRS feed/speed search (cnctwin.optimize.residual_stress) on functions of known optimum,
and on the elastic MIRS model of the Ward 2021 case."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.errors import ConfigError
from cnctwin.mechanics import milling_material
from cnctwin.mechanics.materials import elastic_material
from cnctwin.mechanics.residual_stress import ElasticMirsModel
from cnctwin.optimize.residual_stress import MillingMirs, search_feed_speed


def test_a_chip_load_limit_keeps_the_highest_speed_and_lowers_the_feed() -> None:
    calls: list[tuple[float, float]] = []

    def mirs(feed: float, rpm: float) -> float:  # proportional to the feed per tooth
        calls.append((feed, rpm))
        return 1e6 * feed / rpm

    found = search_feed_speed(mirs, 0.3e6, (100.0, 20000.0), (10000.0, 30000.0))
    assert found.feasible
    assert found.spindle_rpm == 30000.0
    assert found.feed_mm_min == pytest.approx(9000.0, abs=1.0)  # 0.3 * 30000
    assert found.feed_mm_min <= 9000.0 and found.mirs_pa <= 0.3e6
    assert found.evaluations == len(calls)


def test_a_speed_penalty_moves_the_choice_to_a_lower_speed() -> None:
    found = search_feed_speed(
        lambda feed, rpm: feed * rpm, 2.0e7, (100.0, 5000.0), (5000.0, 30000.0), speeds=6
    )
    assert found.feasible
    assert found.spindle_rpm == 5000.0
    assert found.feed_mm_min == 4000.0 or found.feed_mm_min == pytest.approx(4000.0, abs=1.0)


def test_the_upper_feed_bound_wins_when_the_limit_is_loose() -> None:
    found = search_feed_speed(lambda f, n: f / n, 10.0, (100.0, 14400.0), (18000.0, 30000.0))
    assert (found.feasible, found.feed_mm_min, found.spindle_rpm) == (True, 14400.0, 30000.0)


def test_no_allowed_feed_meets_the_limit() -> None:
    found = search_feed_speed(lambda f, n: f / n, 1e-6, (100.0, 200.0), (1000.0, 2000.0))
    assert not found.feasible
    assert (found.feed_mm_min, found.spindle_rpm) == (100.0, 2000.0)
    assert found.mirs_pa == pytest.approx(0.05)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        ((1.0, (0.0, 10.0), (1.0, 2.0)), r"feed_range_mm_min = \(0\.0, 10\.0\)"),
        ((1.0, (1.0, 10.0), (3.0, 2.0)), r"spindle_range_rpm = \(3\.0, 2\.0\)"),
        ((-1.0, (1.0, 10.0), (1.0, 2.0)), r"MIRS limit = -1\.0 Pa"),
    ],
)
def test_bad_bounds_are_one_clear_error(args: tuple, words: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ConfigError, match=words):
        search_feed_speed(lambda f, n: f, *args)


def test_ward_case_thirty_percent_reduction_with_the_elastic_model() -> None:
    """Ward 2021's control objective (30 % less than at 30000 rpm, 14400 mm/min): the search
    stays at the highest speed and finds the feed where the MIRS meets the limit."""
    cut = MillingMirs(
        milling_material("AA7075-T6").coefficients,
        3,
        0.0,
        math.pi,
        ElasticMirsModel(elastic_material("AA7050-T7451"), 0.1e-3, np.linspace(0, 200e-6, 41)),
    )
    start = cut(14400.0, 30000.0)
    found = search_feed_speed(cut, 0.7 * start, (1000.0, 14400.0), (18750.0, 30000.0))
    assert found.feasible and found.spindle_rpm == 30000.0
    assert found.mirs_pa <= 0.7 * start < cut(found.feed_mm_min + 1.0, 30000.0)
