"""The force band of use case 1, against closed forms of its definition."""

from __future__ import annotations

import numpy as np
import pytest

from cnctwin.twin.monitoring import ForceBand
from cnctwin.twin.settings import ForceBandConfig


def test_band_width_follows_the_residual_scatter() -> None:
    cfg = ForceBandConfig(k=4.0, min_width_n=1.0, min_width_rel=0.0, settle_cycles=0,
                          scatter_window=1000)  # fmt: skip
    band = ForceBand(cfg)
    rng = np.random.default_rng(1)
    residuals = rng.normal(0.0, 3.0, 1000)
    for r in residuals:
        band.update(100.0, 100.0 + r)
    # the scatter is the sample standard deviation of the in-band residuals (the k = 4 band
    # at sigma = 3 excludes almost none of 1000 normal samples)
    kept = residuals[np.abs(residuals) <= 4.0 * 3.0 * 1.2]
    assert band.scatter_n == pytest.approx(np.std(kept, ddof=1), rel=0.02)
    result = band.update(100.0, 100.0)
    assert result.high_n - 100.0 == pytest.approx(4.0 * band.scatter_n, rel=0.01)


def test_minimum_widths_and_the_previous_prediction() -> None:
    cfg = ForceBandConfig(k=4.0, min_width_n=15.0, min_width_rel=0.1, settle_cycles=0)
    band = ForceBand(cfg)
    first = band.update(300.0, 300.0)
    assert (first.low_n, first.high_n) == pytest.approx((270.0, 330.0))  # 10 % of 300 N
    second = band.update(100.0, 100.0)  # the prediction fell: the band spans both
    assert (second.low_n, second.high_n) == pytest.approx((85.0, 315.0))


def test_band_arms_after_settling_in_contact_and_flags_a_drop() -> None:
    cfg = ForceBandConfig(k=4.0, min_width_n=15.0, min_predicted_n=10.0, settle_cycles=3)
    band = ForceBand(cfg)
    assert not band.update(5.0, 80.0).armed  # in air: never armed
    results = [band.update(100.0, 101.0) for _ in range(5)]
    assert [r.armed for r in results] == [False, False, False, True, True]
    hole = band.update(100.0, 3.0)  # the tool cuts air where the twin expects material
    assert hole.armed and hole.out_of_band and hole.residual_n == pytest.approx(-97.0)
    band.reset_contact()
    assert not band.update(100.0, 3.0).armed  # after a gap it settles again
